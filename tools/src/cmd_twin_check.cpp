// maglead twin-check: run the controller's TwinMonitor over a recording, tick by tick as the
// loop would, and report what it flagged and when (drift, step-out warning and step-out).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>
#include <span>

#include "cli_common.hpp"
#include "large_blocks.hpp"
#include "maglead/analysis/anomaly.hpp"
#include "maglead/twin/replay.hpp"

namespace maglead::cli {
namespace {

/// The flag's verdict: from free moves only (known external force), never from the load cell.
void print_drift(const twin::TwinOutputs& last, const twin::TwinOutputs& at_drift, double t_drift,
                 double max_stat) {
  using twin::DriftObservability;
  char line[480];
  if (!std::isnan(t_drift)) {
    std::snprintf(line, sizeof line, "  drift warning: at t = %.2f s: %s [reason %d]", t_drift,
                  twin::drift_message(at_drift).c_str(), static_cast<int>(at_drift.drift_reason));
  } else if (last.drift_observability == DriftObservability::none) {
    std::snprintf(line, sizeof line,
                  "  drift not observable: no stretch with a known external force");
  } else if (last.drift_observability == DriftObservability::reference) {
    std::snprintf(line, sizeof line,
                  "  drift not observable yet: %.1f s of known-force stretches (free moves, a "
                  "passive load revisited), no reference formed from them",
                  last.drift_known_s);
  } else {
    // Compared but never judged (too few differences to measure the scatter): not a "none".
    std::snprintf(line, sizeof line,
                  "  %s (%.1f s of known-force stretches, reference at t = %.1f s; at the end %s; "
                  "max statistic %.2f of the margin)",
                  max_stat > 0.0 ? "drift warning: none" : "drift not judged yet",
                  last.drift_known_s, last.drift_reference_t_s,
                  twin::drift_figures_text(last.drift_now).c_str(), max_stat);
  }
  print_line(line, 4);
}

/// A check of the flag against the load cell, where one is logged (the flag never reads it).
void print_load_cell_check(const twin::TwinOutputs& last) {
  if (std::isnan(last.drift_gain_estimate) || std::isnan(last.drift_reference_gain)) {
    std::printf("  load cell check: no coupling-gain estimate (too little sliding under load)\n");
    return;
  }
  char line[240];
  std::snprintf(line, sizeof line,
                "  load cell check (not used by the flag): coupling gain %.3f ± %.3f at the end, "
                "%.3f ± %.3f at its reference: change %+.3f ± %.3f",
                last.drift_gain_estimate, last.drift_gain_stderr, last.drift_reference_gain,
                last.drift_reference_stderr, last.drift_gain_estimate - last.drift_reference_gain,
                std::hypot(last.drift_gain_stderr, last.drift_reference_stderr));
  print_line(line, 4);
}

struct TwinCheckOptions {
  std::string recording, config = default_config_dir(), model, trace;
  bool no_load_cell = false;
};

/// What the run of the monitor flagged and when, and its errors against a logged load cell.
struct CheckSummary {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double t_drift = kNaN, t_warn = kNaN, t_step = kNaN, max_res_m = 0, drift_stat = 0;
  double err_dyn_n = 0, err_static_n = 0;
  std::size_t healthy = 0, counted = 0;
  twin::TwinOutputs last{}, at_drift{};

  void add(double t, const twin::TwinOutputs& out, double load_n) {
    if (out.drift_warning && std::isnan(t_drift)) t_drift = t, at_drift = out;
    if (out.step_out_warning && std::isnan(t_warn)) t_warn = t;
    if (out.step_out && std::isnan(t_step)) t_step = t;
    max_res_m = std::max(max_res_m, std::abs(out.residual_pos_m));
    healthy += out.healthy;
    last = out;
    drift_stat = std::max(drift_stat, out.drift_statistic);
    if (std::isfinite(load_n)) {
      err_dyn_n += std::abs(out.dynamic_output_force_est_n + load_n);
      err_static_n += std::abs(out.static_output_force_est_n + load_n);
      ++counted;
    }
  }
};

/// --trace: the monitor's outputs every 10 ms, as an mls-recording/1 (a value the monitor has
/// not formed, NaN, is an empty field: the readers take it as missing), written whole at the end.
class Trace {
 public:
  explicit Trace(const std::string& path) {
    if (path.empty()) return;
    writer_ = std::make_unique<RecordingWriter>(
        path, std::vector<std::pair<std::string, std::string>>{{"source", "maglead twin-check"}},
        std::vector<std::string>{"t_s", "zero_load_error_n", "zero_load_stderr_n",
                                 "drift_statistic", "drift_observability", "drift_warning",
                                 "drift_reason", "check_gain", "check_gain_stderr", "healthy",
                                 "health_reason", "residual_pos_m", "step_out_warning",
                                 "step_out_reason"},
        WriteMode::whole);
  }
  /// Puts the whole trace in place (a run that fails leaves the path as it was).
  void close() {
    if (writer_) writer_->close();
  }
  void write(std::size_t i, double t, const twin::TwinOutputs& out) {
    if (!writer_ || i % 10 != 0) return;
    const double row[] = {t,
                          out.drift_now.zero_load_n,
                          out.drift_now.zero_load_se_n,
                          out.drift_statistic,
                          static_cast<double>(out.drift_observability),
                          static_cast<double>(out.drift_warning),
                          static_cast<double>(out.drift_reason),
                          out.drift_gain_estimate,
                          out.drift_gain_stderr,
                          static_cast<double>(out.healthy),
                          static_cast<double>(out.health_reason),
                          out.residual_pos_m,
                          static_cast<double>(out.step_out_warning),
                          static_cast<double>(out.step_out_reason)};
    writer_->write_row(row, std::size(row));
  }

