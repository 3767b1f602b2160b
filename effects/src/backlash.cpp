// backlash: lost motion between the motor encoder and the screw; the screw lags the motor by b/2 on
// the side of the transmitted torque, and floats where the coupling pulls it while the torque is
// too small to reach either side of the play.
#include <algorithm>
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
// The screw has no stiffness of its own: the coupling pulls it towards its rest angle (F_m = 0)
// and the gear holds it at most b/2 off, so the true |F_m| is the read one less up to b/2 |k|
// (k = dF_m/dφ), and within b/2 of the rest phase less all of it. The law ramps the lag over a
// float zone z around the rest phase: z = b for a screw free in its bearings (the plant's), z = 0
// for one its bearings hold (a lag b/2 on the torque's side). First order in b outside the zone.
double lag_share(double float_zone_rad, const State& s) {
  const double k = std::abs(s.coupling_slope_n_per_rad);
  if (float_zone_rad <= 0 || k <= 0) return 1.0;
  return std::min(1.0, std::abs(s.coupling_n) / (0.5 * float_zone_rad * k));
}

struct Backlash final : Effect {
  std::string_view id() const override { return "backlash"; }
  std::string_view law() const override {
    return "theta_screw = theta_motor/N - (b/2) sign(torque) min(1, |F_m|/(k z/2)): the screw "
           "floats towards F_m = 0 within z";
  }
  std::vector<ParamSpec> params() const override {
    // A lag b/2 within half a count is what rounding holds where nothing moves: at least a count.
    return {
        {"backlash_rad", "total play b at the screw", 0.0, 0.5, Scale::absolute, 1.0},
        {"float_zone_rad", "phase span z around F_m = 0 over which the lag ramps up", 0.0, 0.5}};
  }
  double force_n(const Params& p, const State& s) const override {
    return -0.5 * param(p, "backlash_rad", 0.0) * sgn(s.coupling_n) *
           std::abs(s.coupling_slope_n_per_rad) * lag_share(param(p, "float_zone_rad", 0.0), s);
  }
  // The float zones the fit tries (its coefficient is b/2): a free screw's zone is its play, a
  // held one's 0.
  std::vector<double> shapes() const override {
    return {0.0,  0.005, 0.0075, 0.01, 0.0125, 0.015, 0.02, 0.025, 0.03, 0.04,
            0.05, 0.06,  0.08,   0.1,  0.12,   0.15,  0.2,  0.25,  0.3};
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double z, const State& s, double* x) const override {
    x[0] = -sgn(s.coupling_n) * std::abs(s.coupling_slope_n_per_rad) * lag_share(z, s);
  }
  std::optional<Params> parameters(double z, const double* c, const State&) const override {
    if (c[0] <= 0) return std::nullopt;
    return Params{{"backlash_rad", 2 * c[0]}, {"float_zone_rad", z}};
  }
};
}  // namespace
const Effect& backlash() {
  static const Backlash e;
  return e;
}
}  // namespace maglead::effects
