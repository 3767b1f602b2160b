#include "free_drift.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/LU>

namespace maglead::twin {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// wᵀ Σ w for a covariance given element-wise.
template <std::size_t N, class Cov>
double quad(const std::array<double, N>& w, Cov cov) {
  double v = 0.0;
  for (std::size_t i = 0; i < N; ++i)
    for (std::size_t j = 0; j < N; ++j)
      v += w[i] * w[j] * cov(static_cast<int>(i), static_cast<int>(j));
  return v;
}
template <std::size_t N>
double dot(const std::array<double, N>& a, const std::array<double, N>& b) {
  double v = 0.0;
  for (std::size_t i = 0; i < N; ++i) v += a[i] * b[i];
  return v;
}
}  // namespace

void ConditionBaselines::clear() noexcept {
  cells_.fill(Cell{});
  diff2_ = 0;
  diffs_ = 0;
}

/// Octaves of speed (factor-2 wide, so no speed scale of one actuator is built in), per direction.
int ConditionBaselines::cell_of(int dir, double speed_m_per_s, bool declared) noexcept {
  const double v = std::abs(speed_m_per_s);
  const int oct =
      v > 0 ? std::clamp(static_cast<int>(std::floor(std::log2(v))) + kOctaves - 4, 0, kOctaves - 1)
            : 0;
  return (declared ? 2 * kOctaves : 0) + (dir > 0 ? kOctaves : 0) + oct;
}

void ConditionBaselines::add_reference(int cell, const std::array<double, 5>& x_mean,
                                       double z_mean) noexcept {
  Cell& c = cells_[cell];
  for (std::size_t i = 0; i < x_mean.size(); ++i) c.ref_x[i] += x_mean[i];
  c.ref_z += z_mean;
  ++c.ref_n;
}

void ConditionBaselines::freeze(const std::array<double, 5>& theta) noexcept {
  for (Cell& c : cells_) {
    if (c.ref_n > 0) c.ref_r = (c.ref_z - dot(c.ref_x, theta)) / c.ref_n;
  }
}

void ConditionBaselines::add(int cell, double r, double level_n, double known_s,
                             double memory_s) noexcept {
  Cell& c = cells_[cell];
  const double dir = dir_of(cell);
  // The change common to all conditions since this one's last pass is taken out of the
  // successive difference: a drift is not scatter.
  const double common = pooled(known_s, memory_s, 0.0).change_n;
  const double now = std::isfinite(common) ? common : 0.0;
  if (c.has_last) {
    const double d = dir * (r - c.last_r) - (now - c.last_common);
    diff2_ += 0.5 * d * d, ++diffs_;
  }
  c.last_r = r, c.last_common = now, c.has_last = true;
  if (c.ref_n == 0) {  // a condition first seen after the reference: its first pass is its baseline
    c.ref_r = r, c.ref_n = 1;
    return;
  }
  const double f = std::exp(-(known_s - c.at_s) / memory_s);
  c.sum = f * c.sum + r, c.lev = f * c.lev + level_n;
  c.w = f * c.w + 1.0, c.w2 = f * f * c.w2 + 1.0, c.at_s = known_s;
}

ConditionBaselines::Estimate ConditionBaselines::estimate(double known_s,
                                                          double memory_s) const noexcept {
  // Until three pass-to-pass differences are measured the scatter is unknown: the change is
  // given without its standard error.
  Estimate e = pooled(known_s, memory_s, diffs_ >= 3 ? diff2_ / diffs_ : 0.0);
  e.scatter_measured = diffs_ >= 3 && diff2_ > 0;
  return e;
}

