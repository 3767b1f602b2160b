#include "maglead/recording/error_stats.hpp"

#include <algorithm>
#include <cmath>

namespace maglead {

ErrorStats error_stats(std::span<const double> error) {
  double sum_abs = 0, sum_sq = 0, max_abs = 0;
  std::size_t n = 0;
  for (double e : error) {
    if (!std::isfinite(e)) continue;
    sum_abs += std::abs(e);
    sum_sq += e * e;
    max_abs = std::max(max_abs, std::abs(e));
    ++n;
  }
  ErrorStats s;
  if (n == 0) return s;
  s.samples = n;
  s.mean_abs = sum_abs / static_cast<double>(n);
  s.rms = std::sqrt(sum_sq / static_cast<double>(n));
  s.max_abs = max_abs;
  return s;
}

ErrorStats error_stats(std::span<const double> estimate, std::span<const double> reference) {
  const std::size_t n = std::min(estimate.size(), reference.size());
  std::vector<double> e(n);
  for (std::size_t i = 0; i < n; ++i) e[i] = estimate[i] - reference[i];
  return error_stats(e);
}

double percentile(std::vector<double> values, double q) {
  std::erase_if(values, [](double v) { return !std::isfinite(v); });
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const double last = static_cast<double>(values.size() - 1);
  const auto k = static_cast<std::size_t>(std::clamp(q * last, 0.0, last));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

}  // namespace maglead
