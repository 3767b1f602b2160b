#include "maglead/physics/force_model.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace maglead {

double PolynomialForceModel::load_force_n(double phase_rad) const {
  double y = 0.0;
  for (std::size_t k = coeffs_ascending.size(); k-- > 0;) y = y * phase_rad + coeffs_ascending[k];
  return y;
}

double PolynomialForceModel::slope_n_per_rad(double phase_rad) const {
  double y = 0.0;
  for (std::size_t k = coeffs_ascending.size(); k-- > 1;)
    y = y * phase_rad + static_cast<double>(k) * coeffs_ascending[k];
  return y;
}

double PeriodicForceModel::load_force_n(double phase_rad) const {
  double y = mean_n;
  for (std::size_t k = 0; k < cos_n.size(); ++k) {
    const double kp = static_cast<double>(k + 1) * phase_rad;
    y += cos_n[k] * std::cos(kp) + sin_n[k] * std::sin(kp);
  }
  return y;
}

double PeriodicForceModel::slope_n_per_rad(double phase_rad) const {
  double y = 0.0;
  for (std::size_t k = 0; k < cos_n.size(); ++k) {
    const double kk = static_cast<double>(k + 1);
    y += kk * (-cos_n[k] * std::sin(kk * phase_rad) + sin_n[k] * std::cos(kk * phase_rad));
  }
  return y;
}

double PeriodicForceModel::peak_n() const {
  // Every half degree: the model has a few harmonics, so a finer grid moves the peak by far
  // less than the effects' bounds that use it could notice.
  constexpr int kSamplesPerLead = 720;
  double peak = 0.0;
  for (int i = 0; i < kSamplesPerLead; ++i)
    peak = std::max(peak, std::abs(load_force_n(2.0 * std::numbers::pi * i / kSamplesPerLead -
                                                std::numbers::pi)));
  return peak;
}

PeriodicForceModel PeriodicForceModel::fit(const std::vector<double>& phase_rad,
                                           const std::vector<double>& load_force_n, int harmonics,
                                           double ridge) {
  if (phase_rad.size() != load_force_n.size() || phase_rad.size() < 2u * harmonics + 1)
    throw std::invalid_argument("periodic fit: too few samples");
  const Eigen::Index n = static_cast<Eigen::Index>(phase_rad.size());
  const Eigen::Index cols = 1 + 2 * static_cast<Eigen::Index>(harmonics);
  Eigen::MatrixXd a(n, cols);
  Eigen::VectorXd y(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double p = phase_rad[static_cast<std::size_t>(i)];
    a(i, 0) = 1.0;
    for (Eigen::Index k = 1; k <= harmonics; ++k) {
      a(i, 2 * k - 1) = std::cos(static_cast<double>(k) * p);
      a(i, 2 * k) = std::sin(static_cast<double>(k) * p);
    }
    y(i) = load_force_n[static_cast<std::size_t>(i)];
  }
  // Ridge grows with harmonic number: higher harmonics are what half a period cannot pin down.
  Eigen::MatrixXd ata = a.transpose() * a;
  const double scale = ata.trace() / static_cast<double>(cols);
  for (Eigen::Index k = 1; k <= harmonics; ++k) {
    ata(2 * k - 1, 2 * k - 1) += ridge * scale * static_cast<double>(k * k);
    ata(2 * k, 2 * k) += ridge * scale * static_cast<double>(k * k);
  }
  const Eigen::VectorXd x = ata.ldlt().solve(a.transpose() * y);
  PeriodicForceModel m;
  m.mean_n = x(0);
  for (Eigen::Index k = 1; k <= harmonics; ++k) {
    m.cos_n.push_back(x(2 * k - 1));
    m.sin_n.push_back(x(2 * k));
  }
  return m;
}

void ForceCalibration::derive_limits() {
  // Walk out from φ = 0 until F̂_s stops falling: that is the edge of the stable branch.
  constexpr double kStep = 1e-3;
  constexpr double kMax = 0.6 * std::numbers::pi;
  auto edge = [&](double dir) {
    double p = 0.0;
    while (std::abs(p) < kMax && polynomial.slope_n_per_rad(p + dir * kStep) < 0.0)
      p += dir * kStep;
    return std::abs(p) >= kMax ? dir * std::numbers::pi / 2 : p;
  };
  stable_max_rad = std::min(edge(+1.0), std::numbers::pi / 2);
  stable_min_rad = std::max(edge(-1.0), -std::numbers::pi / 2);
  peak_push_n = -polynomial.load_force_n(stable_max_rad);
  peak_pull_n = -polynomial.load_force_n(stable_min_rad);
}

ForceCalibration paper_calibration() {
  ForceCalibration cal;
  cal.polynomial.coeffs_ascending = {-4.28, -47.6, 2.59, 8.51, -0.209, -0.378};  // eq. 7
  std::vector<double> ph, f;
  for (double p = -std::numbers::pi / 2; p <= std::numbers::pi / 2; p += 0.01) {
    ph.push_back(p);
    f.push_back(cal.polynomial.load_force_n(p));
  }
  cal.periodic = PeriodicForceModel::fit(ph, f, 3);
  cal.source = "paper eq. 7";
  cal.derive_limits();
  return cal;
}

ForceCalibration scaled(ForceCalibration cal, double gain) {
  for (double& c : cal.polynomial.coeffs_ascending) c *= gain;
  cal.periodic.mean_n *= gain;
  for (double& c : cal.periodic.cos_n) c *= gain;
  for (double& c : cal.periodic.sin_n) c *= gain;
  cal.derive_limits();
  return cal;
}

}  // namespace maglead
