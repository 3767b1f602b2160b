// The control loop on the simulated actuator, stepped with a fake clock (no sleeping): drive
// state machine, position and force modes, edge commands, step-out, watchdog, twin hook.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "maglead/controller/controller.hpp"
#include "maglead/plant/simulated_actuator.hpp"

using namespace maglead;
using namespace maglead::controller;
namespace reg = maglead::registers;

namespace {

constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }

struct Rig {
  SimulatedActuator plant;
  ControllerConfig cfg;
  std::unique_ptr<Controller> ctl;
  CommandImage image;
  double t_s = 0.0;

  explicit Rig(double spring_n_per_m = 2000.0, TwinHook* twin = nullptr,
               const ControllerConfig& config = {})
      : plant(paper_like_plant(), 7, 0.02), cfg(config) {
    if (spring_n_per_m > 0) {
      LoadSetting load;
      load.kind = LoadSetting::Kind::spring_to_wall;
      load.stiffness_n_per_m = spring_n_per_m;
      load.damping_n_s_per_m = 5.0;
      load.anchor_pos_m = 0.02;
      plant.set_load(load);
    }
    ctl = std::make_unique<Controller>(cfg, plant);
    ctl->attach_twin(twin);
    image = ctl->initial_image();
    run(0.01);
  }
  template <class F>
  void run(double seconds, F&& each_cycle) {
    const int n = static_cast<int>(std::lround(seconds * 1000.0));
    for (int i = 0; i < n; ++i) {
      t_s += 1e-3;
      ctl->step(t_s);
      each_cycle(ctl->snapshot());
    }
  }
  void run(double seconds) {
    run(seconds, [](const Snapshot&) {});
  }
  void post(bool heartbeat = false) {
    ASSERT_TRUE(ctl->post(Command{image, heartbeat}));
    run(0.002);
  }
  void control(std::uint16_t word) {
    image.control_word = word;
    post();
  }
  Snapshot snap() const { return ctl->snapshot(); }
  bool status(int b) const { return (snap().status_word >> b) & 1u; }
  bool cmd(int b) const { return (snap().command_status >> b) & 1u; }
  void enable() {
    control(bit(reg::kEnable));
    ASSERT_EQ(snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  }
  void execute(reg::Mode mode) {
    image.mode_command = static_cast<std::uint16_t>(mode);
    control(static_cast<std::uint16_t>(image.control_word | bit(reg::kExecute)));
    control(static_cast<std::uint16_t>(image.control_word & ~bit(reg::kExecute)));
  }
};

}  // namespace

TEST(Controller, StartsReadyAfterSynchronising) {
  Rig rig;
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  EXPECT_TRUE(rig.status(reg::kReady));
  EXPECT_NEAR(rig.snap().nut_pos_m, 0.02, 50e-6);
  EXPECT_LT(std::abs(rig.snap().phase_rad), 0.1);
}

TEST(Controller, ExecuteNeedsAnEnabledDrive) {
  Rig rig;
  rig.image.position_setpoint_m = 0.025;
  rig.execute(reg::Mode::position);
  EXPECT_TRUE(rig.cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::not_enabled));
  EXPECT_EQ(rig.snap().active_mode, static_cast<std::uint16_t>(reg::Mode::idle));
}

TEST(Controller, PositionMoveRespectsLimitsAndEndsInPosition) {
  Rig rig;
  rig.enable();
  rig.image.position_setpoint_m = 0.026;
  rig.image.velocity_limit_m_s = 0.01;
  rig.image.accel_limit_m_s2 = 0.1;
  rig.image.mode_command = static_cast<std::uint16_t>(reg::Mode::position);
  rig.control(bit(reg::kEnable) | bit(reg::kExecute));
  EXPECT_TRUE(rig.cmd(reg::kExecuteAck));
  double last = rig.snap().profile_pos_m, vmax = 0.0, vlast = 0.0, amax = 0.0;
  bool done_seen = false;
  int n = 0;
  rig.run(1.2, [&](const Snapshot& s) {
    const double v = (s.profile_pos_m - last) / 1e-3;
    vmax = std::max(vmax, std::abs(v));
    // The last step snaps onto the target (a velocity step of at most 2·a·dt): not counted.
    if (n++ > 0 && s.profile_pos_m != 0.026) amax = std::max(amax, std::abs(v - vlast) / 1e-3);
    last = s.profile_pos_m;
    vlast = v;
    done_seen = done_seen || ((s.command_status >> reg::kExecuteDone) & 1u);
  });
  EXPECT_LE(vmax, 0.01 + 1e-9);
  EXPECT_LE(amax, 0.1 + 1e-6);
  EXPECT_TRUE(done_seen);
  EXPECT_TRUE(rig.status(reg::kInPosition));
  EXPECT_NEAR(rig.snap().nut_pos_m, 0.026, 50e-6);
  EXPECT_NEAR(rig.plant.truth().nut_pos_m, 0.026, 60e-6);
  // The ack follows the execute bit down; done stays until the next edge.
  rig.control(bit(reg::kEnable));
  EXPECT_FALSE(rig.cmd(reg::kExecuteAck));
  EXPECT_TRUE(rig.cmd(reg::kExecuteDone));
}

