// Look-up, update and printing of named parameter values (maglead/analysis/results.hpp).
#include "maglead/analysis/results.hpp"

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

std::string with_error(const std::string& name, double value, double standard_error) {
  if (auto v = value_with_error(value, standard_error); !v.empty()) return name + " " + v;
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s %.4g", name.c_str(), value);
  return buf;
}

bool misfit_remains(double final_rms_n, double noise_floor_n) {
  // Above twice the load cell's own noise the residual is force the model leaves out.
  constexpr double kMisfitOverFloor = 2.0;
  return noise_floor_n > 0 && final_rms_n > kMisfitOverFloor * noise_floor_n;
}

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}
}  // namespace

std::string misfit_text(double final_rms_n, double noise_floor_n,
                        const std::vector<Rejected>& not_selected) {
  // A candidate that would take at least half the held-out error is the misfit's likeliest
  // account, even short of significance; below half it says little of what is left.
  constexpr double kMostOfItPct = 50.0;
  std::string s =
      "a misfit of " + num(final_rms_n) + " N RMS remains (floor " + num(noise_floor_n) + " N)";
  for (const auto& r : not_selected) {
    if (r.reason != std::string(kBelowSignificance) || !(r.heldout_gain_pct >= kMostOfItPct))
      continue;
    s += ": " + r.id + " would explain " + num(r.heldout_gain_pct) +
         " % of it held out, but not consistently over the recording's segments (t = " +
         num(r.t_stat) + ", below the threshold";
    if (r.worst_segment_pct && *r.worst_segment_pct < 0)
      s += ", one segment " + num(-*r.worst_segment_pct) + " % worse with it";
    return s + "); not settled by this recording: record longer or with more sliding";
  }
  return s + " that no library effect explains";
}

std::string summary_text(const Parameters& values, const Parameters& standard_errors) {
  std::string s;
  for (const auto& p : values)
    s += (s.empty() ? "" : ", ") +
         with_error(p.name, p.value, parameter_value(standard_errors, p.name, 0.0));
  return s;
}

}  // namespace maglead::analysis
