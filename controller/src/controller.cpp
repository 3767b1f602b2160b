#include "maglead/controller/controller.hpp"
#include "maglead/controller/status_word.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace maglead::controller {
namespace {

using registers::Alarm;
using registers::DriveState;
using registers::Mode;
using registers::Reject;
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kStrokeMargin_m = 0.5e-3;  // beyond the stroke by this much is a fault
// Force mode looks this far ahead at the nut's speed: about the time the position loop takes to
// stop a sliding nut, so the hold lands inside the window.
constexpr double kWindowLookahead_s = 0.05;
// The look-ahead acts only this close to the window's end: a fast slide mid-stroke (a step of
// the setpoint) is the force loop's to stop, and its speed projected 50 ms would stop it early.
constexpr double kWindowNear_m = 5e-3;
// Towards a window end the nut may slide at most its distance to it over this time: an
// exponential approach whose braking force (mass × speed / time) stays small beside the load,
// so the force the observer keeps from the nut's last edge is the load's. Twice the look-ahead:
// a nut on that curve never trips it.
constexpr double kEndApproach_s = 2.0 * kWindowLookahead_s;
// On that curve the nut arrives this close to the end slow enough to hold at once (2 mm/s).
constexpr double kWindowArrive_m = 0.2e-3;
// The window's hold counts as settled once the nut stands this close to where it began: the
// position loop integrates only errors beyond it (quantization).
constexpr double kHoldSettled_counts = 1.5;
constexpr double kMaxTrack_rad = 0.5;  // most the phase tracking may add to a command
// A fault reset is done after the fault stayed away this long: longer than a CiA 402 drive's
// fault-reset handshake and the master's PDO supervision (a few cycles), short for a person.
constexpr double kResetConfirm_s = 0.02;
// After a slip a reset takes a phase that has stood still this long: a nut still sliding over
// the screw may pass through the stable branch and would latch again at once.
constexpr double kResetSettle_s = 0.1;
// "Stood still": within this share of the stable branch's width (encoder steps and a load's slow
// change stay inside it, a slip's lead does not).
constexpr double kStillBandShare = 0.25;
// A position command at the coupling's safe limit with the nut standing (its velocity estimate
// zero: no encoder edge for 0.2 s) this long more is a stall, not a slow start.
constexpr double kStallConfirm_s = 0.1;
constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }

}  // namespace

LoadObserverConfig observer_config(const ControllerConfig& c) {
  LoadObserverConfig o;
  o.calibration = c.calibration;
  o.coupling = c.coupling;
  o.friction = c.friction;
  o.lead_m = c.actuator.lead_m;
  o.linear_count_m = c.actuator.linear_count_m;
  o.stroke_min_m = c.actuator.stroke_min_m;
  o.stroke_max_m = c.actuator.stroke_max_m;
  o.model_uncertainty_n = c.observer_model_uncertainty_n;
  o.load_drift_n_per_s = c.load_drift_n_per_s;
  return o;
}

namespace {

// The configuration with the model's coupling gain folded into the calibration, so every use
// of the calibration in the loop sees the coupling the model describes.
ControllerConfig served(ControllerConfig c) {
  if (!c.coupling.valid())
    throw std::invalid_argument(
        "controller: the model's coupling gain must be positive, its ripple and end effect "
        "below 1");
  c.calibration = scaled(c.calibration, c.coupling.gain);
  c.coupling.gain = 1.0;
  return c;
}

ForceLoopConfig force_loop_config(const ControllerConfig& c, const LoadForceObserver& obs) {
  ForceLoopConfig f;
  f.friction = c.friction;
  f.damping_n_s_per_m = c.force_damping_n_s_per_m;
  f.breakaway_ramp_n_per_s = c.breakaway_ramp_n_per_s;
  f.tolerance_n = c.force_tol_n;
  f.speed_limit_m_s = c.force_speed_limit_m_s;
  // Land where a slide's bound still fits inside the tolerance, with room for the stop.
  f.land_tolerance_n = std::max(0.1, 0.5 * (c.force_tol_n - obs.sliding_half_width_n()));
  const double frac = c.actuator.safe_force_fraction;
  f.drive_min_n = frac * c.calibration.peak_pull_n;
  f.drive_max_n = frac * c.calibration.peak_push_n;
  return f;
}

}  // namespace

Controller::Controller(const ControllerConfig& config, ActuatorHardware& hardware)
    : cfg_(served(config)),
      hw_(hardware),
      velocity_(1.0 / cfg_.actuator.sample_rate_hz, cfg_.actuator.linear_count_m),
      estimator_(cfg_.calibration, cfg_.actuator.coulomb_n, 1e-4),
      observer_(observer_config(cfg_)),
      force_loop_(force_loop_config(cfg_, observer_)) {
  const auto& a = cfg_.actuator;
  const auto& cal = cfg_.calibration;
  if (!(a.sample_rate_hz > 0) || !(a.lead_m > 0) || !(a.gear_ratio > 0) ||
      !(a.stroke_max_m > a.stroke_min_m))
    throw std::invalid_argument("controller: actuator parameters are inconsistent");
  if (!(cal.peak_push_n > 0) || !(cal.peak_pull_n < 0) ||
      !(cal.stable_max_rad > cal.stable_min_rad))
    throw std::invalid_argument(
        "controller: calibration has no usable stable branch (derive_limits?)");
  if (!(a.safe_force_fraction > 0 && a.safe_force_fraction <= 1))
    throw std::invalid_argument("controller: safe_force_fraction must be in (0, 1]");
  if (!(cfg_.velocity_limit_m_s > 0) || !(cfg_.accel_limit_m_s2 > 0) || cfg_.watchdog_s < 0)
    throw std::invalid_argument("controller: limits must be positive, watchdog non-negative");
  if (!(cfg_.reactions.release_rate_n_per_s > 0) ||
      !std::isfinite(cfg_.reactions.release_rate_n_per_s))
    throw std::invalid_argument("controller: fault reaction release rate must be positive [N/s]");
  if (!(cfg_.force_stroke_margin_m >= 0) ||
      !(2.0 * cfg_.force_stroke_margin_m < a.stroke_max_m - a.stroke_min_m))
    throw std::invalid_argument(
        "controller: force_stroke_margin_m must leave a force window inside the stroke");
  // Position control may use the phase range of the safe forces, never more.
  const double f = a.safe_force_fraction * 0.999;
  phase_hi_rad_ = phase_for_output_force(cal, f * cal.peak_push_n, a.safe_force_fraction).phase_rad;
  phase_lo_rad_ = phase_for_output_force(cal, f * cal.peak_pull_n, a.safe_force_fraction).phase_rad;
  image_ = initial_image();
  vmax_ = cfg_.velocity_limit_m_s;
  amax_ = cfg_.accel_limit_m_s2;
  published_.store(s_);
}

