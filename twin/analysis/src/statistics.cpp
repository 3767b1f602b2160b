// Shared statistics of the analysis engines (see statistics.hpp).
#include "statistics.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <stdexcept>
#include <utility>

#include "maglead/analysis/rules.hpp"

namespace maglead::analysis::stats {
namespace {
// A column whose sum of squares is below this share of the largest is zero to rounding (double
// precision: squares of 1e-16 relative; a physical column is far above).
constexpr double kZeroColumn = 1e-20;
// σ from the median absolute deviation, for normal data.
constexpr double kMadToSigma = 1.4826;
// The t of gains with no spread at all: certain when positive.
constexpr double kTWithoutSpread = 1e9;
// Steps of t_s the median sample step is taken from: enough, and quick on an hour's recording.
// Ridge on the normal equations (relative, and absolute below any data's scale): collinear
// columns stay finite.
constexpr double kRidge = 1e-9, kTinyRidge = 1e-300, kPartialRidge = 1e-12;

// The median (upper middle), reordering x: the value does not depend on the order it is given.
double median_reordering(std::vector<double>& x) {
  if (x.empty()) return 0.0;
  const auto mid = x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2);
  std::nth_element(x.begin(), mid, x.end());
  return *mid;
}
}  // namespace

double median_of(std::vector<double> x) { return median_reordering(x); }

double robust_sigma(std::vector<double> x) {
  if (x.empty()) return 0.0;
  // In place: the deviations' median does not depend on their order either.
  const double m = median_reordering(x);
  for (double& v : x) v = std::abs(v - m);
  return kMadToSigma * median_reordering(x);
}

double t_statistic(const std::vector<double>& x) {
  const double n = static_cast<double>(x.size());
  if (n < 2) return 0.0;
  const double mean = std::accumulate(x.begin(), x.end(), 0.0) / n;
  double var = 0;
  for (double v : x) var += (v - mean) * (v - mean);
  var /= n - 1;
  return var > 0 ? mean / std::sqrt(var / n) : (mean > 0 ? kTWithoutSpread : 0.0);
}

double total(const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0); }

void require_finite(const Recording& rec, const std::vector<double>& x, const std::string& name) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (std::isfinite(x[i])) continue;
    // The reader keeps no line numbers: the row's time finds it in any viewer.
    std::string at = "data row " + std::to_string(i + 1);
    if (name != "t_s" && rec.has("t_s") && i < rec.column("t_s").size() &&
        std::isfinite(rec.column("t_s")[i])) {
      char t[48];
      std::snprintf(t, sizeof t, " (t_s = %.6g s)", rec.column("t_s")[i]);
      at += t;
    }
    throw RecordingError(rec.path + ": column '" + name + "' is empty in " + at +
                         ": the analysis needs a value in every row of it; fill the gap or drop "
                         "the row");
  }
}

void require_analysable(const Recording& rec, const std::vector<std::string>& columns) {
  for (const auto& c : columns) require_finite(rec, rec.column(c), c);  // column(): names it
  const std::size_t n = rec.column("t_s").size();
  if (n < rules::kMinRows)
    throw std::invalid_argument(rec.path + ": too short to analyse (" + std::to_string(n) +
                                " rows; the analysis needs at least " +
                                std::to_string(rules::kMinRows) + ")");
}

double white_noise_sigma(const std::vector<double>& y) {
  std::vector<double> d2;
  d2.reserve(y.size());
  for (std::size_t i = 1; i + 1 < y.size(); ++i) d2.push_back(y[i + 1] - 2 * y[i] + y[i - 1]);
  return robust_sigma(std::move(d2)) / std::sqrt(6.0);
}

namespace {

/// The share of `v` (sorted) within `on_step` of a whole number of `step`s from `origin`.
double share_on_grid(const std::vector<double>& v, double origin, double step, double on_step) {
  std::size_t on = 0;
  for (double x : v) {
    const double steps = (x - origin) / step;
    if (std::abs(steps - std::round(steps)) <= on_step) ++on;
  }
  return static_cast<double>(on) / static_cast<double>(v.size());
}

/// The value `v` (sorted) holds most often: a logged value, never a row the reader filled.
double most_common(const std::vector<double>& v, double same) {
  double mode = v.front();
  std::size_t best = 0;
  for (std::size_t i = 0, j = 0; i < v.size(); i = j) {
    while (j < v.size() && v[j] - v[i] <= same) ++j;
    if (j - i > best) best = j - i, mode = v[i];
  }
  return mode;
}

}  // namespace

