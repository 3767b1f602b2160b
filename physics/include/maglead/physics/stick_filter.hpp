#pragma once
// StickFilter: what a stuck nut's friction holds, as a probability over the stick band.
//
// While the nut sticks, friction takes any value n in [lo, hi] (its break-away levels); the
// phase gives the drive, so the load is drive ± n. A load nothing holds (a hand, a process
// force) comes and goes: it is either absent (resting where such loads rest) or acting, and
// then moves on its own as a mean-reverting random walk. The grid holds p(n, acting | stuck so
// far), beside the weight of "absent" at the resting value: shifted as the drive changes, pulled
// towards the resting load, diffused, absorbed at the edges (a path that reached one would have
// broken the nut loose, which it did not; an absent load outside the band likewise). The
// estimate is the median: the value the absolute error is least for, and a resting load, when
// it is the likelier, exactly. Shared by the loop's load observer and the twin's monitor, so
// both see a stuck load the same way. No allocation.
#include <array>
#include <cmath>

namespace maglead {

/// How a load nothing holds behaves while the nut sticks. Acting: an Ornstein-Uhlenbeck walk of
/// this intensity that relaxes with this time constant towards where such loads rest (zero with
/// the screw held; minus the setpoint in force control); relax_s 0: a pure random walk. It comes
/// and goes: absent for absent_s on average, then acting for acting_s on average (a hand that
/// touches and lets go). absent_s 0: always acting (the walk alone). The times were chosen on the
/// project's hand-push plant (seeds 1–6, 11) and checked on recordings it did not make (README).
struct UnheldLoadPrior {
  double walk_n2_per_s = 5.0;
  double relax_s = 1.0;
  double absent_s = 4.0;
  double acting_s = 1.75;
  /// The walk's stationary spread [N].
  double spread_n() const noexcept { return std::sqrt(walk_n2_per_s * relax_s / 2.0); }
  /// The factor a tick of dt_s leaves of a deviation from the resting load.
  double keep(double dt_s) const noexcept { return relax_s > 0 ? std::exp(-dt_s / relax_s) : 1.0; }
  /// The long-run share of time the load is absent (before anything is seen).
  double absent_share() const noexcept {
    return absent_s > 0 ? absent_s / (absent_s + acting_s) : 0.0;
  }
  /// Probabilities that within dt_s an absent load starts acting, an acting one lets go.
  double touch_probability(double dt_s) const noexcept {
    return absent_s > 0 ? -std::expm1(-dt_s / absent_s) : 1.0;
  }
  double let_go_probability(double dt_s) const noexcept {
    return absent_s > 0 && acting_s > 0 ? -std::expm1(-dt_s / acting_s) : 0.0;
  }
  bool valid() const noexcept {
    return walk_n2_per_s > 0 && relax_s >= 0 && absent_s >= 0 && acting_s >= 0 &&
           (absent_s == 0 || acting_s > 0);
  }
};

class StickFilter {
 public:
  static constexpr int kPoints = 81;
  /// The band [lo_n, hi_n] and the resting value centre_n. n0_n: the friction at entry (leaving
  /// a slide: its sliding level, known within n0_sd_n); NaN: unknown, the prior's spread around
  /// the centre. Whether the load is absent starts from the prior's share, weighed by how well a
  /// load at rest explains n0.
  void start(double lo_n, double hi_n, double n0_n, double n0_sd_n, double centre_n,
             const UnheldLoadPrior& prior) noexcept;
  /// One tick of dt_s: n' = c + (n + shift_n − c)·keep (shift_n: the change of the drive that
  /// friction must now take up; c = centre_n), then the walk's diffusion, then the load coming
  /// or going.
  void step(double shift_n, double centre_n, const UnheldLoadPrior& prior, double dt_s) noexcept;
  /// The median of n: the estimate.
  double estimate() const noexcept;
  /// Probability that the load is absent (resting at the centre).
  double absent_probability() const noexcept { return absent_w_; }
  double lo_n() const noexcept { return lo_; }
  double hi_n() const noexcept { return hi_; }

 private:
  bool in_band(double n) const noexcept { return n > lo_ && n < hi_; }
  void drift(double shift_n, double centre_n, double keep) noexcept;
  void diffuse(double variance_n2) noexcept;
  void come_and_go(const UnheldLoadPrior& prior, double dt_s) noexcept;
  void normalise() noexcept;
  std::array<double, kPoints> w_{}, tmp_{};
  double absent_w_ = 0.0, centre_ = 0.0;
  double lo_ = -1, hi_ = 1, dx_ = 0.025;
};

}  // namespace maglead
