// The drift flag in force control as `serve` runs it (issue 23's live gap), in-process on a fake
// clock: the controller's force loop on the simulated plant against the 2000 N/m spring `serve`
// simulates by default, the twin stepped with every cycle's sample (as runtime::TwinRunner does
// on its thread, here on the loop's, so the run is reproducible), a PLC's
// force setpoints held 2.5 s each (the live test's list). The loop lands each step within
// ~0.15 s and holds, so the nut slides one way at a time for a fraction of a second: the case
// `simulate --scenario force-steps` (ramps and a sweep, sliding most of the time) does not
// reproduce. No load cell reaches the twin (the sample's reading is NaN).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <memory>

#include "maglead/controller/controller.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/settings/settings.hpp"
#include "maglead/twin/model.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead {
namespace {

namespace reg = maglead::registers;
using namespace maglead::controller;

constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }
constexpr double kSetpoints_n[] = {5, 10, 15, 20, -5, -10, -15, 12, 8, 3, 0, 18, 6};
constexpr double kHold_s = 2.5, kStart_m = 0.02;

/// The plant's reading without its load cell: the twin must not have one to read.
class NoLoadCell final : public ActuatorHardware {
 public:
  explicit NoLoadCell(ActuatorHardware& hw) : hw_(hw) {}
  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override {
    const HwStatus st = hw_.read_sensors(now_s, out);
    out.load_force_n = std::numeric_limits<double>::quiet_NaN();
    return st;
  }
  HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept override {
    return hw_.write_motor_angle(motor_angle_cmd_rad);
  }
  HwStatus set_power(PowerRequest request) noexcept override { return hw_.set_power(request); }

 private:
  ActuatorHardware& hw_;
};

/// The twin on the loop's thread: each cycle's sample straight into the monitor (the fields
/// runtime::TwinRunner passes it), its whole outputs kept for the test.
class MonitorHook final : public TwinHook {
 public:
  explicit MonitorHook(const twin::TwinMonitorConfig& c) : mon_(c) {}
  void step(const TwinSample& in, TwinReport& out) noexcept override {
    last = mon_.step({in.t_s, in.screw_angle_rad, in.nut_pos_m, in.force_setpoint_n,
                      in.load_force_n, in.free_move});
    out.cycle = in.cycle, out.drift_warning = last.drift_warning;
  }
  void resync(double t_s, double screw_angle_rad, double nut_pos_m) noexcept override {
    mon_.reset(t_s, screw_angle_rad, nut_pos_m);
  }
  twin::TwinOutputs last{};

 private:
  twin::TwinMonitor mon_;
};

struct FlagRun {
  double first_flag_s = std::numeric_limits<double>::quiet_NaN();
  double max_statistic = 0.0, slide_share = 0.0;
  twin::TwinOutputs at_flag{}, last{};
};

