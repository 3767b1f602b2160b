// position_ripple: an extra force A sin(2 pi p / lambda + psi) fixed along the stroke.
#include <cmath>
#include <numbers>

#include "units.hpp"

namespace maglead::effects {
namespace {
constexpr double kPi = std::numbers::pi;
struct PositionRipple final : Effect {
  std::string_view id() const override { return "position_ripple"; }
  std::string_view law() const override { return "F = A sin(2 pi p / lambda + psi)"; }
  // A guide's or cogging ripple is a disturbance beside the drive's force, not a second drive:
  // at most a quarter of the peak force (one at the lead's period and near the coupling's own
  // size is the coupling's force misread, e.g. a calibration off by a factor).
  std::vector<ParamSpec> params() const override {
    return {{"amplitude_n", "A", 0.0, 0.25, Scale::force},
            {"period_m", "lambda", 1e-4, 0.1},
            {"phase_rad", "psi", -kPi, kPi}};
  }
  double force_n(const Params& p, const State& s) const override {
    return param(p, "amplitude_n", 0.0) *
           std::sin(2 * kPi * s.p_m / param(p, "period_m", 5e-3) + param(p, "phase_rad", 0.0));
  }
  std::vector<double> shapes() const override {
    return {1e-3, 1.5e-3, 2e-3, 2.5e-3, 3e-3, 4e-3, 5e-3, 6e-3, 8e-3, 10e-3, 12e-3, 16e-3, 20e-3};
  }
  // A force seen over less than one period is not seen to repeat: it is a spring's, an offset's
  // or a gain's as much as a ripple's.
  bool resolved_at(double lambda, const Scales& s) const override {
    return s.travel_m == 0 || lambda <= s.travel_m;
  }
  int columns() const override { return 2; }
  void regressors(double lambda, const State& s, double* x) const override {
    x[0] = std::sin(2 * kPi * s.p_m / lambda);
    x[1] = std::cos(2 * kPi * s.p_m / lambda);
  }
  std::optional<Params> parameters(double lambda, const double* c, const State&) const override {
    return Params{{"amplitude_n", std::hypot(c[0], c[1])},
                  {"period_m", lambda},
                  {"phase_rad", std::atan2(c[1], c[0])}};
  }
};
}  // namespace
const Effect& position_ripple() {
  static const PositionRipple e;
  return e;
}
}  // namespace maglead::effects
