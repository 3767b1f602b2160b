// The controller's enable, disable, stop and fault reset reach the CiA 402 drive through the
// hardware port: the Controller on the backend "cia402" with the simulated drive, in the loop's
// time. The drive's state is read from the master, the controller's from its snapshot.
#include <gtest/gtest.h>

#include <memory>

#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/canopen/simulated_drive.hpp"
#include "maglead/controller/controller.hpp"

namespace maglead::canopen {
namespace {

namespace reg = maglead::registers;
constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1U << b); }

struct ControllerOnDrive {
  ControllerOnDrive()
      : hw(paper_like_plant().actuator, {},
           std::make_unique<SimulatedActuator>(paper_like_plant(), 3, 0.02)),
        ctl(config(), hw),
        image(ctl.initial_image()) {}
  static controller::ControllerConfig config() {
    controller::ControllerConfig c;
    c.actuator = paper_like_plant().actuator;
    return c;
  }
  void cycles(int n) {
    for (int i = 0; i < n; ++i) ctl.step(t_s += 1e-3);
  }
  void post(std::uint16_t control_word) {
    image.control_word = control_word;
    ASSERT_TRUE(ctl.post(controller::Command{image, false}));
  }
  DriveState drive() const { return hw.master().feedback().state; }
  reg::DriveState state() const { return static_cast<reg::DriveState>(ctl.snapshot().drive_state); }
  /// Posts `control_word`; the drive reaches `drive_state` within 20 cycles and stays there for
  /// 100 more, with the controller in `state` and no alarm.
  ::testing::AssertionResult reaches(std::uint16_t control_word, DriveState drive_state,
                                     reg::DriveState state) {
    post(control_word);
    for (int i = 0; i < 20 && drive() != drive_state; ++i) cycles(1);
    if (drive() != drive_state)
      return ::testing::AssertionFailure() << "the drive is " << drive_state_text(drive());
    cycles(100);
    if (drive() != drive_state || this->state() != state || ctl.snapshot().alarm_code != 0)
      return ::testing::AssertionFailure()
             << "drive " << drive_state_text(drive()) << ", controller state "
             << ctl.snapshot().drive_state << ", alarm " << ctl.snapshot().alarm_code;
    return ::testing::AssertionSuccess();
  }

  ::testing::AssertionResult enables() {
    return reaches(bit(reg::kEnable), DriveState::operation_enabled, reg::DriveState::enabled);
  }
  /// Enable low and a fault reset edge: the drive in switch on disabled, the controller ready;
  /// then an enable edge enables both again.
  ::testing::AssertionResult resets_and_enables() {
    post(0);
    ::testing::AssertionResult reset =
        reaches(bit(reg::kFaultReset), DriveState::switch_on_disabled, reg::DriveState::ready);
    if (!reset) return reset << " after the reset";
    post(0);
    return enables();
  }

  Cia402Hardware hw;
  controller::Controller ctl;
  controller::CommandImage image;
  double t_s = 0.0;
};

TEST(Cia402Power, TheControllersEnableReachesOperationEnabledAndItsDisableLeavesIt) {
  ControllerOnDrive r;
  r.cycles(20);
  // Ready, not enabled: the power stage stays off until the controller's enable.
  EXPECT_EQ(r.state(), reg::DriveState::ready);
  EXPECT_EQ(r.drive(), DriveState::switch_on_disabled);
  EXPECT_TRUE(r.enables());
  EXPECT_TRUE(r.reaches(0, DriveState::switch_on_disabled, reg::DriveState::ready));
}

