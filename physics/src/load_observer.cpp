#include "maglead/physics/load_observer.hpp"

#include "maglead/physics/actuator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace maglead {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

LoadForceObserver::LoadForceObserver(const LoadObserverConfig& config)
    : cfg_(config), nut_({config.linear_count_m, config.stop}) {
  if (!cfg_.friction.valid())
    throw std::invalid_argument(
        "load observer: friction levels must be finite, non-negative, break-away >= kinetic");
  if (!(cfg_.lead_m > 0) || !(cfg_.model_uncertainty_n >= 0) || !(cfg_.load_drift_n_per_s >= 0) ||
      !cfg_.unheld_load.valid() || !cfg_.coupling.valid())
    throw std::invalid_argument(
        "load observer: lead, uncertainty, drift, load prior and coupling gain must be positive, "
        "the ripple and end effect below 1");
  const double count_phase_rad = 2.0 * std::numbers::pi * cfg_.linear_count_m / cfg_.lead_m;
  count_force_n_ = std::abs(cfg_.coupling.gain * cfg_.calibration.polynomial.slope_n_per_rad(0.0)) *
                   count_phase_rad;
}

double LoadForceObserver::sliding_half_width_n() const noexcept {
  return 0.5 * count_force_n_ + cfg_.model_uncertainty_n;
}

double LoadForceObserver::drive_n(double phase_rad) const noexcept {
  const auto& cal = cfg_.calibration;
  const double phi = std::clamp(phase_rad, cal.stable_min_rad, cal.stable_max_rad);
  return -cfg_.coupling.factor(screw_rad_, end_distance_m_) * cal.polynomial.load_force_n(phi) +
         cfg_.friction.offset_n;
}

void LoadForceObserver::start(double t_s, double nut_pos_m) noexcept {
  started_ = true;
  stick_running_ = false;
  position_held_ = hold_ends_at_stop_ = band_keeps_edge_ = false;
  nut_.reset(t_s, nut_pos_m);
  last_t_s_ = t_s;
  est_ = {};
  est_.lo_n = -kInf;
  est_.hi_n = kInf;
  est_.basis = ObserverBasis::band;
}

void LoadForceObserver::slide_sample(double phase_rad, bool at_edge) noexcept {
  est_.drive_n = drive_n(phase_rad);
  // No M·a: an acceleration from encoder edges is noise at 1 kHz; the force the nut's mass
  // needs is within the model uncertainty once it slides steadily.
  est_.force_n = est_.drive_n - cfg_.friction.sliding_n(nut_.velocity_m_s());
  const double u = sliding_half_width_n();
  est_.lo_n = est_.force_n - u;
  est_.hi_n = est_.force_n + u;
  est_.basis = ObserverBasis::sliding;
  stick_running_ = false;
  if (at_edge) edge_force_n_ = est_.force_n;
}

void LoadForceObserver::stuck_sample(double t_s, double phase_rad,
                                     double expected_load_n) noexcept {
  const auto& f = cfg_.friction;
  const double half_count = 0.5 * count_force_n_;
  est_.drive_n = drive_n(phase_rad);
  const double band_lo = est_.drive_n - f.breakaway_n(1) - half_count;
  const double band_hi = est_.drive_n + f.breakaway_n(-1) + half_count;
  if (std::isfinite(expected_load_n)) {
    unheld_stuck_sample(t_s, band_lo, band_hi, expected_load_n);
    return;
  }
  const double widen = cfg_.load_drift_n_per_s * std::max(0.0, t_s - last_t_s_);
  double lo = std::max(est_.lo_n - widen, band_lo), hi = std::min(est_.hi_n + widen, band_hi);
  if (lo > hi) {  // the load changed while the nut stuck, or the model's friction is off
    lo = band_lo, hi = band_hi;
    est_.basis = ObserverBasis::band;
    band_keeps_edge_ = false;
  }
  est_.lo_n = lo, est_.hi_n = hi;
  // Only the band: its centre, unless a slide ended in a hold's stop (its force is still the
  // best guess of a load the braking moved it from; the bound says how little it pins down).
  est_.force_n = est_.basis == ObserverBasis::band && !band_keeps_edge_
                     ? 0.5 * (lo + hi)
                     : std::clamp(est_.force_n, lo, hi);
}

void LoadForceObserver::unheld_stuck_sample(double t_s, double band_lo_n, double band_hi_n,
                                            double expected_load_n) noexcept {
  // Nothing holds the load: anything in the band, and it did not break the nut loose. The
  // filter runs over x = F_out − drive: a drive change shifts x (F_out stays), the load relaxes
  // towards where loads rest.
  const double drive = est_.drive_n;
  const UnheldLoadPrior& prior = cfg_.unheld_load;
  if (!stick_running_) {
    // Right after a slide the load is known (the force at the last edge); after start-up it is not.
    const double x0 = est_.basis == ObserverBasis::stuck ? est_.force_n - drive
                                                         : std::numeric_limits<double>::quiet_NaN();
    stick_.start(band_lo_n - drive, band_hi_n - drive, x0, sliding_half_width_n(),
                 expected_load_n - drive, prior);
    stick_running_ = true;
  } else {
    const double dt = std::max(0.0, t_s - last_t_s_);
    stick_.step(stick_drive_n_ - drive, expected_load_n - drive, prior, dt);
  }
  stick_drive_n_ = drive;
  est_.lo_n = band_lo_n, est_.hi_n = band_hi_n;
  est_.force_n = drive + stick_.estimate();
}

const LoadEstimate& LoadForceObserver::update(double t_s, double phase_rad, double nut_pos_m,
                                              double expected_load_n) noexcept {
  if (!started_) start(t_s, nut_pos_m);
  screw_rad_ = phase_rad + rest_angle_rad(nut_pos_m, cfg_.lead_m);
  end_distance_m_ = std::min(nut_pos_m - cfg_.stroke_min_m, cfg_.stroke_max_m - nut_pos_m);
  const EdgeEvent ev = nut_.update(t_s, nut_pos_m);
  if (ev == EdgeEvent::stopped) {
    // Stopped: the load keeps the force it had at the last edge, known within a slide's width.
    // A stop a position hold made is its braking (the slide has no M·a term): the band only.
    const double u = position_held_ ? kInf : sliding_half_width_n();
    est_.force_n = edge_force_n_;
    est_.lo_n = edge_force_n_ - u;
    est_.hi_n = edge_force_n_ + u;
    est_.basis = position_held_ ? ObserverBasis::band : ObserverBasis::stuck;
    band_keeps_edge_ = position_held_;
    if (hold_ends_at_stop_) position_held_ = hold_ends_at_stop_ = false;
  }
  // The phase where the tracker puts the nut (inside its count), not at the reading.
  const double phi =
      phase_rad - 2.0 * std::numbers::pi * (nut_.position_m() - nut_pos_m) / cfg_.lead_m;
  est_.motion = nut_.direction();
  est_.nut_vel_m_s = nut_.velocity_m_s();
  if (nut_.moving())
    slide_sample(phi, ev == EdgeEvent::edge || ev == EdgeEvent::started);
  else
    stuck_sample(t_s, phi, expected_load_n);
  last_t_s_ = t_s;
  return est_;
}

}  // namespace maglead
