// mass_error: the moving mass differs (the parameter is the total).
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct MassError final : Effect {
  std::string_view id() const override { return "mass_error"; }
  std::string_view law() const override { return "M p'' with M the total moving mass"; }
  std::vector<ParamSpec> params() const override {
    return {{"nut_mass_kg", "moving mass M (the total)", 0.0, 1e4}};
  }
  double force_n(const Params& p, const State& s) const override {
    return -(param(p, "nut_mass_kg", s.nut_mass_kg) - s.nut_mass_kg) * s.a_m_s2;
  }
  int columns() const override { return 1; }
  void regressors(double, const State& s, double* x) const override { x[0] = -s.a_m_s2; }
  std::optional<Params> parameters(double, const double* c, const State& m) const override {
    return Params{{"nut_mass_kg", m.nut_mass_kg + c[0]}};
  }
};
}  // namespace
const Effect& mass_error() {
  static const MassError e;
  return e;
}
}  // namespace maglead::effects
