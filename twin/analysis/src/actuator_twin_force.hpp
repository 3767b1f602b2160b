#pragma once
// The twin's force estimate against the load cell (see actuator_twin_force.cpp).
#include <optional>

#include "maglead/analysis/model_file.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/recording/recording.hpp"

namespace maglead::analysis::actuator {

/// Mean absolute error of the twin's output-force estimate against the load cell over the
/// whole recording [N]; nullopt when the twin is not built or the recording has no time span.
std::optional<double> twin_force_mae_n(const Recording& rec, const ActuatorParams& act,
                                       const ForceCalibration& cal, const ModelFile& model);

}  // namespace maglead::analysis::actuator
