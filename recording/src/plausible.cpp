// Columns whose values cannot be in their unit: a recording in millimetres or milliseconds reads
// as numbers, and the analysis would then find nonsense (a step-out count of 10940) instead of
// saying the file is wrong. Every bound here is physical and generous, or comes from the header
// or the caller's configuration; none is fitted to an actuator.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "maglead/recording/recording.hpp"
#include "time_steps.hpp"

namespace maglead {

namespace {

using time_steps::num;

bool ends_with(const std::string& s, const std::string& end) {
  return s.size() >= end.size() && s.compare(s.size() - end.size(), end.size(), end) == 0;
}

struct Unit {
  double per_si;  // values in this unit are per_si times the SI value
  const char* name;
};

/// The first of `units` that brings `value` within `bound`; nullptr when none does.
const char* likely_unit(double value, double bound, std::initializer_list<Unit> units) {
  for (const auto& u : units)
    if (value / u.per_si <= bound) return u.name;
  return nullptr;
}

/// A position column (`*pos*_m`): every value within ±bound. The error cites the first row
/// beyond it (where a reader looks first); the likely unit comes from the largest value.
void check_position(const Recording& rec, std::size_t c, const PlausibleRanges& r) {
  const auto& v = rec.columns[c];
  std::size_t first = v.size(), worst = v.size();
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i]) || std::abs(v[i]) <= r.position_bound_m) continue;
    if (first == v.size()) first = i;
    if (worst == v.size() || std::abs(v[i]) > std::abs(v[worst])) worst = i;
  }
  if (first == v.size()) return;
  const char* unit = likely_unit(
      std::abs(v[worst]), r.position_bound_m,
      {{1e3, "millimetres (values 1000x metres)"}, {1e6, "micrometres (values 10^6 x metres)"}});
  throw RecordingError(rec.path + ": column " + rec.names[c] +
                       " cannot be in metres: " + num(v[first]) + " at data row " +
                       std::to_string(first + 1) + " is beyond +-" + num(r.position_bound_m) +
                       " m (" + r.position_bound_source +
                       "); likely unit: " + (unit ? unit : "not a length in metres"));
}

/// An angle column (`*_rad`): no step between rows above 100 turns.
void check_angle(const Recording& rec, std::size_t c) {
  constexpr double kTurn_rad = 2.0 * std::numbers::pi;
  constexpr double kMaxStep_rad = 100.0 * kTurn_rad;
  const auto& v = rec.columns[c];
  std::size_t at = 0, prev = v.size();
  double worst = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) continue;
    if (prev < v.size() && std::abs(v[i] - v[prev]) > worst) {
      worst = std::abs(v[i] - v[prev]);
      at = i;
    }
    prev = i;
  }
  if (worst <= kMaxStep_rad) return;
  std::size_t before = at - 1;
  while (!std::isfinite(v[before])) --before;
  // A real step between samples is well under a turn; the unit that makes it so is the guess.
  const char* unit = likely_unit(worst, kTurn_rad,
                                 {{180.0 / std::numbers::pi, "degrees"},
                                  {1e3, "milliradians"},
                                  {1e6, "microradians (the controller's raw unit)"}});
  throw RecordingError(rec.path + ": column " + rec.names[c] +
                       " cannot be in radians: it jumps by " + num(worst) + " rad (" +
                       num(worst / kTurn_rad) + " turns) from " + num(v[before]) + " to " +
                       num(v[at]) + " at data row " + std::to_string(at + 1) +
                       ", and no machine turns 100 turns in one sample; likely unit: " +
                       (unit ? unit : "not an angle in radians"));
}

/// `t_s` against the header's sample_rate_hz: a median step 100x the sample period is not seconds.
void check_time(const Recording& rec, std::size_t c) {
  const auto rate_hz = time_steps::header_rate_hz(rec);
  if (!rate_hz) return;  // nothing to compare with: any step may be right
  const auto& t = rec.columns[c];
  if (t.size() < 3) return;
  const double median_s = time_steps::median_step_s(t);
  const std::string rate_text = *rec.meta("sample_rate_hz");
  const double period_s = 1.0 / *rate_hz;
  if (median_s <= 100.0 * period_s) return;
  const char* unit = likely_unit(median_s, 100.0 * period_s,
                                 {{1e3, "milliseconds (values 1000x seconds)"},
                                  {1e6, "microseconds (values 10^6 x seconds)"}});
  throw RecordingError(rec.path + ": column t_s cannot be in seconds: it advances by " +
                       num(median_s) + " per row (median; values " + num(t.front()) + " .. " +
                       num(t.back()) + ") where the header's sample_rate_hz " + rate_text +
                       " means " + num(period_s) +
                       " s; likely unit: " + (unit ? unit : "not seconds"));
}

}  // namespace

void check_plausible_units(const Recording& rec, const PlausibleRanges& ranges) {
  for (std::size_t c = 0; c < rec.names.size() && c < rec.columns.size(); ++c) {
    const std::string& n = rec.names[c];
    if (n == "t_s")
      check_time(rec, c);
    else if (ends_with(n, "_rad"))
      check_angle(rec, c);
    else if (ends_with(n, "_m") && n.find("pos") != std::string::npos)
      check_position(rec, c, ranges);
  }
}

}  // namespace maglead
