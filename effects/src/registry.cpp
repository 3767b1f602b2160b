// The registry: every effect unit, in the analysis's order of preference among explanations
// the data cannot tell apart (common mechanical causes first, sensor artefacts last).
#include <cmath>
#include <stdexcept>

#include "maglead/effects/effect.hpp"
#include "units.hpp"

namespace maglead::effects {

double sgn(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

void check_columns(const Effect& e) {
  for (const int n : {e.columns(), e.axis_columns()})
    if (n < 0 || n > kMaxColumns)
      throw std::logic_error("effect '" + std::string(e.id()) + "' has " + std::to_string(n) +
                             " regressor columns; a unit has 0 (an event) to " +
                             std::to_string(kMaxColumns) + " (effects::kMaxColumns)");
}

namespace {
std::vector<const Effect*> checked(std::vector<const Effect*> units) {
  for (const Effect* e : units) check_columns(*e);
  return units;
}
}  // namespace

const std::vector<const Effect*>& library() {
  static const std::vector<const Effect*> all =
      checked({&coulomb_friction(), &viscous_friction(), &offset(), &asymmetric_friction(),
               &stribeck_friction(), &spring(), &mass_error(), &gain_drift(), &angle_ripple(),
               &position_ripple(), &end_effect(), &backlash(), &load_cell_delay(),
               &coupling_gain_error(), &sensor_delay(), &external_disturbance(), &step_out()});
  return all;
}

const Effect* find(std::string_view id) {
  for (const Effect* e : library())
    if (e->id() == id) return e;
  return nullptr;
}

void check(const Effect& e, const Params& p) {
  for (const auto& [name, value] : p) {
    bool known = false;
    for (const auto& s : e.params()) known |= s.name == name;
    if (!known)
      throw std::invalid_argument("effect '" + std::string(e.id()) + "' has no parameter '" + name +
                                  "'");
    if (!std::isfinite(value))
      throw std::invalid_argument("effect '" + std::string(e.id()) + "': parameter '" + name +
                                  "' is not a finite number");
  }
}

namespace {
// The size one unit of a range stands for; 0 when the scale is not known.
double unit_of(Scale per, const Scales& scales) {
  switch (per) {
    case Scale::absolute:
      return 1.0;
    case Scale::force:
      return scales.force_n;
    case Scale::force_per_speed:
      return scales.speed_m_s > 0 ? scales.force_n / scales.speed_m_s : 0.0;
  }
  return 0.0;
}
}  // namespace

bool plausible(const Effect& e, const Params& p, const Scales& scales) {
  for (const auto& s : e.params()) {
    const auto it = p.find(s.name);
    if (it == p.end()) continue;
    const double unit = unit_of(s.per, scales);
    const double v = it->second;
    if (unit > 0) {
      if (v < s.min * unit || v > s.max * unit) return false;
    } else if (s.min >= 0 && v < 0) {  // the scale unknown: only the sign is judged
      return false;
    }
  }
  return beyond_its_error(e, p, {}, scales);
}

bool beyond_its_error(const Effect& e, const Params& p, const Params& se, const Scales& scales) {
  for (const auto& s : e.params()) {
    const double v = param(p, s.name.c_str(), NAN), err = param(se, s.name.c_str(), 0.0);
    if (!std::isfinite(v)) continue;
    if (s.least_counts > 0 && v - err < s.least_counts * scales.phase_count_rad) return false;
    // A variant that does not fit a magnitude leaves it at zero: nothing to judge.
    if (s.min == 0 && v != 0 && v - err <= 0) return false;
  }
  return true;
}

double param(const Params& p, const char* name, double fallback) {
  const auto it = p.find(name);
  return it == p.end() ? fallback : it->second;
}

}  // namespace maglead::effects
