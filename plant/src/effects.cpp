// The plant's --effect keys: the ids of docs/effects.md, each with the value of its
// main parameter, and ID.PARAMETER keys (the spec's parameter names) for the shape parameters;
// and friction_drift, a condition of the plant only.
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "maglead/plant/simulated_actuator.hpp"

namespace maglead {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct EffectEntry {
  const char* name;
  double PlantEffects::*field;
  double min, max;   // accepted values (inclusive)
  const char* unit;  // "1" for a ratio
  const char* meaning;
};

constexpr EffectEntry kEffects[] = {
    {"coulomb_friction", &PlantEffects::coulomb_friction_n, -kInf, kInf, "N",
     "added to the Coulomb friction F_c, kinetic and break-away (coulomb_n = F_c + value)"},
    {"viscous_friction", &PlantEffects::viscous_friction_n_s_per_m, -kInf, kInf, "N·s/m",
     "added to the viscous coefficient C (viscous_n_s_per_m = C + value)"},
    {"asymmetric_friction", &PlantEffects::asymmetric_friction_n, -kInf, kInf, "N",
     "kinetic and break-away friction F_c + value moving +p, F_c − value moving −p "
     "(coulomb_pos_n, coulomb_neg_n)"},
    {"stribeck_friction", &PlantEffects::stribeck_friction_n, 0.0, kInf, "N",
     "break-away excess F_s − F_c: F_k(v) = F_c + value·exp(−(v/v_s)²), stuck while "
     "|F_m + F_ext| ≤ F_c + value (breakaway_n = F_c + value)"},
    {"stribeck_friction.stribeck_velocity_m_s", &PlantEffects::stribeck_velocity_m_s, 1e-6, kInf,
     "m/s", "Stribeck velocity v_s (default 0.002)"},
    {"offset", &PlantEffects::offset_n, -kInf, kInf, "N",
     "constant force on the nut along +p, unseen by the load cell (offset_n)"},
    {"spring", &PlantEffects::spring_n_per_m, -kInf, kInf, "N/m",
     "spring −k (p − p₀) on the nut, p₀ mid-stroke (stiffness_n_per_m)"},
    {"mass_error", &PlantEffects::mass_error_kg, -kInf, kInf, "kg",
     "added to the moving mass M (nut_mass_kg = M + value)"},
    {"coupling_gain_error", &PlantEffects::coupling_gain_error, -0.9, kInf, "1",
     "F_m scaled by g = 1 + value (gain)"},
    {"gain_drift", &PlantEffects::gain_drift_per_min, -kInf, kInf, "1/min",
     "F_m scaled by 1 + value·t/60, t from the start (gain_change_per_min)"},
    {"angle_ripple", &PlantEffects::angle_ripple, 0.0, 0.99, "1",
     "F_m scaled by 1 + value·sin(θ + ψ), θ the screw angle (relative_amplitude)"},
    {"angle_ripple.phase_rad", &PlantEffects::angle_ripple_phase_rad, -kInf, kInf, "rad",
     "ψ of angle_ripple (default 0)"},
    {"position_ripple", &PlantEffects::position_ripple_n, -kInf, kInf, "N",
     "extra force value·sin(2πp/λ + ψ) on the nut (amplitude_n)"},
    {"position_ripple.period_m", &PlantEffects::position_ripple_period_m, 1e-6, kInf, "m",
     "λ of position_ripple (default 0.005)"},
    {"position_ripple.phase_rad", &PlantEffects::position_ripple_phase_rad, -kInf, kInf, "rad",
     "ψ of position_ripple (default 0)"},
    {"end_effect", &PlantEffects::end_effect_zone_m, 0.0, kInf, "m",
     "zone z: F_m scaled by 1 − D·s(x), s(x) = x²(3 − 2x), x = clip((z − d)/z, 0, 1), d the "
     "distance to the nearer stroke end (zone_m)"},
    {"end_effect.max_reduction", &PlantEffects::end_effect_max_reduction, 0.0, 1.0, "1",
     "D of end_effect (default 0.5)"},
    {"backlash", &PlantEffects::backlash_rad, 0.0, kInf, "rad",
     "total gear play b at the screw: the screw lags the motor by b/2 on the side of the "
     "transmitted torque (backlash_rad)"},
    {"load_cell_delay", &PlantEffects::load_cell_delay_s, 0.0, 1.0, "s",
     "the load-cell reading lags the true force (delay_s)"},
    {"sensor_delay", &PlantEffects::sensor_delay_s, 0.0, 1.0, "s",
     "the linear and motor encoder readings lag the true position and angle (delay_s)"},
    {"external_disturbance", &PlantEffects::external_disturbance_n, -kInf, kInf, "N",
     "50 ms force pulses on the nut at random times (force_n)"},
    // Not an id of docs/effects.md (the analysis does not look for it): a plant condition for
    // the twin's drift flag, which issue 23 asks to show live for "a friction change" too.
    {"friction_drift", &PlantEffects::coulomb_drift_n_per_min, -kInf, kInf, "N/min",
     "kinetic and break-away friction F_c + value·t/60, t from the start (wear, "
     "temperature; for the twin's drift flag, not an effect the analysis names)"},
};

}  // namespace

