// stribeck_friction: F_k(v) = F_c + (F_s - F_c) exp(-(v/v_s)^2); stuck while |F_m + F_ext| <= F_s.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Stribeck final : Effect {
  std::string_view id() const override { return "stribeck_friction"; }
  std::string_view law() const override {
    return "F_k(v) = F_c + (F_s - F_c) exp(-(v/v_s)^2); stuck while |F_m + F_ext| <= F_s";
  }
  std::vector<ParamSpec> params() const override {
    return {{"breakaway_n", "break-away friction F_s", 0.0, 1.0, Scale::force},
            {"coulomb_n", "kinetic friction F_c at speed", 0.0, 1.0, Scale::force},
            {"stribeck_velocity_m_s", "Stribeck velocity v_s", 1e-5, 0.1}};
  }
  double force_n(const Params& p, const State& s) const override {
    const double fc = param(p, "coulomb_n", s.coulomb_n), fs = param(p, "breakaway_n", fc);
    const double r = s.v_m_s / param(p, "stribeck_velocity_m_s", 1e-3);
    return -sgn(s.v_m_s) * (fc - s.coulomb_n + (fs - fc) * std::exp(-r * r));
  }
  double breakaway_extra_n(const Params& p, const State& m, double) const override {
    return param(p, "breakaway_n", m.coulomb_n) - m.coulomb_n;
  }
  std::vector<double> shapes() const override { return {0.5e-3, 1e-3, 2e-3, 4e-3, 8e-3, 16e-3}; }
  bool friction() const override { return true; }
  int columns() const override { return 1; }
  void regressors(double vs, const State& s, double* x) const override {
    const double r = s.v_m_s / vs;
    x[0] = -sgn(s.v_m_s) * std::exp(-r * r);
  }
  std::optional<Params> parameters(double vs, const double* c, const State& m) const override {
    if (c[0] <= 0) return std::nullopt;  // friction that falls towards rest is not Stribeck's
    return Params{{"breakaway_n", m.coulomb_n + c[0]},
                  {"coulomb_n", m.coulomb_n},
                  {"stribeck_velocity_m_s", vs}};
  }
};
}  // namespace
const Effect& stribeck_friction() {
  static const Stribeck e;
  return e;
}
}  // namespace maglead::effects