CommandImage Controller::initial_image() const noexcept {
  CommandImage im;
  im.watchdog_s = cfg_.watchdog_s;
  im.velocity_limit_m_s = cfg_.velocity_limit_m_s;
  im.accel_limit_m_s2 = cfg_.accel_limit_m_s2;
  im.position_setpoint_m =
      std::clamp(0.5 * (cfg_.actuator.stroke_min_m + cfg_.actuator.stroke_max_m),
                 cfg_.actuator.stroke_min_m, cfg_.actuator.stroke_max_m);
  return im;
}

double Controller::safe_force_limit_n(double force_n) const noexcept {
  const auto& cal = cfg_.calibration;
  return cfg_.actuator.safe_force_fraction * (force_n >= 0.0 ? cal.peak_push_n : cal.peak_pull_n);
}

Controller::Window Controller::force_window() const noexcept {
  const auto& a = cfg_.actuator;
  return {a.stroke_min_m + cfg_.force_stroke_margin_m, a.stroke_max_m - cfg_.force_stroke_margin_m};
}

void Controller::reject(Reject why) noexcept {
  command_bits_ |= bit(registers::kRejected);
  s_.reject_reason = static_cast<std::uint16_t>(why);
}

void Controller::start_hold() noexcept {
  mode_ = Mode::idle;
  prof_pos_m_ = target_m_ = s_.nut_pos_m;
  prof_vel_m_s_ = 0.0;
  // Bumpless: start from the phase the nut sits at now.
  integral_rad_ = std::clamp(s_.phase_rad, phase_lo_rad_, phase_hi_rad_);
}

void Controller::controlled_stop() noexcept {
  if (mode_ == Mode::force) {
    start_hold();
    return;
  }
  // Decelerate the profile at the acceleration limit and hold where it comes to rest.
  target_m_ = prof_pos_m_ + prof_vel_m_s_ * std::abs(prof_vel_m_s_) / (2.0 * amax_);
  mode_ = Mode::idle;
}

FaultReaction Controller::configured_reaction(Alarm alarm) const noexcept {
  const auto& r = cfg_.reactions;
  switch (alarm) {
    case Alarm::watchdog:
      return r.watchdog;
    case Alarm::owner_lost:
      return r.owner_lost;
    case Alarm::sensor_fault:
      return r.sensor_fault;
    case Alarm::step_out:
    case Alarm::phase_jump:
      return r.step_out;
    default:
      return FaultReaction::hold;  // stroke limit, drive fault
  }
}

/// The drive fault's cause as the drive knows it now: a silent drive's process data time out
/// before its heartbeat does, so a later, more specific cause replaces the first.
void Controller::note_drive_fault_cause() noexcept {
  const DriveFaultDetail d = hw_.fault_detail();
  if (d.cause == DriveFaultCause::none) return;
  s_.drive_fault_cause = static_cast<std::uint16_t>(d.cause);
  s_.drive_error_code = d.error_code;
}

void Controller::latch_fault(Alarm alarm) noexcept {
  const bool first = state_ != DriveState::fault;
  if (first) {
    s_.alarm_code = static_cast<std::uint16_t>(alarm);
    s_.drive_fault_cause = s_.drive_error_code = 0;
  }
  if (s_.alarm_code == static_cast<std::uint16_t>(Alarm::drive_fault)) note_drive_fault_cause();
  state_ = DriveState::fault;
  const bool slipped = alarm == Alarm::step_out || alarm == Alarm::phase_jump;
  if (slipped)
    lead_rad_ = kTwoPi * std::round(s_.phase_rad / kTwoPi);  // the lead the nut is in now
  // A faulted or silent drive takes no command, whatever latched before or after it: what the
  // axis does is the drive's own reaction, and the controller keeps its last command.
  if (alarm == Alarm::drive_fault || reaction_ == registers::Reaction::drive_own) {
    reaction_ = registers::Reaction::drive_own;
    fault_position_hold_ = false;
    return;
  }
  if (!first && !slipped) return;  // the first fault's reaction goes on
  FaultReaction how = configured_reaction(alarm);
  if (how == FaultReaction::mode_default)
    how = mode_ == Mode::force ? FaultReaction::release : FaultReaction::hold;
  fault_position_hold_ = false;
  switch (how) {
    case FaultReaction::release:
    case FaultReaction::disable: {
      // Start from the force held now (its setpoint in force mode, else the estimate); past
      // the stable branch the force curve means nothing: release from zero at once.
      double f = mode_ == Mode::force ? drive_n_ - cfg_.friction.offset_n : s_.force_est_n;
      if (slipped || how == FaultReaction::disable || !std::isfinite(f)) f = 0.0;
      release_force_n_ = std::clamp(f, safe_force_limit_n(-1.0), safe_force_limit_n(1.0));
      reaction_ =
          release_force_n_ == 0.0 ? registers::Reaction::released : registers::Reaction::releasing;
      mode_ = Mode::idle;
      prof_pos_m_ = target_m_ = s_.nut_pos_m;
      prof_vel_m_s_ = 0.0;
      break;
    }
    default:
      reaction_ = registers::Reaction::holding;
      if (slipped) {
        // Stop commanding force: park the screw at the rest angle of the lead the nut is in now.
        screw_cmd_rad_ =
            rest_angle_rad(s_.nut_pos_m, cfg_.actuator.lead_m) + phase_offset_rad_ + lead_rad_;
        mode_ = Mode::idle;
        prof_pos_m_ = target_m_ = s_.nut_pos_m;
        prof_vel_m_s_ = 0.0;
      } else if (alarm == Alarm::sensor_fault || alarm == Alarm::following_error) {
        // Nothing measured, or a motor that does not follow: keep the last command.
      } else {
        controlled_stop();
        stopping_ = true;
        fault_position_hold_ = true;
      }
      break;
  }
}

