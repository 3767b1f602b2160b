// What the analysis needs of a recording's rows before any fit, as public checks: `inspect` runs
// them to say what `analyze` would refuse, and `analyze` runs them first to say it plainly.
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "statistics.hpp"

namespace maglead::analysis {

void check_axis_rows(const Recording& rec, double filter_hz) {
  const effects::AxisKind* stated = effects::axis_kind(rec.meta("axis").value_or(""));
  const effects::AxisKind& kind = stated ? *stated : effects::linear_axis();
  const std::vector<std::string> columns{"t_s", std::string(kind.position),
                                         std::string(kind.drive)};
  for (const auto& c : columns)
    if (!rec.has(c)) return;  // the kind's check refuses it (check_axis_columns), naming all
  stats::require_analysable(rec, columns);
  // The axis's position is low-passed zero-phase at this cutoff, which must lie below half the
  // sample rate; a rate far below it is most often t_s written in milliseconds.
  const double cutoff_hz = filter_hz > 0 ? filter_hz : rules::kAxisFilterHz;
  const double rate_hz = maglead::sample_rate_hz(rec);
  if (cutoff_hz < 0.5 * rate_hz) return;
  char b[480];
  std::snprintf(b, sizeof b,
                "%s: the sample rate is %.6g Hz (%s), and the analysis low-passes the %s at "
                "%g Hz, which needs a sample rate above %g Hz: if t_s is in milliseconds, "
                "divide it by 1000; else give a lower --filter-hz (below %.3g)",
                rec.path.c_str(), rate_hz,
                rec.meta("sample_rate_hz") ? "the header's sample_rate_hz" : "t_s's median step",
                std::string(kind.motion).c_str(), cutoff_hz, 2 * cutoff_hz, 0.5 * rate_hz);
  throw std::invalid_argument(b);
}

void check_actuator_rows(const Recording& rec) {
  stats::require_analysable(rec, {"t_s", "nut_pos_m", "load_force_n"});
}

}  // namespace maglead::analysis
