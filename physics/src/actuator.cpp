#include "maglead/physics/actuator.hpp"

#include <stdexcept>
#include <toml++/toml.h>

namespace maglead {
namespace {

void read_positive(const toml::table& t, const std::string& file, const char* key, double& out) {
  auto node = t[key];
  if (!node) return;
  auto v = node.value<double>();
  if (!v || !(*v > 0.0))
    throw std::runtime_error(file + ": [actuator] " + key + " must be a positive number");
  out = *v;
}

}  // namespace

ActuatorParams load_actuator_params(const std::string& path) {
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(path + ":" + std::to_string(e.source().begin.line) + ": " +
                             std::string(e.description()));
  }
  ActuatorParams a;
  const toml::table* t = root["actuator"].as_table();
  if (!t) throw std::runtime_error(path + ": missing [actuator] table");
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
  if (auto v = (*t)["stroke_min_m"].value<double>()) a.stroke_min_m = *v;
  if (a.stroke_min_m >= a.stroke_max_m)
    throw std::runtime_error(path + ": [actuator] stroke_min_m must be below stroke_max_m");
  if (a.safe_force_fraction > 1.0)
    throw std::runtime_error(path + ": [actuator] safe_force_fraction must be at most 1");
  return a;
}

}  // namespace maglead
