#include "maglead/twin/monitor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <numbers>

#include "free_drift.hpp"
#include "maglead/physics/edge_tracker.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/physics/stick_filter.hpp"
#include "rls.hpp"

namespace maglead::twin {

std::string drift_figures_text(const DriftFigures& f) {
  if (std::isnan(f.zero_load_n)) return "no figures yet";
  char buf[320];
  int n = std::snprintf(buf, sizeof buf, "estimate error %+.2f ± %.2f N at zero load",
                        f.zero_load_n, f.zero_load_se_n);
  const auto left = [&] { return sizeof buf - static_cast<std::size_t>(std::max(0, n)); };
  if (f.separable)
    std::snprintf(buf + n, left(),
                  ", %+.2f ± %.2f N at %.1f N; coupling gain %+.3f ± %.3f, friction %+.2f ± %.2f N",
                  f.rated_n, f.rated_se_n, f.rated_force_n, f.gain_change, f.gain_change_se,
                  f.friction_change_n, f.friction_change_se_n);
  else
    std::snprintf(buf + n, left(),
                  ", at %.1f N between %+.2f N (all friction) and %+.2f N (all gain): gain and "
                  "friction cannot be told apart from these moves",
                  f.rated_force_n, f.zero_load_n, f.rated_worst_n);
  return buf;
}

std::string drift_message(const TwinOutputs& o) {
  if (!o.drift_warning) return {};
  static constexpr const char* kWhat[] = {
      "",
      "coupling gain fell",
      "coupling gain rose",
      "friction rose",
      "friction fell",
      "gain fell or friction rose",
      "gain rose or friction fell",
  };
  const int r = std::clamp(static_cast<int>(o.drift_reason), 0, 6);
  char head[96];
  std::snprintf(head, sizeof head, "%s over %.0f s: ", kWhat[r],
                o.drift_warning_t_s - o.drift_reference_t_s);
  return head + drift_figures_text(o.drift_at_warning);
}

namespace {

constexpr double kPi = std::numbers::pi;

FreeDriftSettings free_settings(const TwinMonitorConfig& c, const NutModel& model) {
  FreeDriftSettings s;
  s.friction_n = 0.5 * (model.sliding_friction_n(1, 0.0) + model.sliding_friction_n(-1, 0.0));
  s.rated_n = std::isfinite(c.drift_rated_force_n)
                  ? c.drift_rated_force_n
                  : c.actuator.safe_force_fraction *
                        std::min(c.calibration.peak_push_n, -c.calibration.peak_pull_n);
  s.block_s = c.drift_block_s;
  s.memory_s = c.drift_free_memory_s;
  s.reference_s = c.drift_free_reference_s;
  s.sigmas = c.drift_sigmas;
  s.min_change = c.drift_min_change;
  s.sustain_s = c.drift_sustain_s;
  return s;
}

PassiveDriftSettings passive_settings(const TwinMonitorConfig& c, const FreeDriftSettings& f) {
  PassiveDriftSettings s;
  static_cast<DriftScale&>(s) = f;
  s.window_s = c.drift_passive_window_s;
  s.reference_s = c.drift_passive_reference_s;
  s.stroke_min_m = c.actuator.stroke_min_m;
  s.stroke_max_m = c.actuator.stroke_max_m;
  s.bin_m = c.drift_passive_bin_counts * c.actuator.linear_count_m;
  s.max_accel_force_n = c.stop_force_sd_n;
  s.creep_travel_m = c.drift_min_edges * c.actuator.linear_count_m;
  return s;
}

/// Linear trends over the look-ahead horizon: θ and F_ext continue as they have been moving.
class TrendInput final : public InputSource {
 public:
  double t0 = 0, th0 = 0, th_rate = 0, f0 = 0, f_rate = 0;
  double screw_rad(double t) const noexcept override { return th0 + th_rate * (t - t0); }
  double ext_force_n(double t) const noexcept override { return f0 + f_rate * (t - t0); }
};

}  // namespace

struct TwinMonitor::Impl {
  TwinMonitorConfig cfg;
  NutModel model;
  HybridTwin twin, look;
  StaticForceEstimator static_est;
  EncoderVelocityEstimator static_vel;
  StickFilter stick;
  TrendInput trend;
  double dt, q_m, lead_m;

