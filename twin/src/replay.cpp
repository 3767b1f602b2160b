// Replaying a recording through the twin (see replay.hpp).
#include "maglead/twin/replay.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace maglead::twin {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void check_signals(const ReplaySignals& s) {
  const std::size_t n = s.t_s.size();
  if (n < 2) throw std::invalid_argument("replay: needs at least two samples");
  const auto matches = [n](std::span<const double> c, bool optional) {
    return c.size() == n || (optional && c.empty());
  };
  if (!matches(s.screw_angle_rad, false) || !matches(s.nut_pos_m, false) ||
      !matches(s.force_set_n, true) || !matches(s.load_force_n, true))
    throw std::invalid_argument("replay: columns of different lengths");
}

double at_or_nan(std::span<const double> column, std::size_t i) {
  return column.empty() ? kNaN : column[i];
}

}  // namespace

void replay_monitor(TwinMonitorConfig config, const ReplaySignals& s,
                    const std::function<void(std::size_t, const TwinOutputs&)>& on_tick) {
  check_signals(s);
  const std::size_t n = s.t_s.size();
  const double period_s = (s.t_s[n - 1] - s.t_s[0]) / static_cast<double>(n - 1);
  if (!(period_s > 0)) throw std::invalid_argument("replay: the time column does not advance");
  // The monitor runs at the recording's rate, its integrator capped at one sample as in the loop.
  config.actuator.sample_rate_hz = 1.0 / period_s;
  config.integrator.max_step_s = 1.0 / config.actuator.sample_rate_hz;
  TwinMonitor monitor(config);
  monitor.reset(s.t_s[0], s.screw_angle_rad[0], s.nut_pos_m[0]);
  for (std::size_t i = 0; i < n; ++i)
    on_tick(i, monitor.step({s.t_s[i], s.screw_angle_rad[i], s.nut_pos_m[i],
                             at_or_nan(s.force_set_n, i), at_or_nan(s.load_force_n, i)}));
}

WindowReplay replay_windows(const NutModel& model, const ReplaySignals& s,
                            std::span<const double> v, int windows, std::size_t horizon) {
  check_signals(s);
  const std::size_t n = s.t_s.size();
  if (v.size() != n || s.load_force_n.empty())
    throw std::invalid_argument("replay_windows: needs velocity and load for every sample");
  if (windows < 1 || horizon < 1 || n < horizon + 2)
    throw std::invalid_argument("replay_windows: recording shorter than one window");
  HybridTwin twin(model);
  double sum_sq_m2 = 0;
  std::size_t simulated = 0;
  WindowReplay out;
  for (int w = 0; w < windows; ++w) {
    const std::size_t i0 =
        (n - horizon - 1) * static_cast<std::size_t>(w) / static_cast<std::size_t>(windows);
    const double v0 = v[i0];
    const NutState start{s.nut_pos_m[i0], v0,
                         v0 > 0   ? FrictionMode::slide_pos
                         : v0 < 0 ? FrictionMode::slide_neg
                                  : FrictionMode::stick};
    // Load-cell convention: F_ext is what the load exerts on the nut, the twin's input.
    twin.reset(s.t_s[i0], start, s.screw_angle_rad[i0], s.load_force_n[i0]);
    for (std::size_t k = i0 + 1; k <= i0 + horizon; ++k) {
      if (twin.advance(s.t_s[k], s.screw_angle_rad[k], s.load_force_n[k]) != TwinStatus::ok) {
        ++out.failures;
        break;
      }
      const double e = twin.state().pos_m - s.nut_pos_m[k];
      sum_sq_m2 += e * e;
      ++simulated;
    }
  }
  out.stats = twin.stats();
  out.rms_position_error_m =
      simulated ? std::sqrt(sum_sq_m2 / static_cast<double>(simulated)) : kNaN;
  return out;
}

}  // namespace maglead::twin
