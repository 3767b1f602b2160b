#include "maglead/controller/twin_hook.hpp"

#include <cmath>

#include "maglead/twin/monitor.hpp"

namespace maglead::controller {

TwinMonitorHook::TwinMonitorHook(const twin::TwinMonitorConfig& config)
    : monitor_(std::make_unique<twin::TwinMonitor>(config)) {}

TwinMonitorHook::~TwinMonitorHook() = default;

void TwinMonitorHook::step(const TwinInputs& in, TwinOutputs& out) noexcept {
  // The twin takes the raw measurements: it keeps its own phase and step-out bookkeeping.
  const auto o =
      monitor_->step({in.t_s, in.screw_angle_rad, in.nut_pos_m, in.force_setpoint_n, in.load_force_n});
  out.pred_nut_pos_m = o.predicted_nut_pos_m;
  out.pred_force_n = o.predicted_output_force_n;
  out.residual_pos_m = o.residual_pos_m;
  out.residual_force_n = o.residual_force_n;
  out.dynamic_force_n = o.dynamic_output_force_est_n;
  out.healthy = ok_ && o.healthy && o.solver_ok;
  out.drift_warning = o.drift_warning;
  out.step_out_warning = o.step_out_warning;
  out.drift_reason = static_cast<std::uint16_t>(o.drift_reason);
  out.health_reason = static_cast<std::uint16_t>(ok_ ? o.health_reason : twin::HealthReason::solver);
  out.step_out_reason = static_cast<std::uint16_t>(o.step_out_reason);
  out.gain = std::isfinite(o.drift_gain_estimate) ? o.drift_gain_estimate : 0.0;
  out.gain_stderr = std::isfinite(o.drift_gain_stderr) ? o.drift_gain_stderr : 0.0;
  out.gain_reference = std::isfinite(o.drift_reference_gain) ? o.drift_reference_gain : 0.0;
}

void TwinMonitorHook::clear_warnings() noexcept { monitor_->clear_drift(); }

void TwinMonitorHook::resync(double t_s, double screw_angle_rad, double nut_pos_m) noexcept {
  try {
    monitor_->reset(t_s, screw_angle_rad, nut_pos_m);
    ok_ = true;
  } catch (...) {
    ok_ = false;  // reset() allocates nothing and should not throw; if it does, say so via healthy
  }
}

}  // namespace maglead::controller