 private:
  std::unique_ptr<RecordingWriter> writer_;
};

void print_step_out(const CheckSummary& c) {
  if (std::isnan(c.t_warn) && std::isnan(c.t_step)) {
    std::printf("  step-out: none, no warning\n");
    return;
  }
  if (!std::isnan(c.t_warn)) std::printf("  step-out warning: at t = %.3f s\n", c.t_warn);
  if (std::isnan(c.t_step)) return;
  const std::string lead =
      !std::isnan(c.t_warn) && c.t_warn < c.t_step
          ? ", warned " + std::to_string(std::lround((c.t_step - c.t_warn) * 1e3)) + " ms before"
          : ", not warned before";
  std::printf("  step-out: flagged at t = %.3f s%s\n", c.t_step, lead.c_str());
}

void run_twin_check(const TwinCheckOptions& o) {
  twin::TwinMonitorConfig tc = twin::load_monitor_config(o.config);
  if (!o.model.empty()) tc.model = twin::load_twin_model(o.model);
  const Recording rec =
      read_actuator_recording(o.recording, tc.actuator, o.config, {"t_s", "nut_pos_m"});
  check_phase_on_branch(rec, tc.actuator, tc.calibration);
  const auto& t = rec.column("t_s");
  const auto optional = [&](const char* name) {
    return rec.has(name) ? std::span<const double>(rec.column(name)) : std::span<const double>();
  };
  // A load cell analyze and report set aside (another unit, the other sign) is not scored.
  const std::optional<LoadCellUnitError> unusable =
      rec.has("load_force_n") && !o.no_load_cell
          ? analysis::load_cell_unusable(rec, tc.calibration, tc.actuator)
          : std::nullopt;
  const bool has_load = rec.has("load_force_n") && !o.no_load_cell && !unusable;
  const auto load = has_load ? optional("load_force_n") : std::span<const double>();
  CheckSummary c;
  Trace trace(o.trace);
  const auto t0 = std::chrono::steady_clock::now();
  twin::replay_monitor(
      tc,
      {t, screw_angle_of(rec, tc.actuator), rec.column("nut_pos_m"), optional("force_set_n"), load},
      [&](std::size_t i, const twin::TwinOutputs& out) {
        trace.write(i, t[i], out);
        c.add(t[i], out, has_load ? load[i] : CheckSummary::kNaN);
      });
  trace.close();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::size_t n = t.size();
  char head[96];
  std::snprintf(head, sizeof head, ": %.1f s, %zu ticks (%.0f x real time)", t.back() - t.front(),
                n, (t.back() - t.front()) / wall_s);
  print_line("twin check of " + o.recording + head);
  if (c.counted)
    std::printf("  force MAE against load cell: twin %.2f N, static %.2f N\n",
                c.err_dyn_n / static_cast<double>(c.counted),
                c.err_static_n / static_cast<double>(c.counted));
  else
    print_line("  force estimate against load cell: not judged (" +
                   std::string(!rec.has("load_force_n") ? "no load_force_n column"
                               : o.no_load_cell         ? "--no-load-cell"
                               : unusable               ? unusable->what()
                                                        : "no sample where both are numbers") +
                   ")",
               4);
  std::printf("  position residual: max %.1f µm; healthy %.1f %% of ticks\n", c.max_res_m * 1e6,
              100.0 * static_cast<double>(c.healthy) / static_cast<double>(n));
  print_drift(c.last, c.at_drift, c.t_drift, c.drift_stat);
  if (has_load) print_load_cell_check(c.last);
  print_step_out(c);
}

void add_twin_check(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "twin-check",
      "Run the digital twin monitor over a recording, tick by tick as the controller "
      "does: drift warning (the force estimate's error from free moves, without a load "
      "cell), health, step-out warning and flag; where a load cell is logged, the force "
      "error and a coupling-gain check against it");
  auto o = std::make_shared<TwinCheckOptions>();
  add_recording_option(cmd, o->recording,
                       "mls-recording/1 with t_s, screw or motor angle, nut_pos_m");
  add_config_option(cmd, o->config);
  cmd->add_option("--model", o->model, "Twin model file (default: CONFIG/model.toml)");
  cmd->add_option(
      "--trace", o->trace,
      "Write the monitor's outputs every 10 ms to this mls-recording/1 CSV (gain, its error, "
      "reference, statistic, flags and reason codes; a value not formed yet is an empty field)");
  cmd->add_flag("--no-load-cell", o->no_load_cell,
                "Ignore a logged load_force_n column (the flag never reads it; this shows it)");
  cmd->callback([o] {
    maglead::cli::advise_large_blocks_to_huge_pages();  // reads whole recordings
    run_twin_check(*o);
  });
}

MAGLEAD_COMMAND(45, add_twin_check);

}  // namespace
}  // namespace maglead::cli
