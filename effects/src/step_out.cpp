// step_out: the nut slips by whole leads (|phi| passes pi/2). An event, not a force term.
#include "units.hpp"

namespace maglead::effects {
namespace {
struct StepOut final : EventEffect {
  std::string_view id() const override { return "step_out"; }
  std::string_view law() const override { return "|phi| passes pi/2, phi jumps by about 2 pi"; }
  std::vector<ParamSpec> params() const override { return {{"count", "slips seen", 0.0, 1e9}}; }
};
}  // namespace
const Effect& step_out() {
  static const StepOut e;
  return e;
}
}  // namespace maglead::effects