  // Encoder reconstruction (the load observer's too): position, speed, stop
  EdgeTracker nut;
  double vel = 0, vel_prev = 0, acc = 0, pos_hat = 0;
  FrictionMode mode = FrictionMode::stick;
  double d0_prev = 0;  // model drive without F_ext at the previous tick (stick filter shift)

  // Force
  double fext_hat = 0;   // load convention, along +p
  double fext_rate = 0;  // N/s, smoothed, for the look-ahead
  double theta_prev = 0, theta_rate = 0;
  double nut_rate = 0;  // the nut's velocity through the screw rate's filter (driven test)
  double fset_prev = std::numeric_limits<double>::quiet_NaN(), fset_rate = 0;
  double t_prev = 0;
  bool started = false;

  // Twin prediction
  double next_resync_t = 0;
  int ticks = 0;
  bool solver_ok = true;

  // Step-out
  double branch_center = 0;
  int slips = 0;
  bool step_out = false, warn = false;
  double margin = kPi / 2;
  bool margin_from_setpoint = false;

  // Drift: the coupling gain g, estimated jointly with nuisance parameters (see gain_block()).
  // g, its trend per minute, bias b, friction level, backlash, viscous, load-cell delay
  static constexpr int kP = 7;
  double trend_origin_t = 0, ref_origin_t = 0;
  Rls<kP> gain_rls, ref_rls;
  int block_ticks = 20, block_n = 0;
  std::array<double, kP> block_x{};
  double block_y = 0, block_t = 0;
  double slide_start_t = 0, load_prev = std::numeric_limits<double>::quiet_NaN();
  double excited_s = 0;  // excitation-rich time used since the reference restarted
  double ref_t_sum = 0;  // mean time of the reference blocks
  bool ref_frozen = false;
  double ref_g = std::numeric_limits<double>::quiet_NaN(), ref_se = 0, ref_t = 0;
  double gain_est = std::numeric_limits<double>::quiet_NaN(), gain_se = 0;
  // The flag: drift from known-force (free-move) stretches, never from the load cell.
  FreeMoveDrift free_drift;
  // … and from a passive load the force loop presses, revisited (no load cell either).
  PassiveLoadDrift passive_drift;
  double passive_judged_t = -std::numeric_limits<double>::infinity();
  // Health: open-loop intervals in a row whose prediction missed by more than the tolerance,
  // and whether the current one saw the nut or the twin stick or slip.
  int bad_intervals = 0;
  bool stick_or_slip = false, against_screw = false;
  FrictionMode twin_mode = FrictionMode::stick, measured_mode = FrictionMode::stick;

  explicit Impl(const TwinMonitorConfig& c)
      : cfg(c),
        model(c.actuator, c.calibration.periodic, c.model),
        twin(model, c.integrator),
        look(model, c.integrator),
        static_est(c.calibration, c.actuator.coulomb_n, 1e-5),
        static_vel(1.0 / c.actuator.sample_rate_hz, c.actuator.linear_count_m),
        dt(1.0 / c.actuator.sample_rate_hz),
        q_m(c.actuator.linear_count_m),
        lead_m(c.actuator.lead_m),
        nut({c.actuator.linear_count_m, c.stop}),
        free_drift(free_settings(c, model)),
        passive_drift(passive_settings(c, free_drift.settings())) {}

  double phase_of(double theta, double p) const noexcept { return phase_rad(theta, p, lead_m); }

  /// Output-force estimate from a motion state (the observer's formula, also used on the twin).
  double ext_force(FrictionMode m, double t, double theta, double p, double v, double a,
                   double n_stick) const noexcept {
    const double d0 = model.drive_force_n(t, theta, p, v, 0.0);
    if (m == FrictionMode::stick) return n_stick - d0;
    const int dir = static_cast<int>(m);
    return model.mass_kg() * a - d0 + dir * model.sliding_friction_n(dir, v);
  }

