#include "maglead/physics/estimator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace maglead {

StaticForceEstimator::StaticForceEstimator(ForceCalibration cal, double coulomb_n,
                                           double velocity_deadband_m_s)
    : cal_(std::move(cal)), coulomb_n_(coulomb_n), deadband_m_s_(velocity_deadband_m_s) {}

double StaticForceEstimator::load_force_n(double phase_rad, double nut_vel_m_s) const {
  double friction = 0.0;
  if (nut_vel_m_s > deadband_m_s_) friction = coulomb_n_;
  if (nut_vel_m_s < -deadband_m_s_) friction = -coulomb_n_;
  return cal_.load_force_n(phase_rad) + friction;
}

EncoderVelocityEstimator::EncoderVelocityEstimator(double sample_period_s, double count_m,
                                                   double hold_s)
    : period_s_(sample_period_s), count_m_(count_m), hold_s_(hold_s) {
  if (!(sample_period_s > 0.0) || !(count_m > 0.0) || !(hold_s > 0.0))
    throw std::invalid_argument("velocity estimator: period, count and hold must be positive");
  // A recording sampled this slowly has no two encoder readings within one hold: say it as such.
  if (!(hold_s > sample_period_s)) {
    char buf[200];
    std::snprintf(
        buf, sizeof buf,
        "sampled every %.3g s (%.3g Hz): the nut's velocity needs a sample within "
        "%.3g s, so more than %.3g Hz (if t_s is in milliseconds, divide it by 1000; else "
        "record at 100 Hz or more)",
        sample_period_s, 1.0 / sample_period_s, hold_s, 1.0 / hold_s);
    throw std::invalid_argument(buf);
  }
}

void EncoderVelocityEstimator::reset(double pos_m) {
  t_s_ = edge_t_s_ = 0.0;
  edge_pos_m_ = pos_m;
  vel_m_s_ = 0.0;
  started_ = true;
}

double EncoderVelocityEstimator::update(double pos_m) {
  if (!started_) reset(pos_m);
  t_s_ += period_s_;
  const double since_edge = t_s_ - edge_t_s_;
  if (std::abs(pos_m - edge_pos_m_) >= 0.5 * count_m_) {
    vel_m_s_ = (pos_m - edge_pos_m_) / std::min(since_edge, hold_s_);
    edge_pos_m_ = pos_m;
    edge_t_s_ = t_s_;
  } else if (since_edge >= hold_s_) {
    vel_m_s_ = 0.0;
  } else if (std::abs(vel_m_s_) * since_edge > count_m_) {
    vel_m_s_ = std::copysign(count_m_ / since_edge, vel_m_s_);  // slower than it was, at most
  }
  return vel_m_s_;
}

PhaseForForce phase_for_output_force(const ForceCalibration& cal, double output_force_n,
                                     double safe_fraction) {
  const double limit =
      output_force_n >= 0.0 ? safe_fraction * cal.peak_push_n : safe_fraction * cal.peak_pull_n;
  if (std::abs(output_force_n) > std::abs(limit) || !std::isfinite(output_force_n))
    return {InverseStatus::beyond_safe_limit, 0.0, limit};
  // −F̂_s rises monotonically over the stable branch: bisection cannot miss.
  double lo = cal.stable_min_rad, hi = cal.stable_max_rad;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (-cal.polynomial.load_force_n(mid) < output_force_n)
      lo = mid;
    else
      hi = mid;
  }
  return {InverseStatus::ok, 0.5 * (lo + hi), limit};
}

std::vector<double> central_velocity(const std::vector<double>& t_s,
                                     const std::vector<double>& pos_m, std::size_t half_window) {
  const std::size_t n = pos_m.size();
  std::vector<double> v(n, 0.0);
  if (n < 2) return v;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t a = i >= half_window ? i - half_window : 0;
    const std::size_t b = std::min(n - 1, i + half_window);
    const double dt = t_s[b] - t_s[a];
    v[i] = dt > 0.0 ? (pos_m[b] - pos_m[a]) / dt : 0.0;
  }
  return v;
}

}  // namespace maglead
