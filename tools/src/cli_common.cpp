#include "cli_common.hpp"

#include "maglead/operator/client.hpp"
#include "maglead/report/plot.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>
#include <string_view>
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

std::vector<std::string> config_dir_candidates() {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    // A checkout: BIN is <repository>/build*/bin, and <repository>/config is the one the docs
    // send users to edit (no build-tree copy, so an edit takes effect on the next run).
    const fs::path repo = fs::weakly_canonical(exe.parent_path() / "../..", ec);
    if (!ec && fs::exists(repo / "CMakeLists.txt", ec) && fs::exists(repo / "config", ec))
      out.push_back((repo / "config").string());
    out.push_back(fs::weakly_canonical(exe.parent_path() / "../share/maglead", ec).string());
  }
  out.emplace_back("/etc/maglead");
  return out;
}

std::string default_config_dir() {
  if (const char* env = std::getenv("MAGLEAD_CONFIG"); env && *env) return env;
  std::error_code ec;
  const auto candidates = config_dir_candidates();
  // calibration.toml is the one file every controller needs.
  for (const auto& c : candidates)
    if (std::filesystem::exists(std::filesystem::path(c) / "calibration.toml", ec)) return c;
  return candidates.back();
}

std::string replacing_note(const std::string& path, const std::string& what) {
  std::error_code ec;
  return std::filesystem::exists(path, ec) ? " (replacing " + what + ")" : "";
}

std::string missing_config_hint(const std::string& error) {
  const std::string dir = default_config_dir();
  std::error_code ec;
  const char* env = std::getenv("MAGLEAD_CONFIG");
  // The directory came from the environment, not from anything typed: say where it came from.
  if (env != nullptr && *env != '\0' && error.rfind(dir + "/", 0) == 0)
    return std::filesystem::is_directory(dir, ec)
               ? "\n(the configuration directory '" + dir +
                     "' comes from MAGLEAD_CONFIG; unset it or fix it, or pass --config DIR)"
               : "\nno configuration directory '" + dir +
                     "' (from MAGLEAD_CONFIG; unset it or fix it, or pass --config DIR)";
  if (env != nullptr ||
      std::filesystem::exists(std::filesystem::path(dir) / "calibration.toml", ec) ||
      error.rfind(dir + "/", 0) != 0)
    return "";
  std::string looked;
  for (const auto& c : config_dir_candidates()) looked += (looked.empty() ? "" : ", ") + c;
  return "\nno configuration directory found (looked in " + looked +
         "): pass --config DIR, a directory with calibration.toml and actuator.toml (the "
         "checkout's config/ is one), or set MAGLEAD_CONFIG=DIR";
}

CLI::Validator image_name() {
  return CLI::Validator(
      [](std::string& path) {
        try {
          plot::image_extension(path);
          return std::string();
        } catch (const std::runtime_error& e) {
          return std::string(e.what());
        }
      },
      "FILE.png", "image name");
}

CLI::Validator number_in(const NumberRange& range) {
  return CLI::Validator(
      [range](const std::string& text) {
        const std::string unit = range.unit.empty() ? "" : " " + range.unit;
        const std::string type = ": type e.g. " + range.example;
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') return "'" + text + "' is not a number" + type;
        if (v >= range.lo && v <= range.hi) return std::string();
        char bounds[64];  // no upper bound: "below LO"
        std::snprintf(bounds, sizeof bounds, std::isinf(range.hi) ? "below %g" : "outside %g .. %g",
                      range.lo, range.hi);
        return text + unit + " is " + bounds + unit +
               (range.why.empty() ? "" : " (" + range.why + ")") + type;
      },
      "");  // no name: the option's own type stays in --help
}

CLI::Validator quantity_in(const Quantity& q) {
  return CLI::Validator(
      [q](std::string& text) {
        const std::string type = ": type e.g. " + q.example;
        char* end = nullptr;
        std::strtod(text.c_str(), &end);
        const auto used = static_cast<std::size_t>(end - text.c_str());
        std::string rest = text.substr(used);
        rest.erase(std::remove(rest.begin(), rest.end(), ' '), rest.end());
        if (used > 0 && (rest.empty() || rest == q.unit)) {  // in the option's unit
          text.resize(used);
          return std::string();
        }
        if (q.si_unit.empty()) return "'" + text + "' is not a number of " + q.unit + type;
        try {  // set's vocabulary: 20mm, 500ms, 0.5s
          char converted[32];
          std::snprintf(converted, sizeof converted, "%.17g",
                        op::parse_quantity(text, q.si_unit) / q.si_per_unit);
          text = converted;
          return std::string();
        } catch (const op::ClientError& e) {
          return std::string(e.what()) + " (" + q.unit + " when no unit is typed)" + type;
        }
      },
      "");  // no name: the option's own type stays in --help
}

