#pragma once
// The effect units (one per file in this folder) and a helper they share.
#include "maglead/effects/effect.hpp"

namespace maglead::effects {

double param(const Params& p, const char* name, double fallback);

/// An effect seen as events in time (a slip, a pulse), not as a force law the analysis fits.
struct EventEffect : Effect {
  double force_n(const Params&, const State&) const override { return 0.0; }
  int columns() const override { return 0; }
  void regressors(double, const State&, double*) const override {}
  std::optional<Params> parameters(double, const double*, const State&) const override {
    return std::nullopt;
  }
  bool selectable() const override { return false; }
};

const Effect& coulomb_friction();
const Effect& viscous_friction();
const Effect& asymmetric_friction();
const Effect& stribeck_friction();
const Effect& offset();
const Effect& spring();
const Effect& mass_error();
const Effect& coupling_gain_error();
const Effect& gain_drift();
const Effect& angle_ripple();
const Effect& position_ripple();
const Effect& end_effect();
const Effect& backlash();
const Effect& sensor_delay();
const Effect& load_cell_delay();
const Effect& step_out();
const Effect& external_disturbance();

}  // namespace maglead::effects
