#include "maglead/twin/hybrid_twin.hpp"

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace maglead::twin {

// ---------------------------------------------------------------------------------------------
// Force law

NutModel::NutModel(const ActuatorParams& a, const PeriodicForceModel& coupling, const TwinModel& m)
    : coupling_(coupling),
      lead_m_(a.lead_m),
      stroke_min_m_(a.stroke_min_m),
      stroke_max_m_(a.stroke_max_m),
      mass_kg_(m.nut_mass_kg),
      viscous_(m.viscous_n_s_per_m),
      coulomb_n_(m.coulomb_n) {
  validate_twin_model(m);
  effects::State base;
  base.coulomb_n = coulomb_n_;
  base.viscous_n_s_per_m = viscous_;
  base.nut_mass_kg = mass_kg_;
  for (const auto& t : m.terms) {
    if (!t.enabled) continue;
    const effects::Effect* e = effects::find(t.id);
    const effects::Params p(t.parameters.begin(), t.parameters.end());
    if (t.id == "mass_error") {
      mass_kg_ = p.count("nut_mass_kg") ? p.at("nut_mass_kg") : mass_kg_;  // the total mass
      continue;
    }
    (e->friction() ? friction_terms_ : drive_terms_).push_back({e, p});
    breakaway_extra_pos_n_ += e->breakaway_extra_n(p, base, 1.0);
    breakaway_extra_neg_n_ += e->breakaway_extra_n(p, base, -1.0);
  }
  if (!(mass_kg_ > 0.0)) throw std::invalid_argument("twin model: total moving mass must be > 0");
  if (!(breakaway_n(1) >= 0.0) || !(breakaway_n(-1) >= 0.0))
    throw std::invalid_argument("twin model: break-away friction below zero");
}

effects::State NutModel::state(double t_s, double screw_rad, double pos_m, double vel_m_s,
                               double ext_force_n, double screw_rate_rad_s,
                               double ext_rate_n_s) const noexcept {
  effects::State s;
  s.t_s = t_s;
  s.p_m = pos_m;
  s.v_m_s = vel_m_s;
  // The acceleration and jerk stay 0: the twin's right-hand side is what computes the
  // acceleration (a term reading it would make the balance implicit), and the jerk would need its
  // derivative. A sensor_delay term thus applies its coupling part only (k φ̇); its inertial and
  // viscous parts (−M p⃛, −C p̈) are left out here, as they were before the analysis fitted them.
  s.theta_rad = screw_rad;
  s.phi_rad = phase_rad(screw_rad, pos_m, lead_m_);
  s.phi_rate_rad_s = screw_rate_rad_s - 2.0 * std::numbers::pi * vel_m_s / lead_m_;
  double load_n = 0.0, load_slope = 0.0;
  calibrated_load_n(s.phi_rad, load_n, &load_slope);
  s.coupling_n = -load_n;
  s.coupling_slope_n_per_rad = -load_slope;
  s.load_n = ext_force_n;
  s.load_rate_n_s = ext_rate_n_s;
  s.stroke_min_m = stroke_min_m_;
  s.stroke_max_m = stroke_max_m_;
  s.lead_m = lead_m_;
  s.coulomb_n = coulomb_n_;
  s.viscous_n_s_per_m = viscous_;
  s.nut_mass_kg = mass_kg_;
  return s;
}

void NutModel::calibrated_load_n(double phi_rad, double& load_n, double* slope) const noexcept {
  // The right-hand side's main cost: the harmonics k·φ by the angle-addition recurrence from a
  // single sincos instead of two trigonometric calls per harmonic, force and slope in one pass
  // (the same sums as PeriodicForceModel, to rounding).
  const double c1 = std::cos(phi_rad), s1 = std::sin(phi_rad);
  double ck = c1, sk = s1, f = coupling_.mean_n, df = 0.0;
  const std::size_t n = std::min(coupling_.cos_n.size(), coupling_.sin_n.size());
  for (std::size_t k = 0; k < n; ++k) {
    f += coupling_.cos_n[k] * ck + coupling_.sin_n[k] * sk;
    df += static_cast<double>(k + 1) * (coupling_.sin_n[k] * ck - coupling_.cos_n[k] * sk);
    const double next_c = ck * c1 - sk * s1;
    sk = sk * c1 + ck * s1;
    ck = next_c;
  }
  load_n = f;
  if (slope) *slope = df;
}

double NutModel::coupling_force_n(double, double screw_rad, double pos_m) const noexcept {
  double load_n = 0.0;
  calibrated_load_n(phase_rad(screw_rad, pos_m, lead_m_), load_n, nullptr);
  return -load_n;
}

double NutModel::model_coupling_force_n(double t_s, double screw_rad, double pos_m,
                                        double vel_m_s) const noexcept {
  // A term's share that vanishes with the coupling is part of the coupling.
  auto s = state(t_s, screw_rad, pos_m, vel_m_s, 0.0, 0.0, 0.0);
  auto s0 = s;
  s0.coupling_n = 0.0;
  s0.coupling_slope_n_per_rad = 0.0;
  double f = s.coupling_n;
  for (const auto& t : drive_terms_)
    f += t.effect->force_n(t.params, s) - t.effect->force_n(t.params, s0);
  return f;
}

double NutModel::drive_force_n(double t_s, double screw_rad, double pos_m, double vel_m_s,
                               double ext_force_n, double screw_rate_rad_s,
                               double ext_rate_n_s) const noexcept {
  if (drive_terms_.empty())  // the calibrated model alone: no effect state to build
    return coupling_force_n(t_s, screw_rad, pos_m) + ext_force_n - viscous_ * vel_m_s;
  const auto s = state(t_s, screw_rad, pos_m, vel_m_s, ext_force_n, screw_rate_rad_s, ext_rate_n_s);
  double f = s.coupling_n + ext_force_n - viscous_ * vel_m_s;
  for (const auto& t : drive_terms_) f += t.effect->force_n(t.params, s);
  return f;
}

double NutModel::breakaway_n(int dir) const noexcept {
  return coulomb_n_ + (dir > 0 ? breakaway_extra_pos_n_ : breakaway_extra_neg_n_);
}

double NutModel::sliding_friction_n(int dir, double vel_m_s) const noexcept {
  // Friction units give their force against the motion; at the first instant of sliding the
  // speed is still zero, so the direction comes from the mode.
  if (friction_terms_.empty()) return coulomb_n_;
  effects::State s;
  s.v_m_s = dir * std::max(std::abs(vel_m_s), 1e-12);
  s.coulomb_n = coulomb_n_;
  s.viscous_n_s_per_m = viscous_;
  s.nut_mass_kg = mass_kg_;
  double f = coulomb_n_;
  for (const auto& t : friction_terms_) f -= dir * t.effect->force_n(t.params, s);
  return f;
}

FrictionMode NutModel::mode_at_rest(double drive_n) const noexcept {
  if (drive_n > breakaway_n(1)) return FrictionMode::slide_pos;
  if (drive_n < -breakaway_n(-1)) return FrictionMode::slide_neg;
  return FrictionMode::stick;
}

double NutModel::accel_m_s2(FrictionMode mode, double t_s, double screw_rad, double pos_m,
                            double vel_m_s, double ext_force_n, double screw_rate_rad_s,
                            double ext_rate_n_s) const noexcept {
  if (mode == FrictionMode::stick) return 0.0;
  const int dir = static_cast<int>(mode);
  const double drive =
      drive_force_n(t_s, screw_rad, pos_m, vel_m_s, ext_force_n, screw_rate_rad_s, ext_rate_n_s);
  return (drive - dir * sliding_friction_n(dir, vel_m_s)) / mass_kg_;
}

// ---------------------------------------------------------------------------------------------
// CVODE hybrid integrator

namespace {

/// θ linear over one tick, F_ext held: the per-tick input of advance().
class SegmentInput final : public InputSource {
 public:
  double t0 = 0, t1 = 1, th0 = 0, th1 = 0, f = 0, f_rate = 0;
  double screw_rad(double t) const noexcept override {
    const double span = t1 - t0;
    if (!(span > 0.0)) return th1;
    return th0 + (th1 - th0) * std::clamp((t - t0) / span, 0.0, 1.0);
  }
  double ext_force_n(double) const noexcept override { return f; }
  double screw_rate_rad_s(double) const noexcept override {
    return t1 > t0 ? (th1 - th0) / (t1 - t0) : 0.0;
  }
  double ext_rate_n_s(double) const noexcept override { return f_rate; }
};

}  // namespace

struct HybridTwin::Impl {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr, abstol = nullptr;
  SUNMatrix A = nullptr;
  SUNLinearSolver LS = nullptr;
  SUNNonlinearSolver NLS = nullptr;
  void* mem = nullptr;
  const InputSource* inputs = nullptr;
  SegmentInput segment;
  FrictionMode mode = FrictionMode::stick;
  const NutModel* model = nullptr;
  TwinStats done;  // counters harvested before each re-initialisation
  bool fresh = true;

  ~Impl() {
    if (mem) CVodeFree(&mem);
    if (NLS) SUNNonlinSolFree(NLS);
    if (LS) SUNLinSolFree(LS);
    if (A) SUNMatDestroy(A);
    if (abstol) N_VDestroy(abstol);
    if (y) N_VDestroy(y);
    if (ctx) SUNContext_Free(&ctx);
  }

  // CVODE integrates the sliding nut only: while it sticks, its state is constant (see
  // hold_stuck), so rhs and roots never see the stick mode.
  static int rhs(realtype t, N_Vector yv, N_Vector ydot, void* user) {
    auto* self = static_cast<Impl*>(user);
    const double* s = N_VGetArrayPointer(yv);
    double* d = N_VGetArrayPointer(ydot);
    d[0] = s[1];
    d[1] = self->model->accel_m_s2(self->mode, t, self->inputs->screw_rad(t), s[0], s[1],
                                   self->inputs->ext_force_n(t), self->inputs->screw_rate_rad_s(t),
                                   self->inputs->ext_rate_n_s(t));
    return std::isfinite(d[1]) ? 0 : 1;  // recoverable: CVODE retries with a smaller step
  }

  static int roots(realtype t, N_Vector yv, realtype* g, void* user) {
    auto* self = static_cast<Impl*>(user);
    const double* s = N_VGetArrayPointer(yv);
    g[0] = s[1];  // the nut comes to rest
    g[1] = std::cos(phase_rad(self->inputs->screw_rad(t), s[0], self->model->lead_m()));
    return 0;
  }

  /// How far the drive force on a resting nut at t is beyond break-away: > 0 breaks it loose.
  /// Continuous in t, so a sign change between two samples brackets the release.
  double breakaway_excess_n(double t, double screw_rad, double pos_m) const noexcept {
    const double drive = model->drive_force_n(t, screw_rad, pos_m, 0.0, inputs->ext_force_n(t));
    return std::max(drive - model->breakaway_n(1), -drive - model->breakaway_n(-1));
  }
  double breakaway_excess_n(double t, double pos_m) const noexcept {
    return breakaway_excess_n(t, inputs->screw_rad(t), pos_m);
  }

  /// Release time within (lo, hi], where the excess goes from <= 0 to > 0: Illinois
  /// (regula falsi that halves a stale end's value), to CVODE's own root tolerance. Returns a
  /// time at which the nut is already beyond break-away, as CVODE does for its roots.
  double locate_release(double lo, double g_lo, double hi, double g_hi,
                        double pos_m) const noexcept {
    const double tol = 100.0 * std::numeric_limits<double>::epsilon() * (std::abs(hi) + (hi - lo));
    int kept = 0;  // +1: hi moved last time, -1: lo moved
    for (int i = 0; i < 100 && hi - lo > tol; ++i) {
      double t = hi - g_hi * (hi - lo) / (g_hi - g_lo);
      t = std::clamp(t, lo + 0.25 * tol, hi - 0.25 * tol);
      const double g = breakaway_excess_n(t, pos_m);
      if (g > 0.0) {
        hi = t, g_hi = g;
        if (kept == 1) g_lo *= 0.5;
        kept = 1;
      } else {
        lo = t, g_lo = g;
        if (kept == -1) g_hi *= 0.5;
        kept = -1;
      }
    }
    return hi;
  }

  void harvest() {
    long v = 0;
    if (CVodeGetNumSteps(mem, &v) == CV_SUCCESS) done.steps += v;
    if (CVodeGetNumRhsEvals(mem, &v) == CV_SUCCESS) done.rhs_evals += v;
    if (LS && CVodeGetNumJacEvals(mem, &v) == CVLS_SUCCESS) done.jac_evals += v;
  }
};

namespace {
void check(int flag, const char* what) {
  if (flag < 0)
    throw std::runtime_error(std::string("SUNDIALS ") + what + " failed, flag " +
                             std::to_string(flag));
}
void check_ptr(const void* p, const char* what) {
  if (!p) throw std::runtime_error(std::string("SUNDIALS ") + what + " returned null");
}
}  // namespace

HybridTwin::HybridTwin(NutModel model, IntegratorOptions options)
    : model_(std::move(model)), opt_(options), impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.model = &model_;
  m.inputs = &m.segment;
  check(SUNContext_Create(nullptr, &m.ctx), "SUNContext_Create");
  m.y = N_VNew_Serial(2, m.ctx);
  check_ptr(m.y, "N_VNew_Serial");
  m.abstol = N_VNew_Serial(2, m.ctx);
  check_ptr(m.abstol, "N_VNew_Serial");
  NV_Ith_S(m.y, 0) = 0.0;
  NV_Ith_S(m.y, 1) = 0.0;
  NV_Ith_S(m.abstol, 0) = opt_.abs_tol_pos_m;
  NV_Ith_S(m.abstol, 1) = opt_.abs_tol_vel_m_s;
  m.mem = CVodeCreate(opt_.stiff ? CV_BDF : CV_ADAMS, m.ctx);
  check_ptr(m.mem, "CVodeCreate");
  check(CVodeInit(m.mem, Impl::rhs, 0.0, m.y), "CVodeInit");
  check(CVodeSetUserData(m.mem, &m), "CVodeSetUserData");
  check(CVodeSVtolerances(m.mem, opt_.rel_tol, m.abstol), "CVodeSVtolerances");
  if (opt_.stiff) {
    m.A = SUNDenseMatrix(2, 2, m.ctx);
    check_ptr(m.A, "SUNDenseMatrix");
    m.LS = SUNLinSol_Dense(m.y, m.A, m.ctx);
    check_ptr(m.LS, "SUNLinSol_Dense");
    check(CVodeSetLinearSolver(m.mem, m.LS, m.A), "CVodeSetLinearSolver");
  } else {
    // The nut is not stiff (see IntegratorOptions::stiff): fixed-point iteration converges
    // without a Jacobian or a linear solve.
    m.NLS = SUNNonlinSol_FixedPoint(m.y, 0, m.ctx);
    check_ptr(m.NLS, "SUNNonlinSol_FixedPoint");
    check(CVodeSetNonlinearSolver(m.mem, m.NLS), "CVodeSetNonlinearSolver");
  }
  check(CVodeRootInit(m.mem, 2, Impl::roots), "CVodeRootInit");
  check(CVodeSetNoInactiveRootWarn(m.mem), "CVodeSetNoInactiveRootWarn");
  check(CVodeSetMaxNumSteps(m.mem, opt_.max_internal_steps), "CVodeSetMaxNumSteps");
  if (opt_.max_step_s > 0.0) check(CVodeSetMaxStep(m.mem, opt_.max_step_s), "CVodeSetMaxStep");
  check(CVodeSetMaxOrd(m.mem, opt_.max_order), "CVodeSetMaxOrd");
}

