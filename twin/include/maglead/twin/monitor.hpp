#pragma once
// TwinMonitor: the controller's digital twin, stepped once per control tick beside the loop.
// It knows nothing of Modbus; the controller copies TwinOutputs into its registers.
//
// Per tick: feed the measured screw angle and nut position (quantized encoders, SI units) and
// the force setpoint if force control is active (NaN otherwise). step() is noexcept, does not
// allocate and does not block; everything is created in the constructor / reset().
#include <memory>
#include <string>

#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/twin/hybrid_twin.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::twin {

struct TwinInputs {
  double t_s = 0.0;               // loop time of this sample
  double screw_angle_rad = 0.0;   // measured θ (motor encoder / gear ratio), continuous
  double nut_pos_m = 0.0;         // measured p (linear encoder)
  double force_setpoint_n = 0.0;  // output-force setpoint F_out; NaN if not in force control
};

struct TwinOutputs {
  double predicted_nut_pos_m = 0.0;         // twin's nut position (model driven by θ, F̂_ext)
  double predicted_output_force_n = 0.0;    // twin's output force F_out = −F_ext it carries
  double dynamic_output_force_est_n = 0.0;  // observer estimate of F_out (M p̈ + C ṗ + friction)
  double static_output_force_est_n = 0.0;   // paper eq. 6 on the same samples, for comparison
  double residual_pos_m = 0.0;              // measured − predicted nut position
  double residual_force_n = 0.0;            // dynamic − static estimate (drift statistic input)
  double phase_rad = 0.0;                   // measured φ, unwrapped
  double step_out_margin_rad = 0.0;         // π/2 − max |φ| over the look-ahead (<0: crossing)
  double drift_statistic = 0.0;             // CUSUM value / threshold (≥ 1 raises drift_warning)
  double drift_gain_estimate = 1.0;         // coupling gain the friction windows suggest (≈1)
  bool healthy = true;          // twin and measurement agree within noise (no fault, no drift)
  bool drift_warning = false;   // calibration no longer matches the actuator (latched)
  bool step_out = false;        // φ left the stable branch / nut slipped a lead (latched)
  bool step_out_warning = false;  // look-ahead crosses ±π/2 (not latched)
  int slips = 0;                // signed number of leads slipped since reset
  int friction_mode = 0;        // observer's mode: −1 sliding −p, 0 stuck, +1 sliding +p
  bool solver_ok = true;        // every SUNDIALS call of this tick succeeded
};

struct TwinMonitorConfig {
  ActuatorParams actuator;        // geometry, encoders, sample rate
  ForceCalibration calibration;   // the controller's calibration (periodic model used)
  TwinModel model;                // mass, friction, extra terms (config/model.toml)
  IntegratorOptions integrator;   // CVODE settings of the twin (step cap = sample period)
  // Observer. While the nut sticks its friction is unknown within ± break-away, so the external
  // force needs a prior: a mean-reverting random walk (Ornstein-Uhlenbeck) of this intensity
  // [N²/s] that relaxes with this time constant towards the expected load (−setpoint in force
  // control, else zero: loads come and go). time constant 0 = pure random walk.
  double load_force_rate_n2_per_s = 5.0;
  double load_force_time_constant_s = 1.0;
  double stop_after_intervals = 2.0;  // no encoder edge for this many edge intervals: stopped
  double stop_min_s = 0.010;          // … and at least this long
  double resync_s = 0.020;            // twin runs open loop this long, then re-syncs
  double lookahead_s = 0.050;         // step-out warning horizon
  int lookahead_every_ticks = 10;      // look-ahead cadence (its cost is ~horizon/cap steps)
  double step_out_warn_margin_rad = 0.0;  // warn when look-ahead |φ| exceeds the edge − this
  // Drift detector: CUSUM on the friction-window ratio of stick episodes (see monitor.cpp).
  double drift_shift = 0.05;          // relative calibration error to detect (5 %)
  double drift_threshold = 8.0;       // CUSUM decision threshold (log-likelihood units)
  double healthy_residual_counts = 6.0;  // |position residual| above this: twin not healthy
};

/// Loads config/model.toml, calibration.toml and actuator.toml from a config directory.
TwinMonitorConfig load_monitor_config(const std::string& config_dir);

class TwinMonitor {
 public:
  explicit TwinMonitor(const TwinMonitorConfig& config);
  ~TwinMonitor();
  TwinMonitor(const TwinMonitor&) = delete;
  TwinMonitor& operator=(const TwinMonitor&) = delete;

  /// Re-synchronises to a measured state (start-up, after re-homing or step-out re-sync):
  /// clears the latched flags and the drift statistic.
  void reset(double t_s, double screw_angle_rad, double nut_pos_m);
  /// One control tick. Call at the sample rate with strictly increasing t_s.
  TwinOutputs step(const TwinInputs& in) noexcept;

  const TwinMonitorConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace maglead::twin
