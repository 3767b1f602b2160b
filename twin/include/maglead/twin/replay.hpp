#pragma once
// Replaying a recording through the twin: the one place that feeds logged samples to the
// TwinMonitor (twin-check, the anomaly report) or to the bare HybridTwin (the analysis's
// short-horizon re-simulation), so every caller sees the same ticks the controller would.
#include <cstddef>
#include <functional>
#include <span>

#include "maglead/twin/hybrid_twin.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::twin {

/// What the twin reads of a recording, one value per logged sample (SI units). Optional
/// columns are empty spans when the recording has none.
struct ReplaySignals {
  std::span<const double> t_s, screw_angle_rad, nut_pos_m;
  std::span<const double> force_set_n;   // optional: the observer's prior in force control
  std::span<const double> load_force_n;  // optional: the drift detector needs it
};

/// Runs the TwinMonitor tick by tick at the recording's rate (its mean sample period; the
/// integrator's step is capped at it, as in the loop) and hands every tick's outputs to on_tick.
/// Throws std::invalid_argument for fewer than two samples, mismatched lengths or a time
/// column that does not advance.
void replay_monitor(TwinMonitorConfig config, const ReplaySignals& signals,
                    const std::function<void(std::size_t tick, const TwinOutputs&)>& on_tick);

/// Open-loop re-simulation from measured states: the twin restarts at `windows` evenly spread
/// samples and runs `horizon_samples` ahead driven by the screw angle and the load; how far its
/// position strays from the measured one says how well the model predicts motion.
struct WindowReplay {
  double rms_position_error_m = 0;  // NaN when no sample was simulated
  int failures = 0;                 // windows the integrator gave up on
  TwinStats stats;
};
WindowReplay replay_windows(const NutModel& model, const ReplaySignals& signals,
                            std::span<const double> nut_vel_m_s, int windows,
                            std::size_t horizon_samples);

}  // namespace maglead::twin
