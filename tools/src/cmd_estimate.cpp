// maglead estimate: force estimate from a recording against its load cell (paper Fig. 11).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "cli_common.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/physics/load_observer.hpp"
#include "maglead/recording/error_stats.hpp"
#include "maglead/report/plot.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::cli {
namespace {

void add_estimate(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("estimate",
                         "Estimate the output force from a recording's angles and positions and "
                         "compare it with the load cell; plot as in the paper's Fig. 11");
  struct Opts {
    std::string recording, plot, out, calibration, model, config = default_config_dir(),
                                                          estimator = "static";
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--recording", o->recording,
                  "mls-recording/1 with t_s, screw or motor angle, nut_pos_m, load_force_n")
      ->required();
  cmd->add_option("--estimator", o->estimator,
                  "static: the paper's eq. 6; twin: the digital twin's dynamic observer "
                  "(M p'' + C p' + hybrid stick/slip friction, config/model.toml); observer: the "
                  "controller's stick-aware load observer (force balance while sliding, the "
                  "force at the stop while stuck, same model file)")
      ->check(CLI::IsMember({"static", "twin", "observer"}))
      ->capture_default_str();
  cmd->add_option("--model", o->model,
                  "Model file for --estimator twin (default: CONFIG/model.toml), e.g. the "
                  "model_corrected.toml that maglead analyze wrote")
      ->check(CLI::ExistingFile);
  cmd->add_option("--plot", o->plot, "PNG to write (default: next to the recording)");
  cmd->add_option("--out", o->out,
                  "Also write the estimate as a recording (mls-recording/1): t_s, "
                  "out_force_est_n, out_force_meas_n (the load cell's output force), "
                  "out_force_err_n; the observer adds its bound out_force_lo_n, out_force_hi_n");
  cmd->add_option("--calibration", o->calibration,
                  "Calibration file (default: CONFIG/calibration.toml)");
  cmd->add_option("--config", o->config, "Configuration directory")->capture_default_str();
  cmd->callback([o] {
    const ActuatorParams act = load_actuator_or_default(o->config);
    const ForceCalibration cal = load_calibration(
        o->calibration.empty() ? config_file(o->config, "calibration.toml") : o->calibration);
    const Recording rec =
        read_actuator_recording(o->recording, act, o->config, {"t_s", "nut_pos_m", "load_force_n"});
    const auto screw = screw_angle_of(rec, act);
    const auto& t = rec.column("t_s");
    const auto& pos = rec.column("nut_pos_m");
    const auto& load = rec.column("load_force_n");
    const std::size_t n = t.size();
    if (n < 2) throw RecordingError(o->recording + ": needs at least two samples");
    const double period = (t.back() - t.front()) / static_cast<double>(n - 1);

    std::vector<double> measured(n), estimate(n), error(n), bound_lo, bound_hi;
    const auto model_file = [&] {
      if (!o->model.empty()) return twin::load_twin_model(o->model);
      return twin::load_monitor_config(o->config).model;
    };
    // The same [control] settings as `serve`.
    controller::ControllerConfig c;
    c.actuator = act;
    c.calibration = cal;
    load_control_settings(o->config, c);
    if (o->estimator == "observer") {
      // The observer the controller runs.
      c.friction = twin::friction_model(model_file());
      LoadForceObserver obs(controller::observer_config(c));
      // Under force control the load is what the loop presses (passive); otherwise loads come
      // and go and rest at zero.
      const std::vector<double>* fset =
          rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr;
      bound_lo.resize(n);
      bound_hi.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        const bool pressed = fset && std::isfinite((*fset)[i]);
        const LoadEstimate& e = obs.update(t[i], phase_rad(screw[i], pos[i], act.lead_m), pos[i],
                                           pressed ? LoadForceObserver::kPassiveLoad : 0.0);
        estimate[i] = e.force_n;
        bound_lo[i] = e.lo_n;
        bound_hi[i] = e.hi_n;
        measured[i] = -load[i];
        error[i] = estimate[i] - measured[i];
      }
    } else if (o->estimator == "twin") {
      // The TwinMonitor the controller runs, fed row by row exactly as the loop would.
      twin::TwinMonitorConfig tc = twin::load_monitor_config(o->config);
      tc.actuator = act;
      tc.actuator.sample_rate_hz = period > 0 ? 1.0 / period : act.sample_rate_hz;
      tc.integrator.max_step_s = 1.0 / tc.actuator.sample_rate_hz;
      tc.calibration = cal;
      tc.model = model_file();
      tc.stop_force_sd_n = c.observer_model_uncertainty_n;
      twin::TwinMonitor mon(tc);
      mon.reset(t[0], screw[0], pos[0]);
      const double nan = std::numeric_limits<double>::quiet_NaN();
      const std::vector<double>* fset =
          rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr;
      for (std::size_t i = 0; i < n; ++i) {
        const auto out = mon.step({t[i], screw[i], pos[i], fset ? (*fset)[i] : nan});
        estimate[i] = out.dynamic_output_force_est_n;
        measured[i] = -load[i];
        error[i] = estimate[i] - measured[i];
      }
    } else {
      // The same causal estimator the controller runs: window velocity, eq. 6.
      StaticForceEstimator est(cal, act.coulomb_n, 1e-5);
      EncoderVelocityEstimator vel(period > 0 ? period : 1e-3, act.linear_count_m);
      for (std::size_t i = 0; i < n; ++i) {
        const double v = i == 0 ? (vel.reset(pos[i]), 0.0) : vel.update(pos[i]);
        estimate[i] = est.output_force_n(phase_rad(screw[i], pos[i], act.lead_m), v);
        measured[i] = -load[i];  // output force = −(force on the nut from the load)
        error[i] = estimate[i] - measured[i];
      }
    }
    const ErrorStats s = error_stats(error);
    std::printf("force estimate (%s) against load cell, %s, %zu samples\n", o->estimator.c_str(),
                o->recording.c_str(), s.samples);
    std::printf("  mean absolute error  %6.2f N   (paper, static estimate: 2.3 N)\n", s.mean_abs);
    std::printf("  RMS error            %6.2f N\n", s.rms);
    std::printf("  max absolute error   %6.2f N\n", s.max_abs);

    if (!o->out.empty()) {
      Recording est;
      est.set_meta("source",
                   "maglead estimate --estimator " + o->estimator + " of " + o->recording);
      est.add_column("t_s", t);
      est.add_column("out_force_est_n", estimate);
      est.add_column("out_force_meas_n", measured);
      est.add_column("out_force_err_n", error);
      if (!bound_lo.empty()) {
        est.add_column("out_force_lo_n", bound_lo);
        est.add_column("out_force_hi_n", bound_hi);
      }
      write_recording(o->out, est);
      std::printf("estimate: %s\n", o->out.c_str());
    }
    std::string png = o->plot;
    if (png.empty()) {
      std::filesystem::path p(o->recording);
      png = (p.parent_path() / (p.stem().string() + "_estimate_" + o->estimator + ".png")).string();
    }
    std::vector<double> pos_mm(n), screw_mm(n);
    for (std::size_t i = 0; i < n; ++i) {
      pos_mm[i] = pos[i] * 1e3;
      screw_mm[i] = screw[i] * act.lead_m / (2 * std::numbers::pi) * 1e3;
    }
    plot::save_panels_png(
        png, {{"(a) Output force: estimate against load cell",
               "time [s]",
               "force [N]",
               {{"load cell", t, measured}, {o->estimator + " estimate", t, estimate}}},
              {"(b) Estimation error (estimate - load cell), mean |e| " +
                   std::to_string(s.mean_abs).substr(0, 4) + " N",
               "time [s]",
               "error [N]",
               {{"error", t, error}}},
              {"(c) Nut position and screw angle (as lead travel)",
               "time [s]",
               "[mm]",
               {{"nut position", t, pos_mm}, {"screw angle x L/2pi", t, screw_mm}}}});
    std::printf("plot: %s\n", png.c_str());
  });
}

MAGLEAD_COMMAND(40, add_estimate);

}  // namespace
}  // namespace maglead::cli
