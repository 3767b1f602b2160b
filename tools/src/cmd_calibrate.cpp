// maglead calibrate: fit the static force curve from a calibration recording (paper IV.B).
#include <cstdio>

#include "cli_common.hpp"
#include "maglead/physics/calibration.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/report/plot.hpp"

namespace maglead::cli {
namespace {

void add_calibrate(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "calibrate",
      "Fit load force against phase (orders 1-9, paper Fig. 10), choose the order, write the "
      "calibration file the controller reads");
  struct Opts {
    std::string recording, out, plot, config = default_config_dir();
    double gain_pct = 3.0;
  };
  auto o = std::make_shared<Opts>();
  add_recording_option(cmd, o->recording,
                       "mls-recording/1 with t_s, screw or motor angle, nut_pos_m, load_force_n "
                       "(screw held, nut moved through the stable range)");
  cmd->add_option("-o,--out", o->out, "Calibration file to write (TOML)")->required();
  cmd->add_option("--plot", o->plot, "Also draw data and fit into this PNG")->check(image_name());
  cmd->add_option(
         "--order-gain", o->gain_pct,
         "Choose the lowest order that no higher order improves by more than this [% RMSE]")
      ->capture_default_str();
  add_config_option(cmd, o->config);
  cmd->callback([o] {
    const ActuatorParams act = load_actuator_or_default(o->config);
    const Recording rec =
        read_actuator_recording(o->recording, act, o->config, {"t_s", "nut_pos_m", "load_force_n"});
    const auto screw = screw_angle_of(rec, act);
    const auto& t = rec.column("t_s");
    const auto& pos = rec.column("nut_pos_m");
    const auto vel = central_velocity(t, pos, 50);
    std::vector<double> phase(t.size());
    for (std::size_t i = 0; i < t.size(); ++i) phase[i] = phase_rad(screw[i], pos[i], act.lead_m);
    CalibrationOptions copt;
    copt.order_gain_fraction = o->gain_pct / 100.0;
    auto result = calibrate_static_force(phase, vel, rec.column("load_force_n"), copt);
    result.calibration.source = "maglead calibrate " + o->recording;

    std::printf("static force calibration from %s (%zu moving samples)\n\n", o->recording.c_str(),
                result.samples_used);
    std::printf("  order   RMSE [N]\n");
    for (const auto& f : result.table)
      std::printf("  %5d   %8.3f%s\n", f.order, f.rmse_n,
                  f.order == result.chosen_order ? "   <- chosen" : "");
    std::printf("\nchosen order %d: no higher order lowers its RMSE by more than %.1f %%\n",
                result.chosen_order, o->gain_pct);
    std::printf("friction fitted with it: %.2f N (Coulomb, from the sweep's hysteresis)\n",
                result.coulomb_n);
    std::printf("stable branch: %.3f .. %.3f rad; peak output force %+.1f N / %+.1f N\n",
                result.calibration.stable_min_rad, result.calibration.stable_max_rad,
                result.calibration.peak_push_n, result.calibration.peak_pull_n);
    save_calibration(o->out, result.calibration,
                     "order " + std::to_string(result.chosen_order) + ", fitted friction " +
                         std::to_string(result.coulomb_n) + " N");
    std::printf("wrote %s\n", o->out.c_str());
    if (!o->plot.empty()) {
      plot::Panel p{"Static force against phase", "phase [rad]", "load force [N]", {}};
      plot::Series data{"measured", phase, rec.column("load_force_n")};
      plot::Series fit{"order " + std::to_string(result.chosen_order) + " fit", {}, {}};
      for (double x = result.calibration.stable_min_rad; x <= result.calibration.stable_max_rad;
           x += 0.01) {
        fit.x.push_back(x);
        fit.y.push_back(result.calibration.polynomial.load_force_n(x));
      }
      p.series = {data, fit};
      plot::save_panels_png(o->plot, {p}, 1000, 500);
      std::printf("wrote %s\n", o->plot.c_str());
    }
  });
}

MAGLEAD_COMMAND(30, add_calibrate);

}  // namespace
}  // namespace maglead::cli