HybridTwin::~HybridTwin() = default;

void HybridTwin::reset(double t_s, const NutState& s, double screw_rad,
                       double ext_force_n) noexcept {
  Impl& m = *impl_;
  t_s_ = t_s;
  screw_rad_ = screw_rad;
  state_ = s;
  if (state_.mode == FrictionMode::stick) state_.vel_m_s = 0.0;
  // A stuck nut under more than break-away, or a sliding one at exactly zero speed, takes the
  // mode the physics gives it.
  if (state_.mode == FrictionMode::stick || state_.vel_m_s == 0.0)
    state_.mode =
        model_.mode_at_rest(model_.drive_force_n(t_s, screw_rad, state_.pos_m, 0.0, ext_force_n));
  else
    state_.mode = state_.vel_m_s > 0 ? FrictionMode::slide_pos : FrictionMode::slide_neg;
  m.mode = state_.mode;
  m.segment.t0 = m.segment.t1 = t_s;
  m.segment.th0 = m.segment.th1 = screw_rad;
  m.segment.f = ext_force_n;
  m.fresh = true;
}

TwinStats HybridTwin::stats() const noexcept {
  TwinStats s = impl_->done;
  long v = 0;
  if (CVodeGetNumSteps(impl_->mem, &v) == CV_SUCCESS) s.steps += v;
  if (CVodeGetNumRhsEvals(impl_->mem, &v) == CV_SUCCESS) s.rhs_evals += v;
  if (impl_->LS && CVodeGetNumJacEvals(impl_->mem, &v) == CVLS_SUCCESS) s.jac_evals += v;
  return s;
}

