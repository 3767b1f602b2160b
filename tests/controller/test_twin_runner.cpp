// The twin off the loop's critical path (runtime::TwinRunner): results tagged with their cycle,
// twin_lagging raised when the twin falls behind or its queue overflows, and the step-out
// look-ahead still warning at least 40 ms before the slip when the warning travels through the
// queue and the seqlock: at the worst lag that raises no bit (drained on this thread), and with
// the real twin thread beside the real-time loop (label `threads`: also under ThreadSanitizer).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "maglead/controller/controller.hpp"
#include "maglead/controller/loop_runner.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/runtime/twin_runner.hpp"
#include "maglead/settings/settings.hpp"
#include "maglead/twin/monitor.hpp"

using namespace maglead;
using namespace maglead::controller;
namespace reg = maglead::registers;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

twin::TwinMonitorConfig monitor_config(const ControllerConfig& cfg) {
  twin::TwinMonitorConfig tc = twin::load_monitor_config(MAGLEAD_CONFIG_DIR);
  tc.actuator = cfg.actuator;
  tc.calibration = cfg.calibration;
  tc.integrator.max_step_s = 1.0 / cfg.actuator.sample_rate_hz;
  return tc;
}

TwinSample sample(std::uint64_t cycle) {
  TwinSample s;
  s.cycle = cycle;
  s.t_s = static_cast<double>(cycle) * 1e-3;
  s.nut_pos_m = 0.02;
  s.screw_angle_rad = rest_angle_rad(0.02, ActuatorParams{}.lead_m);
  s.force_setpoint_n = kNaN;
  s.load_force_n = kNaN;
  return s;
}

/// The simulated plant with its screw held by the controller (drive ready, not enabled) and a
/// load pulling the nut along −p, rising at 15 N/s past the coupling's peak: the overload ramp of
/// the twin's own look-ahead test (tests/twin), here seen through the controller's status bits.
class RampedLoad final : public ActuatorHardware {
 public:
  RampedLoad() : plant_(paper_like_plant(), 99, 0.02) {}
  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override {
    LoadSetting load;
    load.kind = LoadSetting::Kind::constant;
    load.force_n = -15.0 * now_s;
    load.damping_n_s_per_m = 5.0;
    plant_.set_load(load);
    return plant_.read_sensors(now_s, out);
  }
  HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept override {
    return plant_.write_motor_angle(motor_angle_cmd_rad);
  }
  HwStatus set_power(PowerRequest request) noexcept override { return plant_.set_power(request); }

 private:
  SimulatedActuator plant_;
};

/// First times (controller time) of the step-out warning and of the step-out bit, from the
/// snapshot of every cycle, and when twin_lagging was on.
struct Lead {
  double warn_t_s = kNaN, flag_t_s = kNaN;
  double first_lag_t_s = kNaN, last_lag_before_flag_t_s = kNaN;
  std::uint64_t lagging_cycles = 0;
  void see(const Snapshot& s) {
    const auto on = [&](int b) { return ((s.status_word >> b) & 1u) != 0; };
    if (on(reg::kStepOutWarning) && std::isnan(warn_t_s)) warn_t_s = s.t_s;
    if (on(reg::kStepOut) && std::isnan(flag_t_s)) flag_t_s = s.t_s;
    if (!on(reg::kTwinLagging)) return;
    ++lagging_cycles;
    if (std::isnan(first_lag_t_s)) first_lag_t_s = s.t_s;
    if (std::isnan(flag_t_s)) last_lag_before_flag_t_s = s.t_s;
  }
  /// The twin said it was behind during the look-ahead's horizon (and a margin) before the bit.
  bool lagged_near_flag() const { return flag_t_s - last_lag_before_flag_t_s <= 0.1; }
};

}  // namespace

TEST(TwinRunner, ResultsCarryTheirCycleAndLateOnesRaiseLagging) {
  const ControllerConfig cfg;
  runtime::TwinRunner twin(monitor_config(cfg), {5});
  const TwinSample first = sample(1);
  twin.resync(first.t_s, first.screw_angle_rad, first.nut_pos_m);
  TwinReport out;
  // Nobody drains (a twin thread that does not run): lagging once results trail by more than 5.
  for (std::uint64_t c = 1; c <= 5; ++c) {
    twin.step(sample(c), out);
    EXPECT_FALSE(out.lagging) << "cycle " << c;
  }
  twin.step(sample(6), out);
  EXPECT_TRUE(out.lagging);
  EXPECT_EQ(out.cycle, 0u);
  // The twin catches up: results of the last queued cycle, in order, and the bit drops.
  EXPECT_EQ(twin.drain(), 7u);  // the resync and six samples
  twin.step(sample(7), out);
  EXPECT_EQ(out.cycle, 6u);
  EXPECT_FALSE(out.lagging);
  EXPECT_TRUE(out.healthy);
  EXPECT_EQ(twin.stats().lagging_cycles, 1u);
  EXPECT_EQ(twin.stats().max_lag_cycles, 6u);
}

