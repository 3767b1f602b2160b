// Fault injection through the hardware seam, the loop run by LoopRunner on a fake clock: a
// sensor fault, a drive fault (reported on read, or a refused write) and a stroke-limit hit each
// latch their documented alarm (README "Safety": 5 sensor_fault, 6 drive_fault, 4 stroke_limit),
// the runner counts exactly the cycles whose hardware access failed, and the motor stops.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "fake_clock.hpp"
#include "fake_hardware.hpp"
#include "maglead/controller/controller.hpp"
#include "maglead/controller/loop_runner.hpp"

using namespace maglead;
using namespace maglead::controller;
using maglead::testing::FakeLoopClock;
using maglead::testing::FaultInjectingHardware;
using Fault = FaultInjectingHardware::Fault;
namespace reg = maglead::registers;

namespace {

constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }
constexpr auto kFault = static_cast<std::uint16_t>(reg::DriveState::fault);

struct FaultRig {
  SimulatedActuator plant;
  FaultInjectingHardware hw{plant};
  ControllerConfig cfg;
  Controller ctl;
  FakeLoopClock clock;
  LoopRunner loop;
  CommandImage image;

  explicit FaultRig(double spring_n_per_m = 2000.0, double start_m = 0.02)
      : plant(paper_like_plant(), 5, start_m),
        ctl((spring(plant, spring_n_per_m), cfg), hw),
        loop(ctl, clock, 16) {
    image = ctl.initial_image();
    loop.run_cycles(10);
  }
  static void spring(SimulatedActuator& p, double k) {
    if (k <= 0) return;
    LoadSetting load;
    load.kind = LoadSetting::Kind::spring_to_wall;
    load.stiffness_n_per_m = k;
    load.damping_n_s_per_m = 5.0;
    load.anchor_pos_m = 0.02;
    p.set_load(load);
  }
  void control(std::uint16_t word) {
    image.control_word = word;
    ASSERT_TRUE(ctl.post(Command{image, false}));
    loop.run_cycles(2);
  }
  void execute(reg::Mode mode) {
    image.mode_command = static_cast<std::uint16_t>(mode);
    control(bit(reg::kEnable) | bit(reg::kExecute));
    control(bit(reg::kEnable));
  }
  void move_to(double pos_m) {
    image.position_setpoint_m = pos_m;
    execute(reg::Mode::position);
  }
  Snapshot snap() const { return ctl.snapshot(); }
};

/// All motor commands from index `from` on are the same value.
bool constant_from(const std::vector<double>& c, std::size_t from) {
  return from < c.size() && std::all_of(c.begin() + static_cast<std::ptrdiff_t>(from), c.end(),
                                        [&](double v) { return v == c[from]; });
}

/// Enabled and 200 cycles into a move to 30 mm, where a test injects its fault.
void start_moving(FaultRig& rig) {
  rig.control(bit(reg::kEnable));
  rig.move_to(0.03);
  rig.loop.run_cycles(200);
}

}  // namespace

TEST(HardwareFault, SensorFaultMidMoveLatchesAlarm5AndStopsTheMotor) {
  FaultRig rig;
  rig.control(bit(reg::kEnable));
  rig.move_to(0.03);
  const double start_m = rig.plant.truth().nut_pos_m;
  rig.loop.run_cycles(200);  // moving at 10 mm/s
  // Moving: the nut may stick and slip against the spring, so judge the travel, not the speed now.
  ASSERT_GT(rig.plant.truth().nut_pos_m - start_m, 1e-3);
  const std::uint64_t before = rig.loop.stats().cycles;
  rig.hw.inject(Fault::sensor);
  const std::size_t at_fault = rig.hw.commands().size();
  rig.loop.run_cycles(7);
  rig.hw.inject(Fault::none);  // the sensor comes back; the fault stays latched
  rig.loop.run_cycles(1000);
  const auto s = rig.snap();
  EXPECT_EQ(s.drive_state, kFault);
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::sensor_fault));
  EXPECT_EQ(s.fault_reaction, static_cast<std::uint16_t>(reg::Reaction::holding));
  const LoopStats st = rig.loop.stats();
  EXPECT_EQ(st.hardware_error_cycles, 7u);
  EXPECT_EQ(st.first_hardware_error_cycle, before + 1);
  // The motor got the last command from before the fault, again and again: it stopped there.
  EXPECT_TRUE(constant_from(rig.hw.commands(), at_fault - 1));
  EXPECT_LT(std::abs(rig.plant.truth().nut_vel_m_s), 1e-4);
  EXPECT_LT(rig.plant.truth().nut_pos_m, 0.03 - 1e-3);  // it did not finish the move
}