TwinStatus HybridTwin::advance(double t_end_s, double screw_end_rad, double ext_force_n) noexcept {
  Impl& m = *impl_;
  m.segment.t0 = t_s_;
  m.segment.t1 = t_end_s;
  m.segment.th0 = screw_rad_;
  m.segment.th1 = screw_end_rad;
  // A new force level that breaks a stuck nut loose shows as a sign change of the break-away
  // root function in the first step of this tick; CVODE locates it there without a restart.
  // The load's rate over the last tick (for a delayed load-cell term).
  m.segment.f_rate = t_end_s > t_s_ ? (ext_force_n - m.segment.f) / (t_end_s - t_s_) : 0.0;
  m.segment.f = ext_force_n;
  m.inputs = &m.segment;
  const TwinStatus st = run(t_end_s, true);
  screw_rad_ = screw_end_rad;
  return st;
}

TwinStatus HybridTwin::integrate_to(double tout_s, const InputSource& inputs) noexcept {
  Impl& m = *impl_;
  if (m.inputs != &inputs) m.fresh = true;
  m.inputs = &inputs;
  const TwinStatus st = run(tout_s, false);
  screw_rad_ = inputs.screw_rad(t_s_);
  return st;
}

TwinStatus HybridTwin::run(double tout_s, bool stop_at_tout) noexcept {
  Impl& m = *impl_;
  for (int events = 0;; ++events) {
    if (events > opt_.max_events_per_call) return ++m.done.failures, TwinStatus::zeno;
    if (!(tout_s > t_s_)) return TwinStatus::ok;
    const Leg leg =
        state_.mode == FrictionMode::stick ? hold_stuck(tout_s) : slide(tout_s, stop_at_tout);
    if (leg == Leg::failed) return ++m.done.failures, TwinStatus::solver_error;
    if (leg == Leg::reached_tout) return TwinStatus::ok;
  }
}

