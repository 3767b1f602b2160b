#include "maglead/controller/status_word.hpp"

namespace maglead::controller {

std::uint16_t pack_status_word(const StatusFacts& f) noexcept {
  using registers::DriveState;
  std::uint16_t sw = 0;
  const auto set = [&sw](int b, bool on) {
    if (on) sw = static_cast<std::uint16_t>(sw | (1u << b));
  };
  set(registers::kReady, f.state == DriveState::ready);
  set(registers::kEnabled, f.state == DriveState::enabled);
  set(registers::kFault, f.state == DriveState::fault);
  set(registers::kMoving, f.moving);
  set(registers::kInPosition, f.in_position);
  set(registers::kForceReached, f.force_reached);
  set(registers::kStepOut, f.stepped_out);
  set(registers::kDriftWarning, f.drift_warning);
  set(registers::kWatchdogExpired, f.watchdog_expired);
  set(registers::kTwinHealthy, f.twin_healthy);
  set(registers::kStepOutWarning, f.step_out_warning);
  set(registers::kStopped, f.stopped);
  set(registers::kStrokeLimit, f.at_stroke_limit);
  set(registers::kTwinLagging, f.twin_lagging);
  set(registers::kForceLimited, f.force_limited);
  return sw;
}

}  // namespace maglead::controller
