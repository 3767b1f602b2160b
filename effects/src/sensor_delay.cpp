// sensor_delay: the position and angle readings lag the true values by tau.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct SensorDelay final : Effect {
  std::string_view id() const override { return "sensor_delay"; }
  std::string_view law() const override {
    return "phi_read(t) = phi(t - tau), p_read(t) = p(t - tau)";
  }
  std::vector<ParamSpec> params() const override { return {{"delay_s", "tau", 0.0, 0.05}}; }
  double force_n(const Params& p, const State& s) const override {
    return param(p, "delay_s", 0.0) * s.coupling_slope_n_per_rad * s.phi_rate_rad_s;
  }
  bool on_axis() const override { return false; }  // a law of the magnetic coupling
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = s.coupling_slope_n_per_rad * s.phi_rate_rad_s;
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