TEST(Controller, HeldExecuteBitDoesNotRetrigger) {
  Rig rig;
  rig.enable();
  rig.image.position_setpoint_m = 0.022;
  rig.image.mode_command = static_cast<std::uint16_t>(reg::Mode::position);
  rig.control(bit(reg::kEnable) | bit(reg::kExecute));
  rig.run(0.6);
  EXPECT_NEAR(rig.snap().active_target_pos_m, 0.022, 1e-12);
  rig.image.position_setpoint_m = 0.03;  // new setpoint, execute still held
  rig.post();
  rig.run(0.3);
  EXPECT_NEAR(rig.snap().active_target_pos_m, 0.022, 1e-12);
  EXPECT_NEAR(rig.snap().nut_pos_m, 0.022, 60e-6);
  rig.control(bit(reg::kEnable));  // falling, then rising: now it applies
  rig.control(bit(reg::kEnable) | bit(reg::kExecute));
  EXPECT_NEAR(rig.snap().active_target_pos_m, 0.03, 1e-12);
}

TEST(Controller, ForceModeHoldsTheSetpointAgainstASpring) {
  Rig rig(3000.0);
  rig.enable();
  rig.image.force_setpoint_n = 12.0;
  rig.execute(reg::Mode::force);
  EXPECT_EQ(rig.snap().active_mode, static_cast<std::uint16_t>(reg::Mode::force));
  rig.run(1.5);
  const auto s = rig.snap();
  EXPECT_NEAR(s.force_est_n, 12.0, 1.5);
  EXPECT_TRUE(rig.status(reg::kForceReached));
  EXPECT_TRUE(rig.cmd(reg::kExecuteDone));
  // The spring really is compressed: the nut moved +p and the load cell sees a push
  // (within static friction of the coupling force).
  EXPECT_GT(s.nut_pos_m, 0.02 + 1e-3);
  EXPECT_NEAR(s.load_cell_force_n, 12.0, rig.cfg.actuator.coulomb_n + 1.5);
  EXPECT_NEAR(s.active_force_setpoint_n, 12.0, 1e-12);
}

TEST(Controller, ForceBeyondTheSafeLimitIsRefusedAndChangesNothing) {
  Rig rig;
  rig.enable();
  const double limit = rig.ctl->safe_force_limit_n(1.0);
  ASSERT_GT(limit, 10.0);
  rig.image.force_setpoint_n = limit + 0.5;
  rig.execute(reg::Mode::force);
  EXPECT_TRUE(rig.cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason,
            static_cast<std::uint16_t>(reg::Reject::force_beyond_safe_limit));
  EXPECT_EQ(rig.snap().active_mode, static_cast<std::uint16_t>(reg::Mode::idle));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
}

TEST(Controller, RejectReasonClearsOnTheNextAcceptedCommand) {
  Rig rig;
  rig.execute(reg::Mode::position);  // not enabled: rejected
  ASSERT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::not_enabled));
  rig.control(bit(reg::kFaultReset));  // an accepted fault reset (no fault to clear)
  rig.control(0);
  EXPECT_TRUE(rig.cmd(reg::kResetDone));
  EXPECT_FALSE(rig.cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason, 0) << "a stale reason after an accepted reset";
  rig.control(bit(reg::kResync));  // rejected: nothing stepped out
  rig.control(0);
  ASSERT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::not_stepped_out));
  rig.enable();
  rig.image.position_setpoint_m = 0.021;
  rig.execute(reg::Mode::position);  // accepted
  EXPECT_EQ(rig.snap().active_mode, static_cast<std::uint16_t>(reg::Mode::position));
  EXPECT_FALSE(rig.cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason, 0) << "a stale reason after an accepted execute";
}