HybridTwin::Leg HybridTwin::hold_stuck(double tout_s) noexcept {
  // A stuck nut's state is constant: there is nothing to integrate, only the break-away guard
  // to watch. It is sampled at the step cap (the inputs' sample period: no feature of the
  // inputs is shorter), as CVODE would check its roots at the ends of capped steps, and a
  // release is located between two samples.
  Impl& m = *impl_;
  const double pos = state_.pos_m;
  const double h = opt_.max_step_s > 0.0 ? opt_.max_step_s : tout_s - t_s_;
  const double lead = model_.lead_m();
  double ta = t_s_, th = m.inputs->screw_rad(ta);
  double ga = m.breakaway_excess_n(ta, th, pos), ca = std::cos(phase_rad(th, pos, lead));
  bool released = ga > 0.0;  // new inputs may already load it past break-away: release now
  while (!released && ta < tout_s) {
    const double tb = std::min(ta + h, tout_s);
    th = m.inputs->screw_rad(tb);
    const double gb = m.breakaway_excess_n(tb, th, pos), cb = std::cos(phase_rad(th, pos, lead));
    ++m.done.stuck_checks;
    if ((ca > 0.0) != (cb > 0.0)) ++m.done.root_events, ++m.done.step_out_crossings;
    if (gb > 0.0) {
      t_s_ = m.locate_release(ta, ga, tb, gb, pos);
      ++m.done.root_events;
      released = true;
    }
    ta = tb, ga = gb, ca = cb;
  }
  if (!released) {
    t_s_ = tout_s;
    return Leg::reached_tout;
  }
  // Broken loose (now, or at the located release): slide in the drive's direction.
  const double drive =
      model_.drive_force_n(t_s_, m.inputs->screw_rad(t_s_), pos, 0.0, m.inputs->ext_force_n(t_s_));
  state_.mode = drive > 0 ? FrictionMode::slide_pos : FrictionMode::slide_neg;
  state_.vel_m_s = 0.0;
  ++m.done.mode_switches;
  m.fresh = true;  // the integrator's history belongs to an earlier slide
  return Leg::switched;
}

