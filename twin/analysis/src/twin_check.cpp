// Short-horizon simulation of the twin (SUNDIALS CVODE, maglead_twin) from measured states:
// baseline model against corrected model, driven by the recording's screw angle and load force.
#include "twin_check.hpp"

#include <algorithm>
#include <cmath>

#ifdef MAGLEAD_HAVE_TWIN
#include "maglead/twin/hybrid_twin.hpp"
#endif

namespace maglead::analysis {

#ifdef MAGLEAD_HAVE_TWIN

nlohmann::json simulate_twins(const TwinCheckInput& in, const ModelFile& baseline,
                              const ModelFile& corrected) {
  nlohmann::json out;
  const std::size_t n = in.t.size();
  const std::size_t horizon = std::max<std::size_t>(2, static_cast<std::size_t>(in.horizon_s * in.fs_hz));
  if (n < horizon * 4) return {{"available", false}, {"reason", "recording too short"}};
  const int windows = static_cast<int>(std::min<std::size_t>(40, n / horizon / 2));
  auto run = [&](const ModelFile& m, twin::TwinStats& stats) {
    twin::HybridTwin tw(twin::NutModel(in.act, in.coupling, m));
    double se = 0;
    std::size_t cnt = 0;
    int failures = 0;
    for (int w = 0; w < windows; ++w) {
      const std::size_t i0 = (n - horizon - 1) * static_cast<std::size_t>(w) / static_cast<std::size_t>(windows);
      const double v0 = in.v[i0];
      twin::NutState st{in.p[i0], v0, v0 > 0 ? twin::FrictionMode::slide_pos
                                             : v0 < 0 ? twin::FrictionMode::slide_neg
                                                      : twin::FrictionMode::stick};
      // Load-cell convention: F_ext is what the load exerts on the nut, the twin's input.
      tw.reset(in.t[i0], st, in.theta[i0], in.load[i0]);
      for (std::size_t k = i0 + 1; k <= i0 + horizon; ++k) {
        if (tw.advance(in.t[k], in.theta[k], in.load[k]) != twin::TwinStatus::ok) {
          ++failures;
          break;
        }
        const double e = tw.state().pos_m - in.p[k];
        se += e * e;
        ++cnt;
      }
    }
    stats = tw.stats();
    return std::make_pair(cnt ? std::sqrt(se / static_cast<double>(cnt)) : NAN, failures);
  };
  twin::TwinStats sb, sc;
  const auto [rb, fb] = run(baseline, sb);
  const auto [rc, fc] = run(corrected, sc);
  out["available"] = true;
  out["integrator"] = "SUNDIALS CVODE (maglead_twin HybridTwin), step capped at the sample period";
  out["horizon_s"] = in.horizon_s;
  out["windows"] = windows;
  out["baseline_rms_position_error_m"] = rb;
  out["corrected_rms_position_error_m"] = rc;
  out["baseline_failures"] = fb;
  out["corrected_failures"] = fc;
  out["steps"] = sc.steps;
  out["root_events"] = sc.root_events;
  return out;
}
#else
nlohmann::json simulate_twins(const TwinCheckInput&, const ModelFile&, const ModelFile&) {
  return {{"available", false}, {"reason", "maglead_twin (SUNDIALS) not built"}};
}
#endif

}  // namespace maglead::analysis