TEST(Controller, ForceReachedMeansWithinTheToleranceForTheWholeDwell) {
  // A tolerance and dwell of our own: the bit must be set exactly when the load observer's whole
  // bound has stayed within the tolerance of the setpoint, the nut stuck, for the dwell, and
  // never otherwise. (A slide leaves a bound ±0.85 N wide here: 1.2 N leaves room to land.)
  ControllerConfig cfg;
  cfg.force_tol_n = 1.2;
  cfg.settle_s = 0.2;
  Rig rig(2000.0, nullptr, cfg);
  rig.enable();
  rig.image.force_setpoint_n = 12.0;
  rig.image.mode_command = static_cast<std::uint16_t>(reg::Mode::force);
  rig.image.control_word = static_cast<std::uint16_t>(rig.image.control_word | bit(reg::kExecute));
  ASSERT_TRUE(rig.ctl->post(Command{rig.image, false}));
  double within_since = -1.0, first_set = -1.0;
  int violations = 0, cycles_set = 0, cycles_settling = 0, reason_violations = 0;
  rig.run(2.0, [&](const Snapshot& s) {
    // The reason agrees with the bit: 0 reached only while it is set, 6 settling while the dwell
    // runs.
    const bool bit_set = (s.status_word >> reg::kForceReached) & 1u;
    const auto reason = static_cast<ForceReachedReason>(s.force_reached_reason);
    if ((reason == ForceReachedReason::reached) != bit_set) ++reason_violations;
    cycles_settling += reason == ForceReachedReason::settling;
    const bool within = s.observer_force_lo_n >= 12.0 - cfg.force_tol_n &&
                        s.observer_force_hi_n <= 12.0 + cfg.force_tol_n && s.observer_basis != 1 &&
                        s.active_mode == 2;
    if (!within)
      within_since = -1.0;
    else if (within_since < 0)
      within_since = s.t_s;
    const bool set = (s.status_word >> reg::kForceReached) & 1u;
    if (set) {
      ++cycles_set;
      if (first_set < 0) first_set = s.t_s;
      // Set only after the estimate stayed within the tolerance for the dwell (one cycle slack).
      if (!(within_since >= 0 && s.t_s - within_since >= cfg.settle_s - 1.5e-3)) ++violations;
    } else if (within_since >= 0 && s.t_s - within_since >= cfg.settle_s + 1.5e-3) {
      ++violations;  // and not left clear once it has
    }
  });
  EXPECT_GT(cycles_set, 100) << "the bit was never set: nothing was tested";
  EXPECT_EQ(violations, 0);
  EXPECT_EQ(reason_violations, 0);
  EXPECT_GT(cycles_settling, 0) << "the dwell never read settling";
  EXPECT_GE(first_set, cfg.settle_s);
}

namespace {
/// A constant load force on the nut (damped, so a nut it drags does not race).
LoadSetting constant_load(double force_n) {
  LoadSetting load;
  load.kind = LoadSetting::Kind::constant;
  load.force_n = force_n;
  load.damping_n_s_per_m = 20.0;
  return load;
}
}  // namespace

TEST(Controller, StepOutLatchesAFaultStopsForceAndNeedsResyncThenReset) {
  Rig rig(0.0);
  rig.enable();
  // A load far above the coupling's peak drags the nut over the stable branch.
  rig.plant.set_load(constant_load(-80.0));
  bool fault_seen = false;
  rig.run(0.3, [&](const Snapshot& s) { fault_seen = fault_seen || s.drive_state == 3; });
  ASSERT_TRUE(fault_seen);
  auto s = rig.snap();
  EXPECT_TRUE((s.alarm_code == static_cast<std::uint16_t>(reg::Alarm::step_out)) ||
              (s.alarm_code == static_cast<std::uint16_t>(reg::Alarm::phase_jump)));
  EXPECT_EQ(s.step_out_count, 1);
  EXPECT_TRUE(rig.status(reg::kStepOut));
  EXPECT_TRUE(rig.status(reg::kFault));
  rig.plant.set_load(LoadSetting{});  // load gone; the nut rests in some other lead
  rig.run(0.3);
  s = rig.snap();
  EXPECT_EQ(s.step_out_count, 1);  // counted once
  // Force is no longer commanded: the screw was parked at a rest angle of the nut's lead.
  EXPECT_LT(std::abs(std::remainder(s.phase_rad, 2.0 * std::numbers::pi)), 0.5);
  // The nut slipped at least one lead: parked at a rest angle, φ is a whole number of turns off
  // the stable branch (within the 0.5 rad checked above), so |φ| >= 2π − 0.5.
  ASSERT_GE(std::abs(s.phase_rad), 2.0 * std::numbers::pi - 0.5) << "the nut did not slip a lead";
  // Reset alone is refused while φ is off the stable branch; resync then reset clears it.
  rig.control(bit(reg::kFaultReset));
  EXPECT_TRUE(rig.cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::still_faulty));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  rig.control(0);
  rig.control(bit(reg::kResync));
  EXPECT_TRUE(rig.cmd(reg::kResyncDone));
  EXPECT_LT(std::abs(rig.snap().phase_rad), 1.0);
  rig.control(bit(reg::kFaultReset));
  EXPECT_TRUE(rig.cmd(reg::kResetAck));
  rig.run(0.03);  // done once the fault has stayed away (kResetConfirm_s)
  EXPECT_TRUE(rig.cmd(reg::kResetDone));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  EXPECT_FALSE(rig.status(reg::kStepOut));
}

