#pragma once
// Estimation drift from stretches where the external force is known (free moves: no contact),
// private to the monitor. No load cell: the force the model needs to move the nut is known up
// to its terms, so a weaker coupling or a higher friction shows up as more coupling force for
// the same motion.
#include <array>
#include <limits>

#include "maglead/twin/monitor.hpp"
#include "passive_drift.hpp"
#include "rls.hpp"

namespace maglead::twin {

struct FreeDriftSettings : DriftScale {
  double reference_s = 5.0;
  double sustain_s = 2.0;
  double min_pass_s = 0.1;  // a shorter pass in one condition is a transition, not a condition held
};

/// Like with like: the residual of each pass (a run of blocks in one condition: direction of
/// motion and speed octave) is compared with the baseline of its own condition, not with a
/// reference fitted on another mix of speeds. The estimator's model error under the position
/// loop's limit cycle depends on the condition, so a reference formed on one mix and a memory
/// filled with another would differ with no physical change. The standard error comes from the
/// scatter between passes of the same condition (successive differences, so a drift does not
/// count as scatter) and the conditions are pooled as random effects: a mismatch that differs
/// between conditions widens the error bar instead of moving the estimate.
class ConditionBaselines {
 public:
  static constexpr int kOctaves = 24;          // speed octaves 2^-20 .. 2^3 m/s
  static constexpr int kCells = 4 * kOctaves;  // × direction × declared (a reference move) or not
  struct Estimate {
    double change_n = std::numeric_limits<double>::quiet_NaN();  // along the motion, zero load
    double se_n = std::numeric_limits<double>::quiet_NaN();
    int conditions = 0;
    bool scatter_measured = false;  // three pass-to-pass differences seen: se_n means something
  };
  /// The conditions' changes d (along the motion) against their coupling-force levels L and
  /// their direction: d = α·L + β + γ·dir. A gain change scales each level (α ≈ −Δg), a friction
  /// change adds the same to each (β), and a change of a direction-independent load (a payload
  /// put on, a cable) adds +γ one way and −γ the other. Under an offset load the levels differ by
  /// direction, so the directions' contrast alone cannot tell a gain change from a load change:
  /// only levels that differ within a direction (speeds, accelerations) resolve α.
  struct Levels {
    static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    /// The change at the conditions' mean level, from d = α·L + β: the zero-load figure when α
    /// is not resolved. NaN until the levels determine that line.
    double mean_n = kNaN, mean_se_n = kNaN;
    double alpha = kNaN, alpha_se = kNaN;  // the slope, where the levels within a direction differ
    /// The change at coupling-force level L without the load term (γ = 0) and its standard error.
    double at(double level_n) const noexcept { return alpha * level_n + beta; }
    double se_at(double level_n) const noexcept;
    double beta = kNaN, var_beta = kNaN, cov_ab = kNaN;
  };
  void clear() noexcept;
  /// A pass before the reference residual can be formed: its means go into the baseline sums.
  void add_reference(int cell, const std::array<double, 5>& x_mean, double z_mean) noexcept;
  /// The reference model is fixed: baselines become mean residuals of the reference passes.
  void freeze(const std::array<double, 5>& theta) noexcept;
  /// A pass after the reference: residual r of the pass, at known-force time known_s.
  /// level: the pass's mean coupling force along the motion (the model's, at the measured phase).
  void add(int cell, double r, double level_n, double known_s, double memory_s) noexcept;
  /// Random-effects mean of the change over the conditions seen within the memory.
  Estimate estimate(double known_s, double memory_s) const noexcept;
  /// Random-effects regressions of the conditions' changes on direction and level (within the
  /// memory); NaN figures until the scatter between passes is measured.
  Levels levels(double known_s, double memory_s) const noexcept;

  static int cell_of(int dir, double speed_m_per_s, bool declared) noexcept;

 private:
  Estimate pooled(double known_s, double memory_s, double s2) const noexcept;
  struct Changes {
    std::array<double, kCells> d{}, v{}, level{}, dir{};
    int k = 0;
  };
  /// Each condition seen within the memory: its change d along the motion, the variance of d in
  /// units of one pass's scatter s2 (or 1 with s2 = 0), its mean level.
  Changes changes(double known_s, double memory_s, double s2) const noexcept;
  struct Cell {
    std::array<double, 5> ref_x{};
    double ref_z = 0, ref_r = 0, last_r = 0, last_common = 0;
    int ref_n = 0;
    bool has_last = false;
    double sum = 0, lev = 0, w = 0, w2 = 0, at_s = 0;  // forgotten sums of the passes since
                                                       // the reference (residual, level)
  };
  static double dir_of(int cell) noexcept { return cell % (2 * kOctaves) >= kOctaves ? 1 : -1; }
  std::array<Cell, kCells> cells_{};
  double diff2_ = 0;  // Σ (r − r_previous)² / 2 over successive passes of one condition
  int diffs_ = 0;
};

class FreeMoveDrift {
 public:
  explicit FreeMoveDrift(const FreeDriftSettings& s) : s_(s) { clear(); }
  const FreeDriftSettings& settings() const noexcept { return s_; }
  void clear() noexcept;
  /// A tick outside a known-force stretch at time t: the running block is dropped, the running
  /// pass ends.
  void skip(double t) noexcept;
  /// One tick of a known-force stretch: u the model's coupling force at the measured phase, y the
  /// coupling force the model needs for the measured motion with the known external force.
  /// declared: the caller says the stretch is free (a reference move): its passes are a
  /// condition of their own, identical by construction from one reference move to the next.
  void add(double t, double dt, double u, double y, int dir, double vel, double pos_m,
           bool declared = false) noexcept;

  /// Evidence from a passive load revisited in force control (PassiveLoadDrift) at time t:
  /// pooled with the free moves' and judged with them. new_window: `e` has just taken in a
  /// window, whose force-control time (e.window_s) counts towards the warning's sustain.
  void passive(double t, const PassiveEstimate& e, bool new_window) noexcept;

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
  void end_pass(double t) noexcept;
  void evaluate(double t, double evidence_s = 0.0) noexcept;
  bool free_figures(DriftFigures& f) const noexcept;
  bool level_figures(DriftFigures& f) const noexcept;
  bool pool_passive(DriftFigures& f, bool free_judged) const noexcept;
  void judge(double t, const DriftFigures& f, double evidence_s) noexcept;
  double rated_factor() const noexcept { return (s_.rated_n + s_.friction_n) / s_.friction_n; }
  double min_error_n() const noexcept { return s_.min_change * s_.rated_n; }

  FreeDriftSettings s_;
  Rls<kP> cur_, ref_;
  ConditionBaselines base_;
  Vec block_x_{}, ref_theta_{}, pass_x_{};
  double pass_z_ = 0, pass_s_ = 0;
  int pass_n_ = 0, pass_cell_ = -1;
  std::array<Vec, kP> ref_cov_{};
  double block_z_ = 0, block_t_ = 0, block_dt_ = 0;
  int block_n_ = 0;
  bool block_declared_ = false;
  double known_s_ = 0, ref_t_sum_ = 0, ref_t_ = 0, warn_t_ = 0;
  bool ref_frozen_ = false, warn_ = false;
  double stat_ = 0, cond_since_ = std::numeric_limits<double>::quiet_NaN();
  DriftReason reason_ = DriftReason::none;
  DriftFigures now_{}, at_warn_{};
  PassiveEstimate passive_{};
};

}  // namespace maglead::twin