double logging_step(const std::vector<double>& y) {
  // Values within this share of the column's largest are one logged value (a decimal step such
  // as 0.1 is written with rounding in its last digits).
  constexpr double kSameValue = 1e-9;
  // A value within this share of a step from a whole number of steps is on the step.
  constexpr double kOnTheStep = 0.01;
  // The reader fills a missing row by interpolating its neighbours, off the logged grid: a step
  // holds when this share of the rows lie on it. A few filled rows stay below the rest; a
  // continuous column lands within kOnTheStep of a grid by chance in only about 2 % of its rows.
  constexpr double kOnGridShare = 0.95;
  // Gaps tried as the step, smallest first: each filled value splits one gap into two pieces
  // off the grid, so this covers several filled values and the grid's own step after them.
  constexpr std::size_t kCandidateGaps = 16;
  std::vector<double> v;
  v.reserve(y.size());
  for (double x : y)
    if (std::isfinite(x)) v.push_back(x);
  std::sort(v.begin(), v.end());
  if (v.size() < 2) return 0.0;
  const double same = kSameValue * std::max(std::abs(v.front()), std::abs(v.back()));
  std::vector<double> gaps;
  for (std::size_t i = 1; i < v.size(); ++i)
    if (v[i] - v[i - 1] > same) gaps.push_back(v[i] - v[i - 1]);
  std::sort(gaps.begin(), gaps.end());
  gaps.erase(std::unique(gaps.begin(), gaps.end(),
                         [&](double a, double b) { return b - a <= kOnTheStep * a; }),
             gaps.end());
  if (gaps.size() > kCandidateGaps) gaps.resize(kCandidateGaps);
  // The largest that holds: half a step (a row filled midway between two logged values) would
  // hold too, and is no step the cell logs.
  const double origin = most_common(v, same);
  for (std::size_t k = gaps.size(); k-- > 0;)
    if (share_on_grid(v, origin, gaps[k], kOnTheStep) >= kOnGridShare) return gaps[k];
  return 0.0;
}

SensorNoise sensor_noise(const std::vector<double>& y) {
  SensorNoise n;
  n.sigma = white_noise_sigma(y);
  n.step = logging_step(y);
  // A uniform rounding error over one step has this standard deviation.
  const double rounding = n.step / std::sqrt(12.0);
  if (n.sigma <= rounding) {
    n.sigma = rounding;
    n.measured = false;
  }
  return n;
}

std::size_t fold_of(double since_start_s, double span_s, int folds) {
  if (!(span_s > 0)) return 0;
  return static_cast<std::size_t>(
      std::clamp<double>(std::floor(folds * since_start_s / span_s), 0.0, folds - 1));
}

std::vector<std::size_t> fold_starts(const std::vector<double>& t, double start_s, double span_s,
                                     int folds) {
  std::vector<std::size_t> starts(static_cast<std::size_t>(folds) + 1, t.size());
  starts[0] = 0;
  std::size_t f = 1;
  for (std::size_t i = 0; i < t.size() && f < starts.size() - 1; ++i)
    while (f < starts.size() - 1 && fold_of(t[i] - start_s, span_s, folds) >= f) starts[f++] = i;
  return starts;
}

Grams::Grams(std::size_t folds, Eigen::Index columns)
    : xx(folds, Eigen::MatrixXd::Zero(columns, columns)),
      xr(folds, Eigen::VectorXd::Zero(columns)),
      rr(folds, 0.0),
      yy(folds, 0.0),
      n(folds, 0) {}

void Grams::add_row(std::size_t fold, const Eigen::VectorXd& x, double r, double y) {
  xx[fold].selfadjointView<Eigen::Lower>().rankUpdate(x);
  xr[fold] += x * r;
  rr[fold] += r * r;
  yy[fold] += y * y;
  ++n[fold];
}