void Controller::on_owner_lost() noexcept {
  if (state_ == DriveState::enabled) latch_fault(Alarm::owner_lost);
  // Nobody holds the levels any more: the next owner starts from a clear control word, so its
  // enable is a fresh edge.
  image_.control_word = 0;
}

void Controller::on_execute() noexcept {
  command_bits_ &= static_cast<std::uint16_t>(
      ~(bit(registers::kExecuteAck) | bit(registers::kExecuteDone) | bit(registers::kRejected)));
  s_.reject_reason = 0;
  execute_pending_ = false;
  if (state_ == DriveState::fault) return reject(Reject::in_fault);
  if (state_ != DriveState::enabled) return reject(Reject::not_enabled);
  if (image_.control_word & bit(registers::kStop)) return reject(Reject::stopped);
  const auto& a = cfg_.actuator;
  ref_move_.cancel();
  switch (static_cast<Mode>(image_.mode_command)) {
    case Mode::idle:
      controlled_stop();
      break;
    case Mode::position: {
      const double target = image_.position_setpoint_m;
      if (!(target >= a.stroke_min_m && target <= a.stroke_max_m))
        return reject(Reject::target_outside_stroke);
      // From force mode, or from a stall short of the last target: the move starts where the
      // nut stands, not where the profile ran ahead.
      if (mode_ == Mode::force || position_limited_) start_hold();
      vmax_ = image_.velocity_limit_m_s;
      amax_ = image_.accel_limit_m_s2;
      target_m_ = target;
      mode_ = Mode::position;
      break;
    }
    case Mode::force: {
      const auto inv =
          phase_for_output_force(cfg_.calibration, image_.force_setpoint_n, a.safe_force_fraction);
      if (inv.status != InverseStatus::ok) return reject(Reject::force_beyond_safe_limit);
      force_set_n_ = image_.force_setpoint_n;
      start_force_loop(mode_ != Mode::force || window_end_ != 0);
      prof_vel_m_s_ = 0.0;  // force mode runs no profile: a move it interrupts has ended
      mode_ = Mode::force;
      break;
    }
    case Mode::reference_move:
      if (!ref_move_.start(cfg_.reference_move, a.stroke_min_m, a.stroke_max_m))
        return reject(Reject::target_outside_stroke);
      if (mode_ == Mode::force) start_hold();
      mode_ = Mode::position;
      next_reference_leg();
      break;
    default:
      return reject(Reject::not_enabled);  // unreachable: the server range-checks mode_command
  }
  settled_s_ = 0.0;
  execute_pending_ = true;
  command_bits_ |= bit(registers::kExecuteAck);
}

void Controller::apply(const Command& c) noexcept {
  if (c.owner_lost) on_owner_lost();
  const std::uint16_t old_cw = image_.control_word;
  const std::uint16_t new_cw = c.image.control_word;
  const auto rising = static_cast<std::uint16_t>(new_cw & ~old_cw);
  const auto falling = static_cast<std::uint16_t>(old_cw & ~new_cw);
  if (c.image.watchdog_s != image_.watchdog_s) last_heartbeat_s_ = s_.t_s;  // fresh start
  image_ = c.image;
  if (c.heartbeat) last_heartbeat_s_ = s_.t_s;

  if (falling & bit(registers::kEnable) && state_ == DriveState::enabled) {
    state_ = DriveState::ready;
    start_hold();  // a move cut short ends here: no profile left running (the moving bit)
  }
  if (rising & bit(registers::kEnable) && state_ == DriveState::ready) {
    state_ = DriveState::enabled;
    last_heartbeat_s_ = s_.t_s;
    start_hold();
  }
  if (falling & bit(registers::kExecute))
    command_bits_ &= static_cast<std::uint16_t>(~bit(registers::kExecuteAck));
  if (falling & bit(registers::kFaultReset))
    command_bits_ &= static_cast<std::uint16_t>(~bit(registers::kResetAck));
  if (falling & bit(registers::kResync))
    command_bits_ &= static_cast<std::uint16_t>(~bit(registers::kResyncAck));

  if (rising & bit(registers::kResync)) {
    command_bits_ &=
        static_cast<std::uint16_t>(~(bit(registers::kResyncDone) | bit(registers::kRejected)));
    s_.reject_reason = 0;  // a reason stays only while its command is the last one
    if (!stepped_out_) {
      reject(Reject::not_stepped_out);
    } else {
      resync_to_nut();
      command_bits_ |=
          static_cast<std::uint16_t>(bit(registers::kResyncAck) | bit(registers::kResyncDone));
    }
  }
  if (rising & bit(registers::kFaultReset)) on_fault_reset();
  if (rising & bit(registers::kExecute)) on_execute();
}

