#pragma once
// LoadForceObserver: the force the load receives (F_out), from the phase and the nut's encoder
// only — no load cell — knowing whether the nut slides or sticks.
//
// While the nut slides, its force balance with the model's terms gives the load force:
//   F_out = F_m(φ) + F_offset − F_f(v)   (M a left out: encoder noise at 1 kHz).
// When it sticks, friction takes any value within its break-away levels, so the phase alone
// says only F_out ∈ [F_m + F_offset − F_s+, F_m + F_offset + F_s−] (the stick band). A passive
// load does not change while nothing moves: the force it had when the nut stopped stays, and
// every stuck sample's band narrows the interval further. A load that changes on its own while
// the nut sticks is seen when the band no longer contains the interval (the data contradict
// it: the interval restarts from the band) or when it breaks the nut loose (motion).
// No allocation and no lock: runs in the 1 kHz loop.
#include <cstdint>
#include <limits>

#include "maglead/physics/edge_tracker.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/physics/friction_model.hpp"
#include "maglead/physics/stick_filter.hpp"

namespace maglead {

/// What pins the estimate down (input register observer_basis).
enum class ObserverBasis : std::uint8_t {
  band = 0,     // only the stick band: nothing slid since start-up or since the data contradicted
  sliding = 1,  // the nut slides: force balance with the model's terms
  stuck = 2,    // stopped after a slide: the load force it had then, narrowed by the band
};

struct LoadEstimate {
  double force_n = 0.0;           // best estimate of F_out (+ pushes the load along +p)
  double lo_n = 0.0, hi_n = 0.0;  // every F_out consistent with what was seen since
  double drive_n = 0.0;           // F_m(φ) + F_offset: the model's drive on the nut now
  double nut_vel_m_s = 0.0;       // from encoder-edge timing, 0 while stuck
  int motion = 0;                 // −1 sliding −p, 0 stuck, +1 sliding +p
  ObserverBasis basis = ObserverBasis::band;
  double width_n() const noexcept { return hi_n - lo_n; }
};

struct LoadObserverConfig {
  ForceCalibration calibration;  // F_m(φ) = −F̂_s(φ) on the stable branch
  CouplingModel coupling;        // the model's gain and ripple over it (F_m = factor(θ) · …)
  FrictionModel friction;
  double lead_m = 0.006;
  double linear_count_m = 2.16e-5;
  double stroke_min_m = 0.0, stroke_max_m = 0.04;  // where the coupling's end effect is measured
  // The model's force error while sliding (friction level, mass, calibration) [N]: the
  // half-width of the interval a slide leaves, beside half a count's force.
  double model_uncertainty_n = 0.3;
  StopRule stop;  // when the nut counts as stopped
  // A load that is not held passive (no force control presses it: a hand, a process force)
  // may change while the nut sticks: the estimate is the mean of the stick filter under this
  // prior, and the interval is the whole stick band.
  UnheldLoadPrior unheld_load;
  // How fast a pressed load may change on its own while the nut sticks (a hand, a process that
  // creeps) [N/s]: the interval widens at this rate. 0: a passive load (a spring, a part).
  double load_drift_n_per_s = 0.0;
};

class LoadForceObserver {
 public:
  /// Throws std::invalid_argument on an invalid friction model or geometry.
  explicit LoadForceObserver(const LoadObserverConfig& config);
  /// Forget everything: the next samples start from the stick band.
  void reset() noexcept { started_ = false; }
  /// One sample: loop time, measured phase φ (within the nut's lead) and nut position.
  /// expected_load_n: NaN while the load is passive (force control presses it: it keeps the
  /// force it had when the nut stopped); else the output force a load that comes and goes is
  /// expected to return to (0 with the screw held).
  const LoadEstimate& update(double t_s, double phase_rad, double nut_pos_m,
                             double expected_load_n = kPassiveLoad) noexcept;
  static constexpr double kPassiveLoad = std::numeric_limits<double>::quiet_NaN();
  /// While on, a position loop holds the nut, not the force balance: a stop then measures its
  /// braking (up to the nut's momentum into the position loop's stiffness: several newtons from
  /// the force mode's speeds) and the loop's creep, not the load. It leaves the stick band alone
  /// (basis band): the load is known again only from a slide of the force loop. Off while the
  /// nut still moves, the stop that ends that motion is still the hold's.
  void position_hold(bool on) noexcept {
    position_held_ = on || (position_held_ && nut_.moving());
    hold_ends_at_stop_ = !on && position_held_;
  }
  const LoadEstimate& estimate() const noexcept { return est_; }
  /// Force of one linear-encoder count of phase near φ = 0: the resolution of any estimate.
  double count_force_n() const noexcept { return count_force_n_; }
  /// Half-width of the interval a slide leaves.
  double sliding_half_width_n() const noexcept;
  const LoadObserverConfig& config() const noexcept { return cfg_; }

 private:
  void start(double t_s, double nut_pos_m) noexcept;
  double drive_n(double phase_rad) const noexcept;
  void slide_sample(double phase_rad, bool at_edge) noexcept;
  void stuck_sample(double t_s, double phase_rad, double expected_load_n) noexcept;
  void unheld_stuck_sample(double t_s, double band_lo_n, double band_hi_n,
                           double expected_load_n) noexcept;

  LoadObserverConfig cfg_;
  double count_force_n_ = 0.0;
  LoadEstimate est_{};
  bool started_ = false;
  double last_t_s_ = 0.0;
  double screw_rad_ = 0.0;      // the screw angle of this sample (the ripple's argument)
  double end_distance_m_ = 0;   // the nut's distance to the nearer stroke end (the end effect's)
  EdgeTracker nut_;             // position and speed from the encoder's edges
  double edge_force_n_ = 0.0;   // the sliding estimate at the last edge
  bool position_held_ = false;  // a position loop holds the nut: its stops measure no load
  bool hold_ends_at_stop_ = false;  // … until the nut's next stop (the hold has ended)
  bool band_keeps_edge_ = false;    // the band after a hold's stop: the estimate is the slide's
  // An unheld load while stuck: the filter over F_out − drive, and the drive it last saw.
  StickFilter stick_;
  bool stick_running_ = false;
  double stick_drive_n_ = 0.0;
};

}  // namespace maglead