ConditionBaselines::Changes ConditionBaselines::changes(double known_s, double memory_s,
                                                        double s2) const noexcept {
  Changes c;
  for (int i = 0; i < kCells; ++i) {
    const Cell& x = cells_[i];
    // Seen within the memory: a condition last met long ago says what the drift was then.
    if (x.w <= 0 || known_s - x.at_s > memory_s) continue;
    c.d[c.k] = dir_of(i) * (x.sum / x.w - x.ref_r);
    c.v[c.k] = (s2 > 0 ? s2 : 1.0) * (1.0 / x.ref_n + x.w2 / (x.w * x.w));
    c.level[c.k] = x.lev / x.w;
    c.dir[c.k] = dir_of(i);
    ++c.k;
  }
  return c;
}

/// DerSimonian–Laird: conditions weighted by 1 / (their variance + the between-condition one).
/// s2 is the scatter of one pass; with s2 = 0 the conditions are weighted by their pass counts
/// alone (the mean is the same for any common scale) and no standard error is given.
ConditionBaselines::Estimate ConditionBaselines::pooled(double known_s, double memory_s,
                                                        double s2) const noexcept {
  const Changes c = changes(known_s, memory_s, s2);
  const auto& d = c.d;
  const auto& v = c.v;
  const int k = c.k;
  Estimate e;
  if (k == 0) return e;
  double sw = 0, sw2 = 0, swd = 0;
  for (int i = 0; i < k; ++i) sw += 1 / v[i], sw2 += 1 / (v[i] * v[i]), swd += d[i] / v[i];
  double q = 0;
  for (int i = 0; i < k; ++i) q += (d[i] - swd / sw) * (d[i] - swd / sw) / v[i];
  const double tau2 = k > 1 && s2 > 0 ? std::max(0.0, (q - (k - 1)) / (sw - sw2 / sw)) : 0.0;
  double w = 0, wd = 0;
  for (int i = 0; i < k; ++i) w += 1 / (v[i] + tau2), wd += d[i] / (v[i] + tau2);
  e.change_n = wd / w, e.conditions = k;
  if (s2 > 0) e.se_n = std::sqrt(1 / w);
  return e;
}

namespace {
template <int P>
struct Fit {
  Eigen::Matrix<double, P, 1> theta;
  Eigen::Matrix<double, P, P> cov;  // (XᵀWX)⁻¹: the covariance of θ for the given variances
  double sw = 0, swd = 0;           // Σw and Σw·d with the final weights
  bool ok = false;
};

/// Random-effects weighted least squares of the conditions' changes on P columns x(i): the
/// between-condition variance around the fit by DerSimonian–Laird's moments,
/// τ² = (Q − (k − P)) / (Σw − tr((XᵀWX)⁻¹ XᵀW²X)), then the fit with weights 1 / (v + τ²).
template <int P, class Changes, class Columns>
Fit<P> random_effects_fit(const Changes& c, Columns x) {
  using Mat = Eigen::Matrix<double, P, P>;
  using Col = Eigen::Matrix<double, P, 1>;
  const auto solve = [&](double tau2, Fit<P>& f) {
    Mat a = Mat::Zero();
    Col b = Col::Zero();
    f.sw = f.swd = 0;
    for (int i = 0; i < c.k; ++i) {
      const Col xi = x(i);
      const double w = 1 / (c.v[i] + tau2);
      a += w * xi * xi.transpose(), b += w * c.d[i] * xi;
      f.sw += w, f.swd += w * c.d[i];
    }
    Eigen::FullPivLU<Mat> lu(a);
    lu.setThreshold(1e-10);  // columns that hardly differ: no fit rather than a huge error bar
    if (!lu.isInvertible()) return false;
    f.cov = lu.inverse(), f.theta = f.cov * b;
    return true;
  };
  Fit<P> f;
  if (c.k <= P || !solve(0.0, f)) return f;
  double q = 0, sw = 0, trace = 0;
  for (int i = 0; i < c.k; ++i) {
    const Col xi = x(i);
    const double w = 1 / c.v[i], e = c.d[i] - xi.dot(f.theta);
    q += w * e * e, sw += w, trace += w * w * xi.dot(f.cov * xi);
  }
  // Σw − tr(…) is positive with more conditions than columns; guarded all the same.
  const double tau2 = sw > trace ? std::max(0.0, (q - (c.k - P)) / (sw - trace)) : 0.0;
  f.ok = solve(tau2, f);
  return f;
}
}  // namespace