  void enter_stick(double t, double theta, int from_dir) noexcept {
    mode = FrictionMode::stick;
    vel = 0.0;
    const double d0 = model.drive_force_n(t, theta, pos_hat, 0.0, 0.0);
    d0_prev = d0;
    // Leaving a slide, friction was at its sliding level: that is where n starts.
    const double n0 = from_dir == 0 ? std::numeric_limits<double>::quiet_NaN()
                                    : from_dir * model.sliding_friction_n(from_dir, 0.0);
    stick.start(-model.breakaway_n(-1), model.breakaway_n(1), n0, cfg.stop_force_sd_n,
                d0 + expected_fext, load_prior());
  }

  // Where a load nothing holds rests: minus the force setpoint in force control, zero otherwise.
  // Only a load nothing presses comes and goes; one the force loop presses acts all the time.
  double expected_fext = 0.0;
  bool force_control = false;
  UnheldLoadPrior load_prior() const noexcept {
    UnheldLoadPrior p = cfg.load_prior;
    if (force_control) p.absent_s = 0.0;
    return p;
  }

  void reset(double t, double theta, double p) noexcept {
    expected_fext = 0.0;
    force_control = false;
    // The reading itself: the calibration was made with the same encoder, so whatever its zero
    // convention (floor or nearest count), the reading maps to the phase as it did there.
    nut.reset(t, p);
    pos_hat = nut.position_m();
    vel = vel_prev = acc = 0.0;
    static_vel.reset(p);
    enter_stick(t, theta, 0);
    fext_hat = stick.estimate() - d0_prev;
    fext_rate = theta_rate = nut_rate = fset_rate = 0.0;
    theta_prev = theta;
    fset_prev = std::numeric_limits<double>::quiet_NaN();
    t_prev = t;
    started = true;
    const double phi = phase_of(theta, pos_hat);
    branch_center = 2.0 * kPi * std::round(phi / (2.0 * kPi));
    slips = 0;
    step_out = warn = false;
    margin = kPi / 2;
    clear_drift();
    bad_intervals = 0;
    load_prev = std::numeric_limits<double>::quiet_NaN();
    slide_start_t = t;
    twin.reset(t, {pos_hat, 0.0, FrictionMode::stick}, theta, fext_hat);
    twin_mode = twin.state().mode;
    measured_mode = mode;
    stick_or_slip = against_screw = false;
    next_resync_t = t + cfg.resync_s;
    ticks = 0;
    solver_ok = true;
  }

  /// Forgets the gain history and the warning: the next excitation-rich stretch becomes the
  /// reference again (after the operator has acted on a warning, e.g. recalibrated).
  void clear_drift() noexcept {
    gain_rls.reset(1e4);
    ref_rls.reset(1e4);
    gain_rls.set(0, 1.0);
    ref_rls.set(0, 1.0);
    block_n = 0;
    trend_origin_t = 0;
    excited_s = 0, ref_t_sum = 0;
    ref_frozen = false;
    ref_g = gain_est = std::numeric_limits<double>::quiet_NaN();
    ref_se = gain_se = 0;
    free_drift.clear();
    passive_drift.clear();
    passive_judged_t = -std::numeric_limits<double>::infinity();
  }

  /// A slide the encoder follows: several edges in a row, so velocity and the interpolated
  /// position are measured, not guessed from one edge (slow creep, stick-slip); the phase well
  /// inside the stable branch, the nut more than the end zone from either stroke end.
  bool slide_measured(double t, double rel_phase) const noexcept {
    const double end_zone =
        std::isfinite(cfg.drift_end_exclusion_m) ? cfg.drift_end_exclusion_m : lead_m;
    const double edge = std::min(cfg.calibration.stable_max_rad, -cfg.calibration.stable_min_rad);
    return mode != FrictionMode::stick && nut.run_edges() >= cfg.drift_min_edges &&
           t - slide_start_t >= cfg.drift_settle_s &&
           std::abs(rel_phase) <= cfg.drift_phase_fraction * edge &&
           pos_hat - cfg.actuator.stroke_min_m >= end_zone &&
           cfg.actuator.stroke_max_m - pos_hat >= end_zone && !step_out;
  }

