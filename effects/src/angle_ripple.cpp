// angle_ripple: F_m scaled by 1 + a sin(theta + psi), once per screw turn (eccentric screw).
#include <cmath>
#include <numbers>

#include "units.hpp"

namespace maglead::effects {
namespace {
constexpr double kPi = std::numbers::pi;
struct AngleRipple final : Effect {
  std::string_view id() const override { return "angle_ripple"; }
  std::string_view law() const override { return "F_m scaled by 1 + a sin(theta + psi)"; }
  std::vector<ParamSpec> params() const override {
    return {{"relative_amplitude", "a", 0.0, 0.5}, {"phase_rad", "psi", -kPi, kPi}};
  }
  double force_n(const Params& p, const State& s) const override {
    return param(p, "relative_amplitude", 0.0) *
           std::sin(s.theta_rad + param(p, "phase_rad", 0.0)) * s.coupling_n;
  }
  // Once per screw turn: over less than a turn it is a gain that varies smoothly with the angle
  // (on a held screw, a constant gain).
  bool resolved_at(double, const Scales& s) const override {
    return s.turn_rad == 0 || s.turn_rad >= 2 * kPi;
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 2; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = s.coupling_n * std::sin(s.theta_rad);  // a cos(psi)
    x[1] = s.coupling_n * std::cos(s.theta_rad);  // a sin(psi)
  }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    return Params{{"relative_amplitude", std::hypot(c[0], c[1])},
                  {"phase_rad", std::atan2(c[1], c[0])}};
  }
};
}  // namespace
const Effect& angle_ripple() {
  static const AngleRipple e;
  return e;
}
}  // namespace maglead::effects
