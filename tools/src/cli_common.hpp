#pragma once
// Shared pieces of the `maglead` command line. Each subcommand lives in its own cmd_*.cpp and
// registers itself with a static MAGLEAD_COMMAND(order, fn), so adding one touches no other file.
#include <CLI/CLI.hpp>
#include <functional>
#include <string>

namespace maglead::cli {

using Registrar = void (*)(CLI::App& app);
struct CommandRegistration {
  CommandRegistration(int order, Registrar fn);
};
void register_all(CLI::App& app);

/// Where config/ lives: --config, else $MAGLEAD_CONFIG, else the repository's config/ next to
/// the executable (build/bin/../../config), else ./config.
std::string default_config_dir();
std::string config_file(const std::string& config_dir, const std::string& name);

/// "30s", "2min", "500ms", "1h" or a plain number of seconds. Throws CLI::ValidationError.
double parse_duration_s(const std::string& text);

/// A one-line progress bar on stderr when it is a terminal, else a line every 10 %.
class Progress {
 public:
  explicit Progress(std::string label);
  void operator()(double fraction);
  void done();

 private:
  std::string label_;
  bool tty_;
  int last_ = -1;
};

/// Exit code for errors the user can fix (bad input, bad file).
inline constexpr int kExitBadInput = 2;

}  // namespace maglead::cli

#define MAGLEAD_CONCAT2(a, b) a##b
#define MAGLEAD_CONCAT(a, b) MAGLEAD_CONCAT2(a, b)
#define MAGLEAD_COMMAND(order, fn)                                          \
  static const ::maglead::cli::CommandRegistration MAGLEAD_CONCAT(reg_, __LINE__) { \
    order, fn                                                               \
  }

#include "maglead/physics/actuator.hpp"
#include "maglead/recording/recording.hpp"

namespace maglead::cli {
/// θ from a recording: `screw_angle_rad`, else `motor_angle_rad` / gear ratio (the recording's
/// `# gear_ratio:` if given, else the actuator's). Throws RecordingError if neither is there.
std::vector<double> screw_angle_of(const Recording& rec, const ActuatorParams& act);
/// Loads config/actuator.toml (defaults when the file is absent).
ActuatorParams load_actuator_or_default(const std::string& config_dir);
}  // namespace maglead::cli
