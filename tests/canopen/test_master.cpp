// The master against the simulated drive: start-up and its read-back, the drive state through
// the controlword sequence, the cycle's supervision (EMCY, a silent drive, lost and late
// frames) and the [drive] settings' checks.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "rig.hpp"

namespace maglead::canopen {
namespace {

using testing::Rig;

std::uint32_t read_u32(Cia402Master& m, std::uint16_t index, std::uint8_t sub) {
  const std::vector<std::uint8_t> d = m.read(index, sub);
  return get_le(d.data(), d.size());
}

TEST(Master, StartsReadsTheIdentityAndReadsBackTheMapping) {
  Rig rig;
  rig.master.start();
  const DriveIdentity& id = rig.master.identity();
  EXPECT_EQ(id.device_type, 0x00020192U);
  EXPECT_EQ(id.vendor_id, 0xFBU);
  EXPECT_EQ(id.serial, SimulatedDriveOptions{}.serial);
  EXPECT_EQ(id.device_name, "maglead simulated CiA 402 drive");
  EXPECT_NE(describe_identity(id).find("vendor 0x000000FB"), std::string::npos);
  Cia402Master& m = rig.master;
  EXPECT_EQ(read_u32(m, 0x6061, 0), 8U);  // cyclic synchronous position in force
  EXPECT_EQ(read_u32(m, 0x60C2, 1), 1U);  // 1 · 10^-3 s
  EXPECT_EQ(read_u32(m, 0x60C2, 2), 0xFDU);
  EXPECT_EQ(read_u32(m, 0x1017, 0), 100U);
  EXPECT_EQ(read_u32(m, 0x1400, 1), 0x201U);
  EXPECT_EQ(read_u32(m, 0x1600, 0), 2U);
  EXPECT_EQ(read_u32(m, 0x1600, 1), 0x60400010U);
  EXPECT_EQ(read_u32(m, 0x1600, 2), 0x607A0020U);
  EXPECT_EQ(read_u32(m, 0x1800, 1), 0x181U);
  EXPECT_EQ(read_u32(m, 0x1800, 2), 1U);  // every SYNC
  EXPECT_EQ(read_u32(m, 0x1A00, 0), 3U);
  EXPECT_EQ(read_u32(m, 0x1A00, 1), 0x60410010U);
  EXPECT_EQ(read_u32(m, 0x1A00, 2), 0x60640020U);
  EXPECT_EQ(read_u32(m, 0x1A00, 3), 0x603F0010U);
  EXPECT_EQ(read_u32(m, 0x1A01, 1), 0x60E40120U);
  EXPECT_EQ(rig.drive.nmt_state(), 0x05);  // operational
  // The first cycles bring PDOs both ways and a heartbeat.
  rig.cycles(150);
  EXPECT_EQ(rig.master.fault(), MasterFault::none) << rig.master.alarm_text();
  EXPECT_EQ(rig.master.feedback().state, DriveState::switch_on_disabled);
  EXPECT_EQ(rig.master.feedback().nmt, NmtState::operational);
  EXPECT_EQ(rig.master.counters().missed_tpdo, 0U);
}

TEST(Master, ASecondEncoderAtAnotherObjectIsMappedThere) {
  DriveConfig c;
  c.second_encoder_index = 0x2211;
  c.second_encoder_sub = 3;
  SimulatedDriveOptions d;
  d.second_encoder_index = 0x2211;
  d.second_encoder_sub = 3;
  Rig rig({}, c, d);
  rig.master.start();
  EXPECT_EQ(read_u32(rig.master, 0x1A01, 1), 0x22110320U);
}

TEST(Master, AWriteTheDriveIgnoresIsRefusedWithTheObjectsIndex) {
  Rig rig;
  rig.drive.ignore_writes_to(0x6060, 0);
  try {
    rig.master.start();
    FAIL() << "started with the mode of operation not taken";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("object 0x6060:00 reads back 0x00 after writing 0x08"), std::string::npos)
        << what;
  }
}

TEST(Master, AnAbortAtStartUpNamesTheObjectAndTheReason) {
  DriveConfig c;
  c.second_encoder_index = 0x2211;  // the drive has no such object
  Rig rig({}, c);
  try {
    rig.master.start();
    FAIL() << "mapped an object the drive does not have";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("0x1A01:01"), std::string::npos) << what;
    EXPECT_NE(what.find("object does not exist"), std::string::npos) << what;
  }
}

