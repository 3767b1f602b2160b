#pragma once
// Effects and their parameters in words for people: the names, laws and units of
// docs/effects.md, as the effect library states them.
#include <string>

#include "maglead/effects/axis_kind.hpp"

namespace maglead::report {

/// "gain drift" for gain_drift.
std::string effect_title(const std::string& id);
/// The effect's law (one line) as an axis of that kind states it (τ = -C ω on a shaft; no load
/// cell on any axis, AxisKind::law); nullptr: the actuator's, the library's own law. Empty for an
/// id the library does not know.
std::string effect_law(const std::string& id, const effects::AxisKind* axis = nullptr);
/// "gain_change_per_min = −0.201 1/min (rate r of the relative coupling gain)", HTML-escaped.
/// With a standard error: "coulomb_n = 20.56 ± 0.18 N (…)", at the digits the error allows.
/// The meaning is in the axis kind's words ("constant torque on the shaft along +θ").
std::string parameter_html(const std::string& effect_id, const std::string& name, double value,
                           double standard_error = 0.0,
                           const effects::AxisKind& kind = effects::linear_axis());

}  // namespace maglead::report