/// Two fits. The changes on the levels (d = α·L + β): at the conditions' weighted mean level
/// this is their weighted mean, as pooled, but a change that follows the levels (a gain change
/// under an offset load, F_c ∓ c) is explained by the line instead of counting as scatter between
/// conditions. And the slope with a term of the direction's own (d = α·L + β + γ·dir): only
/// levels that differ within a direction determine it, so a load put on (±γ) is never read as a
/// gain change. A mismatch that a fit does not explain widens its error bars (τ²).
ConditionBaselines::Levels ConditionBaselines::levels(double known_s,
                                                      double memory_s) const noexcept {
  Levels out;
  if (diffs_ < 3 || !(diff2_ > 0)) return out;
  const Changes c = changes(known_s, memory_s, diff2_ / diffs_);
  const auto line =
      random_effects_fit<2>(c, [&](int i) { return Eigen::Vector2d(c.level[i], 1.0); });
  if (!line.ok) return out;  // too few conditions, or levels that hardly differ
  // At the weighted mean level the line's value is Σw·d / Σw (its residuals sum to zero).
  out.mean_n = line.swd / line.sw, out.mean_se_n = std::sqrt(1 / line.sw);
  const auto lev =
      random_effects_fit<3>(c, [&](int i) { return Eigen::Vector3d(c.level[i], 1.0, c.dir[i]); });
  if (!lev.ok) return out;
  out.alpha = lev.theta(0), out.alpha_se = std::sqrt(lev.cov(0, 0));
  out.beta = lev.theta(1), out.var_beta = lev.cov(1, 1), out.cov_ab = lev.cov(0, 1);
  return out;
}

double ConditionBaselines::Levels::se_at(double level_n) const noexcept {
  return std::sqrt(
      std::max(0.0, level_n * level_n * alpha_se * alpha_se + 2 * level_n * cov_ab + var_beta));
}

void FreeMoveDrift::clear() noexcept {
  cur_.reset(1e4);
  ref_.reset(1e4);
  base_.clear();
  pass_n_ = 0;
  pass_cell_ = -1;
  block_n_ = 0;
  known_s_ = ref_t_sum_ = ref_t_ = warn_t_ = 0;
  ref_frozen_ = warn_ = false;
  stat_ = 0;
  cond_since_ = kNaN;
  reason_ = DriftReason::none;
  now_ = at_warn_ = DriftFigures{};
  passive_ = PassiveEstimate{};
}

DriftObservability FreeMoveDrift::observability() const noexcept {
  if (ref_frozen_) return DriftObservability::tracking;
  return known_s_ > 0 || block_n_ > 0 ? DriftObservability::reference : DriftObservability::none;
}

/// The model needs coupling force y for the measured motion; a coupling of gain g with a friction
/// change ΔF_f needs g·u = y + ΔF_f·dir, so u − y = (1/g − 1)·y + (ΔF_f/g)·dir, linear in
/// α = 1/g − 1 ≈ 1 − g and β ≈ ΔF_f. The regressor is y, not u: u carries the quantization
/// noise of the residual itself. A direction-independent force
/// (an offset, a constant load: c), a viscous mismatch (a dashpot load: γ v) and a force along
/// the stroke (a spring, a cable chain: κ p) are nuisance terms; what stays constant is taken up
/// by the reference. Averaged in blocks of block_s.
void FreeMoveDrift::add(double t, double dt, double u, double y, int dir, double vel, double pos_m,
                        bool declared) noexcept {
  if (block_n_ == 0) {
    block_x_.fill(0.0);
    block_z_ = block_t_ = block_dt_ = 0.0;
  }
  // Scaled to forces of a few N.
  const Vec x{y, static_cast<double>(dir), 1.0, vel * 100.0, pos_m * 100.0};
  for (int i = 0; i < kP; ++i) block_x_[i] += x[i];
  block_z_ += u - y;
  block_t_ += t;
  block_dt_ += dt;
  block_declared_ = declared;
  ++block_n_;
  if (block_dt_ + 0.5 * dt >= s_.block_s) update_block(t);
}

