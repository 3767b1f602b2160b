// external_disturbance: force pulses on the nut that no input explains. Events, not a force law.
#include <cmath>
#include <numbers>

#include "units.hpp"

namespace maglead::effects {
namespace {
constexpr double kPi = std::numbers::pi;
struct Disturbance final : Effect {
  std::string_view id() const override { return "external_disturbance"; }
  std::string_view law() const override { return "force pulses no input explains (events)"; }
  std::vector<ParamSpec> params() const override {
    return {{"count", "pulses seen", 0.0, 1e9}, {"force_n", "largest pulse", -1e3, 1e3}};
  }
  double force_n(const Params&, const State&) const override { return 0.0; }
  int columns() const override { return 0; }
  void regressors(double, const State&, double*) const override {}
  std::optional<Params> parameters(double, const double*, const State&) const override { return std::nullopt; }
  bool selectable() const override { return false; }
};
}  // namespace
const Effect& external_disturbance() {
  static const Disturbance e;
  return e;
}
}  // namespace maglead::effects
