// The anomaly inspection behind `maglead report` (see anomaly.hpp).
#include "maglead/analysis/anomaly.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>

#include "actuator_analysis.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/twin/replay.hpp"

namespace maglead::analysis {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// The start-up transient lasts as long as the static estimator's velocity hold (its friction
// sign is unknown before the encoder has shown motion for that long) and the servo takes to pull
// the screw onto the nut's phase: about 0.2 s on the paper's actuator.
constexpr double kSettleS = 0.2;
// Velocity for the map: central difference over ±20 ms, so one encoder count (21.6 µm) is
// about 0.5 mm/s rather than 20 mm/s of quantisation noise.
constexpr double kVelocityHalfWindowS = 0.020;
// A short recording settles within this share of its duration.
constexpr double kSettleShareOfDuration = 0.1;
// The space map: its cells over velocity and position, the velocity tails left out on either
// side (a few samples at the fastest would squeeze the rest into a few cells), and the fewest
// samples of a cell shown (fewer is one noisy reading, not a place).
constexpr int kMapVelocityCells = 40, kMapPositionCells = 30;
constexpr double kMapVelocityTail = 0.005;
constexpr double kMapMinCellSamples = 3;

std::span<const double> optional_column(const Recording& rec, const char* name) {
  return rec.has(name) ? std::span<const double>(rec.column(name)) : std::span<const double>();
}

std::vector<TimeWindow> windows_where(const std::vector<double>& t, const std::vector<bool>& flag) {
  std::vector<TimeWindow> w;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (!flag[i]) continue;
    if (i > 0 && flag[i - 1])
      w.back().end_s = t[i];
    else
      w.push_back({t[i], t[i]});
  }
  return w;
}

std::optional<ErrorStats> error_stats(const std::vector<double>& estimate,
                                      const std::vector<double>& measured, std::size_t from) {
  ErrorStats s;
  for (std::size_t i = from; i < estimate.size(); ++i) {
    const double e = estimate[i] - measured[i];
    if (!std::isfinite(e)) continue;
    s.mean_abs_n += std::abs(e);
    s.rms_n += e * e;
    s.max_abs_n = std::max(s.max_abs_n, std::abs(e));
    ++s.samples;
  }
  if (!s.samples) return std::nullopt;
  s.mean_abs_n /= static_cast<double>(s.samples);
  s.rms_n = std::sqrt(s.rms_n / static_cast<double>(s.samples));
  return s;
}

// The twin's replay: residuals, its estimate, step-outs and the drift and warning windows.
void replay(const Recording& rec, const twin::TwinMonitorConfig& monitor,
            const std::vector<double>& screw, Anomaly& a) {
  auto& tr = a.trace;
  const std::size_t n = tr.t_s.size();
  tr.residual_pos_m.resize(n);
  tr.twin_estimate_n.resize(n);
  tr.phase_rad.resize(n);
  tr.drift_statistic.resize(n);
  std::vector<bool> drift(n), warn(n);
  int slips = 0;
  twin::replay_monitor(
      monitor,
      {tr.t_s, screw, tr.nut_pos_m, optional_column(rec, "force_set_n"),
       optional_column(rec, "load_force_n")},
      [&](std::size_t i, const twin::TwinOutputs& out) {
        tr.residual_pos_m[i] = out.residual_pos_m;
        tr.twin_estimate_n[i] = out.dynamic_output_force_est_n;
        tr.phase_rad[i] = out.phase_rad;
        tr.drift_statistic[i] = out.drift_statistic;
        drift[i] = out.drift_warning;
        a.drift_observability = static_cast<int>(out.drift_observability);
        // Judged once the statistic has a value: with the reference formed, it stays 0 until the
        // stretches' scatter is known.
        if (out.drift_observability == twin::DriftObservability::tracking &&
            out.drift_statistic > 0.0 && !std::isfinite(a.drift_judged_from_s))
          a.drift_judged_from_s = tr.t_s[i];
        warn[i] = out.step_out_warning;
        if (out.slips != slips)
          a.step_outs.push_back({tr.t_s[i], out.slips - slips, tr.nut_pos_m[i], "twin replay"});
        slips = out.slips;
      });
  a.drift_windows = windows_where(tr.t_s, drift);
  a.step_out_warnings = windows_where(tr.t_s, warn);
  a.max_drift_statistic = *std::max_element(tr.drift_statistic.begin(), tr.drift_statistic.end());
}