HybridTwin::Leg HybridTwin::slide(double tout_s, bool stop_at_tout) noexcept {
  Impl& m = *impl_;
  double* y = N_VGetArrayPointer(m.y);
  if (m.fresh) {
    m.mode = state_.mode;
    y[0] = state_.pos_m;
    y[1] = state_.vel_m_s;
    m.harvest();  // CVodeReInit zeroes the counters; keep their sums
    m.fresh = false;
    ++m.done.reinits;
    if (CVodeReInit(m.mem, t_s_, m.y) < 0) return Leg::failed;
  }
  if (stop_at_tout && CVodeSetStopTime(m.mem, tout_s) < 0) return Leg::failed;
  realtype tret = t_s_;
  const int flag = CVode(m.mem, tout_s, m.y, &tret, CV_NORMAL);
  if (flag < 0) return Leg::failed;
  t_s_ = tret;
  state_.pos_m = y[0];
  state_.vel_m_s = y[1];
  if (flag != CV_ROOT_RETURN) return Leg::reached_tout;  // CV_SUCCESS or CV_TSTOP_RETURN

  int found[2] = {0, 0};
  if (CVodeGetRootInfo(m.mem, found) < 0) return Leg::failed;
  ++m.done.root_events;
  if (found[1]) ++m.done.step_out_crossings;  // no discontinuity: CVODE carries on
  if (!found[0]) return Leg::switched;
  // At rest the physics picks the next mode: stick, or slide back under a reversed drive.
  const double drive = model_.drive_force_n(t_s_, m.inputs->screw_rad(t_s_), state_.pos_m, 0.0,
                                            m.inputs->ext_force_n(t_s_));
  const FrictionMode before = state_.mode;
  state_.mode = model_.mode_at_rest(drive);
  state_.vel_m_s = 0.0;
  if (state_.mode != before) ++m.done.mode_switches;
  m.fresh = true;
  return Leg::switched;
}

