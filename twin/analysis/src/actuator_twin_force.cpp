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

bool rises_beyond_noise(const TwinForceErrors& with, const TwinForceErrors& without,
                        double resolved_n) {
  const std::size_t n = std::min(with.block_mae_n.size(), without.block_mae_n.size());
  if (n == 0) return with.mae_n > without.mae_n + resolved_n;
  double mean = 0;
  for (std::size_t b = 0; b < n; ++b) mean += with.block_mae_n[b] - without.block_mae_n[b];
  mean /= static_cast<double>(n);
  if (!(mean > resolved_n) || !(mean > 0)) return false;
  if (n < 2) return true;
  double ss = 0;
  for (std::size_t b = 0; b < n; ++b) {
    const double d = with.block_mae_n[b] - without.block_mae_n[b] - mean;
    ss += d * d;
  }
  const double se = std::sqrt(ss / static_cast<double>(n - 1) / static_cast<double>(n));
  return mean > kRiseBeyondNoise * se;
}

#ifdef MAGLEAD_HAVE_TWIN
std::optional<TwinForceErrors> twin_force_errors(const Recording& rec, const ActuatorParams& act,
                                                 const ForceCalibration& cal,
                                                 const ModelFile& model) {
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
  // The force estimate is the observer's: the open-loop twin beside it (prediction, health,
  // look-ahead) is most of a tick's cost and changes nothing scored here.
  tc.open_loop_twin = false;
  twin::TwinMonitor mon(tc);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> abs_err;
  abs_err.reserve(std::min(n, kTwinCheckSamples));
  for (const auto& w : scoring_windows(n, kTwinCheckSamples, kTwinCheckWindows)) {
    mon.reset(t[w.begin], screw[w.begin], pos[w.begin]);
    for (std::size_t i = w.begin; i < w.end; ++i) {
      const auto out = mon.step({t[i], screw[i], pos[i], fset ? (*fset)[i] : nan});
      abs_err.push_back(std::abs(out.dynamic_output_force_est_n + load[i]));  // output = −load
    }
  }
  TwinForceErrors e;
  double sum = 0;
  for (double x : abs_err) sum += x;
  e.mae_n = sum / static_cast<double>(abs_err.size());
  const std::size_t blocks = std::min(kTwinCheckBlocks, abs_err.size());
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t lo = abs_err.size() * b / blocks, hi = abs_err.size() * (b + 1) / blocks;
    double s = 0;
    for (std::size_t i = lo; i < hi; ++i) s += abs_err[i];
    e.block_mae_n.push_back(s / static_cast<double>(std::max<std::size_t>(hi - lo, 1)));
  }
  return e;
}
#else
std::optional<TwinForceErrors> twin_force_errors(const Recording&, const ActuatorParams&,
                                                 const ForceCalibration&, const ModelFile&) {
  return std::nullopt;
}
#endif

}  // namespace maglead::analysis::actuator