// A nut still sliding over the screw after a slip may pass through the stable branch; a reset
// taken then would latch again a moment later. The reset is refused (still_faulty) until the
// phase has stood still, even right after a resync put it on the branch.
TEST(Controller, AResetWhileTheNutStillSlidesIsRefused) {
  Rig rig(0.0);
  rig.enable();
  rig.plant.set_load(constant_load(-80.0));  // a fast pull past the peak: a step-out
  LoadSetting drag = constant_load(-70.0);
  drag.damping_n_s_per_m = 2000.0;  // then a slow slide (tens of mm/s) through the tries
  bool fault_seen = false;
  rig.run(0.3, [&](const Snapshot& s) {
    if (!fault_seen && s.drive_state == 3) rig.plant.set_load(drag);
    fault_seen = fault_seen || s.drive_state == 3;
  });
  ASSERT_TRUE(fault_seen);
  ASSERT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  const auto& cal = rig.cfg.calibration;
  int tried_on_branch = 0, accepted = 0;
  for (int i = 0; i < 20 && rig.plant.truth().nut_pos_m > 0.002; ++i) {
    rig.control(bit(reg::kResync));
    rig.control(0);
    const double phase_rad = rig.snap().phase_rad;
    if (phase_rad < cal.stable_min_rad || phase_rad > cal.stable_max_rad) continue;
    ++tried_on_branch;
    rig.control(bit(reg::kFaultReset));
    accepted += rig.cmd(reg::kResetAck) ? 1 : 0;
    EXPECT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::still_faulty));
    rig.control(0);
  }
  std::printf("resets tried with the phase on the branch while the nut slid: %d, accepted %d\n",
              tried_on_branch, accepted);
  EXPECT_GE(tried_on_branch, 3) << "the nut stopped sliding: nothing was tested";
  EXPECT_EQ(accepted, 0);
  // Standing again (the load gone), the same reset works.
  rig.plant.set_load(LoadSetting{});
  rig.run(0.5);
  rig.control(bit(reg::kResync));
  rig.control(0);
  rig.control(bit(reg::kFaultReset));
  rig.run(0.03);
  EXPECT_TRUE(rig.cmd(reg::kResetDone));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
}

TEST(Controller, FaultNeedsAFreshEnableEdge) {
  Rig rig;
  rig.enable();
  rig.image.watchdog_s = 0.05;
  rig.post();
  rig.run(0.1);
  ASSERT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  rig.control(bit(reg::kEnable) | bit(reg::kFaultReset));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  rig.run(0.2);
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
}

TEST(Controller, WatchdogStopsWithoutHeartbeatAndNotWithIt) {
  Rig rig;
  rig.enable();
  rig.image.watchdog_s = 0.1;
  rig.post();
  for (int i = 0; i < 10; ++i) {  // heartbeats every 50 ms keep it alive for 0.5 s
    rig.image.heartbeat = static_cast<std::uint16_t>(i);
    rig.post(true);
    rig.run(0.048);
  }
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_FALSE(rig.status(reg::kWatchdogExpired));
  rig.run(0.15);
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  EXPECT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::watchdog));
  EXPECT_TRUE(rig.status(reg::kWatchdogExpired));
  EXPECT_TRUE(rig.status(reg::kStopped));
}