// ---------------------------------------------------------------------------------------------
// Fixed-step RK4 of the same hybrid model

void Rk4Twin::integrate_to(double tout_s, const InputSource& in) noexcept {
  while (t_s_ < tout_s - 1e-12) {
    const double h = std::min(h_, tout_s - t_s_);
    const double t = t_s_;
    NutState& s = state_;
    if (s.mode == FrictionMode::stick) {
      const double drive =
          model_.drive_force_n(t, in.screw_rad(t), s.pos_m, 0.0, in.ext_force_n(t));
      ++rhs_evals_;
      s.mode = model_.mode_at_rest(drive);
      if (s.mode == FrictionMode::stick) {
        t_s_ += h;
        continue;
      }
    }
    const auto f = [&](double tt, double p, double v, double& dp, double& dv) {
      dp = v;
      dv = model_.accel_m_s2(s.mode, tt, in.screw_rad(tt), p, v, in.ext_force_n(tt),
                             in.screw_rate_rad_s(tt), in.ext_rate_n_s(tt));
      ++rhs_evals_;
    };
    double k1p, k1v, k2p, k2v, k3p, k3v, k4p, k4v;
    f(t, s.pos_m, s.vel_m_s, k1p, k1v);
    f(t + h / 2, s.pos_m + h / 2 * k1p, s.vel_m_s + h / 2 * k1v, k2p, k2v);
    f(t + h / 2, s.pos_m + h / 2 * k2p, s.vel_m_s + h / 2 * k2v, k3p, k3v);
    f(t + h, s.pos_m + h * k3p, s.vel_m_s + h * k3v, k4p, k4v);
    const double v_new = s.vel_m_s + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    const double p_new = s.pos_m + h / 6 * (k1p + 2 * k2p + 2 * k3p + k4p);
    const int dir = static_cast<int>(s.mode);
    if (v_new * dir <= 0.0) {
      // Velocity reached zero within the step: stop at the zero crossing of a linear velocity
      // (first order in the event time, which is why RK4 needs small steps here).
      const double frac = s.vel_m_s / (s.vel_m_s - v_new);
      s.pos_m += frac * h * 0.5 * s.vel_m_s;
      s.vel_m_s = 0.0;
      s.mode = FrictionMode::stick;
    } else {
      s.pos_m = p_new;
      s.vel_m_s = v_new;
    }
    t_s_ += h;
  }
}

// ---------------------------------------------------------------------------------------------
// Demo drive

