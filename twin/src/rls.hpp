#pragma once
// Recursive least squares shared by the monitor's drift estimators (private to twin/).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace maglead::twin {

/// Recursive least squares with exponential forgetting for y = xᵀθ, with an estimate of the
/// noise variance from the a-priori residuals and of their lag-1 correlation (successive blocks
/// share slow model errors: the standard error is inflated by (1+ρ)/(1−ρ), the AR(1) factor).
template <int N>
class Rls {
 public:
  void reset(double prior_var) noexcept {
    for (int i = 0; i < N; ++i) {
      th_[i] = 0.0;
      for (int j = 0; j < N; ++j) P_[i][j] = i == j ? prior_var : 0.0;
    }
    s2_ = 0, w_ = 0, c1_ = 0, e_prev_ = 0, n_ = 0;
  }
  void set(int i, double v) noexcept { th_[i] = v; }
  /// Moves the origin of a trend: θ_i += d·θ_j (θ_j the slope of θ_i), P = T P Tᵀ.
  void shift(int i, int j, double d) noexcept {
    th_[i] += d * th_[j];
    for (int k = 0; k < N; ++k) P_[i][k] += d * P_[j][k];
    for (int k = 0; k < N; ++k) P_[k][i] += d * P_[k][j];
  }
  /// lambda = 1: no forgetting.
  void update(const std::array<double, N>& x, double y, double lambda) noexcept {
    std::array<double, N> Px{};
    double xPx = 0.0, e = y;
    for (int i = 0; i < N; ++i) {
      e -= x[i] * th_[i];
      for (int j = 0; j < N; ++j) Px[i] += P_[i][j] * x[j];
    }
    for (int i = 0; i < N; ++i) xPx += x[i] * Px[i];
    const double den = lambda + xPx;
    for (int i = 0; i < N; ++i) th_[i] += Px[i] / den * e;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) P_[i][j] = (P_[i][j] - Px[i] * Px[j] / den) / lambda;
    // Residual statistics, with the same forgetting (a-priori residual scaled to a-posteriori).
    const double ea = e * lambda / den;
    w_ = lambda * w_ + 1.0;
    s2_ = lambda * s2_ + ea * ea;
    if (n_ > 0) c1_ = lambda * c1_ + ea * e_prev_;
    e_prev_ = ea;
    ++n_;
  }
  /// Bounds the covariance of directions the data stopped exciting (forgetting would grow it
  /// without limit): scales row and column i so that P_ii ≤ cap (P stays positive definite).
  void cap(double max_var) noexcept {
    for (int i = 0; i < N; ++i) {
      if (!(P_[i][i] > max_var)) continue;
      const double f = std::sqrt(max_var / P_[i][i]);
      for (int j = 0; j < N; ++j) P_[i][j] *= f, P_[j][i] *= f;
    }
  }
  double theta(int i) const noexcept { return th_[i]; }
  long count() const noexcept { return n_; }
  /// Standard error of θ_i (NaN until there are more samples than parameters).
  double stderr_of(int i) const noexcept {
    const double v = cov(i, i);
    return std::isnan(v) ? v : std::sqrt(std::max(0.0, v));
  }
  /// Covariance of θ_i and θ_j, NaN until there are more samples than parameters.
  double cov(int i, int j) const noexcept {
    if (n_ <= 2L * N || !(w_ > N)) return std::numeric_limits<double>::quiet_NaN();
    const double var = s2_ / (w_ - N);
    const double rho = std::clamp(s2_ > 0 ? c1_ / s2_ : 0.0, 0.0, 0.95);
    // P holds (Σλ^k x xᵀ)⁻¹; with forgetting the estimate's variance is about var·P.
    return var * P_[i][j] * (1.0 + rho) / (1.0 - rho);
  }

 private:
  std::array<double, N> th_{};
  std::array<std::array<double, N>, N> P_{};
  double s2_ = 0, w_ = 0, c1_ = 0, e_prev_ = 0;
  long n_ = 0;
};

}  // namespace maglead::twin
