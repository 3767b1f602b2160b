// maglead twin-check: run the controller's TwinMonitor over a recording, tick by tick as the
// loop would, and report what it flagged and when (drift, step-out warning and step-out).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "cli_common.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::cli {
namespace {

void add_twin_check(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "twin-check", "Run the digital twin monitor over a recording: drift warning (with time to "
                    "detect), step-out warning and flag, residuals, force error if a load cell is "
                    "logged");
  struct Opts {
    std::string recording, config = default_config_dir(), model;
    double drift_start_s = 0.0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--recording", o->recording, "mls-recording/1 with t_s, screw or motor angle, nut_pos_m")
      ->required();
  cmd->add_option("--config", o->config, "Configuration directory")->capture_default_str();
  cmd->add_option("--model", o->model, "Twin model file (default: CONFIG/model.toml)");
  cmd->add_option("--drift-start", o->drift_start_s,
                  "When the calibration started to drift, for the time-to-detect [s]")
      ->capture_default_str();
  cmd->callback([o] {
    twin::TwinMonitorConfig tc = twin::load_monitor_config(o->config);
    if (!o->model.empty()) tc.model = twin::load_twin_model(o->model);
    const Recording rec = read_recording(o->recording, {"t_s", "nut_pos_m"});
    const auto screw = screw_angle_of(rec, tc.actuator);
    const auto& t = rec.column("t_s");
    const auto& pos = rec.column("nut_pos_m");
    const std::size_t n = t.size();
    if (n < 2) throw RecordingError(o->recording + ": needs at least two samples");
    const double period = (t.back() - t.front()) / static_cast<double>(n - 1);
    if (period > 0) tc.actuator.sample_rate_hz = 1.0 / period;
    tc.integrator.max_step_s = 1.0 / tc.actuator.sample_rate_hz;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const std::vector<double>* fset = rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr;
    const std::vector<double>* load = rec.has("load_force_n") ? &rec.column("load_force_n") : nullptr;

    twin::TwinMonitor mon(tc);
    mon.reset(t[0], screw[0], pos[0]);
    double t_drift = nan, t_warn = nan, t_step = nan, max_res = 0, err_dyn = 0, err_static = 0;
    std::size_t healthy = 0, counted = 0;
    double gain_est = 1.0, drift_stat = 0.0;
    const auto t0 = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < n; ++i) {
      const auto out = mon.step({t[i], screw[i], pos[i], fset ? (*fset)[i] : nan});
      if (out.drift_warning && std::isnan(t_drift)) t_drift = t[i];
      if (out.step_out_warning && std::isnan(t_warn)) t_warn = t[i];
      if (out.step_out && std::isnan(t_step)) t_step = t[i];
      max_res = std::max(max_res, std::abs(out.residual_pos_m));
      healthy += out.healthy;
      gain_est = out.drift_gain_estimate;
      drift_stat = std::max(drift_stat, out.drift_statistic);
      if (load && std::isfinite((*load)[i])) {
        err_dyn += std::abs(out.dynamic_output_force_est_n + (*load)[i]);
        err_static += std::abs(out.static_output_force_est_n + (*load)[i]);
        ++counted;
      }
    }
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("twin check of %s: %.1f s, %zu ticks (%.0f x real time)\n", o->recording.c_str(),
                t.back() - t.front(), n, (t.back() - t.front()) / wall_s);
    if (counted)
      std::printf("  force MAE against load cell: twin %.2f N, static %.2f N\n",
                  err_dyn / static_cast<double>(counted), err_static / static_cast<double>(counted));
    std::printf("  position residual: max %.1f um; healthy %.1f %% of ticks\n", max_res * 1e6,
                100.0 * static_cast<double>(healthy) / static_cast<double>(n));
    if (std::isnan(t_drift))
      std::printf("  drift warning: none (max statistic %.2f of threshold, gain estimate %.3f)\n",
                  drift_stat, gain_est);
    else
      std::printf("  drift warning: at t = %.2f s, %.2f s after the drift started (gain estimate "
                  "%.3f)\n",
                  t_drift, t_drift - o->drift_start_s, gain_est);
    if (std::isnan(t_warn) && std::isnan(t_step))
      std::printf("  step-out: none, no warning\n");
    else {
      if (!std::isnan(t_warn)) std::printf("  step-out warning: at t = %.3f s\n", t_warn);
      if (!std::isnan(t_step))
        std::printf("  step-out: flagged at t = %.3f s%s\n", t_step,
                    !std::isnan(t_warn) && t_warn < t_step
                        ? (", warned " + std::to_string(static_cast<int>(std::lround((t_step - t_warn) * 1e3))) +
                           " ms before").c_str()
                        : ", not warned before");
    }
  });
}

MAGLEAD_COMMAND(45, add_twin_check);

}  // namespace
}  // namespace maglead::cli
