// Short-horizon simulation of the twin (SUNDIALS CVODE, twin::replay_windows) from measured
// states: baseline model against corrected model, driven by the recording's screw angle and load.
#include "twin_check.hpp"

#include <algorithm>
#include <cmath>

#ifdef MAGLEAD_HAVE_TWIN
#include "maglead/twin/replay.hpp"
#endif

namespace maglead::analysis {

#ifdef MAGLEAD_HAVE_TWIN

TwinSimulation simulate_twins(const TwinCheckInput& in, const ModelFile& baseline,
                              const ModelFile& corrected) {
  TwinSimulation out;
  const std::size_t n = in.t.size();
  const std::size_t horizon =
      std::max<std::size_t>(2, static_cast<std::size_t>(in.horizon_s * in.fs_hz));
  if (n < horizon * 4) {
    out.reason = "recording too short";
    return out;
  }
  const int windows = static_cast<int>(std::min<std::size_t>(40, n / horizon / 2));
  const twin::ReplaySignals signals{in.t, in.theta, in.p, {}, in.load};
  const auto run = [&](const ModelFile& m) {
    return twin::replay_windows(twin::NutModel(in.act, in.coupling, m), signals, in.v, windows,
                                horizon);
  };
  const auto b = run(baseline);
  const auto c = run(corrected);
  out.available = true;
  out.integrator = "SUNDIALS CVODE (maglead_twin HybridTwin), step capped at the sample period";
  out.horizon_s = in.horizon_s;
  out.windows = windows;
  out.baseline_rms_position_error_m = b.rms_position_error_m;
  out.corrected_rms_position_error_m = c.rms_position_error_m;
  out.baseline_failures = b.failures;
  out.corrected_failures = c.failures;
  out.steps = c.stats.steps;
  out.root_events = c.stats.root_events;
  return out;
}
#else
TwinSimulation simulate_twins(const TwinCheckInput&, const ModelFile&, const ModelFile&) {
  TwinSimulation out;
  out.reason = "maglead_twin (SUNDIALS) not built";
  return out;
}
#endif

}  // namespace maglead::analysis