void FreeMoveDrift::skip(double t) noexcept {
  block_n_ = 0;
  if (pass_n_ > 0) end_pass(t);
}

void FreeMoveDrift::update_block(double t) noexcept {
  const double n = block_n_;
  for (double& v : block_x_) v /= n;
  const double z = block_z_ / n, tm = block_t_ / n, span = block_dt_;
  block_n_ = 0;
  known_s_ += span;
  const int cell =
      ConditionBaselines::cell_of(block_x_[1] > 0 ? 1 : -1, block_x_[3] / 100.0, block_declared_);
  if (pass_n_ > 0 && cell != pass_cell_) end_pass(t);
  if (pass_n_ == 0) pass_x_.fill(0.0), pass_z_ = pass_s_ = 0.0, pass_cell_ = cell;
  for (int i = 0; i < kP; ++i) pass_x_[i] += block_x_[i];
  pass_z_ += z, pass_s_ += span, ++pass_n_;
  cur_.update(block_x_, z, std::exp(-span / s_.memory_s));
  cur_.cap(1e4);
  if (!ref_frozen_) {
    ref_.update(block_x_, z, 1.0);
    ref_t_sum_ += tm;
    // Frozen once long enough and precise enough to resolve the smallest change worth a warning
    // even if all of it were gain (the worst case at the rated force).
    const Vec w0{s_.friction_n, 1.0, 0.0, 0.0, 0.0};
    const double se0 = std::sqrt(quad(w0, [&](int i, int j) { return ref_.cov(i, j); }));
    if (known_s_ >= s_.reference_s && std::isfinite(se0) &&
        s_.sigmas * se0 <= min_error_n() / rated_factor()) {
      ref_frozen_ = true;
      ref_t_ = ref_t_sum_ / static_cast<double>(ref_.count());
      for (int i = 0; i < kP; ++i) {
        ref_theta_[i] = ref_.theta(i);
        for (int j = 0; j < kP; ++j) ref_cov_[i][j] = ref_.cov(i, j);
      }
      base_.freeze(ref_theta_);
    }
    return;
  }
  // Judged every block on the passes completed so far, so that the sustain time is measured in
  // time, not in pass ends (a pass may last seconds).
  evaluate(t);
}

/// A pass ends (the condition changed or the known-force stretch ended): before the reference
/// it adds to its condition's baseline, after it its residual against the reference model is
/// compared with that baseline.
void FreeMoveDrift::end_pass(double t) noexcept {
  const int n = pass_n_;
  pass_n_ = 0;
  if (pass_s_ < s_.min_pass_s) return;
  for (double& v : pass_x_) v /= n;
  const double z = pass_z_ / n;
  if (!ref_frozen_) {
    base_.add_reference(pass_cell_, pass_x_, z);
    return;
  }
  // The coupling force along the motion, u = y + (u − y): an offset load makes it differ
  // between the directions, which is what lets the levels separate gain from friction.
  const double level = (pass_x_[1] > 0 ? 1.0 : -1.0) * (pass_x_[0] + z);
  base_.add(pass_cell_, z - dot(pass_x_, ref_theta_), level, known_s_, s_.memory_s);
  evaluate(t);
}

void FreeMoveDrift::passive(double t, const PassiveEstimate& e, bool new_window) noexcept {
  passive_ = e;
  evaluate(t, new_window ? e.window_s : 0.0);
}

