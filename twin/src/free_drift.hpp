#pragma once
// Estimation drift from stretches where the external force is known (free moves: no contact),
// private to the monitor. No load cell: the force the model needs to move the nut is known up
// to its terms, so a weaker coupling or a higher friction shows up as more coupling force for
// the same motion.
#include <array>
#include <limits>

#include "maglead/twin/monitor.hpp"
#include "rls.hpp"

namespace maglead::twin {

struct FreeDriftSettings {
  double friction_n = 0.0;  // the model's sliding friction: the coupling force of a free slide
  double rated_n = 0.0;     // rated output force: where the second error figure is given
  double block_s = 0.020;   // ticks averaged into one least-squares sample
  double memory_s = 8.0;    // forgetting time constant, in known-force time
  double reference_s = 5.0;
  double sigmas = 4.0;
  double min_change = 0.03;  // of the rated force: the smallest error change worth a warning
  double sustain_s = 2.0;
};

class FreeMoveDrift {
 public:
  explicit FreeMoveDrift(const FreeDriftSettings& s) : s_(s) { clear(); }
  void clear() noexcept;
  /// A tick outside a known-force stretch: the running block is dropped.
  void skip() noexcept { block_n_ = 0; }
  /// One tick of a known-force stretch: u the model's coupling force at the measured phase, y the
  /// coupling force the model needs for the measured motion with the known external force.
  void add(double t, double dt, double u, double y, int dir, double vel, double pos_m) noexcept;

  DriftObservability observability() const noexcept;
  const DriftFigures& now() const noexcept { return now_; }
  const DriftFigures& at_warning() const noexcept { return at_warn_; }
  bool warning() const noexcept { return warn_; }
  DriftReason reason() const noexcept { return reason_; }
  double statistic() const noexcept { return stat_; }
  double reference_t() const noexcept { return ref_t_; }
  double warning_t() const noexcept { return warn_t_; }
  double known_s() const noexcept { return known_s_; }

 private:
  static constexpr int kP = 5;  // α = 1 − g, friction change β; nuisance: bias, viscous, spring
  using Vec = std::array<double, kP>;
  void update_block(double t) noexcept;
  void evaluate(double t) noexcept;
  double rated_factor() const noexcept { return (s_.rated_n + s_.friction_n) / s_.friction_n; }
  double min_error_n() const noexcept { return s_.min_change * s_.rated_n; }

  FreeDriftSettings s_;
  Rls<kP> cur_, ref_;
  Vec block_x_{}, ref_theta_{};
  std::array<Vec, kP> ref_cov_{};
  double block_z_ = 0, block_t_ = 0, block_dt_ = 0;
  int block_n_ = 0;
  double known_s_ = 0, ref_t_sum_ = 0, ref_t_ = 0, warn_t_ = 0;
  bool ref_frozen_ = false, warn_ = false;
  double stat_ = 0, cond_since_ = std::numeric_limits<double>::quiet_NaN();
  DriftReason reason_ = DriftReason::none;
  DriftFigures now_{}, at_warn_{};
};

}  // namespace maglead::twin
