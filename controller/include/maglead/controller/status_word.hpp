#pragma once
// The status word (input register status_word, discrete inputs 0..15) as a pure function of what
// the cycle decided: one place maps each fact to its bit, testable without a loop.
#include <cstdint>

#include "maglead/registers/registers.hpp"

namespace maglead::controller {

/// The facts the status word reports, in the words of the register table.
struct StatusFacts {
  registers::DriveState state = registers::DriveState::disabled;
  bool moving = false;
  bool in_position = false;    // settled in position (position modes)
  bool force_reached = false;  // settled at the force (force mode)
  bool stepped_out = false;
  bool drift_warning = false;
  bool watchdog_expired = false;
  bool twin_healthy = false;
  bool step_out_warning = false;
  bool stopped = false;          // the stop bit holds the drive
  bool at_stroke_limit = false;  // the nut at or beyond a stroke end
  bool twin_lagging = false;
  bool force_limited = false;  // force mode holds at its stroke window's end, or its speed limit
};

/// The status word's bits for these facts (bit numbers of registers/registers.hpp).
std::uint16_t pack_status_word(const StatusFacts& facts) noexcept;

}  // namespace maglead::controller