CLI::Option* add_config_option(CLI::App* cmd, std::string& config, const std::string& what) {
  return cmd
      ->add_option("--config", config,
                   "Configuration directory" + (what.empty() ? "" : " (" + what + ")") +
                       ". Default: $MAGLEAD_CONFIG, else the checkout's config/ (when run from "
                       "<repository>/build/bin), else <prefix>/share/maglead, else /etc/maglead")
      ->type_name("DIR")
      ->check(CLI::Validator(
          [](const std::string& dir) {
            std::error_code ec;
            return std::filesystem::is_directory(dir, ec)
                       ? std::string()
                       : "no configuration directory '" + dir +
                             "' (from here; leave --config out to use the default)";
          },
          ""));  // no name: the type stays DIR in --help
}

void add_recording_option(CLI::App* cmd, std::string& recording, const std::string& help) {
  // Its own storage, so that both forms given can be told apart from one given twice.
  auto positional = std::make_shared<std::string>();
  cmd->add_option("--recording", recording, help)->type_name("FILE");
  cmd->add_option("RECORDING", *positional, "The recording, as --recording takes it")
      ->type_name("FILE");
  // After --help is handled (CLI11 runs this once the command's words are parsed), before any
  // work.
  cmd->parse_complete_callback([cmd, &recording, positional] {
    const std::string typed = "maglead " + cmd->get_name() + " ";
    if (!positional->empty() && !recording.empty())
      throw CLI::ValidationError("the recording is given twice ('" + *positional +
                                 "' and --recording '" + recording + "'): type it once, e.g. " +
                                 typed + *positional);
    if (!positional->empty()) recording = *positional;
    if (recording.empty())
      throw CLI::RequiredError(
          "a recording is required: type e.g. " + typed + "FILE (or --recording FILE)",
          CLI::ExitCodes::RequiredError);
  });
}

double parse_duration_s(const std::string& text, const std::string& option) {
  char* end = nullptr;
  std::strtod(text.c_str(), &end);
  if (end == text.c_str())
    throw CLI::ValidationError(option,
                               "'" + text + "' is not a duration (e.g. " + option + " 30s, 2min)");
  double v = 0;
  try {  // set's vocabulary, so every time option reads 500ms, 30s, 2min, 1h alike
    v = op::parse_quantity(text, "s");
  } catch (const op::ClientError& e) {
    throw CLI::ValidationError(option, std::string(e.what()) + " (e.g. " + option + " 30s, 2min)");
  }
  if (!(v > 0))
    throw CLI::ValidationError(
        option, "'" + text + "' is not a positive duration (e.g. " + option + " 30s, 2min, 1h)");
  return v;
}

bool& quiet() {
  static bool q = false;
  return q;
}

bool show_progress() { return !quiet() && isatty(STDERR_FILENO) != 0; }

std::size_t terminal_columns() {
  winsize ws{};
  if (isatty(STDOUT_FILENO) == 0 || ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) != 0) return 0;
  return ws.ws_col;
}

std::string error_text(const std::string& line) {
  winsize ws{};
  if (isatty(STDERR_FILENO) == 0 || ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) != 0) return line;
  std::string out;
  std::size_t from = 0;
  for (std::size_t nl = line.find('\n'); from <= line.size(); nl = line.find('\n', from)) {
    const std::size_t end = nl == std::string::npos ? line.size() : nl;
    out += (from ? "\n" : "") + wrapped(line.substr(from, end - from), 2, ws.ws_col);
    if (nl == std::string::npos) break;
    from = nl + 1;
  }
  return out;
}

namespace {
std::size_t columns_of(std::string_view s) {  // UTF-8: continuation bytes take no column
  std::size_t n = 0;
  for (const char c : s) n += (static_cast<unsigned char>(c) & 0xC0U) != 0x80U;
  return n;
}
}  // namespace

