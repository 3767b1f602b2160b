#include "maglead/physics/actuator.hpp"

#include <set>
#include <stdexcept>

#include "maglead/physics/toml_config.hpp"

namespace maglead {
namespace {

void read_positive(const toml::table& t, const std::string& file, const char* key, double& out) {
  const toml::node* node = t.get(key);
  if (!node) return;
  auto v = node->value<double>();
  if (!v || !(*v > 0.0)) config::fail(file, node, std::string("[actuator] ") + key + " must be a positive number");
  out = *v;
}

}  // namespace

ActuatorParams load_actuator_params(const std::string& path) {
  const toml::table root = config::parse_file(path);
  ActuatorParams a;
  const toml::table* t = root["actuator"].as_table();
  if (!t) config::fail(path, root.get("actuator"), "missing [actuator] table");
  static const std::set<std::string> known{"lead_m", "gear_ratio", "motor_counts_per_rev", "linear_count_m",
                                           "nut_mass_kg", "viscous_n_s_per_m", "coulomb_n", "stroke_min_m",
                                           "stroke_max_m", "sample_rate_hz", "safe_force_fraction"};
  for (const auto& [k, v] : *t)
    if (!known.count(std::string(k.str()))) config::fail(path, &v, "[actuator] unknown key '" + std::string(k.str()) + "'");
  read_positive(*t, path, "lead_m", a.lead_m);
  read_positive(*t, path, "gear_ratio", a.gear_ratio);
  read_positive(*t, path, "motor_counts_per_rev", a.motor_counts_per_rev);
  read_positive(*t, path, "linear_count_m", a.linear_count_m);
  read_positive(*t, path, "nut_mass_kg", a.nut_mass_kg);
  read_positive(*t, path, "viscous_n_s_per_m", a.viscous_n_s_per_m);
  read_positive(*t, path, "coulomb_n", a.coulomb_n);
  read_positive(*t, path, "stroke_max_m", a.stroke_max_m);
  read_positive(*t, path, "sample_rate_hz", a.sample_rate_hz);
  read_positive(*t, path, "safe_force_fraction", a.safe_force_fraction);
  if (const toml::node* n = t->get("stroke_min_m")) {
    const auto v = n->value<double>();
    if (!v) config::fail(path, n, "[actuator] stroke_min_m must be a number");
    a.stroke_min_m = *v;
  }
  if (a.stroke_min_m >= a.stroke_max_m)
    config::fail(path, t->get("stroke_min_m") ? t->get("stroke_min_m") : t->get("stroke_max_m"),
                 "[actuator] stroke_min_m must be below stroke_max_m");
  if (a.safe_force_fraction > 1.0)
    config::fail(path, t->get("safe_force_fraction"), "[actuator] safe_force_fraction must be at most 1");
  return a;
}

}  // namespace maglead
