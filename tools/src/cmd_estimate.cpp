// maglead estimate: force estimate from a recording against its load cell (paper Fig. 11).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "cli_common.hpp"
#include "large_blocks.hpp"
#include "maglead/analysis/anomaly.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/physics/load_observer.hpp"
#include "maglead/recording/error_stats.hpp"
#include "maglead/report/plot.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::cli {
namespace {

struct EstimateOptions {
  std::string recording, plot, out, calibration, model, config = default_config_dir(),
                                                        estimator = "static";
};

/// What the recording gives every estimator: time, screw angle and nut position.
struct Inputs {
  const std::vector<double>& t;
  std::vector<double> screw;
  const std::vector<double>& pos;
  const std::vector<double>* force_set;  // nullptr: not logged
  double period_s;
};

/// An estimator's output force per sample, and the observer's bound (empty for the others).
struct Estimates {
  std::vector<double> force_n, lo_n, hi_n;
};

twin::TwinModel model_of(const EstimateOptions& o) {
  if (!o.model.empty()) return twin::load_twin_model(o.model);
  return twin::load_monitor_config(o.config).model;
}

/// The observer the controller runs. Under force control the load is what the loop presses
/// (passive); otherwise loads come and go and rest at zero.
Estimates observer_estimates(const Inputs& in, controller::ControllerConfig c,
                             const EstimateOptions& o) {
  serve_model_terms(model_of(o), c);
  LoadForceObserver obs(controller::observer_config(c));
  const std::size_t n = in.t.size();
  Estimates e{std::vector<double>(n), std::vector<double>(n), std::vector<double>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    const bool pressed = in.force_set && std::isfinite((*in.force_set)[i]);
    const LoadEstimate& le =
        obs.update(in.t[i], phase_rad(in.screw[i], in.pos[i], c.actuator.lead_m), in.pos[i],
                   pressed ? LoadForceObserver::kPassiveLoad : 0.0);
    e.force_n[i] = le.force_n, e.lo_n[i] = le.lo_n, e.hi_n[i] = le.hi_n;
  }
  return e;
}

/// The TwinMonitor the controller runs, fed row by row exactly as the loop would.
Estimates twin_estimates(const Inputs& in, const controller::ControllerConfig& c,
                         const EstimateOptions& o) {
  twin::TwinMonitorConfig tc = twin::load_monitor_config(o.config);
  tc.actuator = c.actuator;
  tc.actuator.sample_rate_hz = in.period_s > 0 ? 1.0 / in.period_s : c.actuator.sample_rate_hz;
  tc.integrator.max_step_s = 1.0 / tc.actuator.sample_rate_hz;
  tc.calibration = c.calibration;
  tc.model = model_of(o);
  tc.stop_force_sd_n = c.observer_model_uncertainty_n;
  twin::TwinMonitor mon(tc);
  mon.reset(in.t[0], in.screw[0], in.pos[0]);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Estimates e{std::vector<double>(in.t.size()), {}, {}};
  for (std::size_t i = 0; i < in.t.size(); ++i)
    e.force_n[i] =
        mon.step({in.t[i], in.screw[i], in.pos[i], in.force_set ? (*in.force_set)[i] : nan})
            .dynamic_output_force_est_n;
  return e;
}

/// The same causal estimator the controller runs: window velocity, eq. 6.
Estimates static_estimates(const Inputs& in, const controller::ControllerConfig& c) {
  const ActuatorParams& act = c.actuator;
  StaticForceEstimator est(c.calibration, act.coulomb_n, 1e-5);
  EncoderVelocityEstimator vel(in.period_s > 0 ? in.period_s : 1e-3, act.linear_count_m);
  Estimates e{std::vector<double>(in.t.size()), {}, {}};
  for (std::size_t i = 0; i < in.t.size(); ++i) {
    const double v = i == 0 ? (vel.reset(in.pos[i]), 0.0) : vel.update(in.pos[i]);
    e.force_n[i] = est.output_force_n(phase_rad(in.screw[i], in.pos[i], act.lead_m), v);
  }
  return e;
}

void write_estimates(const EstimateOptions& o, const Inputs& in, const Estimates& e,
                     const std::vector<double>& measured, const std::vector<double>& error) {
  Recording est;
  est.set_meta("source", "maglead estimate --estimator " + o.estimator + " of " + o.recording);
  est.add_column("t_s", in.t);
  est.add_column("out_force_est_n", e.force_n);
  est.add_column("out_force_meas_n", measured);
  est.add_column("out_force_err_n", error);
  if (!e.lo_n.empty()) {
    est.add_column("out_force_lo_n", e.lo_n);
    est.add_column("out_force_hi_n", e.hi_n);
  }
  write_recording(o.out, est);
  std::printf("estimate: %s\n", o.out.c_str());
}

void plot_estimates(const EstimateOptions& o, const Inputs& in, double lead_m, const Estimates& e,
                    const std::vector<double>& measured, const std::vector<double>& error,
                    double mean_abs_n) {
  std::string png = o.plot;
  if (png.empty()) {
    std::filesystem::path p(o.recording);
    png = (p.parent_path() / (p.stem().string() + "_estimate_" + o.estimator + ".png")).string();
  }
  const std::size_t n = in.t.size();
  std::vector<double> pos_mm(n), screw_mm(n);
  for (std::size_t i = 0; i < n; ++i) {
    pos_mm[i] = in.pos[i] * 1e3;
    screw_mm[i] = in.screw[i] * lead_m / (2 * std::numbers::pi) * 1e3;
  }
  const auto& t = in.t;
  char mean_text[32];  // rounded as the printout rounds it (a cut string read 1.4399 as 1.43)
  std::snprintf(mean_text, sizeof mean_text, "%.2f", mean_abs_n);
  plot::save_panels_png(
      png,
      {{"(a) Output force: estimate against load cell",
        "time [s]",
        "force [N]",
        {{"load cell", t, measured}, {o.estimator + " estimate", t, e.force_n}}},
       {"(b) Estimation error (estimate - load cell), mean |e| " + std::string(mean_text) + " N",
        "time [s]",
        "error [N]",
        {{"error", t, error}}},
       {"(c) Nut position and screw angle (as lead travel)",
        "time [s]",
        "[mm]",
        {{"nut position", t, pos_mm}, {"screw angle x L/2pi", t, screw_mm}}}});
  std::printf("plot: %s\n", png.c_str());
}

/// The recording, with the load cell the comparison needs; one without it is answered with the
/// command that judges the estimate without a load cell.
Recording read_estimated(const EstimateOptions& o, const ActuatorParams& act) {
  try {
    return read_actuator_recording(o.recording, act, o.config,
                                   {"t_s", "nut_pos_m", "load_force_n"});
  } catch (const MissingColumnError& e) {
    refuse_without_load_cell(e, "estimate scores the force estimate against a load cell",
                             o.recording);
  }
}

/// The loads and motion the figures cover: the paper's 2.3 N is over pushes through its force
/// range with the nut sliding; a recording that stays near one load, or never moves, is not that.
void print_what_was_compared(const std::vector<double>& measured_n,
                             const std::vector<double>& nut_pos_m) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double f : measured_n)
    if (std::isfinite(f)) lo = std::min(lo, f), hi = std::max(hi, f);
  std::size_t moved = 0;
  for (std::size_t i = 1; i < nut_pos_m.size(); ++i) moved += nut_pos_m[i] != nut_pos_m[i - 1];
  const double moved_pct = 100.0 * static_cast<double>(moved) /
                           static_cast<double>(std::max<std::size_t>(1, nut_pos_m.size() - 1));
  char line[160];
  std::snprintf(line, sizeof line,
                "  over loads           %.2f .. %.2f N, the nut moving in %.1f %% of the samples",
                lo, hi, moved_pct);
  print_line(line, 23);
  if (moved == 0)
    print_line(
        "  (the nut never moved: the figures say how far the estimate sits from one held "
        "load, not how it tracks a force, and are not comparable with the paper's)",
        3);
}

