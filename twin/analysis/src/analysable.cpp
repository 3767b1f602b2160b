// What the analysis needs of a recording's rows before any fit, as public checks: `inspect` runs
// them to say what `analyze` would refuse, and `analyze` runs them first to say it plainly.
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/reading.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "statistics.hpp"

namespace maglead::analysis {

void check_axis_rows(const Recording& rec) {
  const effects::AxisKind* stated = effects::axis_kind(rec.meta("axis").value_or(""));
  const effects::AxisKind& kind = stated ? *stated : effects::linear_axis();
  const std::vector<std::string> columns{"t_s", std::string(kind.position),
                                         std::string(kind.drive)};
  for (const auto& c : columns)
    if (!rec.has(c)) return;  // the kind's check refuses it (check_axis_columns), naming all
  stats::require_analysable(rec, columns);
  // The position filter's corner follows a slow logger (filter_max_of_rate), but below a rate
  // the motion's acceleration is not resolved; far below it t_s is most often in milliseconds.
  const double rate_hz = maglead::sample_rate_hz(rec);
  if (rate_hz >= rules::kAxisMinRateHz) return;
  char rate[160];
  std::snprintf(rate, sizeof rate,
                ": the sample rate is %.6g Hz (%s), and the analysis of a %s axis needs %g Hz or "
                "more",
                rate_hz,
                rec.meta("sample_rate_hz") ? "the header's sample_rate_hz" : "t_s's median step",
                std::string(kind.name).c_str(), rules::kAxisMinRateHz);
  throw std::invalid_argument(rec.path + rate +
                              " to resolve its acceleration: if t_s is in milliseconds, divide "
                              "it by 1000; else record faster");
}

void check_actuator_rows(const Recording& rec) {
  stats::require_analysable(rec, {"t_s", "nut_pos_m", "load_force_n"});
}

}  // namespace maglead::analysis