std::string wrapped(const std::string& text, std::size_t indent, std::size_t width) {
  constexpr std::size_t kLeastLine = 20;  // narrower than this, wrapping helps no one
  if (width < indent + kLeastLine) return text;
  const std::size_t lead = std::min(text.find_first_not_of(' '), text.size());
  std::string out = text.substr(0, lead);  // the first line's own indentation, as given
  std::size_t used = lead;
  std::size_t pos = lead;
  while (pos < text.size()) {
    const std::size_t space = text.find(' ', pos);
    const std::string_view word(text.data() + pos,
                                (space == std::string::npos ? text.size() : space) - pos);
    const std::size_t w = columns_of(word);
    if (used > indent && used + 1 + w > width) {
      out += '\n' + std::string(indent, ' ');
      used = indent;
    } else if (pos > lead) {
      out += ' ';
      ++used;
    }
    out += word;
    used += w;
    pos = space == std::string::npos ? text.size() : space + 1;
  }
  return out;
}

namespace {
bool g_status_line_cleared = false;  // the cursor stands at the start of an empty line
}  // namespace

void print_line(const std::string& text, std::size_t indent) {
  static const std::size_t width = terminal_columns();
  const std::size_t end = text.find_last_not_of(' ');
  const std::string line = end == std::string::npos ? std::string() : text.substr(0, end + 1);
  std::printf("%s\n", wrapped(line, indent, width).c_str());
  g_status_line_cleared = false;
}

void fresh_line_after_interrupt(int signal_number) {
  static bool done = false;
  if (done || signal_number != SIGINT) return;  // only Ctrl-C makes the terminal echo "^C"
  done = true;
  if (g_status_line_cleared) return;
  if (isatty(STDOUT_FILENO) != 0) {
    std::fputs("\n", stdout);
    std::fflush(stdout);
  } else if (isatty(STDERR_FILENO) != 0) {
    std::fputs("\n", stderr);
  }
}

StatusLine::StatusLine() : width_(quiet() ? 0 : terminal_columns()) {}

StatusLine::~StatusLine() { clear(); }

void StatusLine::show(const std::string& text) {
  if (width_ == 0) return;
  // One column short of the width: a line that fills it would wrap on some terminals, and the
  // carriage return would then redraw only its second half.
  std::string line = text.substr(0, width_ - 1);
  std::printf("\r%s\033[K", line.c_str());
  std::fflush(stdout);
  shown_ = true;
  g_status_line_cleared = false;
}

void StatusLine::clear() {
  if (!shown_) return;
  std::printf("\r\033[K");
  std::fflush(stdout);
  shown_ = false;
  g_status_line_cleared = true;
}

void note(const std::string& text) {
  if (show_progress()) std::fprintf(stderr, "%s\n", text.c_str());
}

Progress::Progress(std::string label) : label_(std::move(label)), show_(show_progress()) {}

void Progress::operator()(double fraction) {
  const int pct = std::clamp(static_cast<int>(fraction * 100.0), 0, 100);
  if (!show_ || pct == last_) return;
  const int filled = pct * 30 / 100;
  std::fprintf(stderr, "\r%s [%.*s%*s] %3d%%", label_.c_str(), filled,
               "##############################", 30 - filled, "", pct);
  std::fflush(stderr);
  last_ = pct;
}

void Progress::done() {
  if (show_ && last_ >= 0) std::fprintf(stderr, "\n");
  last_ = -1;
}

std::string closest_match(const std::string& word, const std::vector<std::string>& candidates) {
  const auto distance = [](const std::string& a, const std::string& b) {
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
      std::size_t diag = row[0];
      row[0] = i;
      for (std::size_t j = 1; j <= b.size(); ++j) {
        const std::size_t up = row[j];
        row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0u : 1u)});
        diag = up;
      }
    }
    return row[b.size()];
  };
  std::string best;
  std::size_t best_d = std::max<std::size_t>(1, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = distance(word, c);
    // A prefix counts as close too: "--calib" for "--calibration".
    const bool prefix = word.size() >= 3 && c.starts_with(word);
    if (d < best_d || (prefix && best.empty())) {
      best = c;
      best_d = prefix ? 0 : d;
    }
  }
  return best;
}

}  // namespace maglead::cli

