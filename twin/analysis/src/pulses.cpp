// The one pulse finder (see pulses.hpp).
#include "pulses.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <string>
#include <utility>

#include <Eigen/Dense>

#include "maglead/analysis/signal.hpp"
#include "statistics.hpp"

namespace maglead::analysis::pulses {
namespace {

// How far the zero-phase filter itself swings a one-sided pulse of this duration to the other
// side (its undershoot): as a share of the pulse's filtered peak, and of its area.
struct Undershoot {
  double of_peak = 0, of_area = 0;
};
Undershoot filter_undershoot(const Floors& f, double duration_s) {
  const double edge_s =
      rules::kPulseEdgeFilterPeriods / f.filter_hz;  // the filter's response has died out by then
  const auto n = static_cast<std::size_t>(std::ceil((duration_s + 2 * edge_s) * f.fs_hz));
  const auto k0 = static_cast<std::size_t>(edge_s * f.fs_hz);
  const auto k1 = k0 + static_cast<std::size_t>(std::max(1.0, duration_s * f.fs_hz));
  std::vector<double> x(n, 0.0);
  for (std::size_t k = k0; k < std::min(k1, n); ++k) x[k] = 1.0;
  const auto y = filtfilt_butter4(x, f.filter_hz, f.fs_hz);
  const double top = *std::max_element(y.begin(), y.end());
  double above = 0, below = 0;
  for (double v : y) (v > 0 ? above : below) += std::abs(v);
  if (!(top > 0) || !(above > 0)) return {};
  return {std::max(0.0, -*std::min_element(y.begin(), y.end())) / top, below / above};
}

// The stretch around sample i: samples no further apart than rules::kPulseGapSteps sample steps.
std::pair<std::size_t, std::size_t> stretch_of(const std::vector<double>& t, std::size_t i,
                                               double step_s) {
  std::size_t a = i, b = i + 1;
  while (a > 0 && t[a] - t[a - 1] < rules::kPulseGapSteps * step_s) --a;
  while (b < t.size() && t[b] - t[b - 1] < rules::kPulseGapSteps * step_s) ++b;
  return {a, b};
}

struct Flanks {
  double level_n = 0;        // median residual beside the run: the misfit it rides on
  double opposite_n = 0;     // the largest swing to the other side of the peak
  double opposite_area = 0;  // Σ|r| over the samples beyond `thr` on the other side [N·sample]
};

// The residual beside the run [i, j) within `reach_s`, in the same stretch.
Flanks flanks_of(const std::vector<double>& t, const std::vector<double>& r, std::size_t i,
                 std::size_t j, double peak, double reach_s, double step_s, double thr) {
  const auto [a, b] = stretch_of(t, i, step_s);
  Flanks out;
  std::vector<double> beside;
  for (std::size_t k = a; k < b; ++k) {
    const double dist_s = k < i ? t[i] - t[k] : (k >= j ? t[k] - t[j - 1] : 0.0);
    if (dist_s > reach_s) continue;
    if (k < i || k >= j) beside.push_back(r[k]);
    if (r[k] * peak >= 0) continue;
    out.opposite_n = std::max(out.opposite_n, std::abs(r[k]));
    if (std::abs(r[k]) > thr) out.opposite_area += std::abs(r[k]);
  }
  if (!beside.empty()) out.level_n = stats::median_of(beside);
  return out;
}

// Whether a run from t0 to t1 lies where the residual is settled: the zero-phase filter runs
// over the recording's ends (and derivatives there are one-sided), so its first and last
// settling times (as filter_undershoot's) cannot tell a pulse from an edge.
bool clear_of_ends(const Floors& f, double t0, double t1) {
  const double edge_s = rules::kPulseEdgeFilterPeriods / f.filter_hz;
  return t0 >= f.start_s + edge_s && t1 <= f.start_s + f.span_s - edge_s;
}

// A run of consecutive samples (no gap in time) beyond the threshold.
struct Run {
  std::size_t end = 0;  // one past its last sample
  double peak = 0;      // its residual farthest from zero
  double area = 0;      // Σ|r| over it [N·sample], its impulse
};

// The run beyond `thr` from i.
Run run_from(const std::vector<double>& t, const std::vector<double>& r, std::size_t i, double thr,
             double step_s) {
  Run run{i};
  std::size_t& j = run.end;
  while (j < r.size() && std::abs(r[j]) > thr &&
         (j == i || t[j] - t[j - 1] < rules::kPulseGapSteps * step_s)) {
    if (std::abs(r[j]) > std::abs(run.peak)) run.peak = r[j];
    run.area += std::abs(r[j]);
    ++j;
  }
  return run;
}

// The samples from t0 to t1 (t is non-decreasing): their first index and one past the last.
std::pair<std::size_t, std::size_t> span_of(const std::vector<double>& t, double t0, double t1) {
  const auto a = std::lower_bound(t.begin(), t.end(), t0);
  const auto b = std::lower_bound(a, t.end(), t1);
  return {static_cast<std::size_t>(a - t.begin()), static_cast<std::size_t>(b - t.begin())};
}

// Per sample, whether it lies more than `reach_s` from every pulse (the samples a law is fitted
// on, so that it cannot fit a pulse itself).
std::vector<bool> away_from(const std::vector<double>& t, const std::vector<Pulse>& found,
                            double reach_s) {
  std::vector<bool> away(t.size(), true);
  for (const auto& p : found) {
    const auto [a, b] = span_of(t, p.t_s - reach_s, p.t_s + p.duration_s + reach_s);
    std::fill(away.begin() + static_cast<std::ptrdiff_t>(a),
              away.begin() + static_cast<std::ptrdiff_t>(b), false);
  }
  return away;
}

// The variant's law fitted to `r` on the samples `away` marks (least squares; a column silent
// there gets no weight, so a law the rest of the recording does not show explains nothing).
Eigen::VectorXd fit_away(const std::vector<double>& r, const std::vector<effects::State>& s,
                         Form form, const std::vector<Column>& cols,
                         const std::vector<bool>& away) {
  const auto rows = static_cast<Eigen::Index>(std::count(away.begin(), away.end(), true));
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> a(
      rows, static_cast<Eigen::Index>(cols.size()));
  Eigen::VectorXd b(rows);
  Eigen::Index n = 0;
  for (std::size_t k = 0; k < r.size(); ++k) {
    if (!away[k]) continue;
    unit_row(form, cols, s[k], a.row(n).data());
    b[n++] = r[k];
  }
  // The minimum-norm solution: a column silent there (a law the samples do not exercise) gets
  // zero, not the infinity a pivoted QR divides out of an empty column.
  return a.completeOrthogonalDecomposition().solve(b);
}

// Whether the fitted law `theta` predicts the pulse's samples back under `thr`.
bool explains(const std::vector<double>& t, const std::vector<double>& r,
              const std::vector<effects::State>& s, Form form, const std::vector<Column>& cols,
              const Eigen::VectorXd& theta, const Pulse& p, double thr) {
  const auto [a, b] = span_of(t, p.t_s, p.t_s + p.duration_s);
  for (std::size_t k = a; k < b; ++k)
    if (!(std::abs(less_fitted(form, cols, s[k], theta, r[k])) <= thr))  // NaN explains nothing
      return false;
  return true;
}

// "40 ms", or "40–60 ms" when the lengths differ at that precision.
std::string ms_range(double shortest_s, double longest_s) {
  char out[64];
  if (std::round(shortest_s * 1e3) == std::round(longest_s * 1e3))
    std::snprintf(out, sizeof out, "%.0f ms", longest_s * 1e3);
  else
    std::snprintf(out, sizeof out, "%.0f–%.0f ms", shortest_s * 1e3, longest_s * 1e3);
  return out;
}

}  // namespace

double threshold(const std::vector<double>& r, const Floors& f) {
  return std::max(f.sigmas * stats::robust_sigma(r), f.min_n);
}

// Short runs of the residual far outside its own spread (robust σ) and above the recording's
// floor, few and far between. A model that is merely wrong leaves structure everywhere, not a
// handful of isolated pulses: a pulse must stand out of the residual beside it (a misfit it rides
// on is not a force that came and went), and a force pulse has one sign (a swing through zero
// beyond what the filter makes of a pulse is a transition the model places at a slightly
// different time: a delay or play under a force step).
std::vector<Pulse> find(const std::vector<double>& t, const std::vector<double>& r,
                        const Floors& f) {
  std::vector<Pulse> out;
  if (r.size() < rules::kPulseMinSamples) return out;
  const double thr = threshold(r, f);
  std::size_t i = 0;
  while (i < r.size()) {
    if (std::abs(r[i]) <= thr) {
      ++i;
      continue;
    }
    const Run run = run_from(t, r, i, thr, f.step_s);
    const std::size_t j = run.end;
    const double peak = run.peak;
    const double duration = t[j - 1] - t[i] + f.step_s;
    // Shorter than the filter resolves is ringing of a transition, not a force that acted.
    if (duration <= f.max_s && duration >= rules::kPulseMinFilterPeriods / f.filter_hz &&
        clear_of_ends(f, t[i], t[j - 1])) {
      const auto fl =
          flanks_of(t, r, i, j, peak, duration + rules::kPulseFlankFilterPeriods / f.filter_hz,
                    f.step_s, thr);
      const bool stands_out = std::abs(peak - fl.level_n) > thr;
      // One sign by its peak, or by its impulse: an 8 N pulse that stalls a moving nut for a few
      // milliseconds is followed by a 1.4 N swing as the coupling throws it on (the filtered
      // acceleration lags the jump), 3 % of the pulse's impulse.
      const auto u = filter_undershoot(f, duration);
      const bool one_sign = fl.opposite_n <= std::max(thr, rules::kPulseOppositeFactor * u.of_peak *
                                                               std::abs(peak)) ||
                            fl.opposite_area <= rules::kPulseOppositeFactor * u.of_area * run.area;
      if (stands_out && one_sign) out.push_back({t[i], duration, peak});
    }
    i = j;
  }
  // Isolated: pulses every few seconds at most; more is a misfit, not a disturbance.
  if (static_cast<double>(out.size()) > f.span_s / f.min_spacing_s) out.clear();
  return out;
}

std::vector<Pulse> unexplained(const std::vector<double>& t, const std::vector<double>& r,
                               const std::vector<effects::State>& s, Form form,
                               const Candidates& cand, const std::vector<int>& model,
                               const Floors& f, std::vector<Pulse> found) {
  if (found.empty()) return found;
  const double thr = threshold(r, f);
  const auto away = away_from(t, found, rules::kPulseFlankFilterPeriods / f.filter_hz);
  std::vector<bool> explained(found.size(), false);
  for (const auto& v : cand.variants) {
    // The model's own terms refit beside the law: a term the selection took in the law's place
    // (a Coulomb level for a coupling gain while sliding against friction) leaves the law's
    // force only where the two differ, which the law alone on the residual cannot predict.
    std::vector<int> idx = model;
    for (int j : v.idx)
      if (std::find(idx.begin(), idx.end(), j) == idx.end()) idx.push_back(j);
    std::vector<Column> cols;
    cols.reserve(idx.size());
    for (int j : idx) cols.push_back(cand.cols[static_cast<std::size_t>(j)]);
    const auto theta = fit_away(r, s, form, cols, away);
    for (std::size_t q = 0; q < found.size(); ++q)
      explained[q] = explained[q] || explains(t, r, s, form, cols, theta, found[q], thr);
  }
  std::vector<Pulse> out;
  for (std::size_t q = 0; q < found.size(); ++q)
    if (!explained[q]) out.push_back(found[q]);
  return out;
}

void report(Findings& J, const std::vector<Pulse>& found) {
  if (found.empty()) return;
  // A pulse's times are sample instants and its force a filtered residual's peak: microseconds
  // and millinewtons carry every digit they hold (no more than the printout's sum of steps).
  const auto to = [](double x, double unit) { return std::round(x / unit) * unit; };
  double largest_n = 0, shortest_s = found.front().duration_s, longest_s = 0;
  for (const auto& q : found) {
    Event ev;
    ev.type = "external_disturbance";
    ev.t_s = to(q.t_s, 1e-6);
    ev.duration_s = to(q.duration_s, 1e-6);
    ev.force_n = to(q.peak_n, 1e-3);
    J.events.push_back(ev);
    if (std::abs(q.peak_n) > std::abs(largest_n)) largest_n = *ev.force_n;
    shortest_s = std::min(shortest_s, q.duration_s), longest_s = std::max(longest_s, q.duration_s);
  }
  EffectFinding e;
  e.id = "external_disturbance";
  set_parameter(e.parameters, "count", static_cast<double>(found.size()), true);
  set_parameter(e.parameters, "force_n", largest_n);
  char buf[192];
  std::snprintf(buf, sizeof buf, "%zu pulse%s, the largest %.2f N, %s long (see events)",
                found.size(), found.size() == 1 ? "" : "s", largest_n,
                ms_range(shortest_s, longest_s).c_str());
  e.summary = buf;
  e.where = "isolated force pulses no input explains (see events)";
  e.evidence.events = found.size();
  J.effects.push_back(e);
}

}  // namespace maglead::analysis::pulses
