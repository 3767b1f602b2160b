#pragma once
// CiA 402 on the master's side: the statusword decoded into the drive's state, and the
// controlword that moves the drive one step toward what the controller wants (enabled,
// disabled, quick stop), including the fault reset's rising edge.
#include <cstdint>

namespace maglead::canopen {

enum class DriveState : std::uint8_t {
  not_ready_to_switch_on,
  switch_on_disabled,
  ready_to_switch_on,
  switched_on,
  operation_enabled,
  quick_stop_active,
  fault_reaction_active,
  fault,
  unknown,  // a statusword no state of CiA 402 fits
};

DriveState decode_statusword(std::uint16_t statusword) noexcept;
const char* drive_state_text(DriveState state) noexcept;

// Controlword commands (CiA 402 table of device control commands; bits 0..3 and 7).
inline constexpr std::uint16_t cw_shutdown = 0x0006;
inline constexpr std::uint16_t cw_switch_on = 0x0007;
inline constexpr std::uint16_t cw_disable_voltage = 0x0000;
inline constexpr std::uint16_t cw_quick_stop = 0x0002;
inline constexpr std::uint16_t cw_disable_operation = 0x0007;
inline constexpr std::uint16_t cw_enable_operation = 0x000F;
inline constexpr std::uint16_t cw_fault_reset = 0x0080;

// Statusword bits the master reads beyond the state.
inline constexpr std::uint16_t sw_warning = 1U << 7;
inline constexpr std::uint16_t sw_following_error = 1U << 13;  // in cyclic synchronous position

/// What the controller asks of the drive.
enum class DriveRequest : std::uint8_t { disabled, enabled, quick_stop, fault_reset };

/// The controlword, one transition per cycle, toward a request. Holds the one bit of memory a
/// fault reset needs: bit 7 low for a cycle, then high (the drive acts on the rising edge).
class Cia402Sequencer {
 public:
  std::uint16_t next(DriveState state, DriveRequest request) noexcept;
  /// A new reset request: bit 7 goes low again first, so a drive that kept its fault after an
  /// earlier reset sees a fresh rising edge.
  void restart_fault_reset() noexcept { reset_low_sent_ = false; }

 private:
  bool reset_low_sent_ = false;
};

}  // namespace maglead::canopen