// Not judged is not back within the margin: a moment without evidence leaves the sustain running.
void FreeMoveDrift::evaluate(double t, double evidence_s) noexcept {
  DriftFigures f;
  f.rated_force_n = s_.rated_n;
  const bool free_judged = ref_frozen_ && free_figures(f);
  const bool judged = pool_passive(f, free_judged) || free_judged;
  if (ref_frozen_ || judged || std::isfinite(passive_.zero_load_n)) now_ = f;
  if (!judged) return;
  judge(t, f, evidence_s);
}

/// The free moves' figures; false while they cannot be judged yet.
bool FreeMoveDrift::free_figures(DriftFigures& f) const noexcept {
  const auto cov = [&](int i, int j) { return cur_.cov(i, j) + ref_cov_[i][j]; };
  const auto change = [&](const Vec& w) {
    double d = 0.0;
    for (int i = 0; i < kP; ++i) d += w[i] * (cur_.theta(i) - ref_theta_[i]);
    return d;
  };
  const double fr = s_.rated_n + s_.friction_n;
  const Vec wr{fr, 1.0, 0.0, 0.0};
  const Vec wg{1.0, 0.0, 0.0, 0.0, 0.0}, wf{0.0, 1.0, 0.0, 0.0, 0.0};
  const ConditionBaselines::Estimate e = base_.estimate(known_s_, s_.memory_s);
  f.zero_load_n = e.change_n;
  // The regression's standard error (the blocks' scatter, AR(1)-inflated) is a lower bound: the
  // scatter between passes can only add to it, and it is there before passes repeat.
  const Vec w0{s_.friction_n, 1.0, 0.0, 0.0, 0.0};
  const double se_blocks = std::sqrt(quad(w0, cov));
  f.zero_load_se_n = std::isfinite(e.se_n) ? std::max(e.se_n, se_blocks) : se_blocks;
  const double se_g = std::sqrt(quad(wg, cov));
  // Separable: the data resolve a gain change of min_change by themselves (accelerations and
  // speeds that make the coupling force differ within a direction of motion).
  f.separable = std::isfinite(se_g) && s_.sigmas * se_g <= s_.min_change;
  if (f.separable) {
    f.rated_n = change(wr), f.rated_se_n = std::sqrt(quad(wr, cov));
    f.gain_change = -change(wg), f.gain_change_se = se_g;
    f.friction_change_n = change(wf), f.friction_change_se_n = std::sqrt(quad(wf, cov));
  } else if (!level_figures(f)) {
    f.rated_worst_n = f.zero_load_n * rated_factor();
  }
  // Not judged before the scatter between passes of one condition is measured: the blocks'
  // scatter alone misses how much passes differ (live, the first passes' baselines made the
  // largest no-drift statistics).
  return e.scatter_measured && std::isfinite(f.zero_load_n) && std::isfinite(f.zero_load_se_n) &&
         (!f.separable || std::isfinite(f.rated_se_n));
}

/// The conditions' changes against their levels (ConditionBaselines::levels): the zero-load
/// figure is the line at the conditions' mean level, its standard error from the passes' own
/// scatter around the line, not from the blocks' regression, whose viscous nuisance is collinear
/// with the direction where the two directions run at different speeds. Where levels within a
/// direction resolve the slope to min_change at the flag's significance, gain and friction are
/// separated (figures at F_c and at the rated force, the load term left out). False: not
/// separable.
bool FreeMoveDrift::level_figures(DriftFigures& f) const noexcept {
  const ConditionBaselines::Levels l = base_.levels(known_s_, s_.memory_s);
  if (!std::isfinite(l.mean_n)) return false;
  f.zero_load_n = l.mean_n, f.zero_load_se_n = l.mean_se_n;
  if (!(s_.sigmas * l.alpha_se <= s_.min_change)) return false;
  const double f0 = s_.friction_n, fr = s_.rated_n + s_.friction_n;
  f.separable = true;
  f.zero_load_n = l.at(f0), f.zero_load_se_n = l.se_at(f0);
  f.rated_n = l.at(fr), f.rated_se_n = l.se_at(fr);
  f.gain_change = -l.alpha, f.gain_change_se = l.alpha_se;
  f.friction_change_n = l.beta, f.friction_change_se_n = std::sqrt(l.var_beta);
  return true;
}