namespace maglead::cli {

void require_angle(const Recording& rec) {
  if (rec.has("screw_angle_rad") || rec.has("motor_angle_rad")) return;
  std::string hint;
  for (const char* wanted : {"screw_angle_rad", "motor_angle_rad"})
    for (const auto& n : rec.names)
      if (hint.empty()) hint = stand_in_hint(n, wanted);
  throw MissingColumnError(rec.path + ": needs column 'screw_angle_rad' or 'motor_angle_rad'" +
                               missing_column_detail(rec.names, "") +
                               (hint.empty() ? "" : "; " + hint),
                           "screw_angle_rad");
}

std::vector<double> screw_angle_of(const Recording& rec, const ActuatorParams& act) {
  if (rec.has("screw_angle_rad")) return rec.column("screw_angle_rad");
  require_angle(rec);
  double gear = act.gear_ratio;
  if (auto g = rec.meta("gear_ratio")) gear = std::stod(*g);
  std::vector<double> out = rec.column("motor_angle_rad");
  for (double& v : out) v /= gear;
  return out;
}

namespace {

// An axis's recording (`# axis:`, or an axis's position column and no nut): not the actuator's.
bool is_axis_recording(const Recording& rec) {
  return rec.meta("axis").has_value() ||
         (!rec.has("nut_pos_m") && (rec.has("pos_m") || rec.has("angle_rad")));
}

// The reader's own error for a recording that lacks an actuator column, unless the recording is
// an axis's: then what to run on it instead. `reader` names what wanted the actuator's.
Recording read_with_columns(const std::string& path, const std::vector<std::string>& required,
                            const ColumnChoice& keep, const std::string& reader) {
  try {
    return read_recording(path, required, keep);
  } catch (const RecordingError&) {
    if (required.empty()) throw;
    std::optional<Recording> whole;
    try {
      whole = read_recording(path);
    } catch (const RecordingError&) {  // malformed as well: the first error says it
    }
    if (!whole || !is_axis_recording(*whole)) throw;
    const std::string kind = whole->meta("axis").value_or("linear");
    throw RecordingError(path + ": a " + kind + " axis's recording, and " + reader +
                         " reads the magnetic actuator's (nut_pos_m and the motor or screw "
                         "angle). Analyse an axis with: "
                         "maglead analyze --recording " +
                         path + " --model BASELINE.toml (docs/analysis.md)");
  }
}

// The coupling keeps the phase θ − 2πp/lead within a lead, so over a travel of kJudgedLeads leads
// the screw turns 2π per lead within 1/kJudgedLeads. Slips break that both ways (a held screw
// while the nut is pushed through leads, a screw spinning past a slow nut), so only the ratios
// a unit makes are judged: degrees 57.3x, milliradians 1000x, microradians 10^6 x, each within
// kUnitTolerance (a median of slips landing there is not a real recording).
constexpr double kJudgedLeads = 2.0;
constexpr double kUnitTolerance = 0.2;
constexpr std::size_t kStretches = 2000;  // starts tried: a median over many stretches
constexpr std::size_t kMinStretches = 5;

/// The median ratio of the screw's turning to 2π per lead of travel over stretches of at least
/// kJudgedLeads leads of travel, between kStretches evenly spaced samples (so at most kStretches²
/// steps, an hour at 1 kHz included); NaN when the nut never travels that far.
double turns_per_lead(const std::vector<double>& screw_rad, const std::vector<double>& pos_m,
                      double lead_m) {
  const std::size_t n = std::min(screw_rad.size(), pos_m.size());
  const double span = kJudgedLeads * lead_m;
  const std::size_t stride = std::max<std::size_t>(1, n / kStretches);
  std::vector<std::size_t> at;  // the evenly spaced samples with both values
  for (std::size_t i = 0; i < n; i += stride)
    if (std::isfinite(pos_m[i]) && std::isfinite(screw_rad[i])) at.push_back(i);
  std::vector<double> ratios;
  for (std::size_t a = 0; a < at.size(); ++a) {
    std::size_t b = a + 1;
    while (b < at.size() && std::abs(pos_m[at[b]] - pos_m[at[a]]) < span) ++b;
    if (b >= at.size()) break;  // no later sample travels that far from here
    const std::size_t i = at[a], j = at[b];
    ratios.push_back((screw_rad[j] - screw_rad[i]) /
                     (2.0 * std::numbers::pi * (pos_m[j] - pos_m[i]) / lead_m));
  }
  if (ratios.size() < kMinStretches) return std::numeric_limits<double>::quiet_NaN();
  auto mid = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), mid, ratios.end());
  return *mid;
}