  /// The coupling force the model needs for the measured motion with the external force known
  /// (f_ext_n, load convention): M p̈ − (D0 − u) + F_f(v) − F_ext.
  double needed_coupling_n(double t, double theta, double u, double f_ext_n) const noexcept {
    const int dir = static_cast<int>(mode);
    const double d0 = model.drive_force_n(t, theta, pos_hat, vel, 0.0);
    return model.mass_kg() * acc - (d0 - u) + dir * model.sliding_friction_n(dir, vel) - f_ext_n;
  }

  /// Screw and nut speeds through the same 20 ms filter: under a position loop the nut rides its
  /// magnetic spring in a limit cycle around the screw (edge-to-edge speeds of half and twice the
  /// screw's), which is still a driven move; a hand pushing past a held screw is not.
  bool driven() const noexcept {
    const double v_screw = theta_rate * lead_m / (2.0 * kPi);
    return static_cast<int>(mode) * v_screw > 0 &&
           std::abs(v_screw - nut_rate) <= cfg.drift_free_speed_fraction * std::abs(nut_rate);
  }

  /// The drift flag's evidence this tick: a passive load pressed in force control, or a free
  /// move outside it.
  void drift_tick(double t, double theta, double rel_phase, double fset_n, bool declared) noexcept {
    const bool force = std::isfinite(fset_n), measured = slide_measured(t, rel_phase);
    passive_tick(t, theta, force, measured);
    free_tick(t, theta, force, measured, declared);
  }

  /// One force-control tick for the passive-load evidence: a slide the encoder follows, driven by
  /// the screw (a load that pushes the nut past the screw is not pressed by it), gives the
  /// model's external-force estimate at the measured position.
  void passive_tick(double t, double theta, bool force, bool measured) noexcept {
    if (!force) {
      passive_drift.end_stretch();
    } else {
      passive_slide(t, theta, measured);
    }
    // Judged again every block while its evidence stands, as free moves are (their estimate
    // changes at pass ends): a warning's sustain is measured in time, or by a new window's own
    // length (FreeMoveDrift::judge).
    const bool due = std::isfinite(passive_drift.estimate().zero_load_n) &&
                     t - passive_judged_t >= cfg.drift_block_s;
    if (passive_drift.updated() || due) {
      free_drift.passive(t, passive_drift.estimate(), passive_drift.updated());
      passive_judged_t = t;
    }
  }
  void passive_slide(double t, double theta, bool measured) noexcept {
    const int dir = static_cast<int>(mode);
    const bool slide = measured && driven();
    double fhat = 0.0;
    if (slide) {
      const double u = model.model_coupling_force_n(t, theta, pos_hat, vel);
      fhat = needed_coupling_n(t, theta, u, 0.0) - u;
    }
    passive_drift.tick(t, dt, slide, fhat, dir, pos_hat, model.mass_kg() * acc);
  }

  /// One tick of the flag's estimator: a free move (no contact, F_ext = 0), declared or
  /// recognised. Recognised: not in force control, the screw drives the nut (a hand pushing the
  /// nut past a held screw is not a move), and the no-load hypothesis fits (the observer's
  /// external force within the model's friction: a contact beyond that is not a drift).
  void free_tick(double t, double theta, bool force, bool measured, bool declared) noexcept {
    const int dir = static_cast<int>(mode);
    if (!measured || force) {
      free_drift.skip(t);
      return;
    }
    const double u = model.model_coupling_force_n(t, theta, pos_hat, vel);
    const double y = needed_coupling_n(t, theta, u, 0.0);
    const bool fits = declared || std::abs(u - y) <= model.sliding_friction_n(dir, 0.0);
    if (!driven() || !fits) {
      free_drift.skip(t);
      return;
    }
    free_drift.add(t, dt, u, y, dir, vel,
                   pos_hat - 0.5 * (cfg.actuator.stroke_min_m + cfg.actuator.stroke_max_m),
                   declared);
  }