// docs/plc.md and watchdog_ms's description: the watchdog counts only while the drive is
// enabled, from the enable edge on; a ready drive without heartbeats never faults.
TEST(Controller, TheWatchdogCountsOnlyWhileEnabledFromTheEnableEdge) {
  Rig rig;
  rig.image.watchdog_s = 0.05;
  rig.post();
  rig.run(0.3);
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  EXPECT_FALSE(rig.status(reg::kWatchdogExpired));
  rig.enable();
  rig.run(0.04);
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  rig.run(0.03);
  EXPECT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::watchdog));
}

TEST(Controller, StopBitHaltsAMoveAndRefusesExecute) {
  Rig rig;
  rig.enable();
  rig.image.position_setpoint_m = 0.035;
  rig.image.mode_command = static_cast<std::uint16_t>(reg::Mode::position);
  rig.control(bit(reg::kEnable) | bit(reg::kExecute));
  rig.run(0.3);
  rig.control(bit(reg::kEnable) | bit(reg::kStop));
  rig.run(0.5);
  const auto s = rig.snap();
  EXPECT_TRUE(rig.status(reg::kStopped));
  EXPECT_LT(s.profile_pos_m, 0.034);  // stopped short of the target
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  rig.control(bit(reg::kEnable) | bit(reg::kStop) | bit(reg::kExecute));
  EXPECT_TRUE(rig.cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::stopped));
}

TEST(Controller, DisableReturnsToReadyAndHolds) {
  Rig rig;
  rig.enable();
  rig.control(0);
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  const double pos = rig.snap().nut_pos_m;
  rig.run(0.5);
  EXPECT_NEAR(rig.snap().nut_pos_m, pos, 50e-6);
}

namespace {
struct FakeTwin final : TwinHook {
  int calls = 0, resyncs = 0;
  std::uint64_t last_cycle = 0;
  bool lagging = false;
  void resync(double, double, double) noexcept override { ++resyncs; }
  double last_pos = 0.0;
  void step(const TwinSample& in, TwinReport& out) noexcept override {
    ++calls;
    last_cycle = in.cycle;
    out.lagging = lagging;
    last_pos = in.nut_pos_m;
    out.pred_nut_pos_m = in.nut_pos_m + 1e-6;
    out.dynamic_force_n = 3.5;
    out.healthy = true;
    out.drift_warning = calls > 100;
  }
};
}  // namespace

TEST(Controller, TwinHookRunsEveryCycleAndPublishes) {
  FakeTwin twin;
  Rig rig(2000.0, &twin);
  const int before = twin.calls;
  EXPECT_EQ(twin.resyncs, 1);  // at start-up synchronisation
  rig.run(0.2);
  EXPECT_EQ(twin.calls - before, 200);
  const auto s = rig.snap();
  EXPECT_NEAR(s.twin.pred_nut_pos_m, s.nut_pos_m + 1e-6, 1e-12);
  EXPECT_EQ(s.twin.dynamic_force_n, 3.5);
  EXPECT_TRUE(rig.status(reg::kTwinHealthy));
  EXPECT_TRUE(rig.status(reg::kDriftWarning));
  EXPECT_EQ(twin.last_cycle, s.cycle);  // the sample is tagged with the cycle it was taken in
  EXPECT_FALSE(rig.status(reg::kTwinLagging));
}

// A twin that reports itself behind raises twin_lagging in the same cycle; nothing else changes.
TEST(Controller, TwinLaggingIsAStatusBit) {
  FakeTwin twin;
  Rig rig(2000.0, &twin);
  rig.run(0.01);
  twin.lagging = true;
  rig.run(0.001);
  EXPECT_TRUE(rig.status(reg::kTwinLagging));
  EXPECT_TRUE(rig.status(reg::kTwinHealthy));
  twin.lagging = false;
  rig.run(0.001);
  EXPECT_FALSE(rig.status(reg::kTwinLagging));
}

TEST(Controller, WithoutTwinTheTwinFieldsReadZero) {
  Rig rig;
  const auto s = rig.snap();
  EXPECT_EQ(s.twin.pred_nut_pos_m, 0.0);
  EXPECT_FALSE(rig.status(reg::kTwinHealthy));
}

