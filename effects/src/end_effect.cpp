// end_effect: F_m scaled by 1 - D s(x), s = x^2 (3 - 2x), x = clip((z - d)/z, 0, 1).
#include <algorithm>
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct EndEffect final : Effect {
  std::string_view id() const override { return "end_effect"; }
  std::string_view law() const override {
    return "F_m scaled by 1 - D s(x), x = clip((z - d)/z, 0, 1)";
  }
  std::vector<ParamSpec> params() const override {
    return {{"max_reduction", "D", 0.0, 1.0}, {"zone_m", "z", 1e-4, 0.02}};
  }
  static double smooth(double z, const State& s) {
    const double d = std::min(s.p_m - s.stroke_min_m, s.stroke_max_m - s.p_m);
    const double x = std::clamp((z - d) / z, 0.0, 1.0);
    return x * x * (3 - 2 * x);
  }
  double force_n(const Params& p, const State& s) const override {
    return -param(p, "max_reduction", 0.0) * smooth(param(p, "zone_m", 5e-3), s) * s.coupling_n;
  }
  std::vector<double> shapes() const override {
    return {2e-3, 3e-3, 4e-3, 5e-3, 6e-3, 8e-3, 10e-3};
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double z, const State& s, double* x) const override {
    x[0] = -smooth(z, s) * s.coupling_n;
  }
  std::optional<Params> parameters(double z, const double* c, const State&) const override {
    return Params{{"max_reduction", c[0]}, {"zone_m", z}};
  }
};
}  // namespace
const Effect& end_effect() {
  static const EndEffect e;
  return e;
}
}  // namespace maglead::effects
