// maglead analyze: twin versus recording (issue 5). Compares a baseline model with a recording
// in the force domain, locates the misfit, names the missing physics, refits, reports.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <tuple>

#include "cli_common.hpp"
#include "large_blocks.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/reading.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/report/analysis_json.hpp"
#include "maglead/report/analysis_page.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::cli {
namespace {

// More segments hold too little each to judge a term, and each costs the fit a Gram matrix.
constexpr int kMaxFolds = 100;
// Beyond this even an hour at 1 kHz keeps a few thousand samples: nothing left to fit.
constexpr double kMaxDecimation = 1000.0;

struct AnalyzeOptions {
  std::string recording, model, out, calibration, config = default_config_dir();
  analysis::AnalysisOptions a;
  bool no_twin_check = false;
  std::string replacing;  // replacing_note of an earlier result in --out
};

/// The baseline model's path: --model, else CONFIG/model.toml when there is one, else empty
/// (the model then comes from CONFIG/actuator.toml).
std::string baseline_path(const AnalyzeOptions& o) {
  if (!o.model.empty()) return o.model;
  const std::string p = config_file(o.config, "model.toml");
  return std::filesystem::exists(p) ? p : std::string();
}

/// One progress bar per stage of the analysis, the last one closed by done().
class StageProgress {
 public:
  void operator()(const std::string& stage, double f) {
    if (stage != stage_) {
      if (bar_) bar_->done();
      bar_ = std::make_unique<Progress>("analyze: " + stage);
      stage_ = stage;
    }
    (*bar_)(f);
  }
  void done() {
    if (bar_) bar_->done();
  }

