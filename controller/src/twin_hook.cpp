#include "maglead/controller/twin_hook.hpp"

#include "maglead/twin/monitor.hpp"

namespace maglead::controller {

TwinMonitorHook::TwinMonitorHook(const twin::TwinMonitorConfig& config)
    : monitor_(std::make_unique<twin::TwinMonitor>(config)) {}

TwinMonitorHook::~TwinMonitorHook() = default;

void TwinMonitorHook::step(const TwinInputs& in, TwinOutputs& out) noexcept {
  // The twin takes the raw measurements: it keeps its own phase and step-out bookkeeping.
  const auto o = monitor_->step({in.t_s, in.screw_angle_rad, in.nut_pos_m, in.force_setpoint_n});
  out.pred_nut_pos_m = o.predicted_nut_pos_m;
  out.pred_force_n = o.predicted_output_force_n;
  out.residual_pos_m = o.residual_pos_m;
  out.residual_force_n = o.residual_force_n;
  out.dynamic_force_n = o.dynamic_output_force_est_n;
  out.healthy = ok_ && o.healthy && o.solver_ok;
  out.drift_warning = o.drift_warning;
  out.step_out_warning = o.step_out_warning;
}

void TwinMonitorHook::resync(double t_s, double screw_angle_rad, double nut_pos_m) noexcept {
  try {
    monitor_->reset(t_s, screw_angle_rad, nut_pos_m);
    ok_ = true;
  } catch (...) {
    ok_ = false;  // reset() allocates nothing and should not throw; if it does, say so via healthy
  }
}

}  // namespace maglead::controller