TEST(TwinRunner, AFullQueueDropsTheSampleRaisesLaggingAndKeepsTheResync) {
  const ControllerConfig cfg;
  runtime::TwinRunner twin(monitor_config(cfg), {1'000'000});  // only the queue can raise it
  TwinReport out;
  std::uint64_t c = 1;
  for (; c <= 256; ++c) {
    twin.step(sample(c), out);
    ASSERT_FALSE(out.lagging) << "cycle " << c;
  }
  twin.step(sample(c), out);  // the 257th: no room
  EXPECT_TRUE(out.lagging);
  EXPECT_EQ(twin.stats().dropped, 1u);
  // A re-sync that finds the queue full is not lost: it goes first once there is room, and the
  // samples wait behind it (they are measured against the re-synchronised state).
  const TwinSample r = sample(++c);
  twin.resync(r.t_s, r.screw_angle_rad, r.nut_pos_m);
  twin.step(sample(++c), out);
  EXPECT_TRUE(out.lagging);
  EXPECT_EQ(twin.drain(), 256u);
  twin.step(sample(++c), out);
  EXPECT_FALSE(out.lagging);
  EXPECT_EQ(twin.drain(), 2u);  // the re-sync, then this cycle's sample
  twin.step(sample(++c), out);
  EXPECT_EQ(out.cycle, c - 1);
  EXPECT_TRUE(out.healthy);
  EXPECT_EQ(twin.stats().dropped, 2u);
}

// The worst the loop accepts without raising twin_lagging: the twin drained only every fifth
// cycle, so its results trail by up to 5 cycles. The warning still comes ≥ 40 ms before the
// controller's step-out bit (its own supervision: φ left the stable branch, not the twin's).
TEST(TwinRunner, StepOutWarningLeadsTheSlipAtTheLagBound) {
  ControllerConfig cfg;
  RampedLoad hw;
  Controller ctl(cfg, hw);
  runtime::TwinRunner twin(monitor_config(cfg), {5});
  ctl.attach_twin(&twin);
  Lead lead;
  for (int k = 1; k <= 5000 && std::isnan(lead.flag_t_s); ++k) {
    ctl.step(k * 1e-3);
    if (k % 5 == 0) twin.drain();
    lead.see(ctl.snapshot());
  }
  std::printf(
      "through the queue, 5 cycles behind: warning %.3f s, step-out bit %.3f s, lead %.0f ms\n",
      lead.warn_t_s, lead.flag_t_s, (lead.flag_t_s - lead.warn_t_s) * 1e3);
  ASSERT_TRUE(std::isfinite(lead.flag_t_s)) << "the plant stepped out";
  ASSERT_TRUE(std::isfinite(lead.warn_t_s));
  EXPECT_EQ(lead.lagging_cycles, 0u);
  EXPECT_GE(lead.flag_t_s - lead.warn_t_s, 0.040);
}

// The same ramp with the real twin thread beside a loop on real time: LoopRunner's deadlines on
// the steady clock, run on this thread (run_cycles) so that every cycle's snapshot is seen.
// Either the warning leads by ≥ 40 ms or the twin said it was behind (twin_lagging) within
// 100 ms before the slip: never a silent late warning, and never a late cycle because of it.
TEST(TwinRunner, StepOutWarningLeadsTheSlipOnTheTwinThread) {
  ControllerConfig cfg;
  RampedLoad hw;
  Controller ctl(cfg, hw);
  runtime::TwinRunner twin(monitor_config(cfg));
  ctl.attach_twin(&twin);
  twin.start(
      {-1, 20});  // as the service asks (SCHED_FIFO below the loop); without privilege, refused
  LoopRunner loop(ctl);
  Lead lead;
  while (std::isnan(lead.flag_t_s)) {
    loop.run_cycles(1);
    const Snapshot s = ctl.snapshot();
    lead.see(s);
    ASSERT_LT(s.t_s, 6.0) << "no step-out within 6 s";
  }
  twin.stop();
  const auto stats = twin.stats();
  std::printf(
      "twin thread: warning %.3f s, step-out bit %.3f s, lead %.0f ms; largest lag %llu cycles, "
      "%llu lagging cycles (first at %.3f s, last before the bit at %.3f s); placement not "
      "granted: %s\n",
      lead.warn_t_s, lead.flag_t_s, (lead.flag_t_s - lead.warn_t_s) * 1e3,
      static_cast<unsigned long long>(stats.max_lag_cycles),
      static_cast<unsigned long long>(lead.lagging_cycles), lead.first_lag_t_s,
      lead.last_lag_before_flag_t_s, twin.refused().empty() ? "nothing" : twin.refused().c_str());
  ASSERT_TRUE(std::isfinite(lead.warn_t_s));
  if (!lead.lagged_near_flag()) {
    EXPECT_GE(lead.flag_t_s - lead.warn_t_s, 0.040);
  }
  EXPECT_EQ(stats.dropped, 0u);
  EXPECT_EQ(stats.lagging_cycles, lead.lagging_cycles);  // the runner's count is what the bits said
}
