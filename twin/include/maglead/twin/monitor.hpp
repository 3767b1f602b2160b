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
  bool healthy = true;          // twin and measurement agree within noise (no fault, no drift)
  bool drift_warning = false;   // calibration no longer matches the actuator (latched)
  bool step_out = false;        // φ left the stable branch / nut slipped a lead (latched)
  bool step_out_warning = false;  // look-ahead crosses ±π/2 (not latched)
  int slips = 0;                // signed number of leads slipped since reset
};

struct TwinMonitorConfig {
  ActuatorParams actuator;        // geometry, encoders, sample rate
  ForceCalibration calibration;   // the controller's calibration (periodic model used)
  TwinModel model;                // mass, friction, extra terms (config/model.toml)
  double lookahead_s = 0.050;     // step-out warning horizon
  double step_out_warn_margin_rad = 0.0;  // warn when look-ahead |φ| exceeds π/2 − this
  // Drift detector (CUSUM on the normalised force residual); see monitor.cpp for the rationale.
  double drift_threshold = 0.0;   // 0: derived from noise and quantization (default)
  double drift_warmup_s = 5.0;    // no drift decision before this much data
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
