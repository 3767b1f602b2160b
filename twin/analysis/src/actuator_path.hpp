#pragma once
// The actuator's path of analyze_recording, which alone calls it (the public header offers
// analyze_recording only).
#include "maglead/analysis/analysis.hpp"

namespace maglead::analysis {

/// The actuator path of analyze_recording (stages over the effect library).
AnalysisResult analyze_actuator(const Recording& rec, const ModelFile& baseline,
                                const ForceCalibration& cal, const ActuatorParams& act,
                                const AnalysisOptions& options);

}  // namespace maglead::analysis
