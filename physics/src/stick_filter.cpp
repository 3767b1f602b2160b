#include "maglead/physics/stick_filter.hpp"

#include <algorithm>
#include <cmath>

namespace maglead {

void StickFilter::start(double lo_n, double hi_n, double n0_n, double centre_n,
                        double sd_n) noexcept {
  lo_ = lo_n, hi_ = std::max(hi_n, lo_n + 1e-9);
  dx_ = (hi_ - lo_) / (kPoints - 1);
  w_.fill(0.0);
  if (!std::isfinite(n0_n)) {
    for (int i = 1; i < kPoints - 1; ++i) {
      const double z = (lo_ + i * dx_ - centre_n) / sd_n;
      w_[i] = std::exp(-0.5 * z * z);
    }
  } else {
    const double x = std::clamp((n0_n - lo_) / dx_, 1.0, kPoints - 2.0);
    const int i = std::min(static_cast<int>(x), kPoints - 2);
    const double f = x - i;
    w_[i] = 1.0 - f;
    w_[i + 1] += f;
  }
  normalise();
}

void StickFilter::step(double shift_n, double centre_n, double keep, double variance_n2) noexcept {
  if (shift_n != 0.0 || keep != 1.0) {
    for (int i = 0; i < kPoints; ++i) {
      const double n_new = lo_ + i * dx_;
      const double n_old = (n_new - centre_n) / keep + centre_n - shift_n;
      const double src = (n_old - lo_) / dx_;
      const int j = static_cast<int>(std::floor(src));
      const double f = src - j;
      double v = 0.0;
      if (j >= 0 && j < kPoints) v += (1.0 - f) * w_[j];
      if (j + 1 >= 0 && j + 1 < kPoints) v += f * w_[j + 1];
      tmp_[i] = v;
    }
    w_ = tmp_;
  }
  // Explicit diffusion, split into sub-steps that keep it stable (α ≤ 0.4 each).
  const double alpha_total = variance_n2 / (2.0 * dx_ * dx_);
  const int sub = std::max(1, static_cast<int>(std::ceil(alpha_total / 0.4)));
  const double alpha = alpha_total / sub;
  for (int k = 0; k < sub; ++k) {
    tmp_[0] = tmp_[kPoints - 1] = 0.0;  // absorbing edges
    for (int i = 1; i < kPoints - 1; ++i)
      tmp_[i] = w_[i] + alpha * (w_[i - 1] - 2.0 * w_[i] + w_[i + 1]);
    w_ = tmp_;
  }
  normalise();
}

double StickFilter::mean() const noexcept {
  double m = 0.0;
  for (int i = 0; i < kPoints; ++i) m += w_[i] * (lo_ + i * dx_);
  return m;
}

void StickFilter::normalise() noexcept {
  double s = 0.0;
  for (double v : w_) s += v;
  if (!(s > 1e-300)) {  // everything absorbed (model and data disagree): fall back to flat
    w_.fill(1.0);
    w_.front() = w_.back() = 0.0;
    s = kPoints - 2;
  }
  for (double& v : w_) v /= s;
}

}  // namespace maglead
