#pragma once
// Shared pieces of the `maglead` command line. Each subcommand lives in its own cmd_*.cpp and
// registers itself with a static MAGLEAD_COMMAND(order, fn), so adding one touches no other file.
#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "maglead/plant/simulated_actuator.hpp"

namespace maglead::cli {

using Registrar = void (*)(CLI::App& app);
struct CommandRegistration {
  CommandRegistration(int order, Registrar fn);
};
void register_all(CLI::App& app);

/// Where the configuration lives when --config is not given: $MAGLEAD_CONFIG, else the
/// checkout's config/ (BIN/../../config beside a CMakeLists.txt: the file the user edits), else
/// an install's BIN/../share/maglead, else /etc/maglead. Nothing of the tree is compiled in.
std::string default_config_dir();
/// The candidates default_config_dir() tries after $MAGLEAD_CONFIG, in order (for messages).
std::vector<std::string> config_dir_candidates();
std::string config_file(const std::string& config_dir, const std::string& name);
/// `--config DIR` on a command, its help stating the lookup rule (not a machine's path).
CLI::Option* add_config_option(CLI::App* cmd, std::string& config, const std::string& what = "");

/// "30s", "2min", "500ms", "1h" or a plain number of seconds. Throws CLI::ValidationError.
double parse_duration_s(const std::string& text);
/// Applies repeated `--effect NAME=VALUE` words (simulate, serve --sim-effect) to the plant's
/// effects; throws CLI::ValidationError naming the option and the bad word.
void apply_plant_effects(const std::string& option, const std::vector<std::string>& words,
                         PlantEffects& effects);

/// --quiet (a global option): no progress and no notes, only results and errors.
bool& quiet();
/// Progress and notes go to stderr only when it is a terminal and --quiet is not given.
bool show_progress();
/// A note on stderr (e.g. "reading FILE"), shown only when show_progress().
void note(const std::string& text);

/// A one-line progress bar on stderr, drawn only when show_progress(); silent otherwise.
class Progress {
 public:
  explicit Progress(std::string label);
  void operator()(double fraction);
  void done();

 private:
  std::string label_;
  bool show_;
  int last_ = -1;
};

/// The candidate closest to `word` by edit distance, if it is close enough to be a likely typo
/// (at most a third of the word's length, at least 1); empty otherwise.
std::string closest_match(const std::string& word, const std::vector<std::string>& candidates);

/// Exit code for errors the user can fix (bad input, bad file).
inline constexpr int kExitBadInput = 2;

}  // namespace maglead::cli

#define MAGLEAD_CONCAT2(a, b) a##b
#define MAGLEAD_CONCAT(a, b) MAGLEAD_CONCAT2(a, b)
#define MAGLEAD_COMMAND(order, fn) \
  static const ::maglead::cli::CommandRegistration MAGLEAD_CONCAT(reg_, __COUNTER__) { order, fn }

#include "maglead/controller/controller.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/recording/recording.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::cli {
/// θ from a recording: `screw_angle_rad`, else `motor_angle_rad` / gear ratio (the recording's
/// `# gear_ratio:` if given, else the actuator's). Throws RecordingError if neither is there.
std::vector<double> screw_angle_of(const Recording& rec, const ActuatorParams& act);
/// Loads config/actuator.toml (defaults when the file is absent).
ActuatorParams load_actuator_or_default(const std::string& config_dir);
/// Reads a recording as read_recording does and, for the actuator (a nut_pos_m column), also
/// refuses positions beyond the configured stroke widened by ten strokes each way: millimetres
/// where metres belong pass the reader's machine-independent 10 m bound on a short stroke.
Recording read_actuator_recording(const std::string& path, const ActuatorParams& act,
                                  const std::string& config_dir,
                                  const std::vector<std::string>& required = {});

/// The [control] table of CONFIG/actuator.toml into the controller's settings: when "reached"
/// holds, and the force loop's and the load observer's settings (README "Force control").
/// Absent keys (or no file) keep the values given. Errors name FILE:LINE:COLUMN.
void load_control_settings(const std::string& config_dir, controller::ControllerConfig& cfg);
/// The controller's settings as `serve` runs them: the actuator, the calibration (CONFIG's or the
/// file given), [control], [reference_move], and the model file's terms (CONFIG/model.toml or
/// the file given, when it exists; else the actuator's friction). `model_used` gets the model
/// file read, empty when none.
controller::ControllerConfig controller_config_of(const std::string& config_dir,
                                                  const std::string& calibration,
                                                  const std::string& model,
                                                  std::string* model_used);
/// The model file's terms the controller compensates with: its friction, offset and mass
/// (twin::friction_model), its coupling's gain, ripple and end effect (the twin applies the rest
/// itself).
void serve_model_terms(const twin::TwinModel& model, controller::ControllerConfig& cfg);
/// The [reference_move] table of CONFIG/actuator.toml (mode_command 3): the window inside the
/// actuator's stroke, the two speeds (slow below fast) and the acceleration. Absent keys keep the
/// values given; a bad value is an error at FILE:LINE:COLUMN and `move` is left unchanged.
void load_reference_move(const std::string& config_dir, const ActuatorParams& actuator,
                         controller::ReferenceMoveConfig& move);
}  // namespace maglead::cli
