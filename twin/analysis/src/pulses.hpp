#pragma once
// The one pulse finder of both analysis paths (internal to twin/analysis): isolated force pulses
// no input explains, in a residual, judged against the recording's own floors.
#include <vector>

#include "candidates.hpp"
#include "maglead/analysis/results.hpp"
#include "maglead/analysis/rules.hpp"

namespace maglead::analysis::pulses {

/// What the recording resolves and how its residual was made; each path passes its own.
struct Floors {
  double min_n = 0;  // the smallest force it resolves (a count's force, sensor noise)
  double sigmas = rules::kPulseSigmas;  // a pulse stands this many robust σ out of the residual …
  double max_s = rules::kPulseMax_s;    // … for at most this long …
  double min_spacing_s = rules::kPulseMinSpacing_s;  // … and this far apart on average
  double filter_hz = 0;            // the residual's band limit (zero-phase Butterworth) …
  double fs_hz = 0;                // … run at this rate
  double step_s = 0;               // the residual's sample spacing: a larger gap ends a stretch
  double start_s = 0, span_s = 0;  // the recording's start and span
};

struct Pulse {
  double t_s, duration_s, peak_n;  // start, length and the residual's peak (the missing force)
};

/// The level a pulse must pass: far outside the residual's own spread and above the floor.
double threshold(const std::vector<double>& r, const Floors& f);

/// Pulses in the residual `r` at times `t` (non-decreasing; gaps where samples were left out).
std::vector<Pulse> find(const std::vector<double>& t, const std::vector<double>& r,
                        const Floors& f);

/// `found` less the pulses a library law explains: fitted to the residual `r` away from every
/// pulse (beyond the filter's support on either side, so the law cannot fit a pulse itself)
/// together with the model's columns `model` (indices into `cand.cols`, the final model's),
/// one of the candidates' laws at the states `s` predicts it back under the threshold. Such a
/// pulse is a force the motion's state explains (the coupling weakened where the nut stood at a
/// stick-slip release, say), not one no input explains.
std::vector<Pulse> unexplained(const std::vector<double>& t, const std::vector<double>& r,
                               const std::vector<effects::State>& s, Form form,
                               const Candidates& cand, const std::vector<int>& model,
                               const Floors& f, std::vector<Pulse> found);

/// The pulses in the report, in the one form of both paths (docs/effects.md's
/// `external_disturbance`, which the report page and graders read): an event per pulse (start,
/// length, the missing force `force_n`) and one finding with their count and the largest force.
/// Nothing is added when there are none.
void report(Findings& J, const std::vector<Pulse>& found);

}  // namespace maglead::analysis::pulses
