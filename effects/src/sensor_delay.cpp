// sensor_delay: the position and angle readings lag the true values by tau.
//
// Read at t, the balance holds at t − tau for every term made from the readings (M p̈, F_m(φ),
// C v, friction), but the load cell reads F_ext(t): the balance is off by
// F_ext(t − tau) − F_ext(t) ≈ −tau dF_ext/dt, and dF_ext/dt follows from the balance itself,
// M p⃛ − k φ̇ + C p̈ (+ the friction's rate, zero while sliding one way under Coulomb friction, the
// only samples the analysis fits). The law says it from the motion, not from the load cell, so
// the twin can apply it without one. Leaving out M p⃛ is right only for light nuts: at 10 ms on
// a 2.5 kg nut it is as large as the coupling term.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct SensorDelay final : Effect {
  std::string_view id() const override { return "sensor_delay"; }
  std::string_view law() const override {
    return "phi_read(t) = phi(t - tau), p_read(t) = p(t - tau); F = tau (k dphi/dt - M d3p/dt3 - "
           "C d2p/dt2)";
  }
  std::vector<ParamSpec> params() const override { return {{"delay_s", "tau", 0.0, 0.05}}; }
  double force_n(const Params& p, const State& s) const override {
    double x = 0;
    regressors(0.0, s, &x);
    return param(p, "delay_s", 0.0) * x;
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = s.coupling_slope_n_per_rad * s.phi_rate_rad_s - s.nut_mass_kg * s.jerk_m_s3 -
           s.viscous_n_s_per_m * s.a_m_s2;
  }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    if (c[0] <= 0) return std::nullopt;
    return Params{{"delay_s", c[0]}};
  }
};
}  // namespace
const Effect& sensor_delay() {
  static const SensorDelay e;
  return e;
}
}  // namespace maglead::effects