// What the controller itself logged, where the recording has it (maglead record).
void logged_step_outs(const Recording& rec, Anomaly& a) {
  if (!rec.has("step_out_count")) return;
  const auto& c = rec.column("step_out_count");
  for (std::size_t i = 1; i < c.size(); ++i)
    if (std::isfinite(c[i]) && std::isfinite(c[i - 1]) && c[i] > c[i - 1])
      a.step_outs.push_back(
          {a.trace.t_s[i], static_cast<int>(c[i] - c[i - 1]), a.trace.nut_pos_m[i], "controller"});
}

// Paper eq. 6 as the controller logged it, else recomputed causally as the controller does.
// It means nothing off the stable branch (after a step-out φ sits leads away): those samples are
// left out rather than scored at millions of newtons.
void static_estimate(const Recording& rec, const twin::TwinMonitorConfig& m,
                     const std::vector<double>& screw, Anomaly& a) {
  auto& tr = a.trace;
  const std::size_t n = tr.t_s.size();
  a.static_estimate_logged = rec.has("out_force_est_n");
  if (a.static_estimate_logged) {
    tr.static_estimate_n = rec.column("out_force_est_n");
  } else {
    tr.static_estimate_n.resize(n);
    StaticForceEstimator est(m.calibration, m.actuator.coulomb_n, 1e-5);
    EncoderVelocityEstimator vel(1.0 / a.sample_rate_hz, m.actuator.linear_count_m);
    for (std::size_t i = 0; i < n; ++i) {
      const double v = i == 0 ? (vel.reset(tr.nut_pos_m[i]), 0.0) : vel.update(tr.nut_pos_m[i]);
      tr.static_estimate_n[i] =
          est.output_force_n(phase_rad(screw[i], tr.nut_pos_m[i], m.actuator.lead_m), v);
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    if (tr.phase_rad[i] < m.calibration.stable_min_rad ||
        tr.phase_rad[i] > m.calibration.stable_max_rad) {
      tr.static_estimate_n[i] = kNaN;
      ++a.off_branch_samples;
    }
}

std::pair<double, double> central_range(std::vector<double> x, double tail) {
  std::erase_if(x, [](double v) { return !std::isfinite(v); });
  if (x.empty()) return {0.0, 1.0};
  std::sort(x.begin(), x.end());
  const auto at = [&](double q) {
    return x[static_cast<std::size_t>(q * static_cast<double>(x.size() - 1))];
  };
  return {at(tail), at(1.0 - tail)};
}

// Where in space the twin and the machine part: the mean twin force error against the load cell
// (or, without one, the position residual) over velocity and position.
Grid space_map(const Anomaly& a) {
  const auto& tr = a.trace;
  const std::size_t n = tr.t_s.size();
  const auto half =
      std::max<std::size_t>(1, static_cast<std::size_t>(kVelocityHalfWindowS * a.sample_rate_hz));
  std::vector<double> v_mm_s(n, kNaN), value(n, kNaN);
  for (std::size_t i = std::max(a.first_settled, half); i + half < n; ++i) {
    v_mm_s[i] = (tr.nut_pos_m[i + half] - tr.nut_pos_m[i - half]) /
                (tr.t_s[i + half] - tr.t_s[i - half]) * 1e3;
    value[i] =
        a.has_load_cell ? tr.twin_estimate_n[i] - tr.output_force_n[i] : tr.residual_pos_m[i] * 1e6;
  }
  Grid g;
  g.title = "Where in space: twin " +
            std::string(a.has_load_cell ? "force error" : "position residual") +
            " over velocity and position";
  g.x_label = "velocity [mm/s]";
  g.y_label = "position [mm]";
  g.value_label = a.has_load_cell ? "twin - load cell [N]" : "measured - twin [um]";
  g.nx = kMapVelocityCells;
  g.ny = kMapPositionCells;
  std::tie(g.x_min, g.x_max) = central_range(v_mm_s, kMapVelocityTail);
  std::vector<double> pos_mm(tr.nut_pos_m.begin() + static_cast<std::ptrdiff_t>(a.first_settled),
                             tr.nut_pos_m.end());
  for (double& p : pos_mm) p *= 1e3;
  std::tie(g.y_min, g.y_max) = central_range(pos_mm, 0.0);
  if (!(g.x_max > g.x_min)) g.x_max = g.x_min + 1.0;
  if (!(g.y_max > g.y_min)) g.y_max = g.y_min + 1.0;
  std::vector<double> sum(static_cast<std::size_t>(g.nx * g.ny), 0.0), count(sum.size(), 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(v_mm_s[i]) || !std::isfinite(value[i])) continue;
    const int ix = static_cast<int>((v_mm_s[i] - g.x_min) / (g.x_max - g.x_min) * g.nx);
    const int iy = static_cast<int>((tr.nut_pos_m[i] * 1e3 - g.y_min) / (g.y_max - g.y_min) * g.ny);
    if (ix < 0 || ix >= g.nx || iy < 0 || iy >= g.ny) continue;
    const auto cell = static_cast<std::size_t>(iy) * static_cast<std::size_t>(g.nx) +
                      static_cast<std::size_t>(ix);
    sum[cell] += value[i];
    count[cell] += 1;
  }
  g.values.resize(sum.size());
  for (std::size_t k = 0; k < sum.size(); ++k)
    g.values[k] = count[k] >= kMapMinCellSamples ? sum[k] / count[k] : kNaN;
  return g;
}

}  // namespace

