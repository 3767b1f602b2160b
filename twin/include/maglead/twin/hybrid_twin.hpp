#pragma once
// The twin's nut dynamics as a hybrid system; the sliding nut is integrated by SUNDIALS CVODE
// (Adams, fixed-point iteration: see IntegratorOptions::stiff).
//
//   M p̈ = F_m(θ, p) + F_other(θ, p) + F_ext − C ṗ − friction(mode)
//
// The friction mode (stick, slide +p, slide −p) is a discrete state kept outside the right-hand
// side: a sign() inside it makes the integrator chatter at ṗ = 0 and a tanh leaves a bias. Roots
// switch it: ṗ crossing zero while sliding (CVODE's root finding), the drive force crossing
// ± break-away while stuck; cos φ crossing zero marks the edge of the stable branch (step-out).
// A stuck nut's state is constant, so it is not integrated: the break-away guard is sampled at
// the step cap and its crossing located between samples. Each slide starts the integrator
// afresh (its history is invalid across a mode switch).
//
// Independent of the simulated plant's code on purpose (the plant plays the real machine).
#include <cstdint>
#include <memory>

#include "maglead/effects/effect.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::twin {

enum class FrictionMode : std::int8_t { slide_neg = -1, stick = 0, slide_pos = 1 };

struct NutState {
  double pos_m = 0.0;
  double vel_m_s = 0.0;
  FrictionMode mode = FrictionMode::stick;
};

/// The force law: calibration, actuator geometry and the model file's terms (effect units of
/// effects/), resolved once.
class NutModel {
 public:
  NutModel(const ActuatorParams& actuator, const PeriodicForceModel& coupling,
           const TwinModel& model);
  double mass_kg() const { return mass_kg_; }
  double lead_m() const { return lead_m_; }
  /// Magnetic force on the nut along +p as calibrated, F_m = −F̂_s(φ) (terms scale it elsewhere).
  double coupling_force_n(double t_s, double screw_rad, double pos_m) const noexcept;
  /// The coupling as the model applies it: F_m with every term that scales it (gain, ripple,
  /// end effect), without the terms that add a force of their own (offset, spring, ...). The
  /// drift detector estimates the factor between the actuator's coupling and this.
  double model_coupling_force_n(double t_s, double screw_rad, double pos_m,
                                double vel_m_s) const noexcept;
  /// Everything except friction and inertia: F_m + F_ext − C ṗ + every non-friction term.
  /// The rates feed terms that need them (sensor and load-cell delays); 0 when unknown.
  double drive_force_n(double t_s, double screw_rad, double pos_m, double vel_m_s,
                       double ext_force_n, double screw_rate_rad_s = 0.0,
                       double ext_rate_n_s = 0.0) const noexcept;
  /// Force needed to break the nut loose in direction dir (±1).
  double breakaway_n(int dir) const noexcept;
  /// Friction magnitude while sliding in direction dir at speed v.
  double sliding_friction_n(int dir, double vel_m_s) const noexcept;
  /// Mode the nut takes at rest under a drive force (stick unless beyond break-away).
  FrictionMode mode_at_rest(double drive_n) const noexcept;
  /// Acceleration in a mode (0 when stuck).
  double accel_m_s2(FrictionMode mode, double t_s, double screw_rad, double pos_m, double vel_m_s,
                    double ext_force_n, double screw_rate_rad_s = 0.0,
                    double ext_rate_n_s = 0.0) const noexcept;

 private:
  struct Term {
    const effects::Effect* effect;
    effects::Params params;
  };
  /// The calibration's F̂_s(φ) (load convention) and, when asked, its slope dF̂_s/dφ.
  void calibrated_load_n(double phi_rad, double& load_n, double* slope) const noexcept;
  effects::State state(double t_s, double screw_rad, double pos_m, double vel_m_s,
                       double ext_force_n, double screw_rate_rad_s,
                       double ext_rate_n_s) const noexcept;
  PeriodicForceModel coupling_;
  double lead_m_, stroke_min_m_, stroke_max_m_;
  double mass_kg_, viscous_, coulomb_n_;
  std::vector<Term> drive_terms_, friction_terms_;
  double breakaway_extra_pos_n_ = 0, breakaway_extra_neg_n_ = 0;
};

