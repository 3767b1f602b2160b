#pragma once
// Model files in the twin's format (config/model.toml, twin/include/maglead/twin/model.hpp):
// [model] with nut_mass_kg, viscous_n_s_per_m, coulomb_n, then [[term]] tables of named effects.
// Two additions for systems that are not the actuator (the EMPS axis), which the twin never
// loads: `system = "axis"` and `fit = ["nut_mass_kg", …]` naming values that are unknown and
// are fitted from the recording as part of the baseline.
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace maglead::analysis {

struct ModelTerm {
  std::string id;
  bool enabled = true;
  std::string note;
  std::vector<std::pair<std::string, double>> parameters;  // twin names (units in the names)
  double get(const std::string& key, double fallback) const;
  void set(const std::string& key, double value);
};

struct ModelFile {
  std::string system = "actuator";  // "actuator": magnetic lead screw; "axis": force-driven axis
  std::string source;
  double nut_mass_kg = 0.12, viscous_n_s_per_m = 2.0, coulomb_n = 7.5;
  std::set<std::string> fit;  // [model] keys whose values are unknown (fitted)
  std::vector<ModelTerm> terms;
  const ModelTerm* find(const std::string& id) const;  // enabled terms only
  ModelTerm& term(const std::string& id);               // finds or appends
};

/// Throws std::runtime_error naming the file, and the term and key where one is at fault.
ModelFile load_model(const std::string& path);
void save_model(const std::string& path, const ModelFile& model, const std::string& header);

}  // namespace maglead::analysis
