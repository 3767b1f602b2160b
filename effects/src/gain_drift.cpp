// gain_drift: F_m scaled by g(t) = 1 + r t / 60, t from the start of the recording.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct GainDrift final : Effect {
  std::string_view id() const override { return "gain_drift"; }
  std::string_view law() const override { return "F_m scaled by 1 + r t/60"; }
  std::vector<ParamSpec> params() const override {
    return {{"gain_change_per_min", "rate r of the relative coupling gain [1/min]", -0.5, 0.5}};
  }
  double force_n(const Params& p, const State& s) const override {
    return param(p, "gain_change_per_min", 0.0) * s.t_s / 60.0 * s.coupling_n;
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = s.coupling_n * s.t_s / 60.0;
  }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    return Params{{"gain_change_per_min", c[0]}};
  }
};
}  // namespace
const Effect& gain_drift() {
  static const GainDrift e;
  return e;
}
}  // namespace maglead::effects