  /// One tick of the gain estimator (the load-cell check). Force balance of the sliding nut, with
  /// the load cell as F_ext:
  ///   M p̈ − (D0 − u) + F_f(v) − F_load = g·u + b + f·sign(v) + k·sign(u)·|F_m'| + c·v + τ·Ḟ_load
  /// u the model's coupling, D0 the model's drive without F_ext (coupling, −C v, additive terms).
  /// g is the coupling gain relative to the model; the nuisance terms take up what a constant
  /// mismatch does (offset: b; friction level or asymmetry: f and b; backlash: k, the force of a
  /// phase error ±b/2 carried on the side of the torque; viscous: c; a late load cell: τ), so that
  /// these do not end up in g. Only excitation-rich ticks count (see the config), averaged over
  /// blocks of block_ticks consecutive ones (quantization averages out along the motion).
  void gain_tick(double t, double theta, double rel_phase, double load_n, double h) noexcept {
    const double load_rate = std::isfinite(load_prev) ? (load_n - load_prev) / h
                                                      : std::numeric_limits<double>::quiet_NaN();
    load_prev = load_n;
    const int dir = static_cast<int>(mode);
    const double u = model.model_coupling_force_n(t, theta, pos_hat, vel);
    const double slope = std::abs(cfg.calibration.periodic.slope_n_per_rad(0.0));
    const double f_count =
        slope * 2.0 * kPi * q_m / lead_m;  // force of one linear count near φ = 0
    const bool rich = slide_measured(t, rel_phase) && std::isfinite(load_n) &&
                      std::isfinite(load_rate) &&
                      std::abs(u) >= cfg.drift_min_force_counts * f_count;
    if (!rich) {
      block_n = 0;
      return;
    }
    const double y = needed_coupling_n(t, theta, u, load_n);
    const double slope_here =
        std::abs(model.model_coupling_force_n(t, theta + 1e-4, pos_hat, vel) - u) / 1e-4;
    // The gain as a local linear trend, g + ġ·(t − t_o), t_o moved to the newest block: g is the
    // gain now, not the average over the memory (a drift would otherwise be seen late).
    const std::array<double, kP> x{u,
                                   u * (t - trend_origin_t) / 60.0,
                                   1.0,
                                   static_cast<double>(dir),
                                   (u > 0 ? 1.0 : -1.0) * slope_here * 0.05,
                                   vel * 100.0,
                                   load_rate * 0.01};  // scaled to forces of a few N
    if (block_n == 0) {
      block_x.fill(0.0);
      block_y = 0, block_t = 0;
    }
    for (int i = 0; i < kP; ++i) block_x[i] += x[i];
    block_y += y, block_t += t;
    if (++block_n < block_ticks) return;
    for (double& v : block_x) v /= block_n;
    block_y /= block_n, block_t /= block_n;
    const double block_s = block_n * dt;
    block_n = 0;
    excited_s += block_s;
    gain_rls.update(block_x, block_y, std::exp(-block_s / cfg.drift_memory_s));
    gain_rls.cap(1e4);
    const double t_prev_origin = trend_origin_t;
    gain_rls.shift(0, 1, (t - trend_origin_t) / 60.0);
    trend_origin_t = t;
    gain_est = gain_rls.theta(0);
    gain_se = gain_rls.stderr_of(0);
    if (!ref_frozen) {
      // The reference fits its stretch with a trend too (the gain may already move), origin at
      // the stretch's first block; its value is taken at the stretch's mean time.
      if (ref_rls.count() == 0) ref_origin_t = t_prev_origin;
      block_x[1] += block_x[0] * (t_prev_origin - ref_origin_t) / 60.0;
      ref_rls.update(block_x, block_y, 1.0);
      ref_t_sum += block_t;
      // Frozen once it is long enough and can resolve the minimum change (4 σ within it);
      // until then it keeps accumulating.
      const double se = ref_rls.stderr_of(0);
      if (excited_s >= cfg.drift_reference_s && std::isfinite(se) &&
          cfg.drift_sigmas * se <= cfg.drift_min_change) {
        ref_frozen = true;
        ref_t = ref_t_sum / static_cast<double>(ref_rls.count());
        ref_rls.shift(0, 1, (ref_t - ref_origin_t) / 60.0);
        ref_g = ref_rls.theta(0);
        ref_se = ref_rls.stderr_of(0);
      }
      return;
    }
  }