TEST(Master, NoDriveOnTheBusIsRefusedAtBootUp) {
  VirtualCanBus bus;
  Cia402Master m(bus.attach(0), DriveConfig{});
  try {
    m.start();
    FAIL() << "started without a drive";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no boot-up message"), std::string::npos) << e.what();
  }
  EXPECT_NEAR(bus.now_s(), DriveConfig{}.boot_timeout_s, 1e-3);
}

TEST(Master, EnablesThroughEveryStateAndFollowsTheTarget) {
  Rig rig;
  rig.master.start();
  rig.master.request(DriveRequest::enabled);
  std::vector<DriveState> seen;
  for (int i = 0; i < 20 && rig.master.feedback().state != DriveState::operation_enabled; ++i) {
    rig.cycles(1);
    const DriveState now = rig.master.feedback().state;
    // Before the first TPDO the master knows no state (unknown): not a state of the drive.
    if (now != DriveState::unknown && (seen.empty() || seen.back() != now)) seen.push_back(now);
  }
  const std::vector<DriveState> expected{DriveState::switch_on_disabled,
                                         DriveState::ready_to_switch_on, DriveState::switched_on,
                                         DriveState::operation_enabled};
  EXPECT_EQ(seen, expected);
  // One motor turn in 1 s, then held: the drive's position ends on the target.
  const std::int32_t start_counts = rig.master.feedback().position_counts;
  const std::int32_t start_linear = rig.master.feedback().second_encoder_counts;
  for (int k = 1; k <= 1000; ++k) {
    rig.master.set_target_counts(start_counts + 4096 * k / 1000);
    rig.cycles(1);
  }
  rig.cycles(500);
  EXPECT_EQ(rig.master.fault(), MasterFault::none) << rig.master.alarm_text();
  EXPECT_NEAR(rig.master.feedback().position_counts, start_counts + 4096, 2);
  // The second encoder is the nut's linear encoder: at rest, the plant's nut position in counts
  // (the encoder reads the nearest count, hence half a count either way).
  const PlantTruth& truth = rig.actuator.truth();
  const double linear_m = rig.actuator.params().actuator.linear_count_m;
  EXPECT_NEAR(rig.master.feedback().second_encoder_counts, truth.nut_pos_m / linear_m, 0.5 + 1e-9);
  // It moved: a motor turn is 6 mm / 6.6 = 0.91 mm of screw lead, 42 counts less the
  // coupling's friction lag (the nut trails the screw's field by a fraction of a pole).
  EXPECT_GT(rig.master.feedback().second_encoder_counts - start_linear, 30);
}

TEST(Master, AnEmcyBecomesAnAlarmWithItsCodeAndTextAndResets) {
  Rig rig;
  rig.enable();
  ASSERT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
  rig.drive.inject_fault(0x8611, rig.bus.now_s());
  ASSERT_TRUE(rig.cycles_until(DriveState::fault, 10));
  EXPECT_EQ(rig.master.fault(), MasterFault::drive_fault);
  EXPECT_EQ(rig.master.last_emergency().error_code, 0x8611);
  EXPECT_EQ(rig.master.last_emergency().error_register, 0x01);
  EXPECT_EQ(rig.master.feedback().error_code, 0x8611);  // 0x603F in the TPDO
  EXPECT_STREQ(rig.master.alarm_text(), "following error");
  EXPECT_EQ(rig.master.counters().emergencies, 1U);
  // Enabled is still asked, but a fault needs its reset: the drive stays in fault.
  rig.cycles(20);
  EXPECT_EQ(rig.master.feedback().state, DriveState::fault);
  rig.master.request(DriveRequest::fault_reset);
  ASSERT_TRUE(rig.cycles_until(DriveState::switch_on_disabled, 5));
  EXPECT_EQ(rig.master.fault(), MasterFault::none);
  EXPECT_EQ(rig.master.feedback().error_code, 0);
  EXPECT_EQ(rig.master.counters().emergencies, 1U);  // the "error reset" EMCY is not an alarm
  rig.master.request(DriveRequest::enabled);
  EXPECT_TRUE(rig.cycles_until(DriveState::operation_enabled, 10));
}