 private:
  std::string stage_;
  std::unique_ptr<Progress> bar_;
};

// One line of the report, broken at spaces to the terminal's width (whole into a pipe or file),
// its continuation lines indented by `indent`.
void say(const std::string& text, std::size_t indent) {
  static const std::size_t width = terminal_columns();
  std::printf("%s\n", wrapped(text, indent, width).c_str());
}

void print_finding(const analysis::EffectFinding& e, int k) {
  constexpr std::size_t kIndent = 5;  // under the effect's name
  char head[48];
  std::snprintf(head, sizeof head, "%d. %-22s ", k, e.id.c_str());
  say(head + (e.summary.empty() ? report::parameters_json(e.parameters).dump() : e.summary),
      kIndent);
  if (e.evidence.heldout_gain_pct) {
    char evidence[160];
    // "6/10" as "better in 6 of 10 segments": beside a t statistic a bare 6/10 reads as a score.
    std::string segments = e.evidence.segments_improved.value_or("?");
    if (const auto slash = segments.find('/'); slash != std::string::npos)
      segments.replace(slash, 1, " of ");
    std::snprintf(evidence, sizeof evidence,
                  "     held-out gain %.2f %% (t = %.1f, better in %s segments), improvement "
                  "%.2f %%",
                  *e.evidence.heldout_gain_pct, e.evidence.t_stat.value_or(NAN), segments.c_str(),
                  e.improvement_pct);
    say(evidence, kIndent);
  }
  if (!e.finding.empty()) say("     " + e.finding, kIndent);
  if (!e.note.empty()) say("     note: " + e.note, kIndent);
  for (const auto& a : e.alternatives) {
    char share[48];
    std::snprintf(share, sizeof share, " (reproduces %.2f %% of it)", a.explains_pct);
    say("     or " + a.id + ": " + analysis::summary_text(a.parameters, {}) + share, kIndent + 3);
  }
}

void print_findings(const analysis::Findings& J) {
  int k = 1;
  for (const auto& e : J.effects) print_finding(e, k++);
  if (J.effects.empty()) say(J.conclusion, 2);
  if (J.unexplained) {
    say(J.unexplained->message, 2);
    say("  where: " + J.unexplained->where, 9);
    say("  check: " + J.unexplained->check, 9);
  }
  if (!J.sliding_note.empty()) say("note: " + J.sliding_note, 6);
  if (const auto& c = J.twin_force_check; c && c->available) {
    char errors[96];
    std::snprintf(errors, sizeof errors,
                  "twin force error %.2f → %.2f N (mean absolute, against the load cell)",
                  c->baseline_mae_n, c->corrected_mae_n);
    std::string line = errors;
    for (const auto& d : c->dropped)
      line += "; " + d + " left out (with it the error rose beyond its noise: its note above)";
    say(line, 2);
  }
}

void print_result(const AnalyzeOptions& o, const std::string& model_path,
                  const analysis::AnalysisResult& result) {
  const auto& J = result.findings;
  say(result.headline, 2);
  say("recording " + o.recording + " (" + J.system + "), baseline " +
          (model_path.empty() ? std::string("config/actuator.toml") : model_path),
      2);
  // A rotary axis's errors are torques (effects/axis_kind.hpp).
  const std::string u(effects::drive_unit_of_system(J.system));
  if (J.samples_used == 0)  // no fit: no figure to print, not a perfect one
    std::printf("baseline   RMS n/a (no sample used by the fit)\n");
  else
    std::printf("baseline   RMS %8.4f %s   relative error %7.3f %%   (full rate %7.3f %%)\n",
                J.baseline.rms_n, u.c_str(), J.baseline.relative_error_pct,
                J.baseline.full_rate_relative_error_pct);
  for (const auto& w : result.where) say("  where: " + w, 9);
  print_findings(J);
  if (!J.final_fit.summary.empty()) say("fitted     " + J.final_fit.summary, 11);
  if (J.samples_used > 0) {
    std::printf("final      RMS %8.4f %s   relative error %7.3f %%   (full rate %7.3f %%)\n",
                J.final_fit.rms_n, u.c_str(), J.final_fit.relative_error_pct,
                J.final_fit.full_rate_relative_error_pct);
    std::string held_out = "held-out:";
    // A held-out error of exactly 0 beside a residual is no fit on held-out segments, not a
    // perfect one.
    const bool judged = !J.validation.empty() &&
                        !(J.validation.front().heldout_rms_n == 0.0 && J.final_fit.rms_n > 0.0);
    if (!judged) held_out += "  not judged (too few sliding samples to hold segments out)";
    for (const auto& v : judged ? J.validation : decltype(J.validation){}) {
      char rms[32];
      std::snprintf(rms, sizeof rms, " %.4g ", v.heldout_rms_n);
      held_out += "  " + v.model + rms + u;
    }
    say(held_out, 11);
  }
  say("wrote " + o.out + "/index.html, analysis.json, model_corrected.toml" + o.replacing, 6);
}

/// The recording, its columns checked before any work: against the actuator's baseline the
/// position and the load cell are required, so an axis's recording is answered with the
/// --model it needs (read_actuator_recording, as report answers it) and one without a load cell
/// with the command that needs none. Only the columns the analysis reads are stored: an hour at
/// 1 kHz stores 29 MB per column.
Recording read_for_analysis(const AnalyzeOptions& o, const ActuatorParams& act,
                            const analysis::ModelFile& model, const std::string& model_path) {
  if (model.system != "actuator") {  // an axis's columns: the axis path names what it misses
    return read_actuator_recording(o.recording, act, o.config, {}, analysis::columns_read);
  }
  const std::string baseline =
      model_path.empty() ? config_file(o.config, "actuator.toml") : model_path;
  try {
    return read_actuator_recording(o.recording, act, o.config, {"t_s", "nut_pos_m", "load_force_n"},
                                   analysis::columns_read,
                                   "analyze with the actuator's baseline (" + baseline + ")");
  } catch (const MissingColumnError& e) {
    refuse_without_load_cell(e, "The analysis compares the model's force with a load cell's",
                             o.recording);
  }
}

void run_analyze(AnalyzeOptions o) {
  o.a.actuator.twin_force_check = !o.no_twin_check;
  const ActuatorParams act = load_actuator_or_default(o.config);
  const std::string model_path = baseline_path(o);
  if (!model_path.empty()) twin::check_model_format(model_path);  // the analysis reader does not
  const analysis::ModelFile model = model_path.empty() ? analysis::actuator_model_from_config(act)
                                                       : analysis::load_model(model_path);
  // The axis takes fewer segments than the actuator (rules.hpp): the model says which it is.
  if (model.system == "actuator" && o.a.folds < analysis::rules::kMinFolds)
    throw CLI::ValidationError("--folds", std::to_string(o.a.folds) +
                                              " is below the actuator analysis's " +
                                              std::to_string(analysis::rules::kMinFolds) +
                                              " held-out segments: type e.g. --folds " +
                                              std::to_string(analysis::rules::kFolds));
  for (const auto& [option, given, what] :
       {std::tuple{"--calibration-accuracy", o.a.actuator.calibration_accuracy_n > 0,
                   "how well its coupling calibration is known"},
        {"--calibration", !o.calibration.empty(), "its coupling calibration"}})
    if (model.system != "actuator" && given)
      throw CLI::ValidationError(option, std::string("applies to the actuator only (") + what +
                                             "); the model is an axis's (system = \"" +
                                             model.system +
                                             "\"), whose drive is taken as logged with no "
                                             "calibration: drop " +
                                             option);
  // The actuator decimates to its own rule (a few sliding samples per filter period).
  if (model.system == "actuator" && o.a.axis.decimation > 0)
    throw CLI::ValidationError("--decimation",
                               "applies to an axis's model only; the actuator keeps its own "
                               "number of samples per filter period: drop --decimation");
  const ForceCalibration cal =
      model.system != "actuator"
          ? paper_calibration()
          : load_calibration(o.calibration.empty() ? config_file(o.config, "calibration.toml")
                                                   : o.calibration);
  note("reading " + o.recording);
  const Recording rec = read_for_analysis(o, act, model, model_path);
  check_phase_on_branch(rec, act, cal);
  StageProgress progress;
  o.a.progress = [&](const std::string& stage, double f) { progress(stage, f); };
  const auto result = analysis::analyze_recording(rec, model, cal, act, o.a);
  progress.done();
  o.replacing = replacing_note((std::filesystem::path(o.out) / "analysis.json").string(),
                               "the results there");
  report::write_analysis_outputs(result, o.out);
  print_result(o, model_path, result);
}

void add_analyze(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "analyze",
      "Compare a baseline model with a recording, locate the misfit, explain it by named "
      "physical effects chosen on held-out data; write the report page index.html (the analysis "
      "part of `maglead report`'s page), analysis.json and the corrected model");
  auto o = std::make_shared<AnalyzeOptions>();
  add_recording_option(
      cmd, o->recording,
      "mls-recording/1: actuator (t_s, screw or motor angle, nut_pos_m, "
      "load_force_n), force-driven axis (t_s, pos_m, drive_force_n) or rotary axis "
      "('# axis: rotary'; t_s, angle_rad, drive_torque_n_m)");
  cmd->add_option("--model", o->model,
                  "Baseline model file (default: CONFIG/model.toml, else CONFIG/actuator.toml); "
                  "e.g. config/emps_baseline.toml for the EMPS data");
  cmd->add_option("-o,--out", o->out, "Output directory")
      ->required()
      ->check(CLI::Validator(output_directory_problem, ""));
  cmd->add_option("--calibration", o->calibration,
                  "Coupling calibration (actuator; default: CONFIG/calibration.toml)");
  cmd->add_option("--folds", o->a.folds,
                  "Held-out time segments, " + std::to_string(analysis::rules::kMinFolds) + " .. " +
                      std::to_string(kMaxFolds) + " (an axis: from " +
                      std::to_string(analysis::rules::kAxisMinFolds) + ")")
      ->check(number_in(
          {analysis::rules::kAxisMinFolds, kMaxFolds, "",
           "held-out segments; the actuator's from " + std::to_string(analysis::rules::kMinFolds),
           "--folds " + std::to_string(analysis::rules::kFolds)}))
      ->capture_default_str();
  cmd->add_option("--filter-hz", o->a.filter_hz,
                  "Zero-phase low-pass of position [Hz] (default 100 for an axis, 20 actuator). "
                  "The actuator counts a sample as sliding from one encoder count per filter "
                  "period: a higher cutoff leaves slow moves out")
      ->check(number_in(
          {0.0, std::numeric_limits<double>::infinity(), "Hz", "0 chooses it", "--filter-hz 20"}));
  cmd->add_option("--decimation", o->a.axis.decimation,
                  "Axis only (refused with the actuator's model): decimation factor (default: "
                  "down to the identification bandwidth)")
      ->check(number_in(
          {0.0, kMaxDecimation, "", "0 chooses it, 1 keeps every sample", "--decimation 1"}));
  cmd->add_option("--min-gain", o->a.min_gain_pct,
                  "Held-out mean-square-error reduction a term must bring [%], 0 .. 100")
      ->check(number_in({0.0, 100.0, "%", "a share of the held-out error", "--min-gain 1"}))
      ->capture_default_str();
  cmd->add_option("--calibration-accuracy", o->a.actuator.calibration_accuracy_n,
                  "Actuator only (refused with an axis's model): how well the calibration is "
                  "known [N] (e.g. its bench's accuracy); "
                  "a finding must change the force by more. Default: a thousandth of the "
                  "calibrated peak force, at least 0.07 N")
      ->check(number_in({0.0, std::numeric_limits<double>::infinity(), "N",
                         "a force the calibration may be off by; 0 takes the default",
                         "--calibration-accuracy 0.5"}));
  cmd->add_flag("--no-twin-check", o->no_twin_check,
                "Skip the twin's force estimate with the corrected model (it runs the twin over "
                "the recording two or more times)");
  add_config_option(cmd, o->config);
  cmd->callback([o] {
    maglead::cli::advise_large_blocks_to_huge_pages();  // reads whole recordings
    run_analyze(*o);
  });
}

MAGLEAD_COMMAND(60, add_analyze);

}  // namespace
}  // namespace maglead::cli
