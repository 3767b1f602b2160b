#pragma once
// Shared pieces of the `maglead` command line. Each subcommand lives in its own cmd_*.cpp and
// registers itself with a static MAGLEAD_COMMAND(order, fn), so adding one touches no other file.
#include <CLI/CLI.hpp>
#include <filesystem>
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
/// `--config DIR` on a command, its help stating the lookup rule (not a machine's path).
/// " (replacing WHAT)" when `path` exists, else "": said beside "wrote PATH", so an
/// earlier recording or result overwritten is never a surprise. Ask before writing.
std::string replacing_note(const std::string& path, const std::string& what = "the one there");
/// For an error naming a file of the default configuration directory: when $MAGLEAD_CONFIG
/// chose it, that it did (and whether the directory exists); when no candidate had one, where
/// maglead looked; with what to type. "" otherwise.
std::string missing_config_hint(const std::string& error);
/// An option naming an image to write: refused at once (exit 2) unless it ends .png or .jpg, so
/// nothing is written before the name is found wrong.
CLI::Validator image_name();
CLI::Option* add_config_option(CLI::App* cmd, std::string& config, const std::string& what = "");
/// The recording a command reads, typed either way: `maglead inspect FILE` or `--recording FILE`
/// (every recording command takes both, so neither form surprises). Both given, or neither, is
/// refused before any work (exit 2) with what to type.
void add_recording_option(CLI::App* cmd, std::string& recording, const std::string& help);

/// What a number option takes: lo .. hi (both included; hi may be infinite) in `unit` ("" for a
/// count), `why` that range (said in parentheses), and `example`, the option as one would type it.
struct NumberRange {
  double lo = 0, hi = 0;
  std::string unit, why, example;
};
/// Refuses a value that is not a number or lies outside the range, before any work (exit 2):
/// "5000 Hz is outside 1 .. 1000 Hz (the loop runs at 1 kHz): type e.g. --rate 100".
CLI::Validator number_in(const NumberRange& range);

/// A length or time an option takes: a bare number in `unit` ("m", "ms"), or a number with a
/// unit of set's (20mm, 0.5s) when `si_unit` ("m", "s") is given: `si_per_unit` SI units make
/// one `unit` (1e-3 for ms). `example`: the option as one would type it, for the error.
struct Quantity {
  std::string unit, si_unit;
  double si_per_unit = 1.0;
  std::string example;
};
/// Rewrites "20mm" to the number in the option's unit (0.02 for metres) before CLI11 converts
/// it; refuses another unit or no number, saying the option's unit (exit 2).
CLI::Validator quantity_in(const Quantity& q);

/// "30s", "2min", "500ms", "1h" or a plain number of seconds, as typed after `option`
/// ("--hold"). Throws CLI::ValidationError naming the option: "--hold: '0s' is not a positive
/// duration (e.g. --hold 30s, 2min, 1h)".
double parse_duration_s(const std::string& text, const std::string& option);
/// Applies repeated `--effect NAME=VALUE` words (simulate, serve --sim-effect) to the plant's
/// effects; throws CLI::ValidationError naming the option and the bad word.
/// The --effect / --sim-effect help: `intro`, then a line per key with its unit and meaning.
std::string plant_effects_help(const std::string& intro);
void apply_plant_effects(const std::string& option, const std::vector<std::string>& words,
                         PlantEffects& effects);

/// --quiet (a global option): no progress and no notes, only results and errors.
bool& quiet();
/// Progress and notes go to stderr only when it is a terminal and --quiet is not given.
bool show_progress();
/// The terminal's width in columns when standard output is one, else 0 (a pipe or a file gets
/// every line whole, for the scripts that read it).
std::size_t terminal_columns();
/// An error line as it goes to stderr: on a terminal wrapped at spaces to its width, continuations
/// two columns in; to a pipe or a log, one line as given (scripts match it whole).
std::string error_text(const std::string& line);
/// `text` broken at spaces into lines of at most `width` columns (UTF-8 characters), every
/// line after the first indented by `indent` spaces; whole when `width` is 0 or too small.
std::string wrapped(const std::string& text, std::size_t indent, std::size_t width);
/// A line of human-readable output on stdout, trailing spaces dropped: on a terminal broken at
/// spaces to its width, continuations `indent` columns in; into a pipe or a file whole (scripts
/// match it whole). Machine output (CSV, JSON) is printed as it is, never through this.
void print_line(const std::string& text, std::size_t indent = 2);
/// After Ctrl-C the terminal has echoed "^C" where the cursor stood: the final message starts on
/// a fresh line (a newline first, on whichever of stdout and stderr is a terminal), so its wrapped
/// lines keep their columns. Once per process; nothing when a StatusLine was just cleared, nor for
/// any signal but SIGINT (SIGTERM echoes nothing). `signal_number` is the signal that stopped it.
void fresh_line_after_interrupt(int signal_number);