/// The nut now sits in some lead: take that lead as the new zero of φ, and start the twin and the
/// observer again from where the nut is.
void Controller::resync_to_nut() noexcept {
  const double leads = std::round(s_.phase_rad / kTwoPi);
  phase_offset_rad_ += leads * kTwoPi;
  s_.phase_rad -= leads * kTwoPi;
  last_phase_rad_ = s_.phase_rad;
  steady_phase_rad_ -= leads * kTwoPi;
  if (twin_) twin_->resync(s_.t_s, s_.screw_angle_rad, s_.nut_pos_m);
  observer_.reset();
}

/// A fault reset edge: acknowledged at once; done when the fault has stayed away for
/// kResetConfirm_s (confirm_reset), so a drive whose cause persists is never reported reset.
void Controller::on_fault_reset() noexcept {
  command_bits_ &=
      static_cast<std::uint16_t>(~(bit(registers::kResetDone) | bit(registers::kRejected)));
  s_.reject_reason = 0;
  // The operator has seen the twin's latched drift warning: clear it (README "Digital twin").
  if (twin_) twin_->clear_warnings();
  const auto& cal = cfg_.calibration;
  const bool stood_still = !stepped_out_ || s_.t_s - phase_steady_since_s_ >= kResetSettle_s;
  const bool phase_ok =
      s_.phase_rad >= cal.stable_min_rad && s_.phase_rad <= cal.stable_max_rad && stood_still;
  if (state_ == DriveState::fault && !phase_ok) {
    reject(Reject::still_faulty);
    return;
  }
  command_bits_ |= bit(registers::kResetAck);
  if (state_ != DriveState::fault) {  // nothing latched: done, unless a reset is still confirming
    if (reset_confirm_cycles_ == 0) command_bits_ |= bit(registers::kResetDone);
    return;
  }
  state_ = DriveState::ready;  // re-enabling needs a fresh enable edge
  // A step-out the release brought back onto the stable branch needs no resync of φ (no whole
  // lead to take), but the twin still holds its step-out: start it again as a resync would.
  if (stepped_out_) resync_to_nut();
  s_.alarm_code = s_.drive_fault_cause = s_.drive_error_code = 0;
  stepped_out_ = watchdog_expired_ = stopping_ = false;
  mode_ = Mode::idle;
  reaction_ = registers::Reaction::none;
  fault_position_hold_ = false;
  lead_rad_ = 0.0;
  last_heartbeat_s_ = s_.t_s;
  drive_reset_pending_ = true;  // the drive's own fault clears with ours
  reset_confirm_cycles_ =
      std::max(1, static_cast<int>(std::ceil(kResetConfirm_s * cfg_.actuator.sample_rate_hz)));
}

/// A reset in confirmation: a fault latched again is its answer (rejected, fault_returned);
/// otherwise done when the cycles are up and the drive has finished its own reset.
void Controller::confirm_reset() noexcept {
  if (reset_confirm_cycles_ == 0) return;
  if (state_ == DriveState::fault) {
    reset_confirm_cycles_ = 0;
    reject(Reject::fault_returned);
    return;
  }
  if (reset_confirm_cycles_ > 1) {
    --reset_confirm_cycles_;
  } else if (!hw_.resetting()) {
    reset_confirm_cycles_ = 0;
    command_bits_ |= bit(registers::kResetDone);
  }
}

void Controller::run_profile(double dt) noexcept {
  const double dist = target_m_ - prof_pos_m_;
  if (dist == 0.0 && prof_vel_m_s_ == 0.0) return;
  // Online trapezoid: accelerate towards the speed from which braking at amax just reaches
  // the target, capped at vmax. Braking in steps of amax·dt covers v²/2a + v·dt/2: solved for v,
  // so the profile stops at the target instead of a step past it.
  const double v_brake =
      amax_ * (std::sqrt(dt * dt / 4.0 + 2.0 * std::abs(dist) / amax_) - dt / 2.0);
  const double v_des = std::copysign(std::min(vmax_, v_brake), dist);
  const double dv = std::clamp(v_des - prof_vel_m_s_, -amax_ * dt, amax_ * dt);
  prof_vel_m_s_ += dv;
  prof_pos_m_ += prof_vel_m_s_ * dt;
  const double left = target_m_ - prof_pos_m_;
  if ((left * dist <= 0.0 || std::abs(left) < 1e-8) &&
      std::abs(prof_vel_m_s_) <= 2.0 * amax_ * dt + 1e-6) {
    prof_pos_m_ = target_m_;
    prof_vel_m_s_ = 0.0;
    next_reference_leg();
  }
}

bool Controller::next_reference_leg() noexcept {
  if (mode_ != Mode::position) ref_move_.cancel();  // a stop or a fault ended it
  ReferenceMove::Leg leg;
  if (!ref_move_.next(leg)) return false;
  target_m_ = leg.target_m;
  vmax_ = leg.speed_m_s;
  amax_ = ref_move_.accel_m_s2();
  return true;
}

double Controller::position_command_rad(double dt) noexcept {
  return position_command_rad(dt, phase_lo_rad_, phase_hi_rad_);
}

