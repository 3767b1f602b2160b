// mass_error: the moving mass differs (the parameter is the total).
#include <cmath>
#include <cstdio>

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
  // M p'' needs the nut's acceleration, and the nut rings on its coupling: sampled below twice
  // that ring, the ring folds into the band the fit sees, where it reads as the acceleration of
  // a mass of any size.
  std::optional<std::string> unjudged_at(const Scales& s) const override {
    if (!(s.sample_rate_hz > 0 && s.ring_hz > 0.5 * s.sample_rate_hz)) return std::nullopt;
    char b[200];
    std::snprintf(b, sizeof b,
                  "not judged: the nut rings on its coupling at %.0f Hz, above this recording's "
                  "Nyquist frequency %.0f Hz, so its acceleration aliases; record at %.0f Hz or "
                  "more to judge the mass",
                  s.ring_hz, 0.5 * s.sample_rate_hz, std::ceil(2.0 * s.ring_hz));
    return std::string(b);
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