void Grams::add_rows(std::size_t fold, const Eigen::Ref<const RowMatrix>& x,
                     const Eigen::Ref<const Eigen::VectorXd>& r, double yy_sum) {
  xx[fold].selfadjointView<Eigen::Lower>().rankUpdate(x.transpose());
  xr[fold].noalias() += x.transpose() * r;
  rr[fold] += r.squaredNorm();
  yy[fold] += yy_sum;
  n[fold] += static_cast<std::size_t>(x.rows());
}

void Grams::symmetrize() {
  for (auto& a : xx) a = a.selfadjointView<Eigen::Lower>();
}

void Grams::add_segment(const Eigen::Ref<const Eigen::MatrixXd>& x, const Eigen::VectorXd& r,
                        double yy_sum) {
  xx.push_back(x.transpose() * x);
  xr.push_back(x.transpose() * r);
  rr.push_back(r.squaredNorm());
  yy.push_back(yy_sum);
  n.push_back(static_cast<std::size_t>(x.rows()));
}

Fit solve(const Grams& g, const std::vector<int>& idx, int skip_fold) {
  const auto m = static_cast<Eigen::Index>(idx.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  for (std::size_t f = 0; f < g.xx.size(); ++f) {
    if (static_cast<int>(f) == skip_fold) continue;
    for (Eigen::Index r = 0; r < m; ++r) {
      b[r] += g.xr[f][idx[static_cast<std::size_t>(r)]];
      for (Eigen::Index c = 0; c < m; ++c)
        A(r, c) += g.xx[f](idx[static_cast<std::size_t>(r)], idx[static_cast<std::size_t>(c)]);
    }
  }
  // A whisper of ridge on the scaled normal equations keeps collinear columns finite. A column
  // that is zero to rounding (F_m sin θ on a screw held at θ = 2π: 1e-16 of F_m) is left out, its
  // coefficient 0: scaled up it would fit the noise with any value.
  const double largest = m ? A.diagonal().maxCoeff() : 0.0;
  for (Eigen::Index r = 0; r < m; ++r) {
    if (A(r, r) <= kZeroColumn * largest) {
      A.row(r).setZero(), A.col(r).setZero(), b[r] = 0;
      A(r, r) = 1;
    }
    A(r, r) += kRidge * A(r, r) + kTinyRidge;
  }
  Fit fit{idx, m ? Eigen::VectorXd(A.ldlt().solve(b)) : Eigen::VectorXd()};
  return fit;
}

double sse(const Grams& g, const Fit& fit, std::size_t f) {
  double s = g.rr[f];
  const auto m = static_cast<Eigen::Index>(fit.idx.size());
  for (Eigen::Index r = 0; r < m; ++r) {
    s -= 2 * fit.theta[r] * g.xr[f][fit.idx[static_cast<std::size_t>(r)]];
    for (Eigen::Index c = 0; c < m; ++c)
      s += fit.theta[r] * fit.theta[c] *
           g.xx[f](fit.idx[static_cast<std::size_t>(r)], fit.idx[static_cast<std::size_t>(c)]);
  }
  return std::max(0.0, s);
}

std::vector<double> heldout(const Grams& g, const std::vector<int>& idx) {
  std::vector<double> out(g.xx.size(), 0.0);
  for (std::size_t f = 0; f < g.xx.size(); ++f) {
    if (g.n[f] == 0) continue;
    out[f] = sse(g, solve(g, idx, static_cast<int>(f)), f);
  }
  return out;
}

Eigen::MatrixXd summed_gram(const Grams& g, const std::vector<int>& idx) {
  const auto m = static_cast<Eigen::Index>(idx.size());
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(m, m);
  for (const auto& xx : g.xx)
    for (Eigen::Index r = 0; r < m; ++r)
      for (Eigen::Index c = 0; c < m; ++c) S(r, c) += xx(idx[r], idx[c]);
  return S;
}

double partial_r2(const Grams& g, const std::vector<int>& base, const std::vector<int>& a,
                  const Eigen::VectorXd& wa, const std::vector<int>& b) {
  std::vector<int> all = base;
  all.insert(all.end(), a.begin(), a.end());
  all.insert(all.end(), b.begin(), b.end());
  const auto m = static_cast<Eigen::Index>(all.size());
  Eigen::MatrixXd S = summed_gram(g, all);
  // Noise independent of the signal adds its sum of squares to its own column's and, in
  // expectation, nothing to the cross terms. A column whose sum of squares the noise would
  // exhaust carries no signal to correct.
  if (g.noise_ss.size() > 0)
    for (Eigen::Index r = 0; r < m; ++r)
      if (const double e = g.noise_ss[all[r]]; e > 0 && e < S(r, r)) S(r, r) -= e;
  const auto nb = static_cast<Eigen::Index>(base.size()), na = static_cast<Eigen::Index>(a.size()),
             nn = static_cast<Eigen::Index>(b.size());
  // Residualise on `base`, then ask how much of z = X_a wa the span of X_b explains.
  Eigen::MatrixXd Sbb = S.topLeftCorner(nb, nb);
  Eigen::MatrixXd R = S;
  if (nb > 0) {
    Eigen::MatrixXd Sbr = S.topRows(nb);
    Eigen::LDLT<Eigen::MatrixXd> ld(Sbb + kPartialRidge * Eigen::MatrixXd::Identity(nb, nb) *
                                              (Sbb.trace() / static_cast<double>(nb) + kTinyRidge));
    R = S - Sbr.transpose() * ld.solve(Sbr);
  }
  const Eigen::MatrixXd Raa = R.block(nb, nb, na, na), Rab = R.block(nb, nb + na, na, nn),
                        Rbb = R.block(nb + na, nb + na, nn, nn);
  const double zz = wa.dot(Raa * wa);
  if (!(zz > 0)) return 0.0;
  const Eigen::VectorXd bz = Rab.transpose() * wa;
  Eigen::LDLT<Eigen::MatrixXd> lb(Rbb + kPartialRidge * Eigen::MatrixXd::Identity(nn, nn) *
                                            (Rbb.trace() / static_cast<double>(nn) + kTinyRidge));
  return std::clamp(bz.dot(lb.solve(bz)) / zz, 0.0, 1.0);
}

double sse(const Grams& g, const Fit& fit) {
  double out = 0;
  for (std::size_t f = 0; f < g.folds(); ++f) out += sse(g, fit, f);
  return out;
}

std::vector<Fit> leave_one_out(const Grams& g, const std::vector<int>& idx) {
  std::vector<Fit> fits;
  for (std::size_t f = 0; f < g.folds(); ++f)
    if (g.n[f] > 0) fits.push_back(solve(g, idx, static_cast<int>(f)));
  return fits;
}

// Over contiguous time segments, so slow drifts and correlated noise count as they would in a
// new recording (a per-sample formula would take them for independent noise).
Named jackknife_se(const std::vector<Named>& leave_one_out_values) {
  std::map<std::string, std::vector<double>, std::less<>> values;
  for (const auto& fit : leave_one_out_values)
    for (const auto& [name, v] : fit) values[name].push_back(v);
  Named se;
  for (const auto& [name, v] : values) {
    if (v.size() < 2) continue;
    const auto k = static_cast<double>(v.size());
    const double mean = std::accumulate(v.begin(), v.end(), 0.0) / k;
    double ss = 0;
    for (double x : v) ss += (x - mean) * (x - mean);
    se[name] = std::sqrt((k - 1) / k * ss);
  }
  return se;
}

Estimates estimate(const Grams& g, const std::vector<int>& idx, const GroupValues& values) {
  Estimates out;
  out.fit = solve(g, idx);
  out.values = values(out.fit);
  std::vector<std::vector<Named>> per_group(out.values.size());
  for (const Fit& fit : leave_one_out(g, idx)) {
    auto v = values(fit);
    for (std::size_t k = 0; k < per_group.size() && k < v.size(); ++k)
      if (v[k]) per_group[k].push_back(std::move(*v[k]));
  }
  for (const auto& group : per_group) out.standard_errors.push_back(jackknife_se(group));
  return out;
}

}  // namespace maglead::analysis::stats
