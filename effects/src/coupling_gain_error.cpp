// coupling_gain_error: F_m scaled by a constant g (magnet strength, air gap).
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct GainError final : Effect {
  std::string_view id() const override { return "coupling_gain_error"; }
  std::string_view law() const override { return "F_m scaled by g"; }
  std::vector<ParamSpec> params() const override { return {{"gain", "coupling gain g", 0.5, 1.5}}; }
  double force_n(const Params& p, const State& s) const override {
    return (param(p, "gain", 1.0) - 1.0) * s.coupling_n;
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override { x[0] = s.coupling_n; }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    return Params{{"gain", 1.0 + c[0]}};
  }
};
}  // namespace
const Effect& coupling_gain_error() {
  static const GainError e;
  return e;
}
}  // namespace maglead::effects
