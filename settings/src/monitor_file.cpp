#include <filesystem>

#include "maglead/settings/settings.hpp"

namespace maglead::twin {

TwinMonitorConfig load_monitor_config(const std::string& dir) {
  TwinMonitorConfig c;
  const auto path = [&](const char* name) { return (std::filesystem::path(dir) / name).string(); };
  if (std::filesystem::exists(path("actuator.toml")))
    c.actuator = load_actuator_params(path("actuator.toml"));
  c.calibration = std::filesystem::exists(path("calibration.toml"))
                      ? load_calibration(path("calibration.toml"))
                      : paper_calibration();
  if (std::filesystem::exists(path("model.toml"))) c.model = load_twin_model(path("model.toml"));
  c.integrator.max_step_s = 1.0 / c.actuator.sample_rate_hz;
  return c;
}

}  // namespace maglead::twin