TEST(Cia402Power, ADriveFaultIsClearedByTheControllersResetWithoutARestart) {
  ControllerOnDrive r;
  ASSERT_TRUE(r.enables());
  r.hw.simulated_drive()->inject_fault(0x2310, 0.0);  // at once: over-current
  r.cycles(20);
  EXPECT_EQ(r.drive(), DriveState::fault);
  EXPECT_EQ(r.state(), reg::DriveState::fault);
  EXPECT_EQ(r.ctl.snapshot().alarm_code, static_cast<std::uint16_t>(reg::Alarm::drive_fault));
  // Its cause and the drive's own code latch with the alarm (IR 68, 69): what a PLC shows.
  EXPECT_EQ(r.ctl.snapshot().drive_fault_cause,
            static_cast<std::uint16_t>(DriveFaultCause::drive_reports_fault));
  EXPECT_EQ(r.ctl.snapshot().drive_error_code, 0x2310);
  // Not "holding": a drive in fault holds nothing of the controller's (IR 54).
  EXPECT_EQ(r.ctl.snapshot().fault_reaction, static_cast<std::uint16_t>(reg::Reaction::drive_own));
  // The operator's reset: enable low, a fault reset edge. The drive leaves fault (controlword
  // bit 7's rising edge) for switch on disabled, and the fault is not reported meanwhile; then
  // the controller can enable again.
  EXPECT_TRUE(r.resets_and_enables());
  EXPECT_EQ(r.ctl.snapshot().drive_fault_cause, 0);
  EXPECT_EQ(r.ctl.snapshot().drive_error_code, 0);
}

TEST(Cia402Power, TheStopBitIsTheDrivesQuickStopAndItsReleaseEnablesAgain) {
  ControllerOnDrive r;
  ASSERT_TRUE(r.enables());
  EXPECT_TRUE(r.reaches(bit(reg::kEnable) | bit(reg::kStop), DriveState::quick_stop_active,
                        reg::DriveState::enabled));
  EXPECT_TRUE(r.enables());
}

// A fault while the drive holds in quick stop: the fault reaction needs the motor, so the drive
// goes back to operation enabled; the reset then disables it like any other.
TEST(Cia402Power, AFaultDuringAQuickStopGivesTheMotorToTheFaultReaction) {
  ControllerOnDrive r;
  ASSERT_TRUE(r.enables());
  ASSERT_TRUE(r.reaches(bit(reg::kEnable) | bit(reg::kStop), DriveState::quick_stop_active,
                        reg::DriveState::enabled));
  ASSERT_TRUE(r.ctl.post(controller::Command{r.image, false, true}));  // the owner is gone
  r.cycles(20);
  EXPECT_EQ(r.state(), reg::DriveState::fault);
  EXPECT_EQ(r.ctl.snapshot().alarm_code, static_cast<std::uint16_t>(reg::Alarm::owner_lost));
  EXPECT_EQ(r.drive(), DriveState::operation_enabled);
  EXPECT_TRUE(r.resets_and_enables());
}

// The drive's following error (statusword bit 13 in cyclic synchronous position) is maglead's
// alarm following_error, the drive itself not in fault; the controller's reset clears it once the
// motor can follow again.
TEST(Cia402Power, TheDrivesFollowingErrorIsAnAlarm) {
  ControllerOnDrive r;
  ASSERT_TRUE(r.enables());
  // A window of one count for 2 ms: a move at 10 mm/s leaves it.
  r.hw.simulated_drive()->set_following_error_window(1, 2);
  r.image.mode_command = static_cast<std::uint16_t>(reg::Mode::position);
  r.image.position_setpoint_m = 0.03;
  r.post(bit(reg::kEnable) | bit(reg::kExecute));
  r.post(bit(reg::kEnable));
  for (int i = 0; i < 500 && r.ctl.snapshot().alarm_code == 0; ++i) r.cycles(1);
  EXPECT_EQ(r.ctl.snapshot().alarm_code, static_cast<std::uint16_t>(reg::Alarm::following_error));
  EXPECT_EQ(r.state(), reg::DriveState::fault);
  EXPECT_EQ(r.drive(), DriveState::operation_enabled);
  r.hw.simulated_drive()->set_following_error_window(0xFFFFFFFFU, 10);  // off again
  EXPECT_TRUE(r.resets_and_enables());
}

}  // namespace
}  // namespace maglead::canopen
