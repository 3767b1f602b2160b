// The analysis's judgement of a load cell (its unit and sign, against the calibrated coupling)
// for the commands that score against one without analysing: estimate and twin-check.
#include <exception>
#include <optional>
#include <string>

#include "actuator_analysis.hpp"
#include "maglead/analysis/anomaly.hpp"

namespace maglead::analysis {

std::optional<std::string> load_cell_unusable(const Recording& rec, const ForceCalibration& cal,
                                              const ActuatorParams& act) {
  try {
    // The analysis's first stage judges the load cell (check_load_cell_scale) before any model
    // term: the baseline's values do not enter it.
    (void)actuator::prepare_actuator(rec, actuator::Baseline{}, cal, act, actuator::StageOptions{});
  } catch (const LoadCellUnitError& e) {
    return e.what();
  } catch (const std::exception&) {  // NOLINT(bugprone-empty-catch): too little to judge it by
  }
  return std::nullopt;
}

}  // namespace maglead::analysis
