#include "cli_common.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace maglead::cli {
namespace {

std::vector<std::pair<int, Registrar>>& registry() {
  static std::vector<std::pair<int, Registrar>> r;
  return r;
}

}  // namespace

CommandRegistration::CommandRegistration(int order, Registrar fn) {
  registry().emplace_back(order, fn);
}

void register_all(CLI::App& app) {
  auto& r = registry();
  std::stable_sort(r.begin(), r.end(), [](auto& a, auto& b) { return a.first < b.first; });
  for (auto& [order, fn] : r) fn(app);
}

std::string default_config_dir() {
  if (const char* env = std::getenv("MAGLEAD_CONFIG")) return env;
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (const fs::path& candidate :
         {exe.parent_path() / "../../config", exe.parent_path() / "../share/maglead/config"}) {
      if (fs::exists(candidate / "actuator.toml", ec)) return fs::weakly_canonical(candidate).string();
    }
  }
  return "config";
}

std::string config_file(const std::string& config_dir, const std::string& name) {
  return (std::filesystem::path(config_dir) / name).string();
}

double parse_duration_s(const std::string& text) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    throw CLI::ValidationError("duration", "'" + text + "' is not a duration (e.g. 30s, 2min)");
  }
  const std::string unit = text.substr(used);
  double scale = 0;
  if (unit.empty() || unit == "s") scale = 1;
  else if (unit == "ms") scale = 1e-3;
  else if (unit == "min" || unit == "m") scale = 60;
  else if (unit == "h") scale = 3600;
  if (scale == 0 || !(v > 0))
    throw CLI::ValidationError("duration", "'" + text + "' is not a positive duration (e.g. 30s, 2min, 1h)");
  return v * scale;
}

Progress::Progress(std::string label) : label_(std::move(label)), tty_(isatty(2) != 0) {}

void Progress::operator()(double fraction) {
  const int pct = static_cast<int>(fraction * 100.0);
  if (tty_) {
    if (pct == last_) return;
    const int filled = pct * 30 / 100;
    std::fprintf(stderr, "\r%s [%.*s%*s] %3d%%", label_.c_str(), filled,
                 "##############################", 30 - filled, "", pct);
    std::fflush(stderr);
  } else if (pct / 10 != last_ / 10) {
    std::fprintf(stderr, "%s: %d%%\n", label_.c_str(), pct);
  }
  last_ = pct;
}

void Progress::done() {
  if (tty_ && last_ >= 0) std::fprintf(stderr, "\n");
}

}  // namespace maglead::cli

namespace maglead::cli {

std::vector<double> screw_angle_of(const Recording& rec, const ActuatorParams& act) {
  if (rec.has("screw_angle_rad")) return rec.column("screw_angle_rad");
  if (!rec.has("motor_angle_rad"))
    throw RecordingError(rec.path + ": needs column 'screw_angle_rad' or 'motor_angle_rad'");
  double gear = act.gear_ratio;
  if (auto g = rec.meta("gear_ratio")) gear = std::stod(*g);
  std::vector<double> out = rec.column("motor_angle_rad");
  for (double& v : out) v /= gear;
  return out;
}

ActuatorParams load_actuator_or_default(const std::string& config_dir) {
  const std::string path = config_file(config_dir, "actuator.toml");
  if (!std::filesystem::exists(path)) return {};
  return load_actuator_params(path);
}

}  // namespace maglead::cli