Anomaly inspect_recording(const Recording& rec, const twin::TwinMonitorConfig& monitor) {
  if (!rec.has("t_s") || !rec.has("nut_pos_m"))
    throw RecordingError(rec.path + ": needs columns 't_s' and 'nut_pos_m'");
  Anomaly a;
  auto& tr = a.trace;
  tr.t_s = rec.column("t_s");
  tr.nut_pos_m = rec.column("nut_pos_m");
  const std::size_t n = tr.t_s.size();
  if (n < 2) throw std::invalid_argument(rec.path + ": needs at least two samples");
  a.duration_s = tr.t_s.back() - tr.t_s.front();
  if (!(a.duration_s > 0)) throw std::invalid_argument(rec.path + ": t_s does not advance");
  a.sample_rate_hz = static_cast<double>(n - 1) / a.duration_s;
  a.linear_count_m = monitor.actuator.linear_count_m;
  const FrictionModel friction = twin::friction_model(monitor.model);
  a.static_friction_band_n = std::max(friction.breakaway_n(1), friction.breakaway_n(-1));
  std::vector<double> geared;
  const auto& screw = actuator::angle_column(rec, monitor.actuator, geared);
  const auto column_or_nan = [&](const char* name, double scale) {
    std::vector<double> c(n, kNaN);
    if (rec.has(name))
      std::transform(rec.column(name).begin(), rec.column(name).end(), c.begin(),
                     [&](double v) { return scale * v; });
    return c;
  };
  tr.pos_set_m = column_or_nan("pos_set_m", 1.0);
  tr.force_set_n = column_or_nan("force_set_n", 1.0);
  tr.output_force_n = column_or_nan("load_force_n", -1.0);  // output force = −load force
  a.has_load_cell = rec.has("load_force_n");

  replay(rec, monitor, screw, a);
  logged_step_outs(rec, a);
  static_estimate(rec, monitor, screw, a);

  a.settle_s = std::min(kSettleS, kSettleShareOfDuration * a.duration_s);
  while (a.first_settled + 1 < n && tr.t_s[a.first_settled] - tr.t_s[0] < a.settle_s)
    ++a.first_settled;
  if (a.has_load_cell) {
    a.static_error = error_stats(tr.static_estimate_n, tr.output_force_n, a.first_settled);
    a.twin_error = error_stats(tr.twin_estimate_n, tr.output_force_n, a.first_settled);
  }
  double sum_sq = 0;
  for (std::size_t i = a.first_settled; i < n; ++i)
    sum_sq += tr.residual_pos_m[i] * tr.residual_pos_m[i];
  a.residual_pos_rms_m = std::sqrt(sum_sq / static_cast<double>(n - a.first_settled));
  a.map_position_velocity = space_map(a);
  return a;
}

void set_aside_load_cell(Anomaly& anomaly, std::string why, std::optional<double> constant_n) {
  anomaly.static_error.reset();
  anomaly.twin_error.reset();
  anomaly.load_cell_unusable = std::move(why);
  anomaly.load_cell_constant_n = constant_n;
}

}  // namespace maglead::analysis