TEST(Controller, RejectsInconsistentConfiguration) {
  SimulatedActuator plant(paper_like_plant(), 1, 0.02);
  ControllerConfig cfg;
  cfg.velocity_limit_m_s = 0.0;
  EXPECT_THROW(Controller(cfg, plant), std::invalid_argument);
  cfg = ControllerConfig{};
  cfg.actuator.safe_force_fraction = 1.5;
  EXPECT_THROW(Controller(cfg, plant), std::invalid_argument);
  for (double gain : {0.0, -0.9, std::nan("")}) {  // a model's coupling gain: a strength, positive
    cfg = ControllerConfig{};
    cfg.coupling.gain = gain;
    EXPECT_THROW(Controller(cfg, plant), std::invalid_argument) << gain;
  }
  cfg = ControllerConfig{};
  cfg.coupling.angle_ripple = 1.0;  // F_m would vanish once per turn
  EXPECT_THROW(Controller(cfg, plant), std::invalid_argument);
  cfg = ControllerConfig{};
  cfg.coupling.end_zone_m = 0.005;
  cfg.coupling.end_max_reduction = 1.0;  // … or at the stroke's ends
  EXPECT_THROW(Controller(cfg, plant), std::invalid_argument);
}

// ---------------------------------------------------------------------------- fault reactions

namespace {

/// Force mode at `force_n` against a 3000 N/m spring, settled.
void hold_force(Rig& rig, double force_n) {
  rig.enable();
  rig.image.force_setpoint_n = force_n;
  rig.execute(reg::Mode::force);
  rig.run(1.5);
  ASSERT_TRUE(rig.status(reg::kForceReached));
  // The spring really carries the force (the nut's Coulomb friction takes up to 7.5 N of it).
  ASSERT_GT(rig.snap().load_cell_force_n, force_n - rig.cfg.actuator.coulomb_n - 1.0);
}

void arm_watchdog(Rig& rig, double seconds) {
  rig.image.watchdog_s = seconds;
  rig.post();
}

std::uint16_t reaction(const Rig& rig) { return rig.snap().fault_reaction; }

/// A fresh controller on the rig's plant with this watchdog reaction.
void use_watchdog_reaction(Rig& rig, FaultReaction how) {
  rig.cfg.reactions.watchdog = how;
  rig.ctl = std::make_unique<Controller>(rig.cfg, rig.plant);
  rig.run(0.01);
}
constexpr auto kReleasing = static_cast<std::uint16_t>(reg::Reaction::releasing);
constexpr auto kReleased = static_cast<std::uint16_t>(reg::Reaction::released);
constexpr auto kHolding = static_cast<std::uint16_t>(reg::Reaction::holding);

/// The simulated actuator with a sensor that fails for a while.
struct FlakySensor final : ActuatorHardware {
  SimulatedActuator& plant;
  double fail_from_s = 1e9, fail_until_s = 0.0;
  explicit FlakySensor(SimulatedActuator& p) : plant(p) {}
  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override {
    const HwStatus s = plant.read_sensors(now_s, out);
    return now_s >= fail_from_s && now_s < fail_until_s ? HwStatus::sensor_fault : s;
  }
  HwStatus write_motor_angle(double a) noexcept override { return plant.write_motor_angle(a); }
  HwStatus set_power(PowerRequest request) noexcept override { return plant.set_power(request); }
};

}  // namespace

// Finding 2: in force mode the watchdog's reaction releases the force against the load (load
// cell, simulated plant), ramping it at the configured rate, instead of holding 20 N.
TEST(FaultReaction, WatchdogInForceModeRampsTheForceToZero) {
  Rig rig(3000.0);
  hold_force(rig, 20.0);
  arm_watchdog(rig, 0.05);
  double trip_s = -1.0;
  rig.run(0.06, [&](const Snapshot& s) {
    if (trip_s < 0 && s.drive_state == static_cast<std::uint16_t>(reg::DriveState::fault))
      trip_s = s.t_s;
  });
  ASSERT_GT(trip_s, 0.0);
  EXPECT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::watchdog));
  // 20 N at 100 N/s: still ramping 0.1 s after the trip, at zero force after 0.2 s.
  rig.run(trip_s + 0.1 - rig.t_s);
  EXPECT_EQ(reaction(rig), kReleasing);
  rig.run(0.15);
  EXPECT_EQ(reaction(rig), kReleased);
  rig.run(1.0);
  const auto s = rig.snap();
  // What is left on the spring is what the nut's Coulomb friction holds (7.5 N), plus noise.
  EXPECT_LT(std::abs(s.load_cell_force_n), rig.cfg.actuator.coulomb_n + 1.0) << s.load_cell_force_n;
  EXPECT_LT(std::abs(rig.plant.truth().coupling_force_n), 2.0);
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  EXPECT_EQ(s.active_mode, static_cast<std::uint16_t>(reg::Mode::idle));
}

