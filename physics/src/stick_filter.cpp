#include "maglead/physics/stick_filter.hpp"

#include <algorithm>
#include <cmath>

namespace maglead {
namespace {
double normal_density(double z, double sd) { return std::exp(-0.5 * z * z / (sd * sd)) / sd; }
}  // namespace

void StickFilter::start(double lo_n, double hi_n, double n0_n, double n0_sd_n, double centre_n,
                        const UnheldLoadPrior& prior) noexcept {
  lo_ = lo_n, hi_ = std::max(hi_n, lo_n + 1e-9);
  dx_ = (hi_ - lo_) / (kPoints - 1);
  centre_ = centre_n;
  w_.fill(0.0);
  double absent = in_band(centre_) ? prior.absent_share() : 0.0;
  const double spread = prior.spread_n();
  if (!std::isfinite(n0_n)) {
    for (int i = 1; i < kPoints - 1; ++i) w_[i] = normal_density(lo_ + i * dx_ - centre_, spread);
  } else {
    const double x = std::clamp((n0_n - lo_) / dx_, 1.0, kPoints - 2.0);
    const int i = std::min(static_cast<int>(x), kPoints - 2);
    const double f = x - i;
    w_[i] = 1.0 - f;
    w_[i + 1] += f;
    // Absent or acting, weighed by how well each explains where the slide left the load.
    const double sd_absent = std::max(n0_sd_n, dx_);
    const double sd_acting = std::hypot(spread, sd_absent);
    const double l_absent = absent * normal_density(n0_n - centre_, sd_absent);
    const double l_acting = (1.0 - absent) * normal_density(n0_n - centre_, sd_acting);
    absent = l_absent + l_acting > 0 ? l_absent / (l_absent + l_acting) : 0.0;
  }
  double grid = 0.0;
  for (double v : w_) grid += v;
  for (double& v : w_) v *= (1.0 - absent) / std::max(grid, 1e-300);
  absent_w_ = absent;
  normalise();
}

void StickFilter::step(double shift_n, double centre_n, const UnheldLoadPrior& prior,
                       double dt_s) noexcept {
  centre_ = centre_n;
  drift(shift_n, centre_n, prior.keep(dt_s));
  diffuse(prior.walk_n2_per_s * dt_s);
  if (!in_band(centre_)) absent_w_ = 0.0;  // at rest there, the load would have broken loose
  come_and_go(prior, dt_s);
  normalise();
}

void StickFilter::drift(double shift_n, double centre_n, double keep) noexcept {
  if (shift_n == 0.0 && keep == 1.0) return;
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

void StickFilter::diffuse(double variance_n2) noexcept {
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
}

void StickFilter::come_and_go(const UnheldLoadPrior& prior, double dt_s) noexcept {
  if (!in_band(centre_)) return;  // neither an absent load nor one that lets go fits the band
  const double touch = absent_w_ * prior.touch_probability(dt_s);
  const double go = prior.let_go_probability(dt_s);
  double let_go = 0.0;
  for (double& v : w_) {
    let_go += v * go;
    v *= 1.0 - go;
  }
  absent_w_ += let_go - touch;
  // A load that starts acting starts from rest.
  const double x = std::clamp((centre_ - lo_) / dx_, 1.0, kPoints - 2.0);
  const int i = std::min(static_cast<int>(x), kPoints - 2);
  w_[i] += touch * (1.0 - (x - i));
  w_[i + 1] += touch * (x - i);
}

double StickFilter::estimate() const noexcept {
  // The median: each grid weight spread over its cell, the absent load a point at the centre.
  double below = 0.0;
  bool absent_pending = absent_w_ > 0.0;
  for (int i = 0; i < kPoints; ++i) {
    const double cell_lo = lo_ + (i - 0.5) * dx_, w = w_[i];
    double from = cell_lo, mass = w;
    if (absent_pending && centre_ < cell_lo + dx_) {
      const double lower = std::clamp((centre_ - cell_lo) / dx_, 0.0, 1.0) * w;
      if (w > 0 && below + lower >= 0.5) return cell_lo + dx_ * (0.5 - below) / w;
      below += lower + absent_w_;
      if (below >= 0.5) return centre_;
      absent_pending = false;
      from = std::max(centre_, cell_lo), mass = w - lower;
    }
    if (w > 0 && below + mass >= 0.5) return from + dx_ * (0.5 - below) / w;
    below += mass;
  }
  return absent_pending ? centre_ : hi_;
}

void StickFilter::normalise() noexcept {
  double s = absent_w_;
  for (double v : w_) s += v;
  if (!(s > 1e-300)) {  // everything absorbed (model and data disagree): fall back to flat
    w_.fill(1.0);
    w_.front() = w_.back() = 0.0;
    absent_w_ = 0.0;
    s = kPoints - 2;
  }
  absent_w_ /= s;
  for (double& v : w_) v /= s;
}

}  // namespace maglead
