// spring: F = -k (p - p0) on the nut (a return spring, a cable chain).
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Spring final : Effect {
  std::string_view id() const override { return "spring"; }
  std::string_view law() const override { return "F = -k (p - p0)"; }
  std::vector<ParamSpec> params() const override {
    return {{"stiffness_n_per_m", "stiffness k", 0.0, 1e6},
            {"rest_position_m", "rest position p0", -1.0, 1.0}};
  }
  double force_n(const Params& p, const State& s) const override {
    return -param(p, "stiffness_n_per_m", 0.0) * (s.p_m - param(p, "rest_position_m", 0.0));
  }
  int columns() const override { return 2; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = -(s.p_m - 0.5 * (s.stroke_min_m + s.stroke_max_m));
    x[1] = 1.0;
  }
  std::optional<Params> parameters(double, const double* c, const State& m) const override {
    if (!(c[0] > 0)) return std::nullopt;
    return Params{{"stiffness_n_per_m", c[0]},
                  {"rest_position_m", 0.5 * (m.stroke_min_m + m.stroke_max_m) + c[1] / c[0]}};
  }
};
}  // namespace
const Effect& spring() {
  static const Spring e;
  return e;
}
}  // namespace maglead::effects