  void drift_outputs(TwinOutputs& o) const noexcept {
    o.drift_gain_estimate = gain_est;
    o.drift_gain_stderr = gain_se;
    o.drift_reference_gain = ref_g;
    o.drift_reference_stderr = ref_se;
    o.drift_statistic = free_drift.statistic();
    o.drift_observability = free_drift.observability();
    if (passive_drift.tracking())
      o.drift_observability = DriftObservability::tracking;
    else if ((passive_drift.seen() || passive_drift.reference()) &&
             o.drift_observability == DriftObservability::none)
      o.drift_observability = DriftObservability::reference;
    o.drift_known_s = free_drift.known_s() + passive_drift.used_s();
    o.drift_now = free_drift.now();
    o.drift_reference_t_s =
        free_drift.observability() == DriftObservability::tracking || !passive_drift.tracking()
            ? free_drift.reference_t()
            : passive_drift.reference_t();
    o.drift_warning = free_drift.warning();
    o.drift_reason = free_drift.reason();
    if (o.drift_warning)
      o.drift_warning_t_s = free_drift.warning_t(), o.drift_at_warning = free_drift.at_warning();
  }

  // One tick in stages: reconstruct the encoder, estimate the force, advance the twin, judge the
  // step-out, the drift ticks, the outputs.
  TwinOutputs step(const TwinInputs& in) noexcept {
    TwinOutputs o;
    if (!started) reset(in.t_s, in.screw_angle_rad, in.nut_pos_m);
    const double t = in.t_s, theta = in.screw_angle_rad;
    const double h = std::max(t - t_prev, 1e-9);
    ++ticks;
    reconstruct(t, theta, in.nut_pos_m, h);
    const double fext_new = estimate_force(in, h);
    bool ok = advance_twin(o, t, theta, fext_new);
    const double phi = phase_of(theta, pos_hat);
    const double rel = judge_step_out(in, t, theta, phi, ok);
    gain_tick(t, theta, rel, in.load_force_n, h);
    drift_tick(t, theta, rel, in.force_setpoint_n, in.free_move);
    if (std::isfinite(in.force_setpoint_n)) fset_prev = in.force_setpoint_n;
    theta_prev = theta;
    t_prev = t;
    solver_ok = ok;
    fill_outputs(o, in, phi, ok);
    return o;
  }

  /// Encoder reconstruction: exact position at edges, bounded extrapolation between; the
  /// friction mode from the edges; the acceleration while sliding.
  void reconstruct(double t, double theta, double nut_pos_m, double h) noexcept {
    const int slide_dir = nut.direction();
    const EdgeEvent ev = nut.update(t, nut_pos_m);
    pos_hat = nut.position_m();
    vel = nut.velocity_m_s();
    if (ev == EdgeEvent::started || ev == EdgeEvent::edge) {
      if (mode == FrictionMode::stick) slide_start_t = t;
      mode = nut.direction() > 0 ? FrictionMode::slide_pos : FrictionMode::slide_neg;
    } else if (ev == EdgeEvent::stopped) {
      enter_stick(t, theta, slide_dir);
    }
    if (mode != FrictionMode::stick) {
      // Acceleration from the reconstructed velocity, smoothed over ~10 ms (quantization).
      const double a_raw = (vel - vel_prev) / h;
      acc += (a_raw - acc) * std::min(1.0, h / 0.010);
    } else {
      acc = 0.0;
    }
    vel_prev = vel;
  }

  /// The force: sliding friction is known; stuck, the filter's posterior mean. Also the rates
  /// the look-ahead extrapolates (force, screw, nut, setpoint).
  double estimate_force(const TwinInputs& in, double h) noexcept {
    const double t = in.t_s, theta = in.screw_angle_rad;
    double n_stick = 0.0;
    if (mode == FrictionMode::stick) {
      const double d0 = model.drive_force_n(t, theta, pos_hat, 0.0, 0.0);
      force_control = std::isfinite(in.force_setpoint_n);
      expected_fext = force_control ? -in.force_setpoint_n : 0.0;
      stick.step(d0 - d0_prev, d0 + expected_fext, load_prior(), h);
      d0_prev = d0;
      n_stick = stick.estimate();
    }
    const double fext_new = ext_force(mode, t, theta, pos_hat, vel, acc, n_stick);
    const double rate_raw = (fext_new - fext_hat) / h;
    fext_rate += (rate_raw - fext_rate) * std::min(1.0, h / 0.050);
    const double th_rate_raw = (theta - theta_prev) / h;
    theta_rate += (th_rate_raw - theta_rate) * std::min(1.0, h / 0.020);
    nut_rate += (vel - nut_rate) * std::min(1.0, h / 0.020);
    if (std::isfinite(in.force_setpoint_n) && std::isfinite(fset_prev))
      fset_rate += ((in.force_setpoint_n - fset_prev) / h - fset_rate) * std::min(1.0, h / 0.050);
    else
      fset_rate = 0.0;
    return fext_new;
  }

