// viscous_friction: the viscous term C v (the parameter is the total C).
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Viscous final : Effect {
  std::string_view id() const override { return "viscous_friction"; }
  std::string_view law() const override { return "F = -C v"; }
  std::vector<ParamSpec> params() const override {
    return {{"viscous_n_s_per_m", "viscous coefficient C (the total)", 0.0, 1.0,
             Scale::force_per_speed}};
  }
  double force_n(const Params& p, const State& s) const override {
    return -(param(p, "viscous_n_s_per_m", s.viscous_n_s_per_m) - s.viscous_n_s_per_m) * s.v_m_s;
  }
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override { x[0] = -s.v_m_s; }
  std::optional<Params> parameters(double, const double* c, const State& m) const override {
    return Params{{"viscous_n_s_per_m", m.viscous_n_s_per_m + c[0]}};
  }
};
}  // namespace
const Effect& viscous_friction() {
  static const Viscous e;
  return e;
}
}  // namespace maglead::effects
