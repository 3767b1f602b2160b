#include "free_drift.hpp"

#include <cmath>

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
}  // namespace

void FreeMoveDrift::clear() noexcept {
  cur_.reset(1e4);
  ref_.reset(1e4);
  block_n_ = 0;
  known_s_ = ref_t_sum_ = ref_t_ = warn_t_ = 0;
  ref_frozen_ = warn_ = false;
  stat_ = 0;
  cond_since_ = kNaN;
  reason_ = DriftReason::none;
  now_ = at_warn_ = DriftFigures{};
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
void FreeMoveDrift::add(double t, double dt, double u, double y, int dir, double vel,
                        double pos_m) noexcept {
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
  ++block_n_;
  if (block_dt_ + 0.5 * dt >= s_.block_s) update_block(t);
}

void FreeMoveDrift::update_block(double t) noexcept {
  const double n = block_n_;
  for (double& v : block_x_) v /= n;
  const double z = block_z_ / n, tm = block_t_ / n, span = block_dt_;
  block_n_ = 0;
  known_s_ += span;
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
    }
    return;
  }
  evaluate(t);
}

void FreeMoveDrift::evaluate(double t) noexcept {
  const auto cov = [&](int i, int j) { return cur_.cov(i, j) + ref_cov_[i][j]; };
  const auto change = [&](const Vec& w) {
    double d = 0.0;
    for (int i = 0; i < kP; ++i) d += w[i] * (cur_.theta(i) - ref_theta_[i]);
    return d;
  };
  const double fr = s_.rated_n + s_.friction_n, k = rated_factor(), m = min_error_n();
  const Vec w0{s_.friction_n, 1.0, 0.0, 0.0, 0.0}, wr{fr, 1.0, 0.0, 0.0};
  const Vec wg{1.0, 0.0, 0.0, 0.0, 0.0}, wf{0.0, 1.0, 0.0, 0.0, 0.0};
  DriftFigures f;
  f.rated_force_n = s_.rated_n;
  f.zero_load_n = change(w0);
  f.zero_load_se_n = std::sqrt(quad(w0, cov));
  const double se_g = std::sqrt(quad(wg, cov));
  // Separable: the data resolve a gain change of min_change by themselves (accelerations and
  // speeds that make the coupling force differ within a direction of motion).
  f.separable = std::isfinite(se_g) && s_.sigmas * se_g <= s_.min_change;
  if (f.separable) {
    f.rated_n = change(wr), f.rated_se_n = std::sqrt(quad(wr, cov));
    f.gain_change = -change(wg), f.gain_change_se = se_g;
    f.friction_change_n = change(wf), f.friction_change_se_n = std::sqrt(quad(wf, cov));
  } else {
    f.rated_worst_n = f.zero_load_n * k;
  }
  now_ = f;
  // Judged on significance and size together: a change counts when it is both beyond sigmas
  // standard errors and beyond the minimum worth a warning. An estimate too imprecise to resolve
  // the minimum is still judged (its own margin is the larger one): a fast drift inflates the
  // standard errors while it runs, and refusing to judge then would hide exactly that drift.
  if (!std::isfinite(f.zero_load_se_n) || (f.separable && !std::isfinite(f.rated_se_n))) {
    cond_since_ = kNaN;
    return;
  }
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
  if (warn_ || t - cond_since_ < s_.sustain_s) return;
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