TEST(Master, ASilentDriveIsCaughtWithinItsHeartbeatTimeout) {
  Rig rig;
  rig.enable();
  rig.cycles(250);  // a few heartbeats, so that the last one lies anywhere in its period
  const double silent_s = rig.bus.now_s();
  rig.bus.silence(1, silent_s);
  for (int i = 0; i < 1000 && !rig.master.heartbeat_lost(); ++i) rig.cycles(1);
  ASSERT_TRUE(rig.master.heartbeat_lost());
  const double found_after_s = rig.master.heartbeat_lost_at_s() - silent_s;
  const DriveConfig& c = rig.config;
  EXPECT_LE(found_after_s, 0.5);
  EXPECT_LE(found_after_s, c.heartbeat_timeout_s + c.loop_period_s + 1e-9);
  // Not before the timeout after the last heartbeat, which came at most one period before.
  EXPECT_GE(found_after_s, c.heartbeat_timeout_s - c.heartbeat_producer_s);
  // The process data stopped first: the master latched that within its allowance of cycles
  // and commands a quick stop.
  EXPECT_EQ(rig.master.fault(), MasterFault::pdo_timeout);
  EXPECT_EQ(rig.master.last_controlword(), cw_quick_stop);
}

TEST(Master, OnePercentOfFramesLostIsCountedAndSurvived) {
  VirtualBusOptions o;
  o.drop_fraction = 0.01;
  o.seed = 11;
  Rig rig(o);
  rig.enable();  // start-up too, with its SDO retries
  ASSERT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
  const std::int32_t start_counts = rig.master.feedback().position_counts;
  const std::uint64_t missed_before = rig.master.counters().missed_tpdo;
  constexpr int cycles = 10000;
  int worst_error = 0;
  for (int k = 0; k < cycles; ++k) {
    // A slow sine of half a motor turn: the servo follows it within a few counts.
    const double phase = 2.0 * 3.141592653589793 * k / 2000.0;
    rig.master.set_target_counts(start_counts + static_cast<std::int32_t>(1024 * std::sin(phase)));
    const double before_s = rig.bus.now_s() + rig.config.loop_period_s;
    rig.bus.advance_to(before_s);
    const double at_s = rig.bus.now_s();
    ASSERT_EQ(rig.master.cycle(at_s), MasterFault::none)
        << "cycle " << k << ": " << rig.master.alarm_text();
    ASSERT_EQ(rig.bus.now_s(), at_s) << "the cycle waited";
    worst_error = std::max(
        worst_error, std::abs(rig.master.feedback().position_counts - rig.drive.target_counts()));
  }
  EXPECT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
  // A cycle misses TPDO1 when its SYNC or the TPDO1 is lost: p = 1 - 0.99² ≈ 2 %, 199 of
  // 10000 expected, standard deviation 14; five of them either side.
  const auto missed = static_cast<double>(rig.master.counters().missed_tpdo - missed_before);
  EXPECT_GT(missed, 199 - 5 * 14);
  EXPECT_LT(missed, 199 + 5 * 14);
  EXPECT_GT(rig.bus.dropped(), 0U);
  // Tracking: the servo and the one-cycle-old feedback lag the sine (3217 counts/s at most) by
  // 28 counts without loss (measured); each lost RPDO or TPDO adds a cycle, 3 counts (31
  // measured here). 40 leaves room for two in a row and no more: a fault, not noise.
  EXPECT_LT(worst_error, 40);
}

TEST(Master, EnablingCommandsNoJumpWhateverTargetWasSetBefore) {
  Rig rig;
  rig.master.start();
  rig.master.set_target_counts(0);  // far from where the motor is (the nut at 20 mm)
  rig.master.request(DriveRequest::enabled);
  int worst_error = 0;
  for (int i = 0; i < 30; ++i) {
    rig.cycles(1);
    if (rig.drive.statusword() & 0x4) {  // operation enabled at the drive
      worst_error = std::max(
          worst_error, std::abs(rig.drive.target_counts() - rig.master.feedback().position_counts));
    }
  }
  ASSERT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
  EXPECT_LE(worst_error, 1);
}

TEST(Master, ALateTpdoIsOneMissedCycleNotAFault) {
  Rig rig;
  rig.enable();
  rig.cycles(10);
  const std::uint64_t missed_before = rig.master.counters().missed_tpdo;
  rig.drive.delay_tpdo(rig.bus.now_s(), 1.5e-3);
  rig.cycles(20);
  EXPECT_EQ(rig.master.counters().missed_tpdo - missed_before, 1U);
  EXPECT_EQ(rig.master.fault(), MasterFault::none);
  EXPECT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
}