namespace {
class DemoDrive final : public InputSource {
 public:
  DemoDrive(std::uint64_t seed, double duration_s, double lead_m) : lead_m_(lead_m) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> len(0.8, kLongestPush_s), peak(10.0, 35.0),
        gap(0.0, 2.5), coin(0.0, 1.0), move(-2.0, 2.0);
    for (double t = 0.3; t < duration_s;) {
      pulses_.push_back({t, len(rng), (coin(rng) < 0.5 ? -1.0 : 1.0) * peak(rng)});
      t += pulses_.back().len + gap(rng);
    }
    for (double t = 0.5; t < duration_s; t += 3.0) moves_.push_back({t, move(rng) * 1e-3});
    double p = 0.02;  // nut target before each move, summed in the order screw_rad adds them
    for (const auto& mv : moves_) target_before_.push_back(p), p += mv.dp;
    // Knocks: 30 ms bumps between pushes, like the plant's external disturbances. Their short
    // duration is what an integrator without a step cap steps over.
    // Only between pushes, so that no load exceeds the coupling's peak (no step-out here).
    std::uniform_real_distribution<double> when(0.0, duration_s), knock(15.0, 30.0);
    for (int i = 0; i < static_cast<int>(duration_s); ++i) {
      const double t = when(rng), f = (coin(rng) < 0.5 ? -1.0 : 1.0) * knock(rng);
      if (push(t) == 0.0 && push(t + kKnock_s) == 0.0 && knock_at(t) == 0.0)
        knocks_.push_back({t, kKnock_s, f});
      std::sort(knocks_.begin(), knocks_.end(), [](auto& a, auto& b) { return a.t0 < b.t0; });
    }
  }
  // The inputs are looked up by bisection, not scanned from the start: the benchmark charges
  // their cost to the integrator, and a scan grows with the drive's length.
  double screw_rad(double t) const noexcept override {
    // Smooth screw moves (cosine blends of 0.4 s) to new nut targets: the moves before the
    // ones still blending are complete and summed in target_before_.
    const auto first = std::lower_bound(moves_.begin(), moves_.end(), t - 2.0 * kBlend_s,
                                        [](const Move& mv, double x) { return mv.t0 < x; });
    if (first == moves_.end() || t <= first->t0)
      return rest_angle_rad(first == moves_.begin() ? 0.02 : final_target(first), lead_m_);
    double p = target_before_[static_cast<std::size_t>(first - moves_.begin())];
    for (auto mv = first; mv != moves_.end() && t > mv->t0; ++mv) {
      const double x = std::min(1.0, (t - mv->t0) / kBlend_s);
      p += mv->dp * 0.5 * (1.0 - std::cos(std::numbers::pi * x));
    }
    return rest_angle_rad(p, lead_m_);
  }
  double ext_force_n(double t) const noexcept override { return push(t) + knock_at(t); }

 private:
  static constexpr double kLongestPush_s = 2.5, kKnock_s = 0.03, kBlend_s = 0.4;
  struct Pulse {
    double t0, len, peak;
  };
  double push(double t) const noexcept { return shape(pulses_, kLongestPush_s, t); }
  double knock_at(double t) const noexcept { return shape(knocks_, kKnock_s, t); }
  /// The earliest pulse (sorted by start, none longer than longest_s) that covers t.
  static double shape(const std::vector<Pulse>& pulses, double longest_s, double t) noexcept {
    auto pl = std::lower_bound(pulses.begin(), pulses.end(), t - 2.0 * longest_s,
                               [](const Pulse& p, double x) { return p.t0 < x; });
    for (; pl != pulses.end(); ++pl) {
      if (t < pl->t0) break;
      const double x = (t - pl->t0) / pl->len;
      if (x < 1.0) {
        const double s = std::sin(std::numbers::pi * x);
        return pl->peak * s * s;
      }
    }
    return 0.0;
  }
  struct Move {
    double t0, dp;
  };
  /// Where the nut target stands once every move before `end` has completed.
  double final_target(std::vector<Move>::const_iterator end) const noexcept {
    const auto i = static_cast<std::size_t>(end - moves_.begin()) - 1;
    return target_before_[i] + moves_[i].dp;
  }
  double lead_m_;
  std::vector<Pulse> pulses_, knocks_;
  std::vector<Move> moves_;
  std::vector<double> target_before_;
};
}  // namespace

std::unique_ptr<InputSource> make_demo_drive(std::uint64_t seed, double duration_s, double lead_m) {
  return std::make_unique<DemoDrive>(seed, duration_s, lead_m);
}

}  // namespace maglead::twin