/// Continuous-time inputs: screw angle θ(t) and external force F_ext(t) (load convention).
class InputSource {
 public:
  virtual ~InputSource() = default;
  virtual double screw_rad(double t_s) const noexcept = 0;
  virtual double ext_force_n(double t_s) const noexcept = 0;
  /// Rates for terms that need them (delays); 0 unless the source knows them.
  virtual double screw_rate_rad_s(double) const noexcept { return 0.0; }
  virtual double ext_rate_n_s(double) const noexcept { return 0.0; }
};

struct IntegratorOptions {
  double rel_tol = 1e-6;
  double abs_tol_pos_m = 1e-9;  // well below one encoder count (21.6 µm)
  double abs_tol_vel_m_s = 1e-7;
  double max_step_s = 1e-3;  // the sample period; 0 removes the cap (tests show why not)
  // The nut on its coupling is a lightly damped oscillator (about 100 Hz, damping ratio ~0.01):
  // its eigenvalues lie near the imaginary axis, not far out on the negative real one, so the
  // system is not stiff. Adams with fixed-point iteration fits it; BDF with a dense Newton
  // solve (stiff = true) pays for Jacobians and linear solves it does not need, and damps the
  // oscillation numerically. The reference solutions use BDF, a method independent of Adams.
  bool stiff = false;
  int max_order = 5;  // order limit (Adams: small orders have the larger stability region)
  int max_events_per_call = 64;  // Zeno guard: more mode switches than this in one call fail
  long max_internal_steps = 100000;
};

struct TwinStats {
  long steps = 0, rhs_evals = 0, jac_evals = 0, root_events = 0, mode_switches = 0;
  long reinits = 0, step_out_crossings = 0, failures = 0;
  long stuck_checks = 0;  // break-away checks while stuck (no integration steps then)
};

enum class TwinStatus : std::uint8_t { ok, solver_error, zeno };

class HybridTwin {
 public:
  HybridTwin(NutModel model, IntegratorOptions options = {});
  ~HybridTwin();
  HybridTwin(const HybridTwin&) = delete;
  HybridTwin& operator=(const HybridTwin&) = delete;

  /// Sets the state at time t_s (the mode is re-derived if the given one is inconsistent).
  void reset(double t_s, const NutState& state, double screw_rad, double ext_force_n) noexcept;
  /// One control tick: θ moves linearly from its last value to screw_end_rad, F_ext is held at
  /// ext_force_n; integrates with a stop time at t_end_s. No allocation.
  TwinStatus advance(double t_end_s, double screw_end_rad, double ext_force_n) noexcept;
  /// Integrates against continuous inputs to tout without forcing a step boundary there (the
  /// output is interpolated); the step cap alone bounds the steps. Call with increasing tout.
  TwinStatus integrate_to(double tout_s, const InputSource& inputs) noexcept;

  const NutState& state() const noexcept { return state_; }
  double time_s() const noexcept { return t_s_; }
  double screw_rad() const noexcept { return screw_rad_; }
  const NutModel& model() const noexcept { return model_; }
  /// Counters summed over re-initialisations.
  TwinStats stats() const noexcept;

 private:
  struct Impl;
  enum class Leg : std::uint8_t { reached_tout, switched, failed };
  TwinStatus run(double tout_s, bool stop_at_tout) noexcept;
  Leg hold_stuck(double tout_s) noexcept;
  Leg slide(double tout_s, bool stop_at_tout) noexcept;
  NutModel model_;
  IntegratorOptions opt_;
  std::unique_ptr<Impl> impl_;
  NutState state_;
  double t_s_ = 0.0, screw_rad_ = 0.0;
};

/// Fixed-step classical RK4 of the same hybrid model (events located at step ends), for the
/// benchmark's accuracy-for-cost comparison.
class Rk4Twin {
 public:
  Rk4Twin(NutModel model, double step_s) : model_(std::move(model)), h_(step_s) {}
  void reset(double t_s, const NutState& s) noexcept { t_s_ = t_s, state_ = s; }
  void integrate_to(double tout_s, const InputSource& inputs) noexcept;
  const NutState& state() const noexcept { return state_; }
  long rhs_evals() const noexcept { return rhs_evals_; }

 private:
  NutModel model_;
  double h_;
  double t_s_ = 0.0;
  NutState state_;
  long rhs_evals_ = 0;
};

/// A reproducible test drive: screw moves and hand-like force pulses (sin² shapes, 10–35 N,
/// random directions), fixed by the seed. Used by the reference test and the benchmark.
std::unique_ptr<InputSource> make_demo_drive(std::uint64_t seed, double duration_s, double lead_m);

}  // namespace maglead::twin