/// One line on stdout redrawn in place while a command waits ("moving to 20.000 mm: …"): on a
/// terminal only, and not under --quiet (a pipe or a file gets nothing: scripts parse the
/// output). Cleared when destroyed or by clear(), before anything else is printed.
class StatusLine {
 public:
  StatusLine();
  ~StatusLine();
  StatusLine(const StatusLine&) = delete;
  StatusLine& operator=(const StatusLine&) = delete;
  bool enabled() const { return width_ > 0; }
  void show(const std::string& text);
  void clear();

 private:
  std::size_t width_;
  bool shown_ = false;
};
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

/// For `--out DIR`: a directory, or nothing there yet (it is created); a file there is refused
/// before any work, in the option's own words.
inline std::string output_directory_problem(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_directory(path, ec))
    return "'" + path + "' is a file; --out takes a directory (created when missing)";
  return {};
}

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
#include "maglead/settings/settings.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::cli {
/// θ from a recording: `screw_angle_rad`, else `motor_angle_rad` / gear ratio (the recording's
/// `# gear_ratio:` if given, else the actuator's). Throws require_angle's error if neither is
/// there.
std::vector<double> screw_angle_of(const Recording& rec, const ActuatorParams& act);
/// Refuses a recording (or its header) with neither `screw_angle_rad` nor `motor_angle_rad`:
/// MissingColumnError listing the columns, and one that stands in for either (screw_angle_deg:
/// convert it to radians).
void require_angle(const Recording& rec);
/// The fewest data rows any command that reads a recording takes.
inline constexpr std::size_t kMinRecordingRows = 2;
/// Reads a recording as read_recording does, refuses one of fewer than kMinRecordingRows rows
/// (naming the file and its rows) and, for the actuator (a nut_pos_m column), also
/// refuses positions beyond the configured stroke widened by ten strokes each way: millimetres
/// where metres belong pass the reader's machine-independent 10 m bound on a short stroke.
/// `keep` stores only the columns it chooses (read_recording). An axis's recording lacking a
/// `required` column is refused with the command that analyses it, saying that `reader` (the
/// command, or what of it) reads the actuator's. Requiring nut_pos_m (the actuator's readers)
/// requires the screw or motor angle too (require_angle, on the header: before any row is read).
Recording read_actuator_recording(const std::string& path, const ActuatorParams& act,
                                  const std::string& config_dir,
                                  const std::vector<std::string>& required = {},
                                  const ColumnChoice& keep = {},
                                  const std::string& reader = "this command");

/// A recording without the load cell a command compares with: rethrows `e` as it is for another
/// column, else with what the command does with the load cell and the command that needs none.
[[noreturn]] void refuse_without_load_cell(const MissingColumnError& e, const std::string& does,
                                           const std::string& recording);
/// Refuses an actuator recording whose phase θ − 2πp/L lies mostly off the calibration's stable
/// branch (of any lead), where a nut cannot rest: its angle is in another unit (degrees), or its
/// lead or calibration is another actuator's. For the commands that judge against the coupling.
void check_phase_on_branch(const Recording& rec, const ActuatorParams& act,
                           const ForceCalibration& cal);

// The configuration readers (maglead/settings) by their short names, as every command uses them.
using settings::config_file;
using settings::controller_config_of;
using settings::load_actuator_or_default;
using settings::load_control_settings;
using settings::load_reference_move;
using settings::serve_model_terms;

}  // namespace maglead::cli
