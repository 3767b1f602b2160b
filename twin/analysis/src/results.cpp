// Look-up, update and printing of named parameter values (maglead/analysis/results.hpp).
#include "maglead/analysis/results.hpp"
#include "maglead/analysis/rules.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace maglead::analysis {

double parameter_value(const Parameters& p, const std::string& name, double fallback) {
  const auto it =
      std::find_if(p.begin(), p.end(), [&](const Parameter& q) { return q.name == name; });
  return it == p.end() ? fallback : it->value;
}

void set_parameter(Parameters& p, const std::string& name, double value, bool is_count) {
  const auto it = std::find_if(p.begin(), p.end(), [&](Parameter& q) { return q.name == name; });
  if (it != p.end())
    *it = {name, value, is_count};
  else
    p.push_back({name, value, is_count});
}

std::string value_with_error(double value, double standard_error) {
  const double se = standard_error;
  // A value on a scanned grid (the same in every segment's fit), or not fitted.
  if (!(se > 1e-9 * std::abs(value)) || !std::isfinite(se)) return "";
  int digits = -static_cast<int>(std::floor(std::log10(se)));
  if (se * std::pow(10.0, digits) < 2.0) ++digits;
  digits = std::clamp(digits, 0, 12);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.*f ± %.*f", digits, value, digits, se);
  return buf;
}

std::string calibration_bound_text(const std::string& name, double bound) {
  const std::string unit = unit_of_parameter(name);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.2g%s%s", bound, unit.empty() ? "" : " ", unit.c_str());
  return buf;
}

std::string with_error(const std::string& name, double value, double standard_error) {
  if (auto v = value_with_error(value, standard_error); !v.empty()) return name + " " + v;
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s %.4g", name.c_str(), value);
  return buf;
}

bool misfit_remains(double final_rms_n, double noise_floor_n) {
  // Above twice the load cell's own noise the residual is force the model leaves out.
  return noise_floor_n > 0 && final_rms_n > rules::kMisfitOverFloor * noise_floor_n;
}

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}
}  // namespace

std::string noise_floor_text(const Findings& f, const effects::AxisKind& kind) {
  const std::string unit = " " + std::string(kind.drive_unit);
  if (!f.noise_step_n) return "noise floor " + num(f.noise_floor_n) + unit;
  if (!(*f.noise_step_n > 0)) return "noise floor not measurable";
  return "noise floor not measurable below the " + num(*f.noise_step_n) + unit +
         " logging step: " + num(f.noise_floor_n) + unit;
}

std::string misfit_text(const Findings& f, const effects::AxisKind& kind) {
  const std::string unit(kind.drive_unit);
  // A candidate that would take at least half the held-out error is the misfit's likeliest
  // account, even short of significance; below half it says little of what is left.
  constexpr double kMostOfItPct = rules::kMostOfItPct;
  std::string s = "a misfit of " + num(f.final_fit.rms_n) + " " + unit + " RMS remains (" +
                  noise_floor_text(f, kind) + ")";
  for (const auto& r : f.not_selected) {
    if (!r.reason || !r.reason->starts_with(kBelowSignificance) ||
        !(r.heldout_gain_pct >= kMostOfItPct))
      continue;
    // The rule it failed, as the left-out table gives it (after "…threshold: ").
    const std::size_t detail = r.reason->find(": ", std::string(kBelowSignificance).size());
    s += ": " + r.id + " would explain " + num(r.heldout_gain_pct) +
         " % of it held out, but short of significance (" +
         (detail == std::string::npos ? std::string("below the threshold")
                                      : r.reason->substr(detail + 2)) +
         ")";
    return kind.words(s + "; not settled by this recording: record longer or with more sliding");
  }
  return kind.words(s + " that no library effect explains");
}

namespace {

std::string count_text(std::size_t n, const std::string& what) {
  return std::to_string(n) + " " + what + (n == 1 ? "" : "s");
}

}  // namespace

