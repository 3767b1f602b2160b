#include "maglead/physics/load_observer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace maglead {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

LoadForceObserver::LoadForceObserver(const LoadObserverConfig& config) : cfg_(config) {
  if (!cfg_.friction.valid())
    throw std::invalid_argument(
        "load observer: friction levels must be finite, non-negative, break-away >= kinetic");
  if (!(cfg_.lead_m > 0) || !(cfg_.linear_count_m > 0) || !(cfg_.model_uncertainty_n >= 0) ||
      !(cfg_.stop_intervals > 0) || !(cfg_.stop_min_s > 0) || !(cfg_.load_drift_n_per_s >= 0) ||
      !(cfg_.load_relax_s > 0))
    throw std::invalid_argument(
        "load observer: lead, count, uncertainty and stop times must be positive");
  const double count_phase_rad = 2.0 * std::numbers::pi * cfg_.linear_count_m / cfg_.lead_m;
  count_force_n_ = std::abs(cfg_.calibration.polynomial.slope_n_per_rad(0.0)) * count_phase_rad;
}

double LoadForceObserver::sliding_half_width_n() const noexcept {
  return 0.5 * count_force_n_ + cfg_.model_uncertainty_n;
}

double LoadForceObserver::drive_n(double phase_rad) const noexcept {
  const auto& cal = cfg_.calibration;
  const double phi = std::clamp(phase_rad, cal.stable_min_rad, cal.stable_max_rad);
  return -cal.polynomial.load_force_n(phi) + cfg_.friction.offset_n;
}

void LoadForceObserver::start(double t_s, double nut_pos_m) noexcept {
  started_ = true;
  last_pos_m_ = edge_pos_m_ = nut_pos_m;
  edge_t_s_ = t_s;
  interval_s_ = cfg_.stop_min_s;
  vel_m_s_ = 0.0;
  edge_pending_ = false;
  est_ = {};
  est_.lo_n = -kInf;
  est_.hi_n = kInf;
  est_.basis = ObserverBasis::band;
}

void LoadForceObserver::on_edge(double t_s, double nut_pos_m) noexcept {
  const double moved_m = nut_pos_m - edge_pos_m_;
  const int dir = moved_m > 0 ? 1 : -1;
  const double dt = t_s - edge_t_s_;
  double v;
  if (est_.motion == dir && dt > 0) {
    // A run of edges: counts over the time between them, averaged over about stop_min_s (at
    // speed several counts fall in one sample and one sample's count is coarse).
    const double w = std::min(1.0, dt / cfg_.stop_min_s);
    v = vel_m_s_ + w * (moved_m / dt - vel_m_s_);
    interval_s_ = dt;
  } else {
    // First edge of a slide: when it broke loose is unknown; at most stop_min_s ago.
    const double since = std::clamp(dt, 1e-6, cfg_.stop_min_s);
    v = moved_m / since;
    interval_s_ = cfg_.stop_min_s;
  }
  vel_m_s_ = v;
  edge_t_s_ = t_s;
  // At an edge the nut is on the boundary of the two counts. The calibration was made with the
  // same encoder, so whatever its zero convention, the boundary maps to the counts' midpoint.
  edge_mid_m_ = 0.5 * (last_pos_m_ + nut_pos_m);
  edge_pos_m_ = nut_pos_m;
  est_.motion = dir;
  edge_pending_ = true;
}

void LoadForceObserver::slide_sample(double t_s, double phase_rad, double nut_pos_m) noexcept {
  // Between edges the nut goes on at its last speed, within one count of the last edge.
  const double q = cfg_.linear_count_m;
  const double ahead = std::clamp(vel_m_s_ * (t_s - edge_t_s_), -q, q);
  const double p_hat = edge_mid_m_ + ahead;
  const double phi_hat = phase_rad - 2.0 * std::numbers::pi * (p_hat - nut_pos_m) / cfg_.lead_m;
  const auto& f = cfg_.friction;
  est_.drive_n = drive_n(phi_hat);
  // No M·a: an acceleration from encoder edges is noise at 1 kHz; the force the nut's mass
  // needs is within the model uncertainty once it slides steadily.
  est_.force_n = est_.drive_n - f.sliding_n(vel_m_s_);
  const double u = sliding_half_width_n();
  est_.lo_n = est_.force_n - u;
  est_.hi_n = est_.force_n + u;
  est_.nut_vel_m_s = vel_m_s_;
  est_.basis = ObserverBasis::sliding;
  if (edge_pending_) edge_force_n_ = est_.force_n;
  edge_pending_ = false;
}

void LoadForceObserver::stuck_sample(double t_s, double phase_rad,
                                     double expected_load_n) noexcept {
  const auto& f = cfg_.friction;
  const double half_count = 0.5 * count_force_n_;
  est_.drive_n = drive_n(phase_rad);
  const double band_lo = est_.drive_n - f.breakaway_n(1) - half_count;
  const double band_hi = est_.drive_n + f.breakaway_n(-1) + half_count;
  if (std::isfinite(expected_load_n)) {
    // Nothing holds the load: anything in the band, drifting back to where loads rest.
    const double dt = std::max(0.0, t_s - last_t_s_);
    const double keep = std::exp(-dt / std::max(cfg_.load_relax_s, 1e-9));
    est_.lo_n = band_lo, est_.hi_n = band_hi;
    est_.force_n =
        std::clamp(expected_load_n + (est_.force_n - expected_load_n) * keep, band_lo, band_hi);
    est_.nut_vel_m_s = 0.0;
    return;
  }
  const double widen = cfg_.load_drift_n_per_s * std::max(0.0, t_s - last_t_s_);
  double lo = std::max(est_.lo_n - widen, band_lo), hi = std::min(est_.hi_n + widen, band_hi);
  if (lo > hi) {  // the load changed while the nut stuck, or the model's friction is off
    lo = band_lo, hi = band_hi;
    est_.basis = ObserverBasis::band;
  }
  est_.lo_n = lo, est_.hi_n = hi;
  est_.force_n =
      est_.basis == ObserverBasis::band ? 0.5 * (lo + hi) : std::clamp(est_.force_n, lo, hi);
  est_.nut_vel_m_s = 0.0;
}

const LoadEstimate& LoadForceObserver::update(double t_s, double phase_rad, double nut_pos_m,
                                              double expected_load_n) noexcept {
  if (!started_) {
    start(t_s, nut_pos_m);
    last_t_s_ = t_s;
  }
  if (nut_pos_m != last_pos_m_) on_edge(t_s, nut_pos_m);
  last_pos_m_ = nut_pos_m;
  if (est_.motion != 0) {
    const double quiet_s = t_s - edge_t_s_;
    if (quiet_s > std::max(cfg_.stop_intervals * interval_s_, cfg_.stop_min_s)) {
      // Stopped: the load keeps the force it had at the last edge, known within a slide's width.
      est_.motion = 0;
      vel_m_s_ = 0.0;
      est_.force_n = edge_force_n_;
      est_.lo_n = edge_force_n_ - sliding_half_width_n();
      est_.hi_n = edge_force_n_ + sliding_half_width_n();
      est_.basis = ObserverBasis::stuck;
    }
  }
  if (est_.motion != 0)
    slide_sample(t_s, phase_rad, nut_pos_m);
  else
    stuck_sample(t_s, phase_rad, expected_load_n);
  last_t_s_ = t_s;
  return est_;
}

}  // namespace maglead
