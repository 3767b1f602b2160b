// The twin's force estimate on the recording the analysis came from, with the baseline and the
// corrected model: the same TwinMonitor, fed row by row as `maglead estimate --estimator twin`
// feeds it (screw angle, nut position, force setpoint; never the load cell). The load cell is
// read here only to score the estimate: checking, not observing.
#include "actuator_twin_force.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "actuator_analysis.hpp"

#ifdef MAGLEAD_HAVE_TWIN
#include "maglead/twin/monitor.hpp"
#endif

namespace maglead::analysis::actuator {

std::vector<SampleWindow> scoring_windows(std::size_t samples, std::size_t budget,
                                          std::size_t windows) {
  if (samples <= budget || windows == 0) return {{0, samples}};
  const std::size_t len = budget / windows;
  std::vector<SampleWindow> out;
  out.reserve(windows);
  const std::size_t gaps = std::max<std::size_t>(windows - 1, 1);
  for (std::size_t k = 0; k < windows; ++k) {
    // Evenly spaced starts: the first window opens the recording, the last one closes it.
    const std::size_t begin = (samples - len) * k / gaps;
    out.push_back({begin, begin + len});
  }
  return out;
}

#ifdef MAGLEAD_HAVE_TWIN
std::optional<double> twin_force_mae_n(const Recording& rec, const ActuatorParams& act,
                                       const ForceCalibration& cal, const ModelFile& model) {
  const auto& t = rec.column("t_s");
  const std::size_t n = t.size();
  if (n < 2 || !(t.back() > t.front())) return std::nullopt;
  std::vector<double> geared;
  const auto& screw = angle_column(rec, act, geared);
  const auto& pos = rec.column("nut_pos_m");
  const auto& load = rec.column("load_force_n");
  const std::vector<double>* fset = rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr;
  twin::TwinMonitorConfig tc;
  tc.actuator = act;
  tc.actuator.sample_rate_hz = static_cast<double>(n - 1) / (t.back() - t.front());
  tc.integrator.max_step_s = 1.0 / tc.actuator.sample_rate_hz;
  tc.calibration = cal;
  tc.model = model;
  // The estimate does not depend on the step-out look-ahead, which is most of the twin's cost.
  tc.lookahead_every_ticks = std::numeric_limits<int>::max();
  twin::TwinMonitor mon(tc);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  double sum = 0;
  std::size_t scored = 0;
  for (const auto& w : scoring_windows(n, kTwinCheckSamples, kTwinCheckWindows)) {
    mon.reset(t[w.begin], screw[w.begin], pos[w.begin]);
    for (std::size_t i = w.begin; i < w.end; ++i) {
      const auto out = mon.step({t[i], screw[i], pos[i], fset ? (*fset)[i] : nan});
      sum += std::abs(out.dynamic_output_force_est_n + load[i]);  // output force = −load
    }
    scored += w.end - w.begin;
  }
  return sum / static_cast<double>(scored);
}
#else
std::optional<double> twin_force_mae_n(const Recording&, const ActuatorParams&,
                                       const ForceCalibration&, const ModelFile&) {
  return std::nullopt;
}
#endif

}  // namespace maglead::analysis::actuator