  /// The twin, driven by θ and last tick's force estimate, open loop between re-syncs; its
  /// prediction into `o`. False when the solver failed.
  bool advance_twin(TwinOutputs& o, double t, double theta, double fext_new) noexcept {
    if (!cfg.open_loop_twin) {
      constexpr double nan = std::numeric_limits<double>::quiet_NaN();
      o.predicted_nut_pos_m = o.residual_pos_m = o.predicted_output_force_n = nan;
      fext_hat = fext_new;
      return true;
    }
    const bool ok = twin.advance(t, theta, fext_hat) == TwinStatus::ok;
    const NutState& ts = twin.state();
    note_modes(ts.mode);
    o.predicted_nut_pos_m = ts.pos_m;
    o.residual_pos_m = pos_hat - ts.pos_m;
    const double twin_acc = model.accel_m_s2(ts.mode, t, theta, ts.pos_m, ts.vel_m_s, fext_hat);
    o.predicted_output_force_n = -ext_force(
        ts.mode, t, theta, ts.pos_m, ts.vel_m_s, twin_acc,
        ts.mode == FrictionMode::stick ? fext_hat + model.drive_force_n(t, theta, ts.pos_m, 0, 0)
                                       : 0.0);
    fext_hat = fext_new;
    if (t >= next_resync_t || !ok) {
      judge_interval(o.residual_pos_m, ok);
      twin.reset(t, {pos_hat, vel, mode}, theta, fext_hat);
      twin_mode = twin.state().mode;  // the reset may take another mode than the one it is given
      next_resync_t = t + cfg.resync_s;
    }
    return ok;
  }

  /// Health, each tick: whether the twin or the nut stuck or slipped in this open-loop interval,
  /// and whether the nut slid against the screw (a reversal, which no stick-slip of a move
  /// makes: an encoder's noise does).
  void note_modes(FrictionMode twin_now) noexcept {
    stick_or_slip |= twin_now != twin_mode || mode != measured_mode;
    const int nut_dir = mode == FrictionMode::slide_pos   ? 1
                        : mode == FrictionMode::slide_neg ? -1
                                                          : 0;
    against_screw |= nut_dir * theta_rate < 0.0;
    twin_mode = twin_now, measured_mode = mode;
  }

  /// Health, at the end of an interval: what the twin predicted, in counts. Where the nut or the
  /// twin stuck or slipped with the screw, the tolerance adds the screw's travel over the stick
  /// timing: in a stick-slip (a move against a stiff spring) when a stick ends is chaotic, and a
  /// twin equal to the plant times it a few ms apart. A failed solver's prediction is a miss.
  void judge_interval(double residual_m, bool ok) noexcept {
    const double screw_speed_m_s = std::abs(theta_rate) * lead_m / (2.0 * kPi);
    const bool stick_slip = stick_or_slip && !against_screw;
    const double tolerance_m = cfg.healthy_residual_counts * q_m +
                               (stick_slip ? screw_speed_m_s * cfg.healthy_stick_timing_s : 0.0);
    const bool missed = !ok || !(std::abs(residual_m) <= tolerance_m);
    bad_intervals = missed ? bad_intervals + 1 : 0;
    stick_or_slip = against_screw = false;
  }