/// The position loop with its phase command kept within [lo_rad, hi_rad] (at most the safe range).
double Controller::position_command_rad(double dt, double lo_rad, double hi_rad) noexcept {
  const auto& a = cfg_.actuator;
  const double gain_rad_per_m = kTwoPi / a.lead_m + cfg_.position_gain_rad_per_m;
  if (!waiting_for_nut(gain_rad_per_m)) run_profile(dt);
  const double err = prof_pos_m_ - s_.nut_pos_m;
  // Integrate only errors beyond one encoder count (within it the error is quantization), and
  // not while the command is at the safe limit the error pushes towards (windup).
  const bool pushing_limit = position_clamped_ && (err > 0) == (integral_rad_ > 0);
  if (std::abs(err) > 1.5 * a.linear_count_m && !pushing_limit)
    integral_rad_ =
        std::clamp(integral_rad_ + cfg_.position_integral_rad_per_m_s * err * dt, lo_rad, hi_rad);
  const double wanted_rad = gain_rad_per_m * err + integral_rad_;
  const double phase = std::clamp(wanted_rad, lo_rad, hi_rad);
  position_clamped_ = phase != wanted_rad;
  position_phase_rad_ = phase;
  return rest_angle_rad(s_.nut_pos_m, a.lead_m) + phase_offset_rad_ + phase;
}

/// A nut the coupling cannot keep up with (the command at its safe limit) is waited for: the
/// profile's clock stops while it leads by more than the error that saturates the command, so
/// it brakes where the nut is and a move at the drive's limits stops at its target.
bool Controller::waiting_for_nut(double gain_rad_per_m) const noexcept {
  if (!position_clamped_ || prof_vel_m_s_ == 0.0) return false;
  const double way = prof_vel_m_s_ > 0.0 ? 1.0 : -1.0;
  const double lead_max_m = (way > 0.0 ? phase_hi_rad_ : -phase_lo_rad_) / gain_rad_per_m;
  return (prof_pos_m_ - s_.nut_pos_m) * way > lead_max_m;
}

/// The phase whose coupling force gives `drive_n` on the nut: the drive is the coupling force
/// plus the model's offset, and the calibration gives F_m. Within the safe phase range; a drive
/// beyond the coupling's peak takes the range's end on its side, one not finite none.
double Controller::phase_for_drive_rad(double drive_n) const noexcept {
  const auto inv = phase_for_output_force(cfg_.calibration, drive_n - cfg_.friction.offset_n, 1.0);
  const double phase = inv.status == InverseStatus::ok ? inv.phase_rad
                       : !std::isfinite(drive_n)       ? 0.0  // no drive known: no force
                       : inv.limit_n > 0               ? phase_hi_rad_
                                                       : phase_lo_rad_;
  return std::clamp(phase, phase_lo_rad_, phase_hi_rad_);
}

double Controller::force_command_rad(double dt) noexcept {
  const auto& a = cfg_.actuator;
  drive_n_ = force_loop_.drive_n(load_, dt);
  const double phase = phase_for_drive_rad(drive_n_);
  // The motor's servo lags a moving nut (a phase error that grows with speed and acts like
  // strong viscous friction): integrate the phase the coupling misses into the command.
  phase_track_rad_ =
      std::clamp(phase_track_rad_ + cfg_.phase_tracking_per_s * dt * (phase - s_.phase_rad),
                 -kMaxTrack_rad, kMaxTrack_rad);
  const double cmd = std::clamp(phase + phase_track_rad_, phase_lo_rad_, phase_hi_rad_);
  return rest_angle_rad(s_.nut_pos_m, a.lead_m) + phase_offset_rad_ + cmd;
}

void Controller::publish_observer() noexcept {
  s_.observer_force_n = load_.force_n;
  s_.observer_force_lo_n = load_.lo_n;
  s_.observer_force_hi_n = load_.hi_n;
  s_.observer_basis = static_cast<std::uint16_t>(load_.basis);
  s_.force_loop_state = static_cast<std::uint16_t>(
      window_end_ != 0 ? ForceLoopState::held_at_stroke_end : force_loop_.state());
  s_.force_reached_reason = static_cast<std::uint16_t>(
      window_end_ != 0 ? ForceReachedReason::stroke_end : force_loop_.reason(load_));
}

// ---------------------------------------------------------------------------- the cycle
// step() runs the stages in order: clock, read, commands, twin, supervise, control by state,
// write, publish. Each stage is one function below.

CycleStatus Controller::step(double now_s, double late_s) noexcept {
  const double dt = advance_clock(now_s, late_s);
  SensorSample sample;
  const HwStatus hs = hw_.read_sensors(now_s, sample);
  CycleStatus status = CycleStatus::ok;
  if (hs != HwStatus::ok) {
    latch_fault(hs == HwStatus::sensor_fault      ? Alarm::sensor_fault
                : hs == HwStatus::following_error ? Alarm::following_error
                                                  : Alarm::drive_fault);
    status = CycleStatus::hardware_error;
  } else {
    read_measurements(now_s, sample);
  }
  take_commands();
  step_twin(now_s);
  if (status == CycleStatus::ok) supervise(now_s);
  last_phase_rad_ = s_.phase_rad;
  const Reached reached = control_by_state(dt);
  if (mode_ != Mode::force || state_ != DriveState::enabled) {
    force_loop_.stop();
    window_end_ = 0;
    observer_.position_hold(false);
  }
  if (mode_ == Mode::force || state_ != DriveState::enabled) {
    position_limited_ = false;
    stall_s_ = 0.0;  // a stall is judged afresh on the next position command
  }
  publish_observer();
  const bool settled = settle(reached, dt);
  if (update_power() != HwStatus::ok) {
    latch_fault(Alarm::drive_fault);
    status = CycleStatus::hardware_error;
  }
  // Also after a sensor fault: the reaction then works from the last good measurement.
  if (hs != HwStatus::drive_fault &&
      hw_.write_motor_angle(screw_cmd_rad_ * cfg_.actuator.gear_ratio) != HwStatus::ok) {
    latch_fault(Alarm::drive_fault);
    status = CycleStatus::hardware_error;
  }
  confirm_reset();
  publish(settled, reached);
  return status;
}