void set_plant_effect(PlantEffects& effects, const std::string& name, double value) {
  if (!std::isfinite(value))
    throw std::invalid_argument("effect '" + name + "': value must be a finite number");
  for (const auto& e : kEffects) {
    if (name == e.name) {
      if (value < e.min || value > e.max) {
        char range[96];
        const std::string unit = std::string(e.unit) == "1" ? "(a ratio)" : e.unit;
        if (std::isinf(e.max))
          std::snprintf(range, sizeof range, "at least %g %s", e.min, unit.c_str());
        else
          std::snprintf(range, sizeof range, "between %g and %g %s", e.min, e.max, unit.c_str());
        throw std::invalid_argument("effect '" + name + "': value must be " + range);
      }
      effects.*(e.field) = value;
      return;
    }
  }
  std::string known;
  for (const auto& e : kEffects) known += (known.empty() ? "" : ", ") + std::string(e.name);
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + known + ")");
}

namespace {

/// Refuses force effects beyond kPeaks × the coupling's peak force, where they stop describing
/// a bench: the coupling cannot hold the nut against them, so it only steps out, lead after
/// lead, for as long as the run lasts.
void check_plant_forces(const PlantEffects& e, const ActuatorParams& a, double coupling_peak_n) {
  constexpr double kPeaks = 10.0;  // well past a step-out, which an effect may want to provoke
  if (!(coupling_peak_n > 0)) return;
  const double bound_n = kPeaks * coupling_peak_n;
  const double half_stroke_m = 0.5 * (a.stroke_max_m - a.stroke_min_m);
  struct Force {
    const char* effect;
    double value, force_n;
    const char* unit;
  };
  const Force forces[] = {
      {"coulomb_friction", e.coulomb_friction_n, e.coulomb_friction_n, "N"},
      {"asymmetric_friction", e.asymmetric_friction_n, e.asymmetric_friction_n, "N"},
      {"stribeck_friction", e.stribeck_friction_n, e.stribeck_friction_n, "N"},
      {"offset", e.offset_n, e.offset_n, "N"},
      {"position_ripple", e.position_ripple_n, e.position_ripple_n, "N"},
      {"external_disturbance", e.external_disturbance_n, e.external_disturbance_n, "N"},
      // A spring's force at the stroke ends, half a stroke from its rest at mid-stroke.
      {"spring", e.spring_n_per_m, e.spring_n_per_m * half_stroke_m, "N/m"},
  };
  for (const auto& f : forces) {
    if (std::abs(f.force_n) <= bound_n) continue;
    const double limit = f.force_n == f.value ? bound_n : bound_n / half_stroke_m;
    char msg[320];
    std::snprintf(msg, sizeof msg,
                  "effect '%s' = %g %s is beyond %g x the coupling's peak force %.3g N: the nut "
                  "would only step out, lead after lead; type a value within -%.4g .. %.4g %s",
                  f.effect, f.value, f.unit, kPeaks, coupling_peak_n, limit, limit, f.unit);
    throw std::invalid_argument(msg);
  }
}

}  // namespace

void check_plant_totals(const PlantEffects& e, const ActuatorParams& a, double coupling_peak_n) {
  check_plant_forces(e, a, coupling_peak_n);
  struct Total {
    const char* effect;
    double change, total, least;
    const char* what;
  };
  const double fc = a.coulomb_n + e.coulomb_friction_n;
  const Total totals[] = {
      {"coulomb_friction", e.coulomb_friction_n, fc, 0.0, "Coulomb friction F_c + value [N]"},
      {"viscous_friction", e.viscous_friction_n_s_per_m,
       a.viscous_n_s_per_m + e.viscous_friction_n_s_per_m, 0.0,
       "viscous coefficient C + value [N·s/m]"},
      {"asymmetric_friction", e.asymmetric_friction_n, fc - std::abs(e.asymmetric_friction_n), 0.0,
       "the weaker side's friction F_c − |value| [N]"},
      // A moving mass must stay positive: the nut's dynamics divide by it.
      {"mass_error", e.mass_error_kg, a.nut_mass_kg + e.mass_error_kg, 1e-6,
       "moving mass M + value [kg]"},
  };
  for (const auto& t : totals)
    if (t.change != 0.0 && !(t.total >= t.least)) {
      char msg[256];
      std::snprintf(msg, sizeof msg,
                    "effect '%s' = %g makes the %s %g on this actuator (configured nominal %g); "
                    "it must be at least %g",
                    t.effect, t.change, t.what, t.total, t.total - t.change, t.least);
      throw std::invalid_argument(msg);
    }
}

std::vector<PlantEffectKey> plant_effect_keys() {
  std::vector<PlantEffectKey> out;
  for (const auto& e : kEffects) out.push_back({e.name, e.unit, e.meaning});
  return out;
}

}  // namespace maglead