/// `serve`'s parts: the model file's friction in the loop and the twin, the twin's settings from
/// config/, the observer's model uncertainty as the twin's stop-force spread.
FlagRun run_force_holds(double gain_per_min, double duration_s) {
  PlantParams plant = paper_like_plant();
  plant.effects.gain_drift_per_min = gain_per_min;
  SimulatedActuator sim(plant, 1, kStart_m);
  LoadSetting spring;
  spring.kind = LoadSetting::Kind::spring_to_wall;
  spring.stiffness_n_per_m = 2000.0;
  spring.damping_n_s_per_m = 5.0;
  spring.anchor_pos_m = kStart_m;
  sim.set_load(spring);
  NoLoadCell hw(sim);
  const twin::TwinModel model = twin::load_twin_model(MAGLEAD_CONFIG_DIR "/model.toml");
  ControllerConfig cfg;
  cfg.actuator = plant.actuator;
  cfg.friction = twin::friction_model(model);
  twin::TwinMonitorConfig tc = twin::load_monitor_config(MAGLEAD_CONFIG_DIR);
  tc.actuator = cfg.actuator;
  tc.calibration = cfg.calibration;
  tc.stop_force_sd_n = cfg.observer_model_uncertainty_n;
  tc.model = model;
  tc.integrator.max_step_s = 1.0 / cfg.actuator.sample_rate_hz;
  MonitorHook twin(tc);
  Controller ctl(cfg, hw);
  ctl.attach_twin(&twin);
  CommandImage image = ctl.initial_image();
  FlagRun r;
  double t = 0.0, moving_s = 0.0;
  const auto run = [&](double seconds) {
    for (int i = 0; i < static_cast<int>(std::lround(seconds * 1000.0)); ++i) {
      t += 1e-3;
      ctl.step(t);
      const twin::TwinOutputs& o = twin.last;
      moving_s += std::abs(ctl.snapshot().nut_vel_m_s) > 1e-3 ? 1e-3 : 0.0;
      if (o.drift_warning && std::isnan(r.first_flag_s)) r.first_flag_s = t, r.at_flag = o;
      r.max_statistic = std::max(r.max_statistic, o.drift_statistic);
      r.last = o;
    }
  };
  const auto post = [&](std::uint16_t word) {
    image.control_word = word;
    EXPECT_TRUE(ctl.post(Command{image, false}));
    run(0.002);
  };
  run(0.01);
  post(bit(reg::kEnable));
  image.mode_command = static_cast<std::uint16_t>(reg::Mode::force);
  for (std::size_t k = 0; t < duration_s; ++k) {
    image.force_setpoint_n = kSetpoints_n[k % std::size(kSetpoints_n)];
    post(bit(reg::kEnable) | bit(reg::kExecute));
    post(bit(reg::kEnable));
    run(kHold_s - 0.004);
  }
  r.slide_share = moving_s / t;
  return r;
}

void print(const char* what, const FlagRun& r) {
  std::printf(
      "%s: nut moving %.1f %% of the time; statistic at most %.2f; flag at %.1f s%s%s; at "
      "the end %s\n",
      what, 100 * r.slide_share, r.max_statistic, r.first_flag_s,
      std::isfinite(r.first_flag_s) ? ": " : "",
      std::isfinite(r.first_flag_s) ? twin::drift_message(r.at_flag).c_str() : "",
      twin::drift_figures_text(r.last.drift_now).c_str());
}

/// The coupling crossing 3 % below its value at the reference (g = 1 + r t / 60), as the offline
/// monitor tests count it; and from the run's start, as the live test does (stricter).
double crossing_s(double loss_per_min, double reference_t_s) {
  return 60.0 * (1.0 - 0.97 * (1.0 - loss_per_min * reference_t_s / 60.0)) / loss_per_min;
}

}  // namespace

// −5 %/min: the coupling is 3 % below its start at 36 s; flagged within 30 s of that.
TEST(DriftForceLoop, HeldForceStepsCouplingLossFlagged) {
  const FlagRun r = run_force_holds(-0.05, 100.0);
  print("held force steps, gain -5 %/min", r);
  ASSERT_TRUE(std::isfinite(r.first_flag_s)) << "not flagged";
  const double cross_s = crossing_s(0.05, r.at_flag.drift_reference_t_s);
  std::printf(
      "reference at %.1f s: 3 %% crossed at %.1f s (at 36.0 s from the start); flagged "
      "%+.1f s after it (%+.1f s from the start's)\n",
      r.at_flag.drift_reference_t_s, cross_s, r.first_flag_s - cross_s, r.first_flag_s - 36.0);
  EXPECT_LE(r.first_flag_s, cross_s + 30.0);
  EXPECT_LE(r.first_flag_s, crossing_s(0.05, 0.0) + 30.0) << "the live test's count, from t = 0";
  EXPECT_TRUE(r.at_flag.drift_reason == twin::DriftReason::gain_fell ||
              r.at_flag.drift_reason == twin::DriftReason::error_rose);
}

TEST(DriftForceLoop, HeldForceStepsWithoutDriftNoWarning) {
  const FlagRun r = run_force_holds(0.0, 150.0);
  print("held force steps, no drift", r);
  EXPECT_TRUE(std::isnan(r.first_flag_s)) << "flagged at " << r.first_flag_s;
  EXPECT_EQ(r.last.drift_observability, twin::DriftObservability::tracking) << "nothing compared";
}

}  // namespace maglead
