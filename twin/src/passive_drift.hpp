#pragma once
// Estimation drift from a passive load revisited (private to the monitor). In force control the
// loop presses a load; where that load is passive (a spring anchored still: the same force at
// the same nut position every time), its force at a position is known in the relative sense,
// although no load cell measures it. The model's estimate of the external force while sliding,
// F̂ = y₀ − u (y₀ the coupling force the motion needs without a load, u the model's coupling at
// the measured phase), is then the same at the same position and direction every time:
//   F̂ ≈ F_load(p) / g + dir · (F_c − F_f / g)
// A weaker coupling (g falls) scales it by g_ref / g; a friction change moves the step between
// the directions. The reference maps F̂ over position and direction; each later window of force
// control is compared with it where it revisits mapped positions: F̂ − F̂_ref = c + α·F̂_ref −
// Δ₀·dir, with its own offset c (an anchor moved between windows), α = g_ref / g − 1 the gain,
// Δ₀ the estimate's error change at zero load. Like with like: the same positions are the same
// phases, so a coupling model that is wrong by a different amount at another phase does not
// look like a drift. Gain and friction are told apart, unlike on free moves. A window that went
// one way only (a PLC's force step, landed and held) cannot tell its own offset from the step:
// within the stretch the map was formed in, the load is anchored where the map found it, so c = 0
// there and the window's intercept is the step.
#include <array>
#include <cmath>
#include <limits>

namespace maglead::twin {

/// What both drift estimators share: the actuator's scale and the judgement's settings.
struct DriftScale {
  double friction_n = 0.0;   // the model's sliding friction: the coupling force of a free slide
  double rated_n = 0.0;      // rated output force: where the second error figure is given
  double block_s = 0.020;    // ticks averaged into one least-squares sample
  double memory_s = 8.0;     // forgetting time constant, in known-force time
  double sigmas = 4.0;       // significance
  double min_change = 0.03;  // of the rated force: the smallest error change worth a warning
};

struct PassiveDriftSettings : DriftScale {
  double window_s = 2.0;     // force-control time taken as one window (one pass)
  double reference_s = 4.0;  // force-control time of accepted windows that makes the reference
  double stroke_min_m = 0.0, stroke_max_m = 0.04;  // where the map lies
  double bin_m = 1e-4;                             // the map's cells (a few encoder counts)
  double max_accel_force_n = 0.3;  // quasi-static: |M·a| of a block within the model's error
  double creep_travel_m = 0.0;     // a block's travel under which a slide's tail is a creep
};

/// The change since the reference, from the windows compared with it (NaN until there is one).
struct PassiveEstimate {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double zero_load_n = kNaN, zero_load_se_n = kNaN;  // along the motion, at zero load
  double rated_n = kNaN, rated_se_n = kNaN;          // along the motion, at the rated force
  double gain_change = kNaN, gain_change_se = kNaN;  // Δg relative to the reference
  bool scatter_measured = false;  // three window-to-window differences of each seen
  double window_s = 0.0;          // force-control time of the newest window compared
};

class PassiveLoadDrift {
 public:
  explicit PassiveLoadDrift(const PassiveDriftSettings& s);
  void clear() noexcept;
  /// One force-control tick: sliding and driven by the screw (slide), or not (the window's time
  /// still runs, its current block is dropped). fhat_n the model's external-force estimate
  /// (load convention) from the sliding force balance, pos_m the nut position.
  void tick(double t, double dt, bool slide, double fhat_n, int dir, double pos_m,
            double accel_force_n) noexcept;
  /// Force control ended: the window is closed (a load met later may be another).
  void end_stretch() noexcept;

  bool seen() const noexcept { return seen_; }
  /// The reference is formed (reference()) and a window has been compared with it (tracking()).
  bool reference() const noexcept { return ref_frozen_; }
  bool tracking() const noexcept { return std::isfinite(est_.zero_load_n); }
  double used_s() const noexcept { return used_s_; }
  double reference_t() const noexcept { return ref_t_; }
  /// True once per window compared after the reference: the estimate below is new.
  bool updated() const noexcept { return updated_; }
  const PassiveEstimate& estimate() const noexcept { return est_; }

