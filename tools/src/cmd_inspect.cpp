// maglead inspect: read a recording as analyze, report and estimate do and say what it holds, so
// a file left by a crash or copied from a bench can be checked before anything else reads it.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cli_common.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/anomaly.hpp"
#include "maglead/analysis/reading.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/settings/settings.hpp"

namespace maglead::cli {
namespace {

/// Values a column holds (missing ones left out) and their range.
struct ColumnSummary {
  std::size_t present = 0;
  double lo = INFINITY, hi = -INFINITY;
};

struct InspectOptions {
  std::string recording, config = default_config_dir();
};

ColumnSummary summarise(const std::vector<double>& v) {
  ColumnSummary s;
  for (const double x : v)
    if (!std::isnan(x)) ++s.present, s.lo = std::min(s.lo, x), s.hi = std::max(s.hi, x);
  return s;
}

/// Whether the header has `wanted` or a column that stands in for it (another unit or case).
bool resembles(const Recording& rec, const std::string& wanted) {
  return std::any_of(rec.names.begin(), rec.names.end(), [&](const std::string& n) {
    return n == wanted || !stand_in_hint(n, wanted).empty();
  });
}

/// An axis's recording: a `# axis:` line, or an axis's column and none of the actuator's (each
/// possibly in another unit: pos_mm is a misnamed axis's position, not an actuator's file).
bool axis_recording(const Recording& rec) {
  if (rec.meta("axis")) return true;
  for (const char* actuator : {"nut_pos_m", "screw_angle_rad", "motor_angle_rad"})
    if (resembles(rec, actuator)) return false;
  for (const effects::AxisKind* k : {&effects::linear_axis(), &effects::rotary_axis()})
    if (resembles(rec, std::string(k->position)) || resembles(rec, std::string(k->drive)))
      return true;
  return false;
}

/// analyze's checks of an axis's recording, as analyze with the axis's model runs them: the
/// kind and its columns (a file without `# axis:` is a linear axis's, as analyze reads it), then
/// the rows. Returns what analyze alone can judge.
std::string check_axis(Recording& rec) {
  const auto& rotary = effects::rotary_axis();
  const bool rotary_columns =
      resembles(rec, std::string(rotary.position)) || resembles(rec, std::string(rotary.drive));
  if (!rec.meta("axis") && !rotary_columns) rec.set_meta("axis", "linear");
  analysis::check_axis_columns(rec);  // analyze's own check: the same refusal, the same fix
  analysis::check_axis_rows(rec);
  return "not checked: the model file (analyze --model), and what the fit finds";
}

/// The actuator's readers' checks: the columns every one of them reads (twin-check's), the phase
/// on the calibration's branch, what the analysis needs of the rows where it is possible, and the
/// load cell's unit and sign as the analysis judges them.
std::string check_actuator(const InspectOptions& o, const Recording& rec,
                           const ActuatorParams& act) {
  if (!rec.has("t_s") || !rec.has("nut_pos_m"))  // read again as they read it: their refusal
    (void)read_actuator_recording(o.recording, act, o.config, {"t_s", "nut_pos_m"}, {}, "inspect");
  require_angle(rec);
  const ForceCalibration cal = load_calibration(config_file(o.config, "calibration.toml"));
  check_phase_on_branch(rec, act, cal);
  if (!rec.has("load_force_n"))
    return "no load_force_n (load cell): twin-check and report read it; estimate, calibrate and "
           "analyze with the actuator's model need one";
  try {
    analysis::check_actuator_rows(rec);
  } catch (const std::exception& e) {
    return std::string("twin-check, estimate and report read it; analyze will not: ") + e.what();
  }
  if (const auto why = analysis::load_cell_unusable(rec, cal, act))
    return std::string(why->what()) +
           ": analyze and estimate refuse it, twin-check and report do not compare with it";
  return "not checked: the model file and what the analysis finds";
}

void print_summary(const Recording& rec) {
  std::printf("%s: %zu rows, %zu columns", rec.path.c_str(), rec.rows(), rec.names.size());
  if (rec.has("t_s") && rec.rows() > 0)
    std::printf(", t_s %g .. %g s", rec.column("t_s").front(), rec.column("t_s").back());
  std::printf("%s\n", rec.warnings.empty() ? "" : " (see the warnings)");
  for (std::size_t c = 0; c < rec.names.size(); ++c) {
    const ColumnSummary s = summarise(rec.columns[c]);
    if (s.present == 0)
      std::printf("  %-30s empty\n", rec.names[c].c_str());
    else
      std::printf("  %-30s %g .. %g (%zu values)\n", rec.names[c].c_str(), s.lo, s.hi, s.present);
  }
}

void add_inspect(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "inspect",
      "Check a recording before analysing it: read it (mls-recording/1) as analyze does and "
      "print its rows, time span and columns, checked as the commands that read it check them: an "
      "axis's (a '# axis:' line, "
      "or an axis's columns) as analyze does with an axis's model (kind, columns, a value in "
      "every row, 200 rows, a sample rate of 50 Hz or more), the actuator's as twin-check, "
      "estimate and report do (the angle, nut_pos_m, the phase on the calibration's branch). "
      "Exit 0 when the readers will take it (a dropped torn last line is a warning; the last "
      "line says what was not checked or which command still refuses it), exit 2 with the "
      "reason and what to fix when not (e.g. fewer than 2 data rows, t_ms for t_s, angle_deg "
      "for angle_rad, a rotary file without '# axis: rotary', a repeated time stamp)");
  auto o = std::make_shared<InspectOptions>();
  add_recording_option(cmd, o->recording, "mls-recording/1 CSV");
  add_config_option(cmd, o->config, "the actuator's stroke and calibration");
  cmd->callback([o] {
    const ActuatorParams act = load_actuator_or_default(o->config);
    Recording rec = read_actuator_recording(o->recording, act, o->config);
    print_summary(rec);  // what was read, before any check may refuse it
    const std::string unchecked =
        axis_recording(rec) ? check_axis(rec) : check_actuator(*o, rec, act);
    print_line(unchecked, 2);
  });
}

MAGLEAD_COMMAND(50, add_inspect);

}  // namespace
}  // namespace maglead::cli