void run_estimate(const EstimateOptions& o) {
  // The same [control] settings as `serve`.
  controller::ControllerConfig c;
  c.actuator = load_actuator_or_default(o.config);
  c.calibration = load_calibration(o.calibration.empty() ? config_file(o.config, "calibration.toml")
                                                         : o.calibration);
  load_control_settings(o.config, c);
  const Recording rec = read_estimated(o, c.actuator);
  check_phase_on_branch(rec, c.actuator, c.calibration);
  // A load cell analyze would refuse (another unit, the other sign) scores nothing: the
  // analysis's own judgement of it, not a second one.
  const auto why = analysis::load_cell_unusable(rec, c.calibration, c.actuator);
  // A constant one is unwired or stuck: neither its unit nor the calibration is the cause.
  if (why && why->constant_n())
    throw LoadCellUnitError(std::string(why->what()) +
                                ". estimate scores the force estimate against the load cell, so "
                                "it scores none against this one; without it: maglead "
                                "twin-check --recording " +
                                o.recording + " --no-load-cell",
                            *why->constant_n());
  if (why)
    throw LoadCellUnitError(std::string(why->what()) +
                            ". estimate scores the force estimate against the load cell, so it "
                            "scores none against this one: fix the column (load_force_n is the "
                            "load on the nut along +p: docs/recording-format.md) or, if it is "
                            "right, the calibration (--calibration); without it: maglead "
                            "twin-check --recording " +
                            o.recording + " --no-load-cell");
  const auto& t = rec.column("t_s");
  const std::size_t n = t.size();
  if (n < 2) throw RecordingError(o.recording + ": needs at least two samples");
  const Inputs in{t, screw_angle_of(rec, c.actuator), rec.column("nut_pos_m"),
                  rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr,
                  (t.back() - t.front()) / static_cast<double>(n - 1)};
  const Estimates e = o.estimator == "observer" ? observer_estimates(in, c, o)
                      : o.estimator == "twin"   ? twin_estimates(in, c, o)
                                                : static_estimates(in, c);
  const auto& load = rec.column("load_force_n");
  std::vector<double> measured(n), error(n);
  for (std::size_t i = 0; i < n; ++i) {
    measured[i] = -load[i];  // output force = −(force on the nut from the load)
    error[i] = e.force_n[i] - measured[i];
  }
  const ErrorStats s = error_stats(error);
  print_line("force estimate (" + o.estimator + ") against load cell, " + o.recording + ", " +
             std::to_string(s.samples) + " samples");
  char mean[160];
  std::snprintf(mean, sizeof mean,
                "  mean absolute error  %6.2f N   (the paper reports 2.3 N for its static "
                "estimate)",
                s.mean_abs);
  print_line(mean, 23);
  std::printf("  RMS error            %6.2f N\n", s.rms);
  std::printf("  max absolute error   %6.2f N\n", s.max_abs);
  print_what_was_compared(measured, rec.column("nut_pos_m"));
  if (!o.out.empty()) write_estimates(o, in, e, measured, error);
  plot_estimates(o, in, c.actuator.lead_m, e, measured, error, s.mean_abs);
}

