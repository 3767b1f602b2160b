#include "maglead/physics/force_model.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include "maglead/fileio/atomic_file.hpp"
#include "maglead/physics/toml_config.hpp"

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

namespace {

std::string join(const std::vector<double>& v) {
  std::ostringstream s;
  s << std::setprecision(10) << "[";
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
  s << "]";
  return s.str();
}

}  // namespace

void save_calibration(const std::string& path, const ForceCalibration& cal,
                      const std::string& header_comment) {
  std::ostringstream out;  // then written atomically: a crash never leaves half a calibration
  out << "# maglead force calibration: load-cell force on the nut [N] against phase phi [rad]\n";
  if (!header_comment.empty()) out << "# " << header_comment << "\n";
  out << std::setprecision(10) << "[calibration]\n"
      << "source = \"" << cal.source << "\"\n"
      << "# F_s(phi) = sum c_k phi^k, valid on the stable branch\n"
      << "polynomial_coeffs_ascending = " << join(cal.polynomial.coeffs_ascending) << "\n"
      << "# periodic model: mean + sum a_k cos(k phi) + b_k sin(k phi)\n"
      << "periodic_mean_n = " << cal.periodic.mean_n << "\n"
      << "periodic_cos_n = " << join(cal.periodic.cos_n) << "\n"
      << "periodic_sin_n = " << join(cal.periodic.sin_n) << "\n";
  write_file_atomically(path, out.str());
}

ForceCalibration load_calibration(const std::string& path) {
  const toml::table root = config::parse_file(path);
  const toml::table* t = config::section(path, root, "calibration", true);
  ForceCalibration cal;
  cal.source = (*t)["source"].value_or(std::string(path));
  cal.polynomial.coeffs_ascending =
      config::read_numbers(path, *t, "[calibration]", "polynomial_coeffs_ascending");
  if (cal.polynomial.coeffs_ascending.size() < 2)
    config::fail(path, t->get("polynomial_coeffs_ascending"),
                 "[calibration] polynomial needs order 1 or more");
  if (!config::read_number(path, *t, "[calibration]", "periodic_mean_n", cal.periodic.mean_n))
    config::fail(path, t, "[calibration] periodic_mean_n missing");
  cal.periodic.cos_n = config::read_numbers(path, *t, "[calibration]", "periodic_cos_n");
  cal.periodic.sin_n = config::read_numbers(path, *t, "[calibration]", "periodic_sin_n");
  if (cal.periodic.cos_n.size() != cal.periodic.sin_n.size())
    config::fail(path, t->get("periodic_sin_n"),
                 "[calibration] periodic_cos_n and periodic_sin_n differ in length");
  cal.derive_limits();
  if (!(cal.peak_push_n > 0.0) || !(cal.peak_pull_n < 0.0))
    config::fail(
        path, t->get("polynomial_coeffs_ascending"),
        "[calibration] curve has no stable branch around phi = 0 (force must fall with phase)");
  // Finite coefficients can still overflow at the branch's edge (a coefficient of 1e308).
  if (!std::isfinite(cal.peak_push_n) || !std::isfinite(cal.peak_pull_n))
    config::fail(path, t->get("polynomial_coeffs_ascending"),
                 "[calibration] curve's peak force on its stable branch is not a finite number");
  return cal;
}

}  // namespace maglead