/// A passive load revisited resolves the gain by itself (its range of forces at the same places),
/// so the figures become separable: the zero-load change pooled by inverse variance with the free
/// moves' (where they are judged), the rated-force change and the gain from the load.
bool FreeMoveDrift::pool_passive(DriftFigures& f, bool free_judged) const noexcept {
  const PassiveEstimate& p = passive_;
  if (!std::isfinite(p.zero_load_n) || !std::isfinite(p.rated_se_n)) return false;
  if (!p.scatter_measured && free_judged) return false;  // the free moves' judged figures stand
  double z = p.zero_load_n, se = p.zero_load_se_n;
  if (free_judged) {
    const double wa = 1 / (f.zero_load_se_n * f.zero_load_se_n), wb = 1 / (se * se);
    z = (wa * f.zero_load_n + wb * z) / (wa + wb), se = std::sqrt(1 / (wa + wb));
  }
  f.zero_load_n = z, f.zero_load_se_n = se;
  f.separable = true;
  f.rated_n = p.rated_n, f.rated_se_n = p.rated_se_n;
  f.rated_worst_n = kNaN;
  f.gain_change = p.gain_change, f.gain_change_se = p.gain_change_se;
  // Δ0 = α·F_c + β with α ≈ −Δg: what is left of the zero-load change is friction.
  f.friction_change_n = z + p.gain_change * s_.friction_n;
  f.friction_change_se_n = std::hypot(se, p.gain_change_se * s_.friction_n);
  return p.scatter_measured;  // shown before, judged once its scatter is measured
}

/// Judged on significance and size together: a change counts when it is both beyond sigmas
/// standard errors and beyond the minimum worth a warning. An estimate too imprecise to resolve
/// the minimum is still judged (its own margin is the larger one): a fast drift inflates the
/// standard errors while it runs, and refusing to judge then would hide exactly that drift.
/// Sustained: past the margin for sustain_s of time, or on a window of evidence at least that
/// long (a passive window is seconds of force control that all moved the estimate past it; a
/// recording that ends, or a stretch that stops, before the clock catches up must not hide it).
void FreeMoveDrift::judge(double t, const DriftFigures& f, double evidence_s) noexcept {
  const double fr = s_.rated_n + s_.friction_n, k = rated_factor(), m = min_error_n();
  const auto ratio = [&](double d, double se, double floor) {
    return std::abs(d) / std::max(s_.sigmas * se, floor);
  };
  stat_ = f.separable ? std::max(ratio(f.zero_load_n, f.zero_load_se_n, m),
                                 ratio(f.rated_n, f.rated_se_n, m))
                      : ratio(f.zero_load_n, f.zero_load_se_n, m / k);
  if (stat_ < 1.0) {
    cond_since_ = kNaN;
    return;
  }
  if (!std::isfinite(cond_since_)) cond_since_ = t;
  if (warn_ || std::max(t - cond_since_, evidence_s) < s_.sustain_s) return;
  warn_ = true;
  warn_t_ = t;
  at_warn_ = f;
  if (!f.separable) {
    reason_ = f.zero_load_n > 0 ? DriftReason::error_rose : DriftReason::error_fell;
  } else if (std::abs(f.gain_change) * fr >= std::abs(f.friction_change_n)) {
    reason_ = f.gain_change < 0 ? DriftReason::gain_fell : DriftReason::gain_rose;
  } else {
    reason_ = f.friction_change_n > 0 ? DriftReason::friction_rose : DriftReason::friction_fell;
  }
}

}  // namespace maglead::twin