void conclude(Findings& f, const Concluding& c) {
  // Events (pulses) are findings beside the model's terms, listed in the events: "1 model term
  // and 2 events found", never "1 effect(s) found" over both.
  std::size_t events_found = 0;
  std::string event_ids;
  for (const auto& e : f.effects) {
    if (!e.evidence.events) continue;
    events_found += *e.evidence.events;
    event_ids += (event_ids.empty() ? "" : ", ") + e.id;
  }
  if (c.terms_named > 0) {
    f.conclusion = events_found == 0 ? std::to_string(c.terms_named) + " effect(s) found"
                                     : count_text(c.terms_named, "model term") + " and " +
                                           count_text(events_found, "event") + " found";
    return;
  }
  if (c.implausible) {
    f.conclusion = "a force is missing that no library effect explains plausibly (see below)";
    return;
  }
  const std::string none =
      "no effect explains a significant part of the held-out error" + c.unresolved;
  // "Nothing is missing" would hide the events; a misfit above the floor beside them is said.
  if (!event_ids.empty()) {
    if (misfit_remains(f.final_fit.rms_n, f.noise_floor_n)) {
      f.conclusion = "events found (" + event_ids + "); " + misfit_text(f, *c.kind) + "; check " +
                     c.kind->words(c.check);
      f.nothing_missing = false;
    } else {
      f.conclusion = "events found (" + event_ids + "); " + none;
    }
  } else if (misfit_remains(f.final_fit.rms_n, f.noise_floor_n)) {
    f.conclusion = misfit_text(f, *c.kind) + "; check " + c.kind->words(c.check);
    f.nothing_missing = false;
  } else {
    f.conclusion = "nothing is missing: " + none;
  }
}

std::string unit_of_parameter(const std::string& name) {
  struct Suffix {
    const char* suffix;
    const char* unit;
  };
  // A rotary axis's names first (effects/axis_kind.hpp): `_n_m_s_per_rad` ends in `_rad` too.
  static constexpr Suffix kSuffixes[] = {{"_n_m_s_per_rad", "N·m·s/rad"},
                                         {"_n_m_per_rad", "N·m/rad"},
                                         {"_rad_s", "rad/s"},
                                         {"_n_m", "N·m"},
                                         {"_kg_m2", "kg·m²"},
                                         {"_n_s_per_m", "N·s/m"},
                                         {"_n_per_m", "N/m"},
                                         {"_per_min", "1/min"},
                                         {"_n", "N"},
                                         {"_kg", "kg"},
                                         {"_rad", "rad"},
                                         {"_m_s", "m/s"},
                                         {"_m", "m"},
                                         {"_s", "s"}};
  for (const auto& s : kSuffixes) {
    const std::string suffix = s.suffix;
    if (name.size() > suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      return s.unit;
  }
  return "";
}

std::string resolvable_text(const std::vector<Resolvable>& r) {
  std::string s;
  for (const auto& x : r) {
    char b[160];
    std::snprintf(b, sizeof b, "%s%s %.2g%s%s", s.empty() ? "" : ", ", x.parameter.c_str(),
                  x.smallest_change, x.unit.empty() ? "" : " ", x.unit.c_str());
    s += b;
  }
  return s;
}

Parameters stated_errors(const Parameters& values, const Parameters& standard_errors) {
  Parameters out;
  for (const auto& e : standard_errors)
    if (!value_with_error(parameter_value(values, e.name, 0.0), e.value).empty()) out.push_back(e);
  return out;
}

std::string summary_text(const Parameters& values, const Parameters& standard_errors) {
  std::string s;
  for (const auto& p : values) {
    const std::string unit = unit_of_parameter(p.name);
    const double se = parameter_value(standard_errors, p.name, 0.0);
    // Beside fitted values, one without an error was scanned on a grid (a period, a delay) or
    // held at the model's: said, so its missing ± is not read as an exact value.
    const bool no_error = !standard_errors.empty() && value_with_error(p.value, se).empty();
    s += (s.empty() ? "" : ", ") + with_error(p.name, p.value, se) +
         (unit.empty() ? "" : " " + unit) + (no_error ? " (no standard error)" : "");
  }
  return s;
}

}  // namespace maglead::analysis
