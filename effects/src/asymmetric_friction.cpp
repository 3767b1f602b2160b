// asymmetric_friction: kinetic and break-away friction differ by direction.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Asymmetric final : Effect {
  std::string_view id() const override { return "asymmetric_friction"; }
  std::string_view law() const override {
    return "F_f = F_c+ (v > 0), -F_c- (v < 0); break-away likewise";
  }
  std::vector<ParamSpec> params() const override {
    return {{"coulomb_pos_n", "friction moving +p", 0.0, 1.0, Scale::force},
            {"coulomb_neg_n", "friction moving -p", 0.0, 1.0, Scale::force},
            {"viscous_pos_n_s_per_m", "viscous coefficient moving +p (optional)", 0.0, 1.0,
             Scale::force_per_speed},
            {"viscous_neg_n_s_per_m", "viscous coefficient moving -p (optional)", 0.0, 1.0,
             Scale::force_per_speed}};
  }
  double force_n(const Params& p, const State& s) const override {
    const double v = s.v_m_s;
    if (v > 0)
      return -(param(p, "coulomb_pos_n", s.coulomb_n) - s.coulomb_n) -
             (param(p, "viscous_pos_n_s_per_m", s.viscous_n_s_per_m) - s.viscous_n_s_per_m) * v;
    if (v < 0)
      return (param(p, "coulomb_neg_n", s.coulomb_n) - s.coulomb_n) -
             (param(p, "viscous_neg_n_s_per_m", s.viscous_n_s_per_m) - s.viscous_n_s_per_m) * v;
    return 0.0;
  }
  double breakaway_extra_n(const Params& p, const State& m, double dir) const override {
    return param(p, dir > 0 ? "coulomb_pos_n" : "coulomb_neg_n", m.coulomb_n) - m.coulomb_n;
  }
  bool friction() const override { return true; }
  int columns() const override { return 2; }
  void regressors(double, const State& s, double* x) const override {
    x[0] = s.v_m_s > 0 ? -1.0 : 0.0;
    x[1] = s.v_m_s < 0 ? 1.0 : 0.0;
  }
  std::optional<Params> parameters(double, const double* c, const State& m) const override {
    return Params{{"coulomb_pos_n", m.coulomb_n + c[0]}, {"coulomb_neg_n", m.coulomb_n + c[1]}};
  }
  // A drive's force sees the viscous slope of each direction as well as its level.
  int axis_columns() const override { return 4; }
  void axis_regressors(double, const State& s, double* x) const override {
    regressors(0.0, s, x);
    x[2] = s.v_m_s > 0 ? -s.v_m_s : 0.0;
    x[3] = s.v_m_s < 0 ? -s.v_m_s : 0.0;
  }
  std::optional<Params> axis_parameters(double, const double* c, const State& m) const override {
    return Params{{"coulomb_pos_n", m.coulomb_n + c[0]},
                  {"coulomb_neg_n", m.coulomb_n + c[1]},
                  {"viscous_pos_n_s_per_m", m.viscous_n_s_per_m + c[2]},
                  {"viscous_neg_n_s_per_m", m.viscous_n_s_per_m + c[3]}};
  }
};
}  // namespace
const Effect& asymmetric_friction() {
  static const Asymmetric e;
  return e;
}
}  // namespace maglead::effects
