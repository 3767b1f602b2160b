// The hardware backend "cia402" with the simulated drive ("sim"): the controller's port through
// the whole CANopen path, in the loop's time.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/canopen/simulated_drive.hpp"

namespace maglead::canopen {
namespace {

std::unique_ptr<SimulatedActuator> plant() {
  return std::make_unique<SimulatedActuator>(paper_like_plant(), 3, 0.02);
}

TEST(Cia402Backend, ReadsTheEncodersAndFollowsTheCommandThroughTheDrive) {
  const ActuatorParams a;
  Cia402Hardware hw(a, {}, plant());
  EXPECT_NE(hw.describe().find("vendor 0x000000FB"), std::string::npos) << hw.describe();
  EXPECT_NE(hw.describe().find("40 % of the bus at 1000000 bit/s"), std::string::npos);
  SensorSample s;
  const double t0_s = 7.0;  // the loop's clock has an origin of its own
  ASSERT_EQ(hw.set_power(PowerRequest::enable), HwStatus::ok);
  ASSERT_EQ(hw.read_sensors(t0_s, s), HwStatus::ok);
  EXPECT_TRUE(std::isnan(s.load_force_n));
  const double start_rad = motor_angle_rad_from_counts(s.motor_counts, a);
  // Half a motor turn in 0.5 s, then held for 0.5 s.
  for (int k = 0; k < 1000; ++k) {
    const double cmd_rad = start_rad + std::numbers::pi * std::min(k, 500) / 500.0;
    ASSERT_EQ(hw.write_motor_angle(cmd_rad), HwStatus::ok) << k;
    ASSERT_EQ(hw.read_sensors(t0_s + (k + 1) * 1e-3, s), HwStatus::ok) << k;
  }
  ASSERT_EQ(hw.write_motor_angle(start_rad + std::numbers::pi), HwStatus::ok);
  const PlantTruth& truth = hw.simulated_plant()->truth();
  // The motor counts are the drive's position actual, the plant's encoder, one cycle old (the
  // motor at rest by now): the truth within a count of quantisation.
  EXPECT_NEAR(static_cast<double>(s.motor_counts),
              truth.motor_angle_rad * a.motor_counts_per_rev / (2 * std::numbers::pi), 1.0);
  EXPECT_NEAR(static_cast<double>(s.motor_counts),
              static_cast<double>(motor_counts_from_rad(start_rad + std::numbers::pi, a)), 2.0);
  EXPECT_NEAR(static_cast<double>(s.linear_counts), truth.nut_pos_m / a.linear_count_m, 1.0);
  EXPECT_EQ(hw.master().counters().missed_tpdo, 0U);
}

TEST(Cia402Backend, ASilentDriveBecomesADriveFaultWithinHalfASecond) {
  Cia402BackendOptions o;
  o.sim_silence_at_s = 0.1;
  Cia402Hardware hw(ActuatorParams{}, o, plant());
  SensorSample s;
  double fault_s = -1.0;
  for (int k = 0; k < 1000 && fault_s < 0.0; ++k) {
    const double t_s = k * 1e-3;
    if (hw.read_sensors(t_s, s) != HwStatus::ok) fault_s = t_s;
    hw.write_motor_angle(motor_angle_rad_from_counts(s.motor_counts, ActuatorParams{}));
  }
  ASSERT_GE(fault_s, 0.1);
  EXPECT_LE(fault_s - 0.1, 0.5);
  for (int k = 0; k < 500; ++k) hw.read_sensors(fault_s + k * 1e-3, s);
  EXPECT_TRUE(hw.master().heartbeat_lost());
  EXPECT_EQ(hw.fault_detail().cause, DriveFaultCause::drive_silent);
}

TEST(Cia402Backend, ADriveFaultKeepsTheBusCyclingWhenTheLoopStopsWriting) {
  Cia402Hardware hw(ActuatorParams{}, {}, plant());
  SensorSample s;
  double t_s = 0.0;
  for (; t_s < 0.05; t_s += 1e-3) {
    ASSERT_EQ(hw.read_sensors(t_s, s), HwStatus::ok);
    hw.write_motor_angle(motor_angle_rad_from_counts(s.motor_counts, ActuatorParams{}));
  }
  hw.simulated_drive()->inject_fault(0x2310, 0.0);  // at once: over-current
  const std::uint64_t missed_before = hw.master().counters().missed_tpdo;
  // As the controller does: after read_sensors reports a drive fault it does not write.
  int faulted = 0;
  for (int k = 0; k < 200; ++k, t_s += 1e-3) {
    if (hw.read_sensors(t_s, s) == HwStatus::ok) {
      hw.write_motor_angle(motor_angle_rad_from_counts(s.motor_counts, ActuatorParams{}));
    } else {
      ++faulted;
    }
  }
  EXPECT_GE(faulted, 195);
  // SYNC went on every cycle: the drive's TPDOs kept coming, the fault stays the drive's own.
  EXPECT_EQ(hw.master().counters().missed_tpdo, missed_before);
  EXPECT_EQ(hw.master().fault(), MasterFault::drive_fault);
  EXPECT_STREQ(hw.master().alarm_text(), "continuous over-current");
  EXPECT_EQ(hw.master().feedback().state, DriveState::fault);
  EXPECT_EQ(hw.fault_detail().cause, DriveFaultCause::drive_reports_fault);
  EXPECT_EQ(hw.fault_detail().error_code, 0x2310);
}

TEST(Cia402Backend, OnePercentLostFramesDoNotStopTheLoop) {
  Cia402BackendOptions o;
  o.sim_drop_fraction = 0.01;
  o.sim_seed = 9;
  const ActuatorParams a;
  Cia402Hardware hw(a, o, plant());
  SensorSample s;
  ASSERT_EQ(hw.set_power(PowerRequest::enable), HwStatus::ok);
  ASSERT_EQ(hw.read_sensors(0.0, s), HwStatus::ok);
  const double start_rad = motor_angle_rad_from_counts(s.motor_counts, a);
  for (int k = 1; k <= 5000; ++k) {
    ASSERT_EQ(hw.write_motor_angle(start_rad + std::sin(k * 2e-3)), HwStatus::ok) << k;
    ASSERT_EQ(hw.read_sensors(k * 1e-3, s), HwStatus::ok) << k << ": " << hw.master().alarm_text();
  }
  EXPECT_GT(hw.master().counters().missed_tpdo, 0U);
}

// A drive that does not reach operation enabled in time is a drive fault, though the drive
// reports none: here a timeout shorter than the three transitions enabling takes.
TEST(Cia402Backend, AnEnableNotReachedInTimeIsADriveFaultUntilTheReset) {
  Cia402BackendOptions o;
  o.enable_timeout_s = 0.002;
  Cia402Hardware hw(ActuatorParams{}, o, plant());
  SensorSample s;
  ASSERT_EQ(hw.set_power(PowerRequest::enable), HwStatus::ok);
  HwStatus last = HwStatus::ok;
  for (int k = 0; k < 10; ++k) {
    last = hw.read_sensors(k * 1e-3, s);
    hw.write_motor_angle(motor_angle_rad_from_counts(s.motor_counts, ActuatorParams{}));
  }
  EXPECT_EQ(last, HwStatus::drive_fault);
  EXPECT_TRUE(hw.enable_timed_out());
  EXPECT_EQ(hw.master().fault(), MasterFault::none);
  EXPECT_EQ(hw.fault_detail().cause, DriveFaultCause::enable_timeout);
  EXPECT_EQ(hw.set_power(PowerRequest::fault_reset), HwStatus::ok);
  EXPECT_FALSE(hw.enable_timed_out());
  EXPECT_EQ(hw.fault_detail().cause, DriveFaultCause::none);
  EXPECT_EQ(hw.read_sensors(0.011, s), HwStatus::ok);
}

TEST(Cia402Backend, RefusesWhatCannotWork) {
  Cia402BackendOptions o;
  o.can = "mlnocan7";
  try {
    Cia402Hardware hw(ActuatorParams{}, o, nullptr);
    FAIL() << "opened a missing CAN interface";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("mlnocan7"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("ip link set"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Cia402Hardware(ActuatorParams{}, Cia402BackendOptions{}, nullptr),
               std::invalid_argument);
  o = Cia402BackendOptions{};
  o.drive.loop_period_s = 2e-3;  // the loop runs at 1 kHz
  EXPECT_THROW(Cia402Hardware(ActuatorParams{}, o, plant()), std::invalid_argument);
}

TEST(Cia402Backend, ScalesTheDrivesUnitsToTheActuatorsCounts) {
  DriveConfig d;
  d.counts_per_motor_turn = 2048;  // a drive counting half the actuator's 4096
  d.second_encoder_m_per_count = 0.0254 / 1176.0 / 4;
  const Cia402Scaling s = cia402_scaling(d, ActuatorParams{});
  EXPECT_DOUBLE_EQ(s.motor_counts_per_drive_count, 2.0);
  EXPECT_DOUBLE_EQ(s.linear_counts_per_encoder_count, 0.25);
  EXPECT_DOUBLE_EQ(s.drive_counts_per_rad * 2 * std::numbers::pi, 2048.0);
}

}  // namespace
}  // namespace maglead::canopen