double Controller::advance_clock(double now_s, double late_s) noexcept {
  const double nominal = 1.0 / cfg_.actuator.sample_rate_hz;
  double dt = synced_ ? now_s - last_t_s_ : nominal;
  if (!(dt > 0.0)) dt = nominal;
  last_t_s_ = now_s;
  s_.t_s = now_s;
  s_.cycle++;
  s_.period_s = dt;
  if (late_s > nominal) s_.overrun_count++;
  s_.late_max_s = std::max(s_.late_max_s, late_s);
  return dt;
}

void Controller::read_measurements(double now_s, const SensorSample& sample) noexcept {
  const auto& a = cfg_.actuator;
  const double screw =
      screw_angle_rad_from_motor_rad(motor_angle_rad_from_counts(sample.motor_counts, a), a);
  const double pos = nut_pos_m_from_counts(sample.linear_counts, a);
  if (!synced_) {
    // At power-up the coupling is taken to be at rest within its lead.
    phase_offset_rad_ = kTwoPi * std::round(phase_rad(screw, pos, a.lead_m) / kTwoPi);
    velocity_.reset(pos);
    recent_count_ = 0;
    screw_cmd_rad_ = screw;
    last_heartbeat_s_ = now_s;
    state_ = DriveState::ready;
    synced_ = true;
    s_.actuator_read = true;
    if (twin_) twin_->resync(now_s, screw, pos);
    observer_.reset();
  }
  s_.screw_angle_rad = screw;
  s_.nut_pos_m = pos;
  s_.phase_rad = phase_rad(screw, pos, a.lead_m) - phase_offset_rad_;
  s_.nut_vel_m_s = velocity_.update(pos);
  update_mean_speed(now_s, pos);
  s_.force_est_n = estimator_.output_force_n(s_.phase_rad, s_.nut_vel_m_s);
  // NaN without a load cell (the cia402 backend): the f32 register carries it so that a client
  // can say "none" rather than show 0 N; the i32 register reads 0, as documented.
  s_.load_cell_force_n = -sample.load_force_n;
  load_cell_reading_n_ = sample.load_force_n;  // the twin's load-cell check only, never its flag
  // Under force control the load is what the loop presses; else loads come and go.
  load_ = observer_.update(now_s, s_.phase_rad, s_.nut_pos_m,
                           mode_ == Mode::force ? LoadForceObserver::kPassiveLoad : 0.0);
}

/// The nut's mean speed over the last kMeanSpeedSamples samples (fewer after start-up), by
/// their times: a late cycle is a longer step, not a faster nut.
void Controller::update_mean_speed(double t_s, double pos_m) noexcept {
  const int size = kMeanSpeedSamples + 1;
  recent_[static_cast<std::size_t>(recent_next_)] = {t_s, pos_m};
  recent_next_ = (recent_next_ + 1) % size;
  recent_count_ = std::min(recent_count_ + 1, size);
  const auto& oldest =
      recent_[static_cast<std::size_t>((recent_next_ - recent_count_ + size) % size)];
  const double span_s = t_s - oldest.t_s;
  mean_vel_m_s_ = span_s > 0.0 ? (pos_m - oldest.pos_m) / span_s : 0.0;
}

void Controller::take_commands() noexcept {
  if (owner_lost_flag_.exchange(false, std::memory_order_acquire)) on_owner_lost();
  Command c;
  // A bounded number per cycle: a flood of writes cannot stretch the cycle.
  for (int i = 0; i < kCommandsPerCycle && commands_.pop(c); ++i) apply(c);
}

void Controller::step_twin(double now_s) noexcept {
  TwinReport tw{};
  if (twin_) {
    const TwinSample in{
        s_.cycle,
        now_s,
        s_.screw_angle_rad,
        screw_cmd_rad_,
        s_.nut_pos_m,
        s_.nut_vel_m_s,
        s_.phase_rad,
        s_.force_est_n,
        mode_ == Mode::force ? force_set_n_ : std::numeric_limits<double>::quiet_NaN(),
        load_cell_reading_n_,
        ref_move_.active() && mode_ == Mode::position};
    twin_->step(in, tw);
  }
  s_.twin = tw;
}

/// Supervision, in order of severity: step-out, stroke, watchdog, the stop bit.
void Controller::supervise(double now_s) noexcept {
  const auto& a = cfg_.actuator;
  const auto& cal = cfg_.calibration;
  const bool outside = s_.phase_rad < cal.stable_min_rad || s_.phase_rad > cal.stable_max_rad;
  if (std::abs(s_.phase_rad - steady_phase_rad_) >
      kStillBandShare * (cal.stable_max_rad - cal.stable_min_rad)) {
    steady_phase_rad_ = s_.phase_rad;
    phase_steady_since_s_ = now_s;
  }
  if (outside && !stepped_out_) {
    stepped_out_ = true;
    s_.step_out_count++;
    latch_fault(std::abs(s_.phase_rad - last_phase_rad_) > std::numbers::pi ? Alarm::phase_jump
                                                                            : Alarm::step_out);
  }
  // Beyond the stroke, only motion further out is a fault: a nut found there (pushed by hand,
  // a step-out) may be enabled and moved back inside, as a drive at a limit switch allows.
  const int beyond = s_.nut_pos_m > a.stroke_max_m + kStrokeMargin_m   ? 1
                     : s_.nut_pos_m < a.stroke_min_m - kStrokeMargin_m ? -1
                                                                       : 0;
  if (beyond != 0 && beyond * s_.nut_vel_m_s > 0.0 && state_ == DriveState::enabled)
    latch_fault(Alarm::stroke_limit);
  if (state_ == DriveState::enabled && image_.watchdog_s > 0.0 &&
      now_s - last_heartbeat_s_ > image_.watchdog_s) {
    watchdog_expired_ = true;
    latch_fault(Alarm::watchdog);
  }
  const bool stop_bit = image_.control_word & bit(registers::kStop);
  if (state_ == DriveState::enabled) {
    if (stop_bit && !stopping_) controlled_stop();
    // A drive's quick stop may have stopped the nut short of the profile's end: hold where it
    // stands rather than pull it there unprofiled.
    if (!stop_bit && stopping_ && prof_vel_m_s_ == 0.0) prof_pos_m_ = target_m_ = s_.nut_pos_m;
    stopping_ = stop_bit;
  }
}

