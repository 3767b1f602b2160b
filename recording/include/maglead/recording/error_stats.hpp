#pragma once
// Error statistics of a recorded signal against its reference (e.g. a force estimate against the
// load cell): the one place the project computes mean absolute, RMS, maximum and percentiles.
#include <cstddef>
#include <limits>
#include <span>
#include <vector>

namespace maglead {

/// Statistics of an error signal, in the signal's unit. Non-finite samples (gaps, columns a
/// recording lacks at the start) are left out; NaN where no sample is left.
struct ErrorStats {
  std::size_t samples = 0;
  double mean_abs = std::numeric_limits<double>::quiet_NaN();
  double rms = std::numeric_limits<double>::quiet_NaN();
  double max_abs = std::numeric_limits<double>::quiet_NaN();
};

/// Of the errors themselves.
ErrorStats error_stats(std::span<const double> error);
/// Of estimate − reference, sample by sample (the shorter length).
ErrorStats error_stats(std::span<const double> estimate, std::span<const double> reference);

/// The q-quantile (q in 0..1) of the finite values, by the nearest rank at or below
/// q·(n − 1); NaN when there is none.
double percentile(std::vector<double> values, double q);

}  // namespace maglead