/// The screw's lead the recording states (`# lead_m:`), else the actuator's.
double lead_of(const Recording& rec, const ActuatorParams& act) {
  if (auto l = rec.meta("lead_m")) return std::strtod(l->c_str(), nullptr);
  return act.lead_m;
}

/// Refuses angle columns that turn a unit's factor more than radians of this screw would.
void check_turns_per_lead(const Recording& rec, const ActuatorParams& act) {
  if (!rec.has("screw_angle_rad") && !rec.has("motor_angle_rad")) return;  // the reader says so
  const double lead_m = lead_of(rec, act);
  if (!(lead_m > 0)) return;
  // The screw angle the tools read (screw_angle_of: the motor's through the gear if need be).
  const char* name = rec.has("screw_angle_rad") ? "screw_angle_rad" : "motor_angle_rad";
  const double r = turns_per_lead(screw_angle_of(rec, act), rec.column("nut_pos_m"), lead_m);
  constexpr std::pair<double, const char*> kUnits[] = {
      {180.0 / std::numbers::pi, "degrees"}, {1e3, "milliradians"}, {1e6, "microradians"}};
  for (const auto& [factor, unit] : kUnits) {
    if (!(std::abs(r / factor - 1.0) < kUnitTolerance)) continue;
    char text[320];
    std::snprintf(text, sizeof text,
                  "%s: column %s cannot be in radians: over the nut's travel the screw turns %.3g "
                  "times 2 pi per lead (lead %g m; the coupling keeps it at 1); likely unit: %s",
                  rec.path.c_str(), name, r, lead_m, unit);
    throw RecordingError(text);
  }
}

}  // namespace

void refuse_without_load_cell(const MissingColumnError& e, const std::string& does,
                              const std::string& recording) {
  if (e.column() != "load_force_n") throw e;
  throw RecordingError(std::string(e.what()) + ". " + does +
                       " (load_force_n); without one, the twin judges it: maglead twin-check "
                       "--recording " +
                       recording + " (drift from free moves and step-outs, no load cell)");
}

// A recording's phase sits on the stable branch of some lead except while a step-out crosses it;
// mostly elsewhere, it does not describe this coupling, and every force judged from it (and the
// load cell against it) would be meaningless.
void check_phase_on_branch(const Recording& rec, const ActuatorParams& act,
                           const ForceCalibration& cal) {
  constexpr double kMinOnBranch = 0.5;  // most samples: step-outs cross the branch only briefly
  const double lead_m = lead_of(rec, act);
  if (!rec.has("nut_pos_m") || (!rec.has("screw_angle_rad") && !rec.has("motor_angle_rad")) ||
      !(lead_m > 0))
    return;
  const auto theta = screw_angle_of(rec, act);
  const auto& pos = rec.column("nut_pos_m");
  const std::size_t n = pos.size(), stride = std::max<std::size_t>(1, n / 20000);
  std::size_t on = 0, all = 0;
  for (std::size_t i = 0; i < n; i += stride) {
    const double phi =
        std::remainder(theta[i] - 2 * std::numbers::pi * pos[i] / lead_m, 2 * std::numbers::pi);
    if (!std::isfinite(phi)) continue;
    ++all;
    on += phi >= cal.stable_min_rad && phi <= cal.stable_max_rad;
  }
  if (all == 0 || static_cast<double>(on) >= kMinOnBranch * static_cast<double>(all)) return;
  char b[400];
  std::snprintf(b, sizeof b,
                "%s: the phase theta - 2 pi p / lead (lead %g m) lies on the coupling's stable "
                "branch (%.2f .. %.2f rad) in %.0f %% of the samples; a nut cannot rest elsewhere: "
                "the angle column is likely in another unit (degrees: x57.3), or lead_m or the "
                "calibration is another actuator's",
                rec.path.c_str(), lead_m, cal.stable_min_rad, cal.stable_max_rad,
                100.0 * static_cast<double>(on) / static_cast<double>(all));
  throw RecordingError(b);
}

