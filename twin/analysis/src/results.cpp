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

std::string summary_text(const Parameters& values, const Parameters& standard_errors) {
  std::string s;
  for (const auto& p : values)
    s += (s.empty() ? "" : ", ") +
         with_error(p.name, p.value, parameter_value(standard_errors, p.name, 0.0));
  return s;
}

}  // namespace maglead::analysis
