#include "maglead/canopen/cia402.hpp"

namespace maglead::canopen {

DriveState decode_statusword(std::uint16_t statusword) noexcept {
  // CiA 402 table "state coding": bits 0..3, 5 and 6; bit 5 (quick stop) only where it tells
  // the states apart, hence two masks.
  const unsigned wide = statusword & 0x4FU, narrow = statusword & 0x6FU;
  if (wide == 0x00) return DriveState::not_ready_to_switch_on;
  if (wide == 0x40) return DriveState::switch_on_disabled;
  if (narrow == 0x21) return DriveState::ready_to_switch_on;
  if (narrow == 0x23) return DriveState::switched_on;
  if (narrow == 0x27) return DriveState::operation_enabled;
  if (narrow == 0x07) return DriveState::quick_stop_active;
  if (wide == 0x0F) return DriveState::fault_reaction_active;
  if (wide == 0x08) return DriveState::fault;
  return DriveState::unknown;
}

const char* drive_state_text(DriveState state) noexcept {
  switch (state) {
    case DriveState::not_ready_to_switch_on:
      return "not ready to switch on";
    case DriveState::switch_on_disabled:
      return "switch on disabled";
    case DriveState::ready_to_switch_on:
      return "ready to switch on";
    case DriveState::switched_on:
      return "switched on";
    case DriveState::operation_enabled:
      return "operation enabled";
    case DriveState::quick_stop_active:
      return "quick stop active";
    case DriveState::fault_reaction_active:
      return "fault reaction active";
    case DriveState::fault:
      return "fault";
    case DriveState::unknown:
      break;
  }
  return "unknown drive state";
}

std::uint16_t Cia402Sequencer::next(DriveState state, DriveRequest request) noexcept {
  if (state != DriveState::fault) reset_low_sent_ = false;
  switch (request) {
    case DriveRequest::fault_reset:
      if (state != DriveState::fault) return cw_disable_voltage;
      if (!reset_low_sent_) {
        reset_low_sent_ = true;
        return cw_disable_voltage;
      }
      return cw_fault_reset;
    case DriveRequest::disabled:
      return cw_disable_voltage;
    case DriveRequest::quick_stop:
      // Quick stop from operation enabled; elsewhere the same command disables the voltage.
      return cw_quick_stop;
    case DriveRequest::enabled:
      break;
  }
  switch (state) {
    case DriveState::switch_on_disabled:
      return cw_shutdown;  // transition 2
    case DriveState::ready_to_switch_on:
      return cw_switch_on;  // transition 3
    case DriveState::switched_on:
    case DriveState::operation_enabled:
    case DriveState::quick_stop_active:
      return cw_enable_operation;  // transitions 4 and 16
    case DriveState::not_ready_to_switch_on:
    case DriveState::fault_reaction_active:
    case DriveState::fault:
    case DriveState::unknown:
      break;
  }
  return cw_disable_voltage;  // a fault needs an explicit reset; nothing else to ask meanwhile
}

}  // namespace maglead::canopen
