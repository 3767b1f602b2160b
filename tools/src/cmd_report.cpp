// maglead report: the twin-versus-actual anomaly report for an operator. Parses options, runs
// the anomaly inspection (the recording replayed through the controller's twin) and the
// analysis, and has the report library write the page; prints the headline.
#include <cstdio>
#include <filesystem>
#include <memory>

#include "cli_common.hpp"
#include "large_blocks.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/anomaly.hpp"
#include "maglead/report/anomaly_page.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::cli {
namespace {

struct ReportOpts {
  std::string recording, out, config = default_config_dir(), calibration, model;
  bool no_analysis = false;
};

report::AnalysisOutcome run_analysis(const ReportOpts& o, const Recording& rec,
                                     const ActuatorParams& act, const ForceCalibration& cal) {
  report::AnalysisOutcome outcome;
  if (o.no_analysis) {
    outcome.reason = "--no-analysis";
    return outcome;
  }
  try {
    std::string model_path = o.model;
    if (model_path.empty() && std::filesystem::exists(config_file(o.config, "model.toml")))
      model_path = config_file(o.config, "model.toml");
    const auto model = model_path.empty() ? analysis::actuator_model_from_config(act)
                                          : analysis::load_model(model_path);
    analysis::AnalysisOptions ao;
    std::unique_ptr<Progress> bar;
    std::string stage;
    ao.progress = [&](const std::string& st, double f) {
      if (st != stage) {
        if (bar) bar->done();
        bar = std::make_unique<Progress>("report: analysis: " + st);
        stage = st;
      }
      (*bar)(f);
    };
    outcome.result = analysis::analyze_recording(rec, model, cal, act, ao);
    if (bar) bar->done();
    outcome.status = report::AnalysisOutcome::Status::done;
  } catch (const LoadCellUnitError& e) {
    outcome.status = report::AnalysisOutcome::Status::failed;
    outcome.reason = e.what();
    outcome.load_cell_unusable = true;
    outcome.load_cell_constant_n = e.constant_n();
  } catch (const std::exception& e) {
    // The report is still worth having without the analysis: say why it is missing.
    outcome.status = report::AnalysisOutcome::Status::failed;
    outcome.reason = e.what();
  }
  return outcome;
}

/// What the analysis came to, in a word or its own conclusion: "done" never stands beside a
/// headline that says it could not judge.
std::string analysis_line(const report::AnalysisOutcome& o) {
  using S = report::AnalysisOutcome::Status;
  if (o.status == S::skipped) return "skipped";
  if (o.status == S::failed) return "not possible";
  const std::string& c = o.result ? o.result->findings.conclusion : std::string();
  return c.starts_with("not judged") ? c : "done";
}

void add_report(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "report",
      "Twin-versus-actual anomaly report of a recording: where twin and machine part, the missing "
      "physics, the fit, step-outs and drift; one self-contained HTML page with interactive plots");
  auto o = std::make_shared<ReportOpts>();
  add_recording_option(cmd, o->recording,
                       "mls-recording/1 (t_s, screw or motor angle, nut_pos_m; "
                       "load_force_n, out_force_est_n, force_set_n if logged)");
  cmd->add_option("-o,--out", o->out,
                  "Output directory (index.html, the page with its plots inlined; report.json)")
      ->required()
      ->check(CLI::Validator(output_directory_problem, ""));
  add_config_option(cmd, o->config);
  cmd->add_option("--calibration", o->calibration,
                  "Force calibration (default: CONFIG/calibration.toml)");
  cmd->add_option("--model", o->model,
                  "Baseline model for the analysis (default: CONFIG/model.toml)");
  cmd->add_flag("--no-analysis", o->no_analysis, "Skip the analysis (quicker)");
  cmd->callback([o] {
    maglead::cli::advise_large_blocks_to_huge_pages();  // reads whole recordings
    const ActuatorParams act = load_actuator_or_default(o->config);
    const ForceCalibration cal = load_calibration(
        o->calibration.empty() ? config_file(o->config, "calibration.toml") : o->calibration);
    const Recording rec =
        read_actuator_recording(o->recording, act, o->config, {"t_s", "nut_pos_m"});
    check_phase_on_branch(rec, act, cal);
    twin::TwinMonitorConfig monitor = twin::load_monitor_config(o->config);
    monitor.actuator = act;
    monitor.calibration = cal;
    note("report: replaying the recording through the twin");
    auto anomaly = analysis::inspect_recording(rec, monitor);
    const auto outcome = run_analysis(*o, rec, act, cal);
    if (outcome.load_cell_unusable)
      analysis::set_aside_load_cell(anomaly, outcome.reason, outcome.load_cell_constant_n);
    report::write_anomaly_report(o->out, o->recording, anomaly, outcome);
    print_line(report::anomaly_headline(anomaly, outcome));
    std::printf("step-outs: %zu, drift windows: %zu, twin position residual RMS %.1f µm\n",
                anomaly.step_outs.size(), anomaly.drift_windows.size(),
                anomaly.residual_pos_rms_m * 1e6);
    if (anomaly.static_error && anomaly.twin_error) {
      char line[160];
      std::snprintf(line, sizeof line,
                    "force error against load cell: static %.2f N, twin %.2f N (mean absolute, "
                    "after the first %.2g s)",
                    anomaly.static_error->mean_abs_n, anomaly.twin_error->mean_abs_n,
                    anomaly.settle_s);
      print_line(line);
    }
    print_line("analysis: " + analysis_line(outcome));
    print_line("wrote " + (std::filesystem::path(o->out) / "index.html").string() +
               ", report.json");
  });
}

MAGLEAD_COMMAND(87, add_report);

}  // namespace
}  // namespace maglead::cli
