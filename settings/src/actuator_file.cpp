#include "maglead/settings/settings.hpp"

#include <cmath>
#include <cstdio>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "maglead/physics/toml_config.hpp"

namespace maglead {
namespace {

/// Bounds a length must keep to be in metres at all (not a fit to any actuator): beyond them the
/// number was typed in millimetres, which the simulated plant would follow without complaint.
struct LengthBound {
  const char* key;
  double max_m;
  const char* what;  // why no value beyond max_m is metres
};
constexpr LengthBound kLengthBounds[] = {
    {"lead_m", 1.0, "no lead screw advances a metre per turn"},
    {"linear_count_m", 1e-3,
     "no linear encoder that resolves the coupling's phase counts coarser than 1 mm"},
    {"stroke_min_m", 10.0, "no lead-screw actuator travels 10 m"},
    {"stroke_max_m", 10.0, "no lead-screw actuator travels 10 m"}};

void check_lengths_are_metres(const std::string& path, const toml::table& t,
                              const ActuatorParams& a) {
  const double values[] = {a.lead_m, a.linear_count_m, a.stroke_min_m, a.stroke_max_m};
  for (std::size_t i = 0; i < std::size(kLengthBounds); ++i) {
    const LengthBound& b = kLengthBounds[i];
    if (std::abs(values[i]) <= b.max_m) continue;
    char text[320];
    std::snprintf(text, sizeof text,
                  "[actuator] %s = %g cannot be metres (%s); likely millimetres: write %g", b.key,
                  values[i], b.what, values[i] * 1e-3);
    config::fail(path, t.get(b.key), text);
  }
}

}  // namespace

ActuatorParams load_actuator_params(const std::string& path) {
  const toml::table root = config::parse_file(path);
  ActuatorParams a;
  const toml::table& t = *config::section(path, root, "actuator", true);
  const std::string label = "[actuator]";
  config::check_keys(path, t, label,
                     {"lead_m", "gear_ratio", "motor_counts_per_rev", "linear_count_m",
                      "nut_mass_kg", "viscous_n_s_per_m", "coulomb_n", "stroke_min_m",
                      "stroke_max_m", "sample_rate_hz", "safe_force_fraction"});
  const auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  for (auto [key, out] : {std::pair{"lead_m", &a.lead_m},
                          {"gear_ratio", &a.gear_ratio},
                          {"motor_counts_per_rev", &a.motor_counts_per_rev},
                          {"linear_count_m", &a.linear_count_m},
                          {"nut_mass_kg", &a.nut_mass_kg},
                          {"viscous_n_s_per_m", &a.viscous_n_s_per_m},
                          {"coulomb_n", &a.coulomb_n},
                          {"stroke_max_m", &a.stroke_max_m},
                          {"sample_rate_hz", &a.sample_rate_hz},
                          {"safe_force_fraction", &a.safe_force_fraction}})
    config::read_number(path, t, label, key, *out, positive, "a positive number");
  config::read_number(path, t, label, "stroke_min_m", a.stroke_min_m);
  check_lengths_are_metres(path, t, a);
  if (a.stroke_min_m >= a.stroke_max_m)
    config::fail(path, t.get("stroke_min_m") ? t.get("stroke_min_m") : t.get("stroke_max_m"),
                 "[actuator] stroke_min_m must be below stroke_max_m");
  if (a.safe_force_fraction > 1.0)
    config::fail(path, t.get("safe_force_fraction"),
                 "[actuator] safe_force_fraction must be at most 1");
  // The file's other tables, checked here whoever reads the file: a misspelt key under [control]
  // is refused by analyze as by serve (docs/configuration.md: any unknown key is refused).
  config::check_keys(path, root, "actuator.toml", {"actuator", "reference_move", "control"});
  controller::ControllerConfig control;
  settings::read_control_section(path, control);
  controller::ReferenceMoveConfig move;
  settings::read_reference_move_section(path, a, move);
  return a;
}

}  // namespace maglead