TEST(HardwareFault, DriveFaultOnReadLatchesAlarm6AndSendsNoCommand) {
  FaultRig rig;
  start_moving(rig);
  rig.hw.inject(Fault::drive_on_read);
  const std::size_t at_fault = rig.hw.commands().size();
  rig.loop.run_cycles(50);
  EXPECT_EQ(rig.hw.commands().size(), at_fault) << "no command to a drive that reports a fault";
  rig.hw.inject(Fault::none);
  rig.loop.run_cycles(1000);
  const auto s = rig.snap();
  EXPECT_EQ(s.drive_state, kFault);
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::drive_fault));
  // Nothing of the controller's holds the axis: the PLC reads that the drive's reaction acts.
  EXPECT_EQ(s.fault_reaction, static_cast<std::uint16_t>(reg::Reaction::drive_own));
  EXPECT_EQ(rig.loop.stats().hardware_error_cycles, 50u);
  EXPECT_TRUE(constant_from(rig.hw.commands(), at_fault - 1));
  EXPECT_LT(std::abs(rig.plant.truth().nut_vel_m_s), 1e-4);
}

// A drive that faults after another fault latched (here a sensor fault, whose reaction holds):
// the first alarm stays, but the controller's hold no longer holds anything.
TEST(HardwareFault, ADriveFaultAfterAnotherFaultIsTheDrivesOwnReaction) {
  FaultRig rig;
  start_moving(rig);
  rig.hw.inject(Fault::sensor);
  rig.loop.run_cycles(5);
  rig.hw.inject(Fault::none);
  rig.loop.run_cycles(100);
  ASSERT_EQ(rig.snap().fault_reaction, static_cast<std::uint16_t>(reg::Reaction::holding));
  rig.hw.inject(Fault::drive_on_read);
  rig.loop.run_cycles(20);
  const auto s = rig.snap();
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::sensor_fault));
  EXPECT_EQ(s.fault_reaction, static_cast<std::uint16_t>(reg::Reaction::drive_own));
}

TEST(HardwareFault, RefusedWriteLatchesAlarm6AndTheCommandStaysPut) {
  FaultRig rig;
  start_moving(rig);
  rig.hw.inject(Fault::drive_on_write);
  const std::size_t at_fault = rig.hw.commands().size();
  rig.loop.run_cycles(3);
  rig.hw.inject(Fault::none);
  rig.loop.run_cycles(1000);
  const auto s = rig.snap();
  EXPECT_EQ(s.drive_state, kFault);
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::drive_fault));
  EXPECT_EQ(rig.hw.refused_writes(), 3u);
  EXPECT_EQ(rig.loop.stats().hardware_error_cycles, 3u);
  // From then on the drive gets one command, again and again: the one it refused first.
  ASSERT_GT(rig.hw.commands().size(), at_fault);
  EXPECT_TRUE(constant_from(rig.hw.commands(), at_fault));
  EXPECT_LT(std::abs(rig.plant.truth().nut_vel_m_s), 1e-4);
}

TEST(HardwareFault, ANutBeyondTheStrokeMovingOutLatchesAlarm4AndHoldsIt) {
  // A free nut found beyond the stroke (pushed by hand, a step-out) may be enabled; driven
  // further out (here a force setpoint outwards), the drive latches stroke_limit and holds it.
  FaultRig rig(0.0, 0.0408);
  rig.control(bit(reg::kEnable));
  rig.loop.run_cycles(500);
  ASSERT_NE(rig.snap().drive_state, kFault) << "alarm " << rig.snap().alarm_code;
  rig.image.force_setpoint_n = 5.0;
  rig.execute(reg::Mode::force);
  std::uint64_t latched_at = 0;
  for (int i = 0; i < 5000 && latched_at == 0; ++i) {
    rig.loop.run_cycles(1);
    if (rig.snap().drive_state == kFault) latched_at = rig.loop.stats().cycles;
  }
  ASSERT_NE(latched_at, 0u) << "nut at " << rig.snap().nut_pos_m;
  EXPECT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::stroke_limit));
  EXPECT_GT(rig.snap().nut_pos_m, rig.cfg.actuator.stroke_max_m);
  const double at_latch_m = rig.snap().nut_pos_m;
  rig.loop.run_cycles(2000);
  const auto s = rig.snap();
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::stroke_limit));
  EXPECT_EQ(s.step_out_count, 0u);
  EXPECT_EQ(s.fault_reaction, static_cast<std::uint16_t>(reg::Reaction::holding));
  EXPECT_EQ(s.active_mode, static_cast<std::uint16_t>(reg::Mode::idle));  // force control ended
  EXPECT_EQ(rig.loop.stats().hardware_error_cycles, 0u);                  // not a hardware error
  // Stopped: the nut at rest close to where the limit latched, the motor command settled.
  EXPECT_LT(std::abs(rig.plant.truth().nut_vel_m_s), 1e-4);
  EXPECT_NEAR(s.nut_pos_m, at_latch_m, 1e-3);
  const auto& c = rig.hw.commands();
  const auto [lo, hi] = std::minmax_element(c.end() - 100, c.end());
  EXPECT_LT(*hi - *lo, 1e-6);
}

