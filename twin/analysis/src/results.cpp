// Look-up and update of named parameter values (maglead/analysis/results.hpp).
#include "maglead/analysis/results.hpp"

#include <algorithm>

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

}  // namespace maglead::analysis