/// The power stage follows the drive state: enabled → enable (quick stop while the stop bit
/// holds), ready → disable. A fault keeps what the stage had but ends a quick stop: its reaction
/// (release, hold) needs the motor. The fault reset passes on to the drive, which then stays
/// disabled until the next enable.
HwStatus Controller::update_power() noexcept {
  PowerRequest want = power_;
  const bool reset = drive_reset_pending_;  // every reset goes on, a repeated one too
  drive_reset_pending_ = false;
  if (reset) {
    want = PowerRequest::fault_reset;
  } else if (state_ == DriveState::enabled) {
    want = stopping_ ? PowerRequest::quick_stop : PowerRequest::enable;
  } else if (state_ == DriveState::fault) {
    if (power_ == PowerRequest::quick_stop) want = PowerRequest::enable;
  } else if (power_ != PowerRequest::fault_reset) {
    want = PowerRequest::disable;
  }
  if (want == power_ && !reset) return HwStatus::ok;
  power_ = want;
  return hw_.set_power(want);
}

/// The screw command of this cycle by drive state and mode; what the mode reached.
Controller::Reached Controller::control_by_state(double dt) noexcept {
  Reached r;
  switch (state_) {
    case DriveState::disabled:
    case DriveState::ready:
      break;  // hold the last command
    case DriveState::enabled:
      if (mode_ == Mode::force) {
        screw_cmd_rad_ = force_mode_command_rad(dt, r);
      } else {
        screw_cmd_rad_ = position_command_rad(dt);
        r.position = prof_pos_m_ == target_m_ && prof_vel_m_s_ == 0.0 &&
                     std::abs(target_m_ - s_.nut_pos_m) <= cfg_.in_position_tol_m;
        update_position_limit(dt);
      }
      break;
    case DriveState::fault:
      fault_reaction_command(dt);
      break;
  }
  return r;
}

/// The coupling at its safe limit with the nut stalled short of the profile: the load needs
/// more force than the safe fraction allows. Said (force_limited, in_position_reason
/// coupling_limit), no fault: the command stays at the limit and the next setpoint is taken.
void Controller::update_position_limit(double dt) noexcept {
  const bool stalled = position_clamped_ && s_.nut_vel_m_s == 0.0 &&
                       std::abs(prof_pos_m_ - s_.nut_pos_m) > cfg_.in_position_tol_m;
  stall_s_ = stalled ? stall_s_ + dt : 0.0;
  position_limited_ = stall_s_ >= kStallConfirm_s;
}

/// Why in_position is clear: not holding a position, the profile running, settling, or the
/// coupling's limit.
InPositionReason Controller::in_position_reason(bool settled, const Reached& r) const noexcept {
  using R = InPositionReason;
  if (state_ != DriveState::enabled || mode_ == Mode::force) return R::not_holding;
  if (settled && r.position) return R::reached;
  if (position_limited_) return R::coupling_limit;
  return prof_pos_m_ != target_m_ || prof_vel_m_s_ != 0.0 ? R::moving : R::settling;
}

/// Force mode: the force loop, unless the nut heads past the force window's end; then the
/// position loop holds it there until the next setpoint.
/// The force loop towards force_set_n_; `afresh` from a position hold: from the phase the nut has.
void Controller::start_force_loop(bool afresh) noexcept {
  if (afresh) {
    drive_n_ = load_.drive_n;
    phase_track_rad_ = 0.0;
  }
  force_loop_.start(force_set_n_, drive_n_, load_);
  window_end_ = 0;
  observer_.position_hold(false);
}

double Controller::force_mode_command_rad(double dt, Reached& r) noexcept {
  if (window_end_ == 0)
    check_force_window();
  else
    release_window_end();
  if (window_end_ != 0) return window_hold_command_rad(dt);
  const auto [lo, hi] = force_window();
  force_loop_.set_speed_caps(std::max(0.0, hi - s_.nut_pos_m) / kEndApproach_s,
                             std::max(0.0, s_.nut_pos_m - lo) / kEndApproach_s);
  const double cmd = force_command_rad(dt);
  r.force = force_loop_.reason(load_) == ForceReachedReason::reached;
  return cmd;
}

/// A nut whose position a moment ahead lies past the window, moving outwards, is held where it
/// is (inside the window): the push ends as a defined outcome, not a stroke_limit fault.
void Controller::check_force_window() noexcept {
  const auto [lo, hi] = force_window();
  const double p = s_.nut_pos_m, v = mean_vel_m_s_;
  const double ahead = p + v * kWindowLookahead_s;
  // Only a nut the loop drives outwards is held (its setpoint beyond the load that way); one
  // still coasting out while the setpoint calls it back is left to the loop.
  const bool up = v > 0.0 && force_set_n_ > load_.force_n &&
                  (p >= hi - kWindowArrive_m || (ahead >= hi && p >= hi - kWindowNear_m));
  const bool down = v < 0.0 && force_set_n_ < load_.force_n &&
                    (p <= lo + kWindowArrive_m || (ahead <= lo && p <= lo + kWindowNear_m));
  window_end_ = up ? 1 : down ? -1 : 0;
  if (window_end_ == 0) return;
  // The position loop stops the nut now: that stop is its braking, not the load (2 to 17 N off
  // on a free nut stopped from 30 to 60 mm/s); the observer learns nothing from it.
  observer_.position_hold(true);
  hold_at_setpoint_ = hold_settled_ = false;
  target_m_ = prof_pos_m_ = std::clamp(s_.nut_pos_m, lo, hi);
  prof_vel_m_s_ = 0.0;
  integral_rad_ = 0.0;
}