TEST(Master, AQuickStopRequestStopsAndEnableResumes) {
  Rig rig;
  rig.enable();
  rig.master.request(DriveRequest::quick_stop);
  EXPECT_TRUE(rig.cycles_until(DriveState::quick_stop_active, 5));
  rig.master.request(DriveRequest::enabled);
  EXPECT_TRUE(rig.cycles_until(DriveState::operation_enabled, 5));
  rig.master.request(DriveRequest::disabled);
  EXPECT_TRUE(rig.cycles_until(DriveState::switch_on_disabled, 5));
}

TEST(DriveSettings, TheLoadOfTheCycleAndWhatCannotFit) {
  DriveConfig c;
  // SYNC 55 + RPDO1 (6 bytes) 115 + TPDO1 (8) 135 + TPDO2 (4) 95 bits, heartbeat 65 bits / 100
  // cycles: 400.65 bits per 1 ms at 1 Mbit/s.
  EXPECT_NEAR(bus_load_fraction(c), 400.65 / 1000.0, 1e-9);
  EXPECT_NO_THROW(check_drive_config(c));
  c.bitrate_bit_s = 500'000;  // 80 %: refused
  EXPECT_THROW(check_drive_config(c), std::invalid_argument);
  try {
    check_drive_config(c);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("80 % of the bus at 500000 bit/s"), std::string::npos)
        << e.what();
  }
  c.loop_period_s = 2e-3;  // 40 % at 500 kbit/s again
  EXPECT_NO_THROW(check_drive_config(c));
  DriveConfig bad;
  bad.node_id = 0;
  EXPECT_THROW(check_drive_config(bad), std::invalid_argument);
  bad = DriveConfig{};
  bad.heartbeat_timeout_s = 0.12;  // under 1.5 producer periods
  EXPECT_THROW(check_drive_config(bad), std::invalid_argument);
  bad = DriveConfig{};
  bad.bitrate_bit_s = 1'234'000;
  EXPECT_THROW(check_drive_config(bad), std::invalid_argument);
  std::uint8_t value = 0;
  std::int8_t exponent = 0;
  ASSERT_TRUE(interpolation_period_code(2.5e-3, value, exponent));
  EXPECT_EQ(value, 25);
  EXPECT_EQ(exponent, -4);
  EXPECT_FALSE(interpolation_period_code(1.0 / 3.0, value, exponent));
}

TEST(Protocol, PdoPackingEmcyAndNmtFrames) {
  CanFrame f;
  const std::array<std::uint32_t, 2> v{0x000F, static_cast<std::uint32_t>(-5)};
  ASSERT_TRUE(pack_pdo(rpdo1_map(), v, f));
  EXPECT_EQ(f.len, 6);
  EXPECT_EQ(f.data[0], 0x0F);
  EXPECT_EQ(f.data[2], 0xFB);  // -5, little-endian
  EXPECT_EQ(f.data[5], 0xFF);
  std::array<std::uint32_t, 2> back{};
  ASSERT_TRUE(unpack_pdo(rpdo1_map(), f, back));
  EXPECT_EQ(static_cast<std::int32_t>(back[1]), -5);
  f.len = 5;
  EXPECT_FALSE(unpack_pdo(rpdo1_map(), f, back));  // shorter than its mapping
  EXPECT_FALSE(pack_pdo(rpdo1_map(), std::array<std::uint32_t, 1>{1}, f));
  CanFrame e;
  e.len = 8;
  e.data = {0x11, 0x86, 0x01, 1, 2, 3, 4, 5};
  EXPECT_EQ(decode_emergency(e).error_code, 0x8611);
  EXPECT_STREQ(emergency_text(0x8611), "following error");
  EXPECT_STREQ(emergency_text(0x2399), "current");
  EXPECT_STREQ(emergency_text(0x8199), "communication");
  EXPECT_STREQ(emergency_text(0x0A00), "unknown error code");
  const CanFrame nmt = nmt_frame(NmtCommand::reset_communication, 3);
  EXPECT_EQ(nmt.id, 0U);
  EXPECT_EQ(nmt.data[0], 0x82);
  EXPECT_EQ(nmt.data[1], 3);
  EXPECT_EQ(nmt_state_of(0x85), NmtState::operational);  // bit 7: the guarding toggle
}

}  // namespace
}  // namespace maglead::canopen