TEST(FaultReaction, WatchdogInPositionModeHoldsPosition) {
  Rig rig(3000.0);
  rig.enable();
  rig.image.position_setpoint_m = 0.023;
  rig.execute(reg::Mode::position);
  rig.run(1.0);
  ASSERT_NEAR(rig.snap().nut_pos_m, 0.023, 60e-6);
  const double force_before = rig.snap().load_cell_force_n;  // about 9 N of spring
  arm_watchdog(rig, 0.05);
  rig.run(1.0);
  const auto s = rig.snap();
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::watchdog));
  EXPECT_EQ(reaction(rig), kHolding);
  EXPECT_NEAR(s.nut_pos_m, 0.023, 60e-6);
  EXPECT_NEAR(s.load_cell_force_n, force_before, 1.0);
}

TEST(FaultReaction, ConfiguredHoldKeepsTheForceAndDisableDropsItAtOnce) {
  {
    Rig rig(3000.0);
    use_watchdog_reaction(rig, FaultReaction::hold);
    hold_force(rig, 20.0);
    arm_watchdog(rig, 0.05);
    rig.run(1.0);
    EXPECT_EQ(reaction(rig), kHolding);
    EXPECT_GT(rig.snap().load_cell_force_n, 20.0 - rig.cfg.actuator.coulomb_n - 1.0);
  }
  {
    Rig rig(3000.0);
    use_watchdog_reaction(rig, FaultReaction::disable);
    hold_force(rig, 20.0);
    arm_watchdog(rig, 0.05);
    bool releasing_seen = false, released_seen = false;
    rig.run(0.06, [&](const Snapshot& s) {
      releasing_seen = releasing_seen || s.fault_reaction == kReleasing;
      released_seen = released_seen || s.fault_reaction == kReleased;
    });
    EXPECT_TRUE(released_seen);
    EXPECT_FALSE(releasing_seen);  // no ramp
    rig.run(1.0);
    EXPECT_LT(std::abs(rig.snap().load_cell_force_n), rig.cfg.actuator.coulomb_n + 1.0);
  }
}

// Finding 1, loop side: owner loss is a fault with its reaction; a ready drive just stays ready.
TEST(FaultReaction, OwnerLossFaultsAnEnabledDriveAndReleasesTheForce) {
  Rig rig(3000.0);
  hold_force(rig, 20.0);
  rig.image.control_word = 0;
  ASSERT_TRUE(rig.ctl->post(Command{rig.image, false, true}));
  rig.run(0.002);
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  EXPECT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::owner_lost));
  rig.run(1.0);
  EXPECT_EQ(reaction(rig), kReleased);
  EXPECT_LT(std::abs(rig.snap().load_cell_force_n), rig.cfg.actuator.coulomb_n + 1.0);
  // Taking over: fault reset, then a fresh enable edge.
  rig.control(bit(reg::kFaultReset));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  rig.control(bit(reg::kEnable));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));

  Rig idle;                       // not enabled: nothing to react to
  idle.ctl->signal_owner_lost();  // the lock-free path (command queue full)
  idle.run(0.01);
  EXPECT_EQ(idle.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
}

TEST(FaultReaction, SensorFaultInForceModeReleasesFromTheLastMeasurement) {
  Rig rig(3000.0);
  FlakySensor flaky(rig.plant);
  rig.ctl = std::make_unique<Controller>(rig.cfg, flaky);
  rig.run(0.01);
  hold_force(rig, 20.0);
  flaky.fail_from_s = rig.t_s + 0.0005;
  flaky.fail_until_s = rig.t_s + 0.005;  // five cycles without sensors
  rig.run(1.5);
  const auto s = rig.snap();
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::sensor_fault));
  EXPECT_EQ(reaction(rig), kReleased);
  EXPECT_LT(std::abs(s.load_cell_force_n), rig.cfg.actuator.coulomb_n + 1.0);
}

TEST(FaultReaction, ReleaseRateMustBePositive) {
  SimulatedActuator plant(paper_like_plant(), 1, 0.02);
  ControllerConfig cfg;
  cfg.reactions.release_rate_n_per_s = 0.0;
  EXPECT_THROW(Controller(cfg, plant), std::invalid_argument);
}

