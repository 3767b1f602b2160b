// The analysis's judgement of a load cell (its unit and sign, against the calibrated coupling)
// for the commands that score against one without analysing: estimate and twin-check.
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "actuator_analysis.hpp"
#include "maglead/analysis/anomaly.hpp"
#include "maglead/analysis/rules.hpp"

namespace maglead::analysis {
namespace {

// Empty cells (NaN) take the last value before them (the first row's from the first value
// after): the judgement fits a balance over thousands of rows, which a few held values do not
// move, and a filter over a NaN would spread it over the whole column. False: no value at all.
bool hold_over_blanks(std::vector<double>& x) {
  std::size_t first = 0;
  while (first < x.size() && !std::isfinite(x[first])) ++first;
  if (first == x.size()) return false;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!std::isfinite(x[i])) x[i] = i < first ? x[first] : x[i - 1];
  return true;
}

}  // namespace

std::optional<LoadCellUnitError> load_cell_unusable(const Recording& rec,
                                                    const ForceCalibration& cal,
                                                    const ActuatorParams& act) {
  if (!rec.has("load_force_n") || rec.column("t_s").size() < rules::kMinRows) return std::nullopt;
  Recording filled = rec;
  for (auto& column : filled.columns)
    if (!hold_over_blanks(column)) return std::nullopt;
  try {
    actuator::judge_load_cell(filled, cal, act);
  } catch (const LoadCellUnitError& e) {
    return e;
  }
  return std::nullopt;
}

}  // namespace maglead::analysis
