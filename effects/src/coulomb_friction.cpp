// coulomb_friction: F_f = F_c sign(v) while sliding; stuck while |F_m + F_ext| <= F_c.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Coulomb final : Effect {
  std::string_view id() const override { return "coulomb_friction"; }
  std::string_view law() const override {
    return "F_f = F_c sign(v); stuck while |F_m + F_ext| <= F_c";
  }
  std::vector<ParamSpec> params() const override {
    return {
        {"coulomb_n", "kinetic and break-away friction F_c (the total)", 0.0, 1.0, Scale::force}};
  }
  double force_n(const Params& p, const State& s) const override {
    return -(param(p, "coulomb_n", s.coulomb_n) - s.coulomb_n) * sgn(s.v_m_s);
  }
  double breakaway_extra_n(const Params& p, const State& m, double) const override {
    return param(p, "coulomb_n", m.coulomb_n) - m.coulomb_n;
  }
  bool friction() const override { return true; }
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override { x[0] = -sgn(s.v_m_s); }
  std::optional<Params> parameters(double, const double* c, const State& m) const override {
    return Params{{"coulomb_n", m.coulomb_n + c[0]}};
  }
};
}  // namespace
const Effect& coulomb_friction() {
  static const Coulomb e;
  return e;
}
}  // namespace maglead::effects