/// Held at a window's end, the hold lasts only while the force error asks for motion towards
/// that end. A load that presses harder from outside pushes the nut off the end against the
/// hold's drive, which is at most the setpoint's (window_hold_command_rad): once it slides away
/// with the hold at that drive and the observer's load force past the setpoint, the force loop
/// takes over at once. A nut still coasting out, stopping, or pulled back by the hold itself is
/// not released: while it stops the sliding estimate carries its braking, not the load.
void Controller::release_window_end() noexcept {
  const bool pushed_off = load_.motion == -window_end_ && hold_at_setpoint_;
  if (pushed_off && (force_set_n_ - load_.force_n) * window_end_ < 0.0) start_force_loop(true);
}

/// The hold at a window's end: the position loop, but never pushing towards that end harder
/// than the setpoint asks (the force loop's drive for it). A load pressing back harder than the
/// setpoint and the nut's break-away then moves the nut off the end, and the observer sees the
/// slide and the load's force: a stiffer hold would stand, and no one would know the load.
double Controller::window_hold_command_rad(double dt) noexcept {
  const double set_rad = phase_for_drive_rad(force_set_n_);
  // Only once the nut stands where the hold began (within the position loop's quantization):
  // stopping it and taking it back there may need more, and the force the observer keeps is
  // the one it stops with.
  hold_settled_ = hold_settled_ ||
                  (load_.motion == 0 && std::abs(target_m_ - s_.nut_pos_m) <=
                                            kHoldSettled_counts * cfg_.actuator.linear_count_m);
  if (!hold_settled_) return position_command_rad(dt);
  const double cmd = position_command_rad(dt, window_end_ < 0 ? set_rad : phase_lo_rad_,
                                          window_end_ > 0 ? set_rad : phase_hi_rad_);
  hold_at_setpoint_ = position_phase_rad_ == set_rad;
  return cmd;
}

/// The fault reaction's own state machine: releasing (ramp the output force to zero) →
/// released (keep it there: the screw follows the nut); or hold (the controlled stop continues,
/// then holds); none leaves the last command.
void Controller::fault_reaction_command(double dt) noexcept {
  const auto& a = cfg_.actuator;
  if (reaction_ == registers::Reaction::releasing || reaction_ == registers::Reaction::released) {
    const double step = cfg_.reactions.release_rate_n_per_s * dt;
    release_force_n_ = std::abs(release_force_n_) <= step
                           ? 0.0
                           : release_force_n_ - std::copysign(step, release_force_n_);
    if (release_force_n_ == 0.0) reaction_ = registers::Reaction::released;
    const auto inv =
        phase_for_output_force(cfg_.calibration, release_force_n_, a.safe_force_fraction);
    const double phase = inv.status == InverseStatus::ok ? inv.phase_rad : 0.0;
    screw_cmd_rad_ = rest_angle_rad(s_.nut_pos_m, a.lead_m) + phase_offset_rad_ + lead_rad_ + phase;
  } else if (fault_position_hold_) {
    screw_cmd_rad_ = position_command_rad(dt);
  }
}

/// A target counts as reached once it has held for settle_s; the execute handshake's done then.
bool Controller::settle(const Reached& r, double dt) noexcept {
  const bool reached = r.position || r.force;
  settled_s_ = reached ? settled_s_ + dt : 0.0;
  const bool settled = reached && settled_s_ >= cfg_.settle_s;
  if (execute_pending_ && settled) {
    command_bits_ |= bit(registers::kExecuteDone);
    execute_pending_ = false;
  }
  if (state_ != DriveState::enabled) execute_pending_ = false;
  return settled;
}

void Controller::publish(bool settled, const Reached& r) noexcept {
  const auto& a = cfg_.actuator;
  const auto& tw = s_.twin;
  s_.status_word = pack_status_word(
      {state_, s_.nut_vel_m_s != 0.0 || prof_vel_m_s_ != 0.0, settled && r.position,
       settled && r.force, stepped_out_, tw.drift_warning, watchdog_expired_, tw.healthy,
       tw.step_out_warning, stopping_,
       s_.nut_pos_m <= a.stroke_min_m || s_.nut_pos_m >= a.stroke_max_m, tw.lagging,
       window_end_ != 0 || position_limited_ ||
           force_loop_.state() == ForceLoopState::speed_limited ||
           (force_loop_.drive_limited() &&
            s_.force_reached_reason ==
                static_cast<std::uint16_t>(ForceReachedReason::drive_limit))});
  s_.in_position_reason = static_cast<std::uint16_t>(in_position_reason(settled, r));
  // Inside the tolerance, force_reached still clear: the dwell runs (reached only with the bit).
  if (r.force && !settled)
    s_.force_reached_reason = static_cast<std::uint16_t>(ForceReachedReason::settling);
  s_.drive_state = static_cast<std::uint16_t>(state_);
  s_.active_mode = static_cast<std::uint16_t>(mode_);
  s_.command_status = command_bits_;
  s_.profile_pos_m = prof_pos_m_;
  s_.active_force_setpoint_n = mode_ == Mode::force ? force_set_n_ : 0.0;
  s_.fault_reaction = static_cast<std::uint16_t>(
      state_ == DriveState::fault ? reaction_ : registers::Reaction::none);
  s_.active_target_pos_m = target_m_;
  published_.store(s_);
}

}  // namespace maglead::controller
