#pragma once
// What the plausibility check and the even-sampling rule both read of t_s and the header: one
// parse of sample_rate_hz, one median step, one number format for their messages.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "maglead/recording/recording.hpp"

namespace maglead::time_steps {

inline std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

/// The header's sample_rate_hz, nothing when it has none; throws RecordingError when it is not
/// a positive number (every reader would read the rows at a rate it cannot know).
inline std::optional<double> header_rate_hz(const Recording& rec) {
  const auto h = rec.meta("sample_rate_hz");
  if (!h) return std::nullopt;
  char* end = nullptr;
  const double f = std::strtod(h->c_str(), &end);
  while (end && std::isspace(static_cast<unsigned char>(*end))) ++end;
  if (end == h->c_str() || *end != '\0' || !(f > 0) || !std::isfinite(f))
    throw RecordingError(rec.path + ": header sample_rate_hz '" + *h +
                         "' is not a positive number: fix the '# sample_rate_hz:' line or "
                         "delete it");
  return f;
}

/// The median of single steps of t, from at most about 100 000 of them (enough for a median).
inline double median_step_s(const std::vector<double>& t) {
  if (t.size() < 2) return 0.0;
  const std::size_t stride = std::max<std::size_t>(1, t.size() / 100000);
  std::vector<double> d;
  d.reserve(t.size() / stride + 1);
  for (std::size_t i = 1; i < t.size(); i += stride) d.push_back(t[i] - t[i - 1]);
  auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  return *mid;
}

}  // namespace maglead::time_steps
