#include "maglead/analysis/signal.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace maglead::analysis {
namespace {

struct Biquad {
  double b0, b1, b2, a1, a2;  // a0 normalised to 1
};

// A 4th-order Butterworth is two RBJ low-pass sections with Q = 1/(2 cos(π/8)), 1/(2 cos(3π/8)).
std::vector<Biquad> butter4(double cutoff_hz, double fs_hz) {
  if (!(cutoff_hz > 0.0) || !(cutoff_hz < 0.5 * fs_hz))
    throw std::invalid_argument("filter cutoff " + std::to_string(cutoff_hz) +
                                " Hz must lie between 0 and half the sample rate (" +
                                std::to_string(0.5 * fs_hz) + " Hz)");
  std::vector<Biquad> out;
  const double w0 = 2.0 * std::numbers::pi * cutoff_hz / fs_hz;
  for (double q : {1.0 / (2.0 * std::cos(std::numbers::pi / 8)),
                   1.0 / (2.0 * std::cos(3.0 * std::numbers::pi / 8))}) {
    const double alpha = std::sin(w0) / (2.0 * q), c = std::cos(w0), a0 = 1.0 + alpha;
    out.push_back({(1.0 - c) / 2.0 / a0, (1.0 - c) / a0, (1.0 - c) / 2.0 / a0, -2.0 * c / a0,
                   (1.0 - alpha) / a0});
  }
  return out;
}

// Transposed direct form II, started in the steady state of the ramp through the first two
// inputs (a level is a ramp without slope): a section passes a ramp delayed by its DC group delay
// tau, so a signal that starts moving leaves no start-up transient.
// Over [first, last) in the iterators' direction: a reverse iterator runs the backward pass in
// place, with the same arithmetic as reversing, running forward and reversing back.
template <class It>
void run(const Biquad& f, It first, It last) {
  if (last - first < 2) return;
  const double tau =
      (f.b1 + 2.0 * f.b2) / (f.b0 + f.b1 + f.b2) - (f.a1 + 2.0 * f.a2) / (1.0 + f.a1 + f.a2);
  const double u0 = first[0], d = first[1] - first[0], y0 = u0 - d * tau;
  double z1 = y0 - f.b0 * u0;
  double z2 = (y0 + d) - f.b0 * (u0 + d) - f.b1 * u0 + f.a1 * y0;
  for (; first != last; ++first) {
    const double in = *first;
    const double y = f.b0 * in + z1;
    z1 = f.b1 * in - f.a1 * y + z2;
    z2 = f.b2 * in - f.a2 * y;
    *first = y;
  }
}

// The padding before x[0], `pad` samples, continuing x's local quadratic: the odd reflection of
// what is left after it. A plain odd reflection keeps the level and slope but flips the
// curvature, so a recording that starts accelerating read zero acceleration at its first sample
// (a 95 kg carriage at 0.4 m/s²: 37 N of force no effect explains).
std::vector<double> lead_in(const std::vector<double>& x, std::size_t pad) {
  // Least squares x[k] − x[0] ≈ c0 + c1 u + c2 u², u = k / pad (scaled and levelled so the
  // normal equations keep the curvature a level of metres would round away).
  const double scale = static_cast<double>(pad);
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i <= pad; ++i) {
    const double u = static_cast<double>(i) / scale;
    const Eigen::Vector3d row(1.0, u, u * u);
    a += row * row.transpose();
    r += row * (x[i] - x[0]);
  }
  const Eigen::Vector3d c = a.ldlt().solve(r);
  const auto q = [&](double k) {
    const double u = k / scale;
    return c[0] + c[1] * u + c[2] * u * u;
  };
  std::vector<double> out(pad);
  for (std::size_t i = 0; i < pad; ++i) {  // out[i] stands at k = −(pad − i)
    const std::size_t k = pad - i;
    const double kk = static_cast<double>(k);
    out[i] = x[0] + q(-kk) + 2.0 * (0.0 - q(0)) - ((x[k] - x[0]) - q(kk));
  }
  return out;
}

}  // namespace

std::vector<double> filtfilt_butter4(const std::vector<double>& x, double cutoff_hz,
                                     double sample_rate_hz) {
  const auto sections = butter4(cutoff_hz, sample_rate_hz);
  const std::size_t n = x.size();
  if (n < 3) return x;
  // Padding of about three time constants of the slowest section, continuing the curvature.
  const std::size_t pad = std::min<std::size_t>(
      n - 1, static_cast<std::size_t>(std::ceil(3.0 * sample_rate_hz / cutoff_hz)) + 12);
  // y is built by appending (no zero-fill of n samples only to overwrite them); only the first
  // pad + 1 samples from the end are reversed for the tail, which is all lead_in reads.
  std::vector<double> y;
  y.reserve(n + 2 * pad);
  const auto head = lead_in(x, pad);
  y.insert(y.end(), head.begin(), head.end());
  y.insert(y.end(), x.begin(), x.end());
  const std::vector<double> reversed(x.rbegin(), x.rbegin() + static_cast<std::ptrdiff_t>(pad + 1));
  const auto tail = lead_in(reversed, pad);
  y.insert(y.end(), tail.rbegin(), tail.rend());
  for (const auto& s : sections) run(s, y.begin(), y.end());
  for (const auto& s : sections) run(s, y.rbegin(), y.rend());
  // Drop the padding in place rather than copy the n samples into a new vector.
  y.erase(y.begin(), y.begin() + static_cast<std::ptrdiff_t>(pad));
  y.resize(n);
  return y;
}

std::vector<double> central_diff(const std::vector<double>& x, double dt_s) {
  const std::size_t n = x.size();
  if (n < 2) return std::vector<double>(n, 0.0);
  std::vector<double> d;  // appended in order: no zero-fill to overwrite
  d.reserve(n);
  d.push_back((x[1] - x[0]) / dt_s);
  for (std::size_t i = 1; i + 1 < n; ++i) d.push_back((x[i + 1] - x[i - 1]) / (2.0 * dt_s));
  d.push_back((x[n - 1] - x[n - 2]) / dt_s);
  return d;
}

std::vector<double> central_diff2(const std::vector<double>& x, double dt_s) {
  const std::size_t n = x.size();
  if (n < 3) return std::vector<double>(n, 0.0);
  std::vector<double> d;  // appended in order: no zero-fill to overwrite
  d.reserve(n);
  d.push_back(0.0);  // d[1], set below
  for (std::size_t i = 1; i + 1 < n; ++i)
    d.push_back((x[i + 1] - 2.0 * x[i] + x[i - 1]) / (dt_s * dt_s));
  d[0] = d[1];
  d.push_back(d[n - 2]);
  return d;
}

double decimation_cutoff_hz(int factor, double sample_rate_hz) {
  return 0.8 * 0.5 * sample_rate_hz / factor;
}

std::vector<double> decimate(const std::vector<double>& x, int factor, double sample_rate_hz) {
  if (factor <= 1) return x;
  const auto f = filtfilt_butter4(x, decimation_cutoff_hz(factor, sample_rate_hz), sample_rate_hz);
  std::vector<double> out;
  out.reserve(x.size() / static_cast<std::size_t>(factor) + 1);
  for (std::size_t i = 0; i < f.size(); i += static_cast<std::size_t>(factor)) out.push_back(f[i]);
  return out;
}

}  // namespace maglead::analysis
