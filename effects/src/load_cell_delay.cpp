// load_cell_delay: the force reading lags the true force by tau.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct LoadCellDelay final : Effect {
  std::string_view id() const override { return "load_cell_delay"; }
  std::string_view law() const override { return "F_read(t) = F_ext(t - tau)"; }
  std::vector<ParamSpec> params() const override { return {{"delay_s", "tau", 0.0, 0.05}}; }
  // The true force is the reading tau later: F_ext(t) = F_read(t + tau) ~ F_read + tau dF_read/dt.
  double force_n(const Params& p, const State& s) const override {
    return param(p, "delay_s", 0.0) * s.load_rate_n_s;
  }
  bool on_axis() const override { return false; }  // a law of the load cell
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override { x[0] = s.load_rate_n_s; }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    if (c[0] <= 0) return std::nullopt;
    return Params{{"delay_s", c[0]}};
  }
};
}  // namespace
const Effect& load_cell_delay() {
  static const LoadCellDelay e;
  return e;
}
}  // namespace maglead::effects
