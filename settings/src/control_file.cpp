#include <cstdio>
#include <filesystem>

#include "maglead/physics/toml_config.hpp"
#include "maglead/settings/settings.hpp"

namespace maglead::settings {

std::string config_file(const std::string& config_dir, const std::string& name) {
  return (std::filesystem::path(config_dir) / name).string();
}

ActuatorParams load_actuator_or_default(const std::string& config_dir) {
  const std::string path = config_file(config_dir, "actuator.toml");
  if (!std::filesystem::exists(path)) return {};
  return load_actuator_params(path);
}

void serve_model_terms(const twin::TwinModel& model, controller::ControllerConfig& cfg) {
  cfg.friction = twin::friction_model(model);
  cfg.coupling = twin::coupling_model(model);
}

void load_control_settings(const std::string& config_dir, controller::ControllerConfig& r) {
  const std::string path = config_file(config_dir, "actuator.toml");
  if (!std::filesystem::exists(path)) return;
  read_control_section(path, r);
}

void read_control_section(const std::string& path, controller::ControllerConfig& r) {
  const toml::table root = config::parse_file(path);
  const toml::table* t = config::section(path, root, "control");
  if (!t) return;
  config::check_keys(
      path, *t, "[control]",
      {"force_reached_tolerance_n", "in_position_tolerance_m", "reached_dwell_s",
       "force_damping_n_s_per_m", "breakaway_ramp_n_per_s", "observer_model_uncertainty_n",
       "load_drift_n_per_s", "force_stroke_margin_m", "force_speed_limit_m_s"});
  const struct {
    const char* key;
    double* out;
    double lo, hi;
  } keys[] = {{"force_reached_tolerance_n", &r.force_tol_n, 0.0, 100.0},
              {"in_position_tolerance_m", &r.in_position_tol_m, 0.0, 0.01},
              {"reached_dwell_s", &r.settle_s, 0.0, 60.0},
              {"force_damping_n_s_per_m", &r.force_damping_n_s_per_m, 1e-3, 1e5},
              {"breakaway_ramp_n_per_s", &r.breakaway_ramp_n_per_s, 1e-3, 1e5},
              {"observer_model_uncertainty_n", &r.observer_model_uncertainty_n, 0.0, 100.0},
              {"load_drift_n_per_s", &r.load_drift_n_per_s, 0.0, 1000.0},
              {"force_stroke_margin_m", &r.force_stroke_margin_m, 0.0, 1.0},
              {"force_speed_limit_m_s", &r.force_speed_limit_m_s, 1e-4, 10.0}};
  for (const auto& key : keys) {
    char range[64];
    std::snprintf(range, sizeof range, "a number in %g .. %g", key.lo, key.hi);
    config::read_number(
        path, *t, "[control]", key.key, *key.out,
        [&](double v) { return v >= key.lo && v <= key.hi; }, range);
  }
}

controller::ControllerConfig controller_config_of(const std::string& config_dir,
                                                  const std::string& calibration,
                                                  const std::string& model,
                                                  std::string* model_used) {
  controller::ControllerConfig cfg;
  cfg.actuator = load_actuator_or_default(config_dir);
  cfg.calibration = load_calibration(
      calibration.empty() ? config_file(config_dir, "calibration.toml") : calibration);
  load_control_settings(config_dir, cfg);
  load_reference_move(config_dir, cfg.actuator, cfg.reference_move);
  const std::string model_path = model.empty() ? config_file(config_dir, "model.toml") : model;
  if (model_used) model_used->clear();
  if (std::filesystem::exists(model_path)) {
    serve_model_terms(twin::load_twin_model(model_path), cfg);
    if (model_used) *model_used = model_path;
  } else {
    cfg.friction = friction_from_actuator(cfg.actuator);
  }
  return cfg;
}

void load_reference_move(const std::string& config_dir, const ActuatorParams& actuator,
                         controller::ReferenceMoveConfig& move) {
  const std::string path = config_file(config_dir, "actuator.toml");
  if (!std::filesystem::exists(path)) return;
  read_reference_move_section(path, actuator, move);
}

void read_reference_move_section(const std::string& path, const ActuatorParams& actuator,
                                 controller::ReferenceMoveConfig& move) {
  const toml::table root = config::parse_file(path);
  const toml::table* t = config::section(path, root, "reference_move");
  if (!t) return;
  const char* label = "[reference_move]";
  config::check_keys(path, *t, label,
                     {"window_min_m", "window_max_m", "slow_m_s", "fast_m_s", "accel_m_s2"});
  controller::ReferenceMoveConfig r = move;  // `move` changes only when every value is good
  char stroke[96];
  std::snprintf(stroke, sizeof stroke, "a position within the stroke %g .. %g m",
                actuator.stroke_min_m, actuator.stroke_max_m);
  const auto in_stroke = [&](double v) {
    return v >= actuator.stroke_min_m && v <= actuator.stroke_max_m;
  };
  config::read_number(path, *t, label, "window_min_m", r.window_min_m, in_stroke, stroke);
  config::read_number(path, *t, label, "window_max_m", r.window_max_m, in_stroke, stroke);
  // The ranges a PLC may write to velocity_limit and accel_limit (registers 1016, 1018).
  const auto speed = [](double v) { return v >= 1e-5 && v <= 0.1; };
  config::read_number(path, *t, label, "slow_m_s", r.slow_m_s, speed, "a number in 1e-05 .. 0.1");
  config::read_number(path, *t, label, "fast_m_s", r.fast_m_s, speed, "a number in 1e-05 .. 0.1");
  config::read_number(
      path, *t, label, "accel_m_s2", r.accel_m_s2, [](double v) { return v >= 1e-4 && v <= 5.0; },
      "a number in 0.0001 .. 5");
  // Two speeds and a window with room: otherwise the move cannot separate what it is for.
  const auto pair_error = [&](const char* key, const char* what, double other) {
    char text[160];
    std::snprintf(text, sizeof text, "%s %s must be above %s (%g)", label, key, what, other);
    config::fail(path, t->get(key) ? t->get(key) : static_cast<const toml::node*>(t), text);
  };
  if (!(r.window_max_m > r.window_min_m))
    pair_error("window_max_m", "window_min_m", r.window_min_m);
  if (!(r.fast_m_s > r.slow_m_s)) pair_error("fast_m_s", "slow_m_s", r.slow_m_s);
  move = r;
}

}  // namespace maglead::settings
