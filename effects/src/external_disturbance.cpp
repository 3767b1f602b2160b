// external_disturbance: force pulses on the nut that no input explains. Events, not a force law.
#include "units.hpp"

namespace maglead::effects {
namespace {
struct Disturbance final : EventEffect {
  std::string_view id() const override { return "external_disturbance"; }
  std::string_view law() const override { return "force pulses no input explains (events)"; }
  std::vector<ParamSpec> params() const override {
    return {{"count", "pulses seen", 0.0, 1e9}, {"force_n", "largest pulse", -1e3, 1e3}};
  }
};
}  // namespace
const Effect& external_disturbance() {
  static const Disturbance e;
  return e;
}
}  // namespace maglead::effects
