#pragma once
// StickFilter: what a stuck nut's friction holds, as a probability over the stick band.
//
// While the nut sticks, friction takes any value n in [lo, hi] (its break-away levels); the
// phase gives the drive, so the load is drive ± n. A load nothing holds (a hand, a process
// force) moves on its own: modelled as a mean-reverting random walk towards where such loads
// rest. The grid holds p(n | stuck so far): shifted as the drive changes, pulled towards the
// resting load, diffused, and absorbed at the edges (a path that reached one would have broken
// the nut loose, which it did not). Its mean is the estimate. Shared by the loop's load observer
// and the twin's monitor, so both see a stuck load the same way. No allocation.
#include <array>
#include <cmath>

namespace maglead {

/// How a load nothing holds moves on its own while the nut sticks: an Ornstein-Uhlenbeck walk
/// of this intensity that relaxes with this time constant towards where such loads rest (zero
/// with the screw held; minus the setpoint in force control). relax_s 0: a pure random walk.
struct UnheldLoadPrior {
  double walk_n2_per_s = 5.0;
  double relax_s = 1.0;
  /// The walk's stationary spread [N].
  double spread_n() const noexcept { return std::sqrt(walk_n2_per_s * relax_s / 2.0); }
  /// The factor a tick of dt_s leaves of a deviation from the resting load.
  double keep(double dt_s) const noexcept { return relax_s > 0 ? std::exp(-dt_s / relax_s) : 1.0; }
};

class StickFilter {
 public:
  static constexpr int kPoints = 81;
  /// The band [lo_n, hi_n]; n0_n: the friction at entry (leaving a slide: its sliding level);
  /// NaN: unknown, start from N(centre_n, sd_n²) inside the band.
  void start(double lo_n, double hi_n, double n0_n, double centre_n, double sd_n) noexcept;
  /// One tick: n' = c + (n + shift_n − c)·keep (shift_n: the change of the drive that friction
  /// must now take up; c = centre_n, where the load rests; keep = exp(−dt/τ)), then diffusion of
  /// variance_n2 (the walk's intensity × dt).
  void step(double shift_n, double centre_n, double keep, double variance_n2) noexcept;
  double mean() const noexcept;
  double lo_n() const noexcept { return lo_; }
  double hi_n() const noexcept { return hi_; }

 private:
  void normalise() noexcept;
  std::array<double, kPoints> w_{}, tmp_{};
  double lo_ = -1, hi_ = 1, dx_ = 0.025;
};

}  // namespace maglead
