#pragma once
// The twin-hook port: what the control loop hands a digital twin each cycle and what it reads
// back for its registers. The controller owns this interface; runtime/ implements it with the
// twin (twin::TwinMonitor, whose own richer TwinInputs/TwinOutputs stay inside twin/).
#include <cstdint>

namespace maglead::controller {

/// One cycle's measurements, as the loop hands them to the twin.
struct TwinSample {
  std::uint64_t cycle = 0;  // the controller's cycle number (1-based); results are tagged with it
  double t_s = 0.0, screw_angle_rad = 0.0, screw_cmd_rad = 0.0, nut_pos_m = 0.0, nut_vel_m_s = 0.0;
  double phase_rad = 0.0, static_force_n = 0.0;
  double force_setpoint_n = 0.0;  // NaN unless in force mode
  double load_force_n = 0.0;      // load cell, force on the nut from the load (NaN without one)
  bool free_move = false;         // no contact declared (a reference move): F_ext = 0 is known
};

/// What the twin publishes; zero / false until a twin is attached.
struct TwinReport {
  std::uint64_t cycle = 0;  // the cycle whose sample these results belong to (0: none yet)
  double pred_nut_pos_m = 0.0;
  double pred_force_n = 0.0;
  double residual_pos_m = 0.0;
  double residual_force_n = 0.0;
  double dynamic_force_n = 0.0;
  bool healthy = false;
  bool drift_warning = false;
  bool step_out_warning = false;
  // The twin is behind the loop: its input queue overflowed or its latest results belong to a
  // cycle older than the bound its runner was given (status bit twin_lagging).
  bool lagging = false;
  // Reason codes (twin::DriftReason, HealthReason, StepOutReason, DriftObservability).
  std::uint16_t drift_reason = 0, health_reason = 0, step_out_reason = 0, drift_observability = 0;
  // The load-cell check of the coupling gain (0 until estimated; never used by the flag).
  double gain = 0.0, gain_stderr = 0.0, gain_reference = 0.0;
  // The drift flag's figures, from free moves (0 until tracking): change of the force estimate's
  // error since the reference at zero load and at the rated force (separable: estimated; not:
  // the worst case, all gain), standard errors, and the gain / friction split where separable.
  double drift_zero_load_n = 0.0, drift_zero_load_se_n = 0.0;
  double drift_rated_n = 0.0, drift_rated_se_n = 0.0;
  double drift_gain_change = 0.0, drift_friction_change_n = 0.0;
  double drift_known_s = 0.0, drift_statistic = 0.0;
  bool drift_separable = false;
};

/// The loop calls step() once per cycle on its own thread, after the measurement and before
/// supervision and control: it must not block, lock or allocate, and returns the latest results
/// it has (which may belong to an earlier cycle: `out.cycle` says which). resync() at start-up
/// and when a client re-synchronises after a step-out; clear_warnings() on a fault_reset edge.
/// Attach with Controller::attach_twin before the loop starts.
class TwinHook {
 public:
  virtual ~TwinHook() = default;
  virtual void step(const TwinSample& in, TwinReport& out) noexcept = 0;
  virtual void resync(double /*t_s*/, double /*screw_angle_rad*/, double /*nut_pos_m*/) noexcept {}
  /// A fault_reset edge: clear the latched drift warning (the twin takes a new reference).
  virtual void clear_warnings() noexcept {}
};

}  // namespace maglead::controller
