#include "maglead/controller/force_loop.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace maglead::controller {
namespace {
// A bound inside the tolerance is good enough; a landing within the land tolerance is better.
// The loop tries this many times for the better one, then holds what it has.
constexpr int kRefineAttempts = 3;
// The speed counts as at the limit from this share of it on: the estimate moves in steps of one
// encoder count per sample, so the limited speed dithers just below the limit.
constexpr double kAtLimitShare = 0.9;
// Once at the limit the loop says so until the speed stays below this share of it (and the
// drive unclipped) for kLeaveLimit_s, and not again once it has landed, so the state (and a
// PLC's force_limited bit) does not blink with each count of the speed estimate.
constexpr double kLeaveLimitShare = 0.5;
// The speed-limited slide swings at the nut-and-coupling resonance (about 90 Hz: between 30
// and 70 mm/s near the window's end) and its edge-timed estimate in steps of a count per
// sample: below half the limit for up to 5 ms at a time. 50 ms is several swings.
constexpr double kLeaveLimit_s = 0.05;
// Once landing, the state stays landing while the nut slides on, unless the estimate stays
// beyond the force_reached tolerance this long. Creeping in, the sliding estimate swings with
// each encoder edge, beyond the land tolerance for up to 60 ms and beyond the force_reached
// tolerance for up to 8 ms (ForceAtLoad's four loads): the state would flip 2↔3 with each edge
// (up to 38 flips 3→2 per setpoint). 30 ms is about four times that longest swing. Only the
// published state waits: the feed-forward still follows the land tolerance every cycle, so
// force control is not delayed.
constexpr double kLeaveLanding_s = 0.03;
}  // namespace

ForceLoop::ForceLoop(const ForceLoopConfig& config) : cfg_(config) {
  if (!(cfg_.damping_n_s_per_m > 0) || !(cfg_.breakaway_ramp_n_per_s > 0) ||
      !(cfg_.tolerance_n > 0) || !(cfg_.land_tolerance_n > 0) ||
      !(cfg_.drive_max_n > cfg_.drive_min_n) || !cfg_.friction.valid() ||
      !(cfg_.speed_limit_m_s > 0) || !std::isfinite(cfg_.speed_limit_m_s))
    throw std::invalid_argument(
        "force loop: damping, ramp, tolerances and speed limit must be positive, the friction "
        "model valid");
}

bool ForceLoop::bound_inside_tolerance(const LoadEstimate& est) const noexcept {
  return est.lo_n >= setpoint_n_ - cfg_.tolerance_n && est.hi_n <= setpoint_n_ + cfg_.tolerance_n;
}

ForceReachedReason ForceLoop::reason(const LoadEstimate& est) const noexcept {
  if (state_ == ForceLoopState::off) return ForceReachedReason::not_force_mode;
  if (state_ == ForceLoopState::speed_limited) return ForceReachedReason::speed_limit;
  if (est.motion != 0) return ForceReachedReason::moving;
  if (bound_inside_tolerance(est)) return ForceReachedReason::reached;
  if (drive_limited_) return ForceReachedReason::drive_limit;
  if (est.basis == ObserverBasis::band) return ForceReachedReason::bound_unknown;
  if (est.width_n() > 2.0 * cfg_.tolerance_n) return ForceReachedReason::bound_too_wide;
  return ForceReachedReason::load_force_off;
}

void ForceLoop::start(double setpoint_n, double drive_now_n, const LoadEstimate& est) noexcept {
  setpoint_n_ = setpoint_n;
  hold_drive_n_ = ramp_n_ = drive_now_n;
  // A setpoint the known bound already covers needs no motion: say so and stay.
  attempts_ = 0;
  slid_ = false;
  landed_once_ = false;
  held_by_bound_ = est.motion == 0 && bound_inside_tolerance(est);
  state_ = held_by_bound_ ? ForceLoopState::holding_no_motion : ForceLoopState::approaching;
  // No motion needed: still move the coupling to the stick band's centre (the nut stays put,
  // friction only eases) so that a disturbance either way finds the most margin.
  if (held_by_bound_) hold_drive_n_ = est.force_n;
}

double ForceLoop::breakaway_drive_n(const LoadEstimate& est, double dt_s) noexcept {
  const auto& f = cfg_.friction;
  if (state_ != ForceLoopState::breaking_away && state_ != ForceLoopState::blocked) {
    const double e = setpoint_n_ - est.force_n;
    dir_ = e >= 0.0 ? 1 : -1;
    // The lowest drive that could move the nut towards the setpoint, given the bound.
    ramp_n_ = dir_ > 0 ? est.lo_n + f.breakaway_n(1) : est.hi_n - f.breakaway_n(-1);
    state_ = ForceLoopState::breaking_away;
    ++attempts_;
  }
  // Beyond the highest drive that must have moved it (twice the model's break-away past the
  // bound) something else holds the nut: stop raising the force.
  const double limit =
      dir_ > 0 ? est.hi_n + 2.0 * f.breakaway_n(1) : est.lo_n - 2.0 * f.breakaway_n(-1);
  ramp_n_ += dir_ * cfg_.breakaway_ramp_n_per_s * dt_s;
  if ((ramp_n_ - limit) * dir_ >= 0.0) {
    ramp_n_ = limit;
    state_ = ForceLoopState::blocked;
  }
  return ramp_n_;
}