void add_estimate(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("estimate",
                         "Estimate the output force from a recording's angles and positions and "
                         "compare it with the load cell; plot as in the paper's Fig. 11");
  auto o = std::make_shared<EstimateOptions>();
  add_recording_option(cmd, o->recording,
                       "mls-recording/1 with t_s, screw or motor angle, nut_pos_m, load_force_n");
  cmd->add_option("--estimator", o->estimator,
                  "static: the paper's eq. 6; twin: the digital twin's dynamic observer "
                  "(M p'' + C p' + hybrid stick/slip friction, config/model.toml); observer: the "
                  "controller's stick-aware load observer (force balance while sliding, the "
                  "force at the stop while stuck, same model file)")
      ->check(CLI::IsMember({"static", "twin", "observer"}))
      ->capture_default_str();
  cmd->add_option("--model", o->model,
                  "Model file for --estimator twin and observer (default: CONFIG/model.toml), "
                  "e.g. the model_corrected.toml that maglead analyze wrote; the observer takes "
                  "its friction, offset, mass, coupling gain and angle ripple, as serve does")
      ->check(CLI::ExistingFile);
  cmd->add_option("--plot", o->plot, "PNG to write (default: next to the recording)")
      ->check(image_name());
  cmd->add_option("-o,--out", o->out,
                  "Also write the estimate as a recording (mls-recording/1): t_s, "
                  "out_force_est_n, out_force_meas_n (the load cell's output force), "
                  "out_force_err_n; the observer adds its bound out_force_lo_n, out_force_hi_n");
  cmd->add_option("--calibration", o->calibration,
                  "Calibration file (default: CONFIG/calibration.toml)");
  add_config_option(cmd, o->config);
  cmd->callback([o] {
    maglead::cli::advise_large_blocks_to_huge_pages();  // reads whole recordings
    run_estimate(*o);
  });
}

MAGLEAD_COMMAND(40, add_estimate);

}  // namespace
}  // namespace maglead::cli
