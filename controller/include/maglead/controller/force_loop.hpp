#pragma once
// The force loop: puts the setpoint on the load, not just on the coupling.
//
// While the nut slides the coupling must carry friction and damping besides the load, so the
// loop commands F_set + F_f(v) − D·v: friction fed forward from the model, damping D so the nut
// creeps into the load without overshoot. Near the setpoint (|F_set − F̂| ≤ land tolerance) it
// drops the friction feed-forward and the nut stops at once, with the load force where it was.
// Stuck, the load keeps that force whatever the phase does inside the stick band, so the loop
// holds the coupling at the observer's load force (the band's centre: most margin both ways).
// A stuck nut whose load force is off, or unknown, is broken loose by a ramp that starts at the
// lowest drive that could move it towards the setpoint. Sliding towards the setpoint, the drive
// never exceeds the one that keeps the nut at the speed limit (the load force plus friction,
// with the damping D acting on the speed's distance from the limit), so a push into nothing does
// not race to the stroke's end. No allocation: loop thread.
#include <cstdint>
#include <limits>

#include "maglead/physics/friction_model.hpp"
#include "maglead/physics/load_observer.hpp"

namespace maglead::controller {

/// What the force loop is doing (input register force_loop_state).
enum class ForceLoopState : std::uint8_t {
  off = 0,                 // not in force mode
  breaking_away = 1,       // stuck off the setpoint (or unknown): ramping the drive until it moves
  approaching = 2,         // sliding towards the setpoint with friction feed-forward and damping
  landing = 3,             // came within the land tolerance: feed-forward off, friction stops it
  holding = 4,             // stuck with the load force at the setpoint: coupling held mid-band
  holding_no_motion = 5,   // the setpoint was already inside the known load-force bound
  blocked = 6,             // the ramp reached twice the model's break-away without motion
  held_at_stroke_end = 7,  // the controller holds the nut at its force window's end
  speed_limited = 8,       // sliding towards the setpoint at the force mode's speed limit
};

/// Why force_reached is clear (input register force_reached_reason).
enum class ForceReachedReason : std::uint8_t {
  reached = 0,
  not_force_mode = 1,
  load_force_off = 2,  // the observer's load force is outside the tolerance
  bound_unknown = 3,   // nothing pins the load force down (start-up, or the load changed)
  bound_too_wide = 4,  // the bound is wider than the tolerance allows (model uncertainty)
  moving = 5,          // the nut slides: the load force is still changing
  settling = 6,        // inside the tolerance, the dwell is running
  stroke_end = 7,      // the force window ended before the force (the controller holds there)
  speed_limit = 8,     // the nut slides at the force mode's speed limit towards the setpoint
  drive_limit = 9,     // the coupling is at its safe limit, the nut stuck short of the setpoint
};

struct ForceLoopConfig {
  FrictionModel friction;
  double damping_n_s_per_m = 60.0;        // D: damps a 10 kN/m load on a 0.12 kg nut (ζ ≈ 0.9)
  double breakaway_ramp_n_per_s = 200.0;  // drive ramp while breaking a stuck nut loose
  double tolerance_n = 1.5;               // force_reached tolerance
  double land_tolerance_n = 0.4;          // drop the feed-forward within this of the setpoint
  double drive_min_n = -35.0, drive_max_n = 35.0;  // safe coupling forces
  double speed_limit_m_s = 0.1;  // the fastest the loop lets the nut slide towards the setpoint
};

class ForceLoop {
 public:
  /// Throws std::invalid_argument on non-positive gains or an empty drive range.
  explicit ForceLoop(const ForceLoopConfig& config);
  /// A new setpoint (execute edge): `drive_now_n` is the coupling drive the nut sits at.
  void start(double setpoint_n, double drive_now_n, const LoadEstimate& est) noexcept;
  void stop() noexcept { state_ = ForceLoopState::off; }
  /// The coupling drive F_m + F_offset to command this cycle.
  double drive_n(const LoadEstimate& est, double dt_s) noexcept;
  /// True when the observer's whole bound lies inside setpoint ± tolerance.
  bool bound_inside_tolerance(const LoadEstimate& est) const noexcept;
  /// Why force_reached would be clear now (reached when it is not).
  ForceReachedReason reason(const LoadEstimate& est) const noexcept;
  ForceLoopState state() const noexcept { return state_; }
  /// The drive asked for is beyond the safe range [drive_min_n, drive_max_n] and clamped to it.
  bool drive_limited() const noexcept { return drive_limited_; }
  double setpoint_n() const noexcept { return setpoint_n_; }
  /// This cycle's speed limits towards +p and −p where they are below the configured one (the
  /// controller's, slowing the nut before its force window ends); +inf where not.
  void set_speed_caps(double up_m_s, double down_m_s) noexcept {
    cap_up_m_s_ = up_m_s, cap_down_m_s_ = down_m_s;
  }

 private:
  double breakaway_drive_n(const LoadEstimate& est, double dt_s) noexcept;
  double sliding_drive_n(const LoadEstimate& est, double dt_s) noexcept;
  double speed_limited_n(double drive_n, const LoadEstimate& est, bool was_limited,
                         double dt_s) noexcept;

  ForceLoopConfig cfg_;
  ForceLoopState state_ = ForceLoopState::off;
  double setpoint_n_ = 0.0, hold_drive_n_ = 0.0, ramp_n_ = 0.0;
  double off_setpoint_s_ = 0.0;  // landing, the estimate beyond the tolerance this long
  double below_limit_s_ = 0.0;   // speed-limited, the speed below the limit's share this long
  double cap_up_m_s_ = std::numeric_limits<double>::infinity();
  double cap_down_m_s_ = std::numeric_limits<double>::infinity();
  int dir_ = 1;
  bool held_by_bound_ = false;
  bool slid_ = false;         // the nut slid since the setpoint came
  bool landed_once_ = false;  // it came within the land tolerance since the setpoint came
  bool drive_limited_ = false;
  int attempts_ = 0;  // break-aways since the setpoint came: after a few, a bound inside will do //
                      // holding because the bound fits the tolerance (else: landed)
};

}  // namespace maglead::controller
