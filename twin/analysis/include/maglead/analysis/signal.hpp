#pragma once
// Zero-phase filtering, differentiation and decimation as the EMPS benchmark prescribes
// (Butterworth low-pass run forward and backward, central differences, parallel decimation).
#include <cstddef>
#include <vector>

namespace maglead::analysis {

/// 4th-order Butterworth low-pass applied forward and backward (zero phase, squared magnitude),
/// padded at each end by the continuation of its local quadratic (so a signal that starts or
/// ends accelerating keeps its curvature there) and each pass started on the ramp it meets. Throws
/// std::invalid_argument if cutoff_hz is not inside (0, sample_rate_hz / 2).
std::vector<double> filtfilt_butter4(const std::vector<double>& x, double cutoff_hz,
                                     double sample_rate_hz);

/// First and second central differences (one-sided at the ends), uniform step dt_s.
std::vector<double> central_diff(const std::vector<double>& x, double dt_s);
std::vector<double> central_diff2(const std::vector<double>& x, double dt_s);

/// Low-pass below the new Nyquist frequency (zero phase), then keep every `factor`-th sample.
std::vector<double> decimate(const std::vector<double>& x, int factor, double sample_rate_hz);
/// The cutoff decimate filters at: 80 % of the new Nyquist frequency, as MATLAB's decimate.
double decimation_cutoff_hz(int factor, double sample_rate_hz);

}  // namespace maglead::analysis