double ForceLoop::sliding_drive_n(const LoadEstimate& est, double dt_s) noexcept {
  const double e = setpoint_n_ - est.force_n;
  const double damping = cfg_.damping_n_s_per_m * est.nut_vel_m_s;
  const bool was_landing = state_ == ForceLoopState::landing;
  const bool was_limited = state_ == ForceLoopState::speed_limited;
  off_setpoint_s_ = was_landing && std::abs(e) > cfg_.tolerance_n ? off_setpoint_s_ + dt_s : 0.0;
  if (std::abs(e) <= cfg_.land_tolerance_n) {
    // Friction alone stops the nut here. At the speed limit the estimate swings by up to 2 N
    // and touches the setpoint now and then: the state leaves the limit for a landing only as
    // it would for a slower slide (kLeaveLimit_s), so force_limited does not blink.
    below_limit_s_ = was_limited ? below_limit_s_ + dt_s : 0.0;
    if (was_limited && below_limit_s_ < kLeaveLimit_s) return setpoint_n_ - damping;
    state_ = ForceLoopState::landing;
    landed_once_ = true;
    return setpoint_n_ - damping;
  }
  // The feed-forward comes back at once; the state says approaching again only once the
  // estimate has stayed off the setpoint (kLeaveLanding_s).
  state_ = was_landing && off_setpoint_s_ < kLeaveLanding_s ? ForceLoopState::landing
                                                            : ForceLoopState::approaching;
  // Feed friction forward only while the nut moves the way the load force must go; moving
  // the other way, friction and damping brake it.
  const bool towards = (e > 0.0) == (est.motion > 0);
  if (!towards) return setpoint_n_ - damping;
  return speed_limited_n(setpoint_n_ - damping + cfg_.friction.sliding_n(est.nut_vel_m_s), est,
                         was_limited, dt_s);
}

/// The gentler of `drive_n` and the drive that holds the nut at the speed limit: the load force
/// and friction it slides against, plus D times the speed still allowed (negative past it).
double ForceLoop::speed_limited_n(double drive_n, const LoadEstimate& est, bool was_limited,
                                  double dt_s) noexcept {
  const double v = est.nut_vel_m_s;
  const double dir = v >= 0.0 ? 1.0 : -1.0;
  const double limit = std::min(cfg_.speed_limit_m_s, dir > 0 ? cap_up_m_s_ : cap_down_m_s_);
  const double at_limit_n =
      est.force_n + cfg_.friction.sliding_n(v) + cfg_.damping_n_s_per_m * (dir * limit - v);
  const bool clipped = (drive_n - at_limit_n) * dir > 0.0;
  const double share = std::abs(v) / limit;
  const bool at_limit = clipped || share >= kLeaveLimitShare;
  below_limit_s_ = was_limited && !at_limit ? below_limit_s_ + dt_s : 0.0;
  if (!landed_once_ &&
      ((clipped && share >= kAtLimitShare) || (was_limited && below_limit_s_ < kLeaveLimit_s)))
    state_ = ForceLoopState::speed_limited;
  return clipped ? at_limit_n : drive_n;
}

double ForceLoop::drive_n(const LoadEstimate& est, double dt_s) noexcept {
  drive_limited_ = false;
  if (state_ == ForceLoopState::off) return hold_drive_n_;
  double drive;
  if (est.motion != 0) {
    slid_ = true;
    drive = sliding_drive_n(est, dt_s);
  } else {
    const bool holding =
        state_ == ForceLoopState::holding || state_ == ForceLoopState::holding_no_motion;
    const bool inside = bound_inside_tolerance(est);
    // Landed: stopped at the setpoint after a slide of this approach. A stop from before the
    // setpoint came (a disable since may have widened the bound to the stick band) is no landing:
    // standing still, the loop would never learn the load again.
    const bool landed = slid_ && est.basis == ObserverBasis::stuck &&
                        std::abs(setpoint_n_ - est.force_n) <= cfg_.land_tolerance_n;
    // Hold while what made us hold still holds: the bound inside the tolerance (it widens if
    // the load may change on its own: then land again), or a landing the bound cannot refine.
    if (holding && (held_by_bound_ ? inside : landed || inside)) {
      drive = hold_drive_n_;
    } else if (landed || (inside && attempts_ >= kRefineAttempts)) {
      state_ = ForceLoopState::holding;
      held_by_bound_ = inside;
      hold_drive_n_ = drive = est.force_n;  // the stick band's centre
    } else {
      drive = breakaway_drive_n(est, dt_s);
    }
  }
  drive_limited_ = drive > cfg_.drive_max_n || drive < cfg_.drive_min_n;
  return std::clamp(drive, cfg_.drive_min_n, cfg_.drive_max_n);
}

}  // namespace maglead::controller
