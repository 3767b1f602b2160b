// offset: a constant force on the nut along +p that the load cell does not see.
#include <cmath>

#include "units.hpp"

namespace maglead::effects {
namespace {
struct Offset final : Effect {
  std::string_view id() const override { return "offset"; }
  std::string_view law() const override {
    return "F = F_o (constant, along +p, unseen by the load cell)";
  }
  std::string_view axis_law() const override { return "F = F_o (constant, along +p)"; }
  std::vector<ParamSpec> params() const override {
    return {{"offset_n", "constant force on the nut along +p", -1.0, 1.0, Scale::force}};
  }
  double force_n(const Params& p, const State&) const override { return param(p, "offset_n", 0.0); }
  int columns() const override { return 1; }
  void regressors(double, const State&, double* x) const override { x[0] = 1.0; }
  std::optional<Params> parameters(double, const double* c, const State&) const override {
    return Params{{"offset_n", c[0]}};
  }
};
}  // namespace
const Effect& offset() {
  static const Offset e;
  return e;
}
}  // namespace maglead::effects