Recording read_actuator_recording(const std::string& path, const ActuatorParams& act,
                                  const std::string& config_dir,
                                  const std::vector<std::string>& required,
                                  const ColumnChoice& keep, const std::string& reader) {
  // The actuator's readers (nut_pos_m) all turn the angle: refused from the header, where every
  // name is (a keep would drop screw_angle_deg before the error could name it).
  const bool actuator = std::find(required.begin(), required.end(), "nut_pos_m") != required.end();
  const ColumnChoice checked = [&](const Recording& header) {
    if (actuator) require_angle(header);
    return keep ? keep(header) : header.names;
  };
  Recording rec = read_with_columns(path, required, checked, reader);
  // Every reader needs two samples at least (a sample period, a step of the twin, a difference):
  // refused here, once, so inspect says what analyze, report, twin-check and estimate will do.
  if (rec.rows() < kMinRecordingRows)
    throw RecordingError(path + ": " + std::to_string(rec.rows()) +
                         (rec.rows() == 1 ? " data row" : " data rows") +
                         " below its header; analyze, report, twin-check, estimate and "
                         "calibrate need at least " +
                         std::to_string(kMinRecordingRows) +
                         " (record one: maglead record --duration 10s --out FILE)");
  if (!rec.has("nut_pos_m")) return rec;  // another machine (pos_m): its stroke is not ours
  const double stroke_m = act.stroke_max_m - act.stroke_min_m;
  PlausibleRanges r;
  r.position_bound_m =
      std::max(std::abs(act.stroke_min_m), std::abs(act.stroke_max_m)) + 10.0 * stroke_m;
  const std::string file = config_file(config_dir, "actuator.toml");
  char text[160];
  std::snprintf(text, sizeof text, "the stroke %g .. %g m of %s widened by 10 strokes each way",
                act.stroke_min_m, act.stroke_max_m,
                std::filesystem::exists(file) ? file.c_str() : "the built-in defaults");
  r.position_bound_source = text;
  check_plausible_units(rec, r);
  check_turns_per_lead(rec, act);
  return rec;
}

}  // namespace maglead::cli

namespace maglead::cli {

std::string plant_effects_help(const std::string& intro) {
  std::string help = intro;
  for (const auto& k : plant_effect_keys())
    help += "\n  " + k.name + "  " + k.unit + "  " + k.meaning;
  return help;
}

void apply_plant_effects(const std::string& option, const std::vector<std::string>& words,
                         PlantEffects& effects) {
  for (const auto& e : words) {
    const auto eq = e.find('=');
    if (eq == std::string::npos)
      throw CLI::ValidationError(option, "'" + e + "' is not NAME=VALUE");
    const std::string name = e.substr(0, eq), text = e.substr(eq + 1);
    // A value may carry exactly its effect's unit (offset=2N), as set's values carry theirs.
    std::string unit;
    std::vector<std::string> names;
    for (const auto& k : plant_effect_keys()) {
      if (k.name == name) unit = k.unit;
      names.push_back(k.name);
    }
    if (unit.empty()) {  // a typo: the closest id, not the whole list
      const std::string guess = closest_match(name, names);
      throw CLI::ValidationError(
          option, "unknown effect '" + name + "'" +
                      (guess.empty() ? "" : "; did you mean '" + guess + "'?") + " ('maglead " +
                      (option == "--effect" ? "simulate" : "serve") + " --help' lists the " +
                      std::to_string(names.size()) + " effects)");
    }
    double v = 0;
    std::size_t used = 0;
    try {
      v = std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    std::string rest = used > 0 ? text.substr(used) : text;
    rest.erase(std::remove(rest.begin(), rest.end(), ' '), rest.end());
    if (used == 0 || (!rest.empty() && rest != unit))
      throw CLI::ValidationError(
          option, "'" + text + "' in '" + e + "' is not a number" +
                      (unit.empty() || unit == "1" ? std::string()
                                                   : ": " + name + " is in " + unit + ", e.g. " +
                                                         name + "=2 or " + name + "=2" + unit));
    set_plant_effect(effects, name, v);
  }
}

}  // namespace maglead::cli