 private:
  static constexpr int kMaxBlocks = 512;
  static constexpr int kBins = 512;  // per direction
  static constexpr int kP = 3;
  using Vec = std::array<double, kP>;
  struct Block {
    double t, p, f, ref;  // ref: the reference's F̂ at p in this direction (NaN: none)
    int dir;
    double travel_m = 0.0, span_s = 0.0;  // the nut's travel over the block, its duration
    double dref = std::numeric_limits<double>::quiet_NaN();  // ∂ref/∂p there (a shifted window)
  };
  struct Fit {
    double offset = 0, gain = 0, step = 0, var_gain = 0, var_step = 0;  // c, slope, step
    double var_res = 0;                                                 // the residuals' variance
    int m = 0;                                                          // the blocks used
    bool ok = false, has_step = false;  // both directions in the window: the step is resolved
  };
  struct Cell {
    double sum_p = 0, sum_f = 0;
    int n = 0;
  };
  /// Forgotten means weighted by inverse variance: Σ w, Σ w·x, Σ f²/v.
  struct Mean {
    double w = 0, wx = 0, f2v = 0, at_s = 0;
    void add(double now_s, double memory_s, double x, double v) noexcept {
      const double fg = std::exp(-(now_s - at_s) / memory_s);
      w = fg * w + 1 / v, wx = fg * wx + x / v, f2v = fg * fg * f2v + 1 / v, at_s = now_s;
    }
    double mean() const noexcept { return wx / w; }
    double var() const noexcept { return f2v / (w * w); }
  };
  /// Successive differences in units of their own variances: Σ Δ² / (v + v').
  struct Dispersion {
    double last = 0, last_v = 0, sum = 0;
    int n = 0;
    bool has_last = false;
    void add(double x, double v) noexcept {
      if (has_last) sum += (x - last) * (x - last) / (v + last_v), ++n;
      last = x, last_v = v, has_last = true;
    }
    double factor() const noexcept { return n > 0 ? std::max(1.0, sum / n) : 1.0; }
  };
  void close_block() noexcept;
  void end_slide() noexcept;
  void close_window() noexcept;
  /// Which blocks a fit uses and its regressors.
  struct Design {
    bool compare = false, has_step = false, shifted = false;  // shifted: c = 0, a shift instead
    bool anchored = false;  // one direction in the map's stretch: c = 0, the step the intercept
    bool joint = false;   // shifted, the shift a parameter: its column −∂ref/∂p in place of c
    int only = 0, m = 0;  // only: the one direction used (0: both); m: the blocks used
    double p_mean = 0;
    int params() const noexcept { return has_step ? kP : kP - 1; }
    bool used(const Block& b) const noexcept {
      return (!compare || std::isfinite(b.ref)) && (!joint || std::isfinite(b.dref)) &&
             (only == 0 || b.dir == only);
    }
    Vec row(const Block& b, double& y) const noexcept {
      y = compare ? b.f - b.ref : b.f;
      return {joint ? -b.dref : 1.0, compare ? b.ref : b.p - p_mean,
              has_step ? static_cast<double>(b.dir) : 0.0};
    }
  };
  Design design(bool compare, bool joint = false) const noexcept;
  Fit fit(bool compare, bool joint = false) const noexcept;
  Fit with_shift_variances(Fit best) const noexcept;
  Fit compare_window() noexcept;
  void set_refs() noexcept;
  void set_slopes() noexcept;
  static double residual(const Design& d, const Vec& th, const Block& b) noexcept;
  bool parts_on_line(const Design& d, const Vec& th, double sd) const noexcept;
  int bin_of(double p) const noexcept;
  void map_window(const Fit& cmp) noexcept;
  template <class F>
  void span_slide(const Block& a, const Block& b, const F& in_frame) noexcept;
  void reference_window(const Fit& cmp, double span_s) noexcept;
  double reference_at(double p, int dir) const noexcept;
  void add_window(const Fit& f) noexcept;
  void evaluate() noexcept;

  PassiveDriftSettings s_;
  std::array<Block, kMaxBlocks> blocks_{};
  std::array<Cell, std::size_t{2} * kBins> map_{};
  int n_blocks_ = 0;
  double win_t0_ = 0, win_s_ = 0, slide_s_ = 0;
  double b_t_ = 0, b_p_ = 0, b_f_ = 0, b_s_ = 0, b_a_ = 0;  // the running block
  double b_p_first_ = 0, b_p_last_ = 0;                     // its first and last position
  int slide_first_ = 0;  // the first block of the running slide (n_blocks_: none yet)
  int b_n_ = 0, b_dir_ = 0;
  double ref_s_ = 0, ref_t_sum_ = 0, ref_t_ = 0;
  int ref_n_ = 0;
  bool ref_frozen_ = false, seen_ = false, updated_ = false, in_stretch_ = false;
  double shift_m_ = 0;  // the window's position shift from the map's frame (a moved anchor)
  int stretch_ = 0, map_stretch_ = 0;  // force-control stretches ended; the one the map began in
  Dispersion disp_gain_, disp_step_;
  Mean gain_, step_;
  double fc_s_ = 0;  // force-control time since the reference
  double used_s_ = 0;
  PassiveEstimate est_{};
};

}  // namespace maglead::twin
