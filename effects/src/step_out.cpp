// step_out: the nut slips by whole leads (|phi| passes pi/2). An event, not a force term.
#include <cmath>
#include <numbers>

#include "units.hpp"

namespace maglead::effects {
namespace {
constexpr double kPi = std::numbers::pi;
struct StepOut final : Effect {
  std::string_view id() const override { return "step_out"; }
  std::string_view law() const override { return "|phi| passes pi/2, phi jumps by about 2 pi"; }
  std::vector<ParamSpec> params() const override { return {{"count", "slips seen", 0.0, 1e9}}; }
  double force_n(const Params&, const State&) const override { return 0.0; }
  int columns() const override { return 0; }
  void regressors(double, const State&, double*) const override {}
  std::optional<Params> parameters(double, const double*, const State&) const override { return std::nullopt; }
  bool selectable() const override { return false; }
};
}  // namespace
const Effect& step_out() {
  static const StepOut e;
  return e;
}
}  // namespace maglead::effects