  /// Step-out: the measured φ against the stable branch, and the look-ahead every few ticks.
  /// Returns φ relative to the branch's centre; `ok` false when the look-ahead's solver failed.
  double judge_step_out(const TwinInputs& in, double t, double theta, double phi,
                        bool& ok) noexcept {
    double rel = phi - branch_center;
    const double edge_hi = cfg.calibration.stable_max_rad, edge_lo = cfg.calibration.stable_min_rad;
    if (rel > edge_hi || rel < edge_lo) step_out = true;
    while (rel > kPi) branch_center += 2 * kPi, ++slips, rel -= 2 * kPi;
    while (rel < -kPi) branch_center -= 2 * kPi, --slips, rel += 2 * kPi;
    if (!cfg.open_loop_twin || ticks % std::max(1, cfg.lookahead_every_ticks) != 0) return rel;
    trend.t0 = t, trend.th0 = theta, trend.th_rate = theta_rate, trend.f0 = fext_hat;
    trend.f_rate = fext_rate;
    look.reset(t, {pos_hat, vel, mode}, theta, fext_hat);
    double worst = std::max(rel - edge_hi, edge_lo - rel);  // ≤ 0 inside the branch
    const int n_out = 10;
    for (int i = 1; i <= n_out && ok; ++i) {
      const double tt = t + cfg.lookahead_s * i / n_out;
      ok = look.integrate_to(tt, trend) == TwinStatus::ok;
      const double r = phase_of(trend.screw_rad(tt), look.state().pos_m) - branch_center;
      worst = std::max(worst, std::max(r - edge_hi, edge_lo - r));
    }
    margin = -worst;
    const double worst_only = margin;
    // A setpoint trend heading beyond the calibrated peak is a warning of its own.
    if (std::isfinite(in.force_setpoint_n)) {
      const double f_ahead = in.force_setpoint_n + fset_rate * cfg.lookahead_s;
      if (f_ahead > cfg.calibration.peak_push_n || f_ahead < cfg.calibration.peak_pull_n)
        margin = std::min(margin, 0.0);
    }
    warn = margin < cfg.step_out_warn_margin_rad;
    margin_from_setpoint = warn && !(worst_only < cfg.step_out_warn_margin_rad);
    return rel;
  }

  void fill_outputs(TwinOutputs& o, const TwinInputs& in, double phi, bool ok) noexcept {
    const double theta = in.screw_angle_rad;
    o.dynamic_output_force_est_n = -fext_hat;
    const double v_static = static_vel.update(in.nut_pos_m);
    o.static_output_force_est_n =
        static_est.output_force_n(phase_rad(theta, in.nut_pos_m, lead_m), v_static);
    o.residual_force_n = o.dynamic_output_force_est_n - o.predicted_output_force_n;
    o.phase_rad = phi;
    o.step_out_margin_rad = margin;
    o.step_out = step_out;
    o.step_out_warning = warn || step_out;
    o.slips = slips;
    drift_outputs(o);
    o.friction_mode = static_cast<int>(mode);
    o.solver_ok = ok;
    // Health: the twin explains the measurements within their resolution. Its prediction over
    // each open-loop interval (resync_s) is judged in linear-encoder counts, and only a miss
    // repeated over healthy_intervals intervals in a row counts: a stick or a slip the twin
    // times a few ms differently is not a fault.
    o.health_reason = !ok                                      ? HealthReason::solver
                      : step_out                               ? HealthReason::step_out
                      : bad_intervals >= cfg.healthy_intervals ? HealthReason::position_residual
                                                               : HealthReason::none;
    o.healthy = o.health_reason == HealthReason::none;
    o.step_out_reason = step_out ? StepOutReason::stepped_out
                        : warn   ? (margin_from_setpoint ? StepOutReason::setpoint_beyond_peak
                                                         : StepOutReason::lookahead_crosses_edge)
                                 : StepOutReason::none;
  }
};

TwinMonitor::TwinMonitor(const TwinMonitorConfig& config) : impl_(std::make_unique<Impl>(config)) {}
TwinMonitor::~TwinMonitor() = default;
void TwinMonitor::reset(double t_s, double screw_angle_rad, double nut_pos_m) {
  impl_->reset(t_s, screw_angle_rad, nut_pos_m);
}
void TwinMonitor::clear_drift() noexcept { impl_->clear_drift(); }
TwinOutputs TwinMonitor::step(const TwinInputs& in) noexcept { return impl_->step(in); }
const TwinMonitorConfig& TwinMonitor::config() const { return impl_->cfg; }

}  // namespace maglead::twin
