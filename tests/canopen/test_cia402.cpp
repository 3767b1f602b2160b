// CiA 402: the statusword's decoding, the master's controlword sequence, and every transition
// of the device state machine driven on the simulated drive by controlwords in the RPDO.
#include <gtest/gtest.h>

#include <vector>

#include "maglead/canopen/cia402.hpp"
#include "rig.hpp"

namespace maglead::canopen {
namespace {

using testing::Rig;

TEST(Cia402, EveryStateDecodesFromItsStatuswordWhateverTheOtherBits) {
  const std::vector<std::pair<std::uint16_t, DriveState>> words{
      {0x0000, DriveState::not_ready_to_switch_on}, {0x0040, DriveState::switch_on_disabled},
      {0x0021, DriveState::ready_to_switch_on},     {0x0023, DriveState::switched_on},
      {0x0027, DriveState::operation_enabled},      {0x0007, DriveState::quick_stop_active},
      {0x000F, DriveState::fault_reaction_active},  {0x0008, DriveState::fault},
  };
  // Voltage enabled, warning, remote, target reached, following error: none changes the state.
  const std::uint16_t others = 0x0010 | 0x0080 | 0x0200 | 0x0400 | 0x2000;
  for (const auto& [word, state] : words) {
    EXPECT_EQ(decode_statusword(word), state) << std::hex << word;
    // Bit 5 is "don't care" where the state does not depend on it.
    const bool bit5_free = state == DriveState::not_ready_to_switch_on ||
                           state == DriveState::switch_on_disabled ||
                           state == DriveState::fault_reaction_active || state == DriveState::fault;
    const auto extra = static_cast<std::uint16_t>(others | (bit5_free ? 0x0020 : 0));
    EXPECT_EQ(decode_statusword(word | extra), state) << std::hex << (word | extra);
  }
  EXPECT_EQ(decode_statusword(0x0003), DriveState::unknown);  // switched on without bit 5
}

TEST(Cia402, TheSequencerTakesOneTransitionPerCycleTowardEnabled) {
  Cia402Sequencer s;
  EXPECT_EQ(s.next(DriveState::switch_on_disabled, DriveRequest::enabled), cw_shutdown);
  EXPECT_EQ(s.next(DriveState::ready_to_switch_on, DriveRequest::enabled), cw_switch_on);
  EXPECT_EQ(s.next(DriveState::switched_on, DriveRequest::enabled), cw_enable_operation);
  EXPECT_EQ(s.next(DriveState::operation_enabled, DriveRequest::enabled), cw_enable_operation);
  EXPECT_EQ(s.next(DriveState::quick_stop_active, DriveRequest::enabled), cw_enable_operation);
  EXPECT_EQ(s.next(DriveState::fault, DriveRequest::enabled), cw_disable_voltage);
  EXPECT_EQ(s.next(DriveState::operation_enabled, DriveRequest::disabled), cw_disable_voltage);
  EXPECT_EQ(s.next(DriveState::operation_enabled, DriveRequest::quick_stop), cw_quick_stop);
  // A fault reset is a rising edge of bit 7: low first, then high, held until the drive leaves.
  EXPECT_EQ(s.next(DriveState::fault, DriveRequest::fault_reset), cw_disable_voltage);
  EXPECT_EQ(s.next(DriveState::fault, DriveRequest::fault_reset), cw_fault_reset);
  EXPECT_EQ(s.next(DriveState::fault, DriveRequest::fault_reset), cw_fault_reset);
  // The drive kept its fault: a second reset starts with bit 7 low again, a fresh edge.
  s.restart_fault_reset();
  EXPECT_EQ(s.next(DriveState::fault, DriveRequest::fault_reset), cw_disable_voltage);
  EXPECT_EQ(s.next(DriveState::fault, DriveRequest::fault_reset), cw_fault_reset);
  EXPECT_EQ(s.next(DriveState::switch_on_disabled, DriveRequest::fault_reset), cw_disable_voltage);
}

// The drive started by the master (PDOs mapped, operational), then driven by raw RPDOs.
struct RawDrive {
  RawDrive() { rig.master.start(); }
  /// Sends `controlword` (target: where the motor is) with a SYNC and returns the state the
  /// drive's TPDO reports for it.
  DriveState apply(std::uint16_t controlword) {
    CanFrame rpdo;
    rpdo.id = cob_rpdo1 + 1;
    const std::array<std::uint32_t, 2> v{controlword, static_cast<std::uint32_t>(position_)};
    pack_pdo(rpdo1_map(), v, rpdo);
    rig.port.send(rpdo);
    rig.port.send(sync_frame());
    return await_tpdo();
  }
  DriveState await_tpdo() {
    const double deadline_s = rig.bus.now_s() + 1e-3;
    CanFrame f;
    while (rig.port.receive(f, deadline_s) == CanStatus::ok) {
      if (f.id != cob_tpdo1 + 1) continue;
      std::array<std::uint32_t, 3> v{};
      unpack_pdo(tpdo1_map(), f, v);
      position_ = static_cast<std::int32_t>(v[1]);
      return decode_statusword(static_cast<std::uint16_t>(v[0]));
    }
    return DriveState::unknown;
  }
  Rig rig;
  std::int32_t position_ = 0;
};

struct Step {
  std::uint16_t controlword;
  DriveState expected;
  int transition;  // CiA 402's number of the transition this step takes
};

TEST(Cia402, EveryTransitionOfTheSimulatedDrive) {
  using S = DriveState;
  const std::vector<Step> steps{
      {cw_shutdown, S::ready_to_switch_on, 2},
      {cw_switch_on, S::switched_on, 3},
      {cw_enable_operation, S::operation_enabled, 4},
      {cw_disable_operation, S::switched_on, 5},
      {cw_shutdown, S::ready_to_switch_on, 6},
      {cw_disable_voltage, S::switch_on_disabled, 7},
      {cw_shutdown, S::ready_to_switch_on, 2},
      {cw_switch_on, S::switched_on, 3},
      {cw_enable_operation, S::operation_enabled, 4},
      {cw_shutdown, S::ready_to_switch_on, 8},
      {cw_enable_operation, S::operation_enabled, 34},
      {cw_disable_voltage, S::switch_on_disabled, 9},
      {cw_shutdown, S::ready_to_switch_on, 2},
      {cw_switch_on, S::switched_on, 3},
      {cw_quick_stop, S::switch_on_disabled, 10},
      {cw_shutdown, S::ready_to_switch_on, 2},
      {cw_quick_stop, S::switch_on_disabled, 7},
      {cw_shutdown, S::ready_to_switch_on, 2},
      {cw_enable_operation, S::operation_enabled, 34},
      {cw_quick_stop, S::quick_stop_active, 11},
      {cw_enable_operation, S::operation_enabled, 16},
      {cw_quick_stop, S::quick_stop_active, 11},
      {cw_disable_voltage, S::switch_on_disabled, 12},
      // Commands a state has no transition for leave it where it is.
      {cw_switch_on, S::switch_on_disabled, 0},
      {cw_enable_operation, S::switch_on_disabled, 0},
  };
  RawDrive d;
  EXPECT_EQ(d.apply(cw_disable_voltage), DriveState::switch_on_disabled);  // transition 1 done
  for (const Step& s : steps)
    EXPECT_EQ(d.apply(s.controlword), s.expected) << "transition " << s.transition;
}

TEST(Cia402, AFaultReactsThenFaultsAndResetsOnTheRisingEdgeOnly) {
  RawDrive d;
  d.apply(cw_shutdown);
  d.apply(cw_switch_on);
  ASSERT_EQ(d.apply(cw_enable_operation), DriveState::operation_enabled);
  d.rig.drive.inject_fault(0x7300, d.rig.bus.now_s());
  EXPECT_EQ(d.apply(cw_fault_reset), DriveState::fault_reaction_active);  // 13; bit 7 now high
  d.rig.bus.advance_to(d.rig.bus.now_s() + 3e-3);                         // the reaction time
  EXPECT_EQ(d.apply(cw_fault_reset), DriveState::fault);  // 14; bit 7 held high: no edge
  EXPECT_EQ(d.apply(cw_disable_voltage), DriveState::fault);
  EXPECT_EQ(d.apply(cw_fault_reset), DriveState::switch_on_disabled);  // 15, on the edge
}

}  // namespace
}  // namespace maglead::canopen