namespace {

/// Records what the controller tells the twin about free moves.
struct FreeMoveTwin final : TwinHook {
  int free_ticks = 0;
  double lo = 1.0, hi = -1.0;
  void step(const TwinSample& in, TwinReport&) noexcept override {
    if (!in.free_move) return;
    ++free_ticks;
    lo = std::min(lo, in.nut_pos_m);
    hi = std::max(hi, in.nut_pos_m);
  }
};

// mode_command 3: a back-and-forth over the configured window at its two speeds, with the
// twin told the nut is free while it runs (and only then).
TEST(Controller, ReferenceMoveRunsTheWindowAtTwoSpeedsAndTellsTheTwin) {
  FreeMoveTwin twin;
  Rig rig(0.0, &twin);
  rig.enable();
  rig.execute(reg::Mode::reference_move);
  EXPECT_FALSE(rig.cmd(reg::kRejected));
  double vmax = 0.0;
  rig.run(5.0, [&](const Snapshot& s) { vmax = std::max(vmax, std::abs(s.nut_vel_m_s)); });
  const ReferenceMoveConfig c;
  EXPECT_NEAR(twin.lo, c.window_min_m, 1e-4);
  EXPECT_NEAR(twin.hi, c.window_max_m, 1e-4);
  EXPECT_GT(vmax, 0.8 * c.fast_m_s);
  EXPECT_GT(twin.free_ticks, 2000);
  const int n = twin.free_ticks;
  rig.run(0.5);
  EXPECT_EQ(twin.free_ticks, n);  // over: no longer declared free
}

}  // namespace

// A step-out the fault reaction brought back onto the stable branch (a pull just past the
// coupling's peak, gone again at once): the fault reset alone is accepted, and it starts the twin
// again from the nut, as a resync would; the twin is not left holding its step-out.
TEST(Controller, AResetOfAStepOutBackOnTheBranchResyncsTheTwin) {
  FakeTwin twin;
  Rig rig(0.0, &twin);
  rig.enable();
  rig.plant.set_load(constant_load(-60.0));
  bool fault_seen = false;
  rig.run(0.3, [&](const Snapshot& s) {
    if (!fault_seen && s.drive_state == 3) rig.plant.set_load(LoadSetting{});
    fault_seen = fault_seen || s.drive_state == 3;
  });
  ASSERT_TRUE(fault_seen);
  rig.run(0.3);
  const auto& cal = rig.cfg.calibration;
  std::printf("after the release: phase %.3f rad (stable %.3f .. %.3f)\n", rig.snap().phase_rad,
              cal.stable_min_rad, cal.stable_max_rad);
  ASSERT_GT(rig.snap().phase_rad, cal.stable_min_rad) << "the nut slipped a lead: not this case";
  ASSERT_LT(rig.snap().phase_rad, cal.stable_max_rad) << "the nut slipped a lead: not this case";
  const int resyncs = twin.resyncs;
  rig.control(bit(reg::kFaultReset));
  EXPECT_TRUE(rig.cmd(reg::kResetAck));
  rig.run(0.03);
  EXPECT_TRUE(rig.cmd(reg::kResetDone));
  EXPECT_EQ(twin.resyncs, resyncs + 1);
  EXPECT_FALSE(rig.status(reg::kStepOut));
}

TEST(Controller, AFastMoveToAStrokeEndDoesNotOvershootIt) {
  for (const double target_m : {0.040, 0.0}) {
    Rig rig(0.0);
    rig.enable();
    rig.image.position_setpoint_m = target_m;
    rig.image.velocity_limit_m_s = 0.1;  // the fastest and hardest a client may ask
    rig.image.accel_limit_m_s2 = 5.0;
    rig.image.mode_command = static_cast<std::uint16_t>(reg::Mode::position);
    rig.control(bit(reg::kEnable) | bit(reg::kExecute));
    double beyond_m = 0.0, lag_m = 0.0;
    rig.run(1.0, [&](const Snapshot& s) {
      const double nut = rig.plant.truth().nut_pos_m;
      beyond_m = std::max(beyond_m, target_m > 0.02 ? nut - target_m : target_m - nut);
      lag_m = std::max(lag_m, std::abs(s.profile_pos_m - s.nut_pos_m));
    });
    std::printf("target %.1f mm: nut beyond it by at most %.0f um, profile ahead by %.2f mm\n",
                target_m * 1e3, beyond_m * 1e6, lag_m * 1e3);
    EXPECT_LE(beyond_m, 50e-6);
    EXPECT_TRUE(rig.status(reg::kInPosition));
  }
}
