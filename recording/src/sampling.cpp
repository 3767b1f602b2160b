// Even sampling: every reader of a recording (analysis filters, derivatives, the twin's replay)
// takes its rows as one sample period apart. Rows a recorder missed are filled in; a header rate
// the rows contradict, or a recording with whole stretches lost, is refused.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "maglead/recording/recording.hpp"
#include "time_steps.hpp"

namespace maglead {
namespace {

// A step this many periods long has a row missing; a recorder's jitter stays well below it.
constexpr double kGapSteps = 1.5;
// A gap is filled up to this many rows or this long, whichever is more: a recorder that fell a
// few polls behind, or whose process a loaded machine stalled for a time slice. A longer gap is
// a lost stretch that interpolation would invent.
constexpr long kMaxFilledRows = 10;
constexpr double kMaxFilledGap_s = 0.05;
// More rows missing than this share of what the rate implies, and more than one filled gap
// holds, the rate or the file is wrong (a wrong rate leaves most rows missing; a few polls
// missed in a short recording are a recorder's hiccup).
constexpr double kMaxMissingShare = 0.1;
// More rows than the rate implies by this share and these rows: the header's rate is too low
// (a recorder's clock is far better than 1 %; repeated rows are refused before). The rows: a
// recorder polling on a schedule may write its first and last row up to a period or so off the
// grid, which shortens the span of a short recording by as much.
constexpr double kMaxExtraShare = 0.01;
constexpr double kMaxExtraRows = 3.0;

using time_steps::median_step_s;
using time_steps::num;

/// The period the rows should step by: the header's rate, else the median step.
double period_of(const Recording& rec, const std::vector<double>& t) {
  if (const auto f = time_steps::header_rate_hz(rec)) return 1.0 / *f;
  return median_step_s(t);
}

std::string rate_advice(const std::vector<double>& t) {
  return "t_s steps by " + num(median_step_s(t) * 1e3) + " ms (median), i.e. " +
         num(1.0 / median_step_s(t)) + " Hz";
}

/// Refuses a time stamp equal to the one before: every reader takes the rows as a period apart,
/// so one repeated row shifts all later ones by a period (and a stamp written twice has a gap
/// after it that filling would turn into an extra row). Names the rows, up to kListedRepeats.
void refuse_repeated_times(const Recording& rec, const std::vector<double>& t) {
  constexpr std::size_t kListedRepeats = 5;
  std::size_t repeats = 0, same_values = 0;
  std::string rows;
  for (std::size_t i = 1; i < t.size(); ++i) {
    if (t[i] != t[i - 1]) continue;
    bool same = true;
    for (const auto& c : rec.columns)
      same = same && (c[i] == c[i - 1] || (std::isnan(c[i]) && std::isnan(c[i - 1])));
    same_values += same;
    if (++repeats <= kListedRepeats)
      rows += (rows.empty() ? "" : ", ") + std::to_string(i + 1) + " (t = " + num(t[i]) + " s)";
  }
  if (repeats == 0) return;
  std::string what = rec.path + ": " + std::to_string(repeats) +
                     (repeats == 1 ? " row repeats" : " rows repeat") +
                     " the time of the row before, at data row" + (repeats == 1 ? " " : "s ") +
                     rows + (repeats > kListedRepeats ? ", …" : "") +
                     "; the readers take each row as one sample period after the one before: ";
  // Many stamps repeated with their values differing, the rows still advancing at a rate: t_s
  // was written with fewer decimals than its rate needs (%.3f at 2 kHz).
  constexpr std::size_t kCoarseShare = 10;  // one row in this many repeats its stamp
  const double mean_step_s = (t.back() - t.front()) / static_cast<double>(t.size() - 1);
  if (same_values < repeats && repeats * kCoarseShare >= t.size() && mean_step_s > 0)
    what += "t_s has too few decimals for its rate (a step of " + num(mean_step_s) +
            " s on average): write it with more (six decimals, say)";
  else if (same_values == repeats)
    what += "the repeated rows are copies, delete them";
  else if (same_values == 0)
    what +=
        "their values differ, so the time stamps are wrong: fix t_s (a recorder's clock "
        "that stalled) or delete the rows that are not samples";
  else
    what += std::to_string(same_values) +
            " of them are copies of the row before (delete them), the others differ (fix their "
            "t_s)";
  throw RecordingError(what);
}

/// Refuses rows the header's rate contradicts: more than it allows, too many missing, or a gap
/// too long to fill.
void check_against_rate(const Recording& rec, const std::vector<double>& t, double period_s) {
  const double span_s = t.back() - t.front();
  const double expected = span_s / period_s + 1.0;
  const auto rows = static_cast<double>(t.size());
  const std::string rate = num(1.0 / period_s) + " Hz";
  if (rows > expected * (1.0 + kMaxExtraShare) + kMaxExtraRows)
    throw RecordingError(rec.path + ": " + num(rows) + " rows over " + num(span_s) +
                         " s of t_s are more than " + rate + " allows (" + num(expected) +
                         "): the header's sample_rate_hz is wrong; " + rate_advice(t) +
                         ": fix the '# sample_rate_hz:' line or delete it");
  const long max_run = std::max(kMaxFilledRows, std::lround(kMaxFilledGap_s / period_s));
  long missing = 0;
  for (std::size_t i = 1; i < t.size(); ++i) {
    const long m = rows_missing_between(t[i] - t[i - 1], period_s);
    if (m > max_run)
      throw RecordingError(rec.path + ": t_s jumps from " + num(t[i - 1]) + " s to " + num(t[i]) +
                           " s at data row " + std::to_string(i + 1) + ": " + std::to_string(m) +
                           " rows missing at " + rate + ", more than the " +
                           std::to_string(max_run) +
                           " that are filled in; analyse the rows before and after the gap as "
                           "two recordings");
    missing += m;
  }
  if (missing > kMaxFilledRows && static_cast<double>(missing) > kMaxMissingShare * expected)
    throw RecordingError(
        rec.path + ": " + std::to_string(missing) + " of the " + num(expected) + " rows " + rate +
        " implies are missing; either the header's "
        "sample_rate_hz is wrong (" +
        rate_advice(t) + ") or the recorder fell behind (record at a lower --rate)");
}

/// Column c with `missing` rows filled in each gap, linearly between its neighbours; a coded
/// column (whole numbers both sides: a status word, a mode) keeps the value before.
std::vector<double> filled(const std::vector<double>& v, const std::vector<double>& t,
                           double period_s, std::size_t rows, bool is_time) {
  std::vector<double> out;
  out.reserve(rows);
  out.push_back(v.front());
  for (std::size_t i = 1; i < v.size(); ++i) {
    const long m = rows_missing_between(t[i] - t[i - 1], period_s);
    const bool coded = !is_time && v[i - 1] == std::floor(v[i - 1]) && v[i] == std::floor(v[i]);
    for (long k = 1; k <= m; ++k) {
      const double w = static_cast<double>(k) / static_cast<double>(m + 1);
      out.push_back(coded ? v[i - 1] : v[i - 1] + w * (v[i] - v[i - 1]));
    }
    out.push_back(v[i]);
  }
  return out;
}

}  // namespace

void make_evenly_sampled(Recording& rec) {
  if (!rec.has("t_s")) return;
  const std::vector<double>& t = rec.column("t_s");
  if (t.size() < 3) return;  // too short for any reader: each says so
  refuse_repeated_times(rec, t);
  const double period_s = period_of(rec, t);
  check_against_rate(rec, t, period_s);
  long missing = 0, longest = 0;
  double longest_at_s = 0.0;
  std::size_t gaps = 0;
  for (std::size_t i = 1; i < t.size(); ++i) {
    const long m = rows_missing_between(t[i] - t[i - 1], period_s);
    if (m == 0) continue;
    missing += m, ++gaps;
    if (m > longest) longest = m, longest_at_s = t[i - 1];
  }
  if (missing == 0) return;              // the usual case: nothing copied
  const std::vector<double> t_read = t;  // the t_s column itself is replaced below
  const std::size_t rows = t_read.size() + static_cast<std::size_t>(missing);
  for (std::size_t c = 0; c < rec.columns.size(); ++c)
    rec.columns[c] = filled(rec.columns[c], t_read, period_s, rows, rec.names[c] == "t_s");
  std::string warning = rec.path + ": filled " + std::to_string(missing) + " missing rows in " +
                        std::to_string(gaps) + " gaps of t_s (the longest " +
                        std::to_string(longest) + " rows, after t = " + num(longest_at_s) +
                        " s) by linear interpolation, so the rows step by " + num(period_s * 1e3) +
                        " ms as the analysis assumes";
  std::fprintf(stderr, "warning: %s\n", warning.c_str());
  rec.warnings.push_back(std::move(warning));
}

double sample_rate_hz(const Recording& rec) {
  if (const auto f = time_steps::header_rate_hz(rec)) return *f;
  const double step_s = rec.has("t_s") ? median_step_s(rec.column("t_s")) : 0.0;
  if (!(step_s > 0)) throw RecordingError(rec.path + ": t_s does not advance");
  return 1.0 / step_s;
}

long rows_missing_between(double step_s, double period_s) {
  return step_s > kGapSteps * period_s ? std::lround(step_s / period_s) - 1 : 0;
}

}  // namespace maglead