TEST(HardwareFault, ANutBeyondTheStrokeIsBroughtBackByAResetAndAMoveInside) {
  FaultRig rig(0.0, 0.0408);
  rig.control(bit(reg::kEnable));
  rig.image.force_setpoint_n = 5.0;
  rig.execute(reg::Mode::force);
  rig.loop.run_cycles(2000);
  ASSERT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::stroke_limit));
  rig.control(bit(reg::kFaultReset));
  rig.control(0);
  rig.control(bit(reg::kEnable));
  rig.image.position_setpoint_m = 0.030;
  rig.execute(reg::Mode::position);
  rig.loop.run_cycles(3000);
  const auto s = rig.snap();
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_EQ(s.alarm_code, 0);
  EXPECT_NEAR(s.nut_pos_m, 0.030, 50e-6);
  EXPECT_TRUE((s.status_word >> reg::kInPosition) & 1u);
}

// The power stage follows the controller's drive state through the port: enable and disable
// with the enable bit, quick stop while the stop bit holds, enabled while a fault's reaction
// runs (out of a quick stop too), the fault reset passed on; each request once, when the state
// changes.
TEST(HardwareFault, ThePowerStageFollowsTheDriveState) {
  using P = PowerRequest;
  FaultRig rig;
  EXPECT_TRUE(rig.hw.power_requests().empty()) << "ready at start: the stage stays disabled";
  rig.control(bit(reg::kEnable));
  rig.control(bit(reg::kEnable) | bit(reg::kStop));
  rig.loop.run_cycles(20);
  rig.control(bit(reg::kEnable));
  rig.hw.inject(Fault::drive_on_read);
  rig.loop.run_cycles(20);
  rig.hw.inject(Fault::none);
  rig.control(0);
  rig.control(bit(reg::kFaultReset));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  rig.control(0);
  rig.control(bit(reg::kEnable) | bit(reg::kStop));
  rig.hw.inject(Fault::sensor);  // a fault while stopped: its reaction takes the motor
  rig.loop.run_cycles(20);
  rig.hw.inject(Fault::none);
  rig.control(0);
  rig.control(bit(reg::kFaultReset));
  rig.control(0);
  rig.control(bit(reg::kEnable));
  rig.control(0);
  const std::vector<P> want = {P::enable, P::quick_stop,  P::enable, P::fault_reset, P::quick_stop,
                               P::enable, P::fault_reset, P::enable, P::disable};
  EXPECT_EQ(rig.hw.power_requests(), want);
}

// A fault reset is done only when the fault stays away: a drive that still reports its fault
// after the reset makes it rejected (fault_returned, the alarm kept), never done then undone.
TEST(HardwareFault, AResetIsNotDoneWhileTheDriveKeepsItsFault) {
  FaultRig rig;
  rig.control(bit(reg::kEnable));
  rig.hw.inject(Fault::drive_on_read);
  rig.loop.run_cycles(20);
  ASSERT_EQ(rig.snap().drive_state, kFault);
  rig.control(0);
  rig.control(bit(reg::kFaultReset));  // the drive still reports its fault
  rig.loop.run_cycles(50);
  auto cmd = [&](int b) { return ((rig.snap().command_status >> b) & 1u) != 0; };
  EXPECT_FALSE(cmd(reg::kResetDone));
  EXPECT_TRUE(cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().reject_reason, static_cast<std::uint16_t>(reg::Reject::fault_returned));
  EXPECT_EQ(rig.snap().drive_state, kFault);
  EXPECT_EQ(rig.snap().alarm_code, static_cast<std::uint16_t>(reg::Alarm::drive_fault));
  // The cause gone, the next reset is done, and no sooner than the confirmation time.
  rig.hw.inject(Fault::none);
  rig.control(0);
  rig.control(bit(reg::kFaultReset));
  EXPECT_TRUE(cmd(reg::kResetAck));
  EXPECT_FALSE(cmd(reg::kResetDone)) << "done before the fault had time to come back";
  rig.loop.run_cycles(50);
  EXPECT_TRUE(cmd(reg::kResetDone));
  EXPECT_FALSE(cmd(reg::kRejected));
  EXPECT_EQ(rig.snap().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
}
