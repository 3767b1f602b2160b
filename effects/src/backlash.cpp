// backlash: lost motion between the motor encoder and the screw; the screw lags the motor by b/2 on
// the side of the transmitted torque.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Backlash final : Effect {
  std::string_view id() const override { return "backlash"; }
  std::string_view law() const override {
    return "theta_screw = theta_motor/N - (b/2) sign(torque)";
  }
  std::vector<ParamSpec> params() const override {
    // A lag b/2 within half a count is what rounding holds where nothing moves: at least a count.
    return {{"backlash_rad", "total play b at the screw", 0.0, 0.5, Scale::absolute, 1.0}};
  }
  // The screw carries the coupling's reaction: to hold F_m along +p the motor turns it ahead,
  // so the gear's contact side follows sign(F_m). First order in b: F_m(phi - b/2 s) - F_m(phi).
  double force_n(const Params& p, const State& s) const override {
    return -0.5 * param(p, "backlash_rad", 0.0) * sgn(s.coupling_n) * s.coupling_slope_n_per_rad;
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = -sgn(s.coupling_n) * s.coupling_slope_n_per_rad;
  }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    if (c[0] <= 0) return std::nullopt;
    return Params{{"backlash_rad", 2 * c[0]}};
  }
};
}  // namespace
const Effect& backlash() {
  static const Backlash e;
  return e;
}
}  // namespace maglead::effects
