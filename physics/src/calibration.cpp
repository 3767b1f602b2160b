#include "maglead/physics/calibration.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace maglead {

CalibrationResult calibrate_static_force(const std::vector<double>& phase_rad,
                                         const std::vector<double>& nut_vel_m_s,
                                         const std::vector<double>& load_force_n,
                                         const CalibrationOptions& options) {
  if (phase_rad.size() != nut_vel_m_s.size() || phase_rad.size() != load_force_n.size())
    throw std::invalid_argument("calibration: columns differ in length");
  std::vector<std::size_t> used;
  double lo = 0.0, hi = 0.0;
  for (std::size_t i = 0; i < phase_rad.size(); ++i) {
    if (std::abs(nut_vel_m_s[i]) < options.min_speed_m_s) continue;
    if (!std::isfinite(phase_rad[i]) || !std::isfinite(load_force_n[i])) continue;
    used.push_back(i);
    lo = std::min(lo, phase_rad[i]);
    hi = std::max(hi, phase_rad[i]);
  }
  const int max_order = *std::max_element(options.orders.begin(), options.orders.end());
  if (used.size() < 10 * static_cast<std::size_t>(max_order + 2))
    throw std::invalid_argument("calibration: only " + std::to_string(used.size()) +
                                " moving samples; move the nut through the stable range");
  if (hi - lo < 1.0)
    throw std::invalid_argument("calibration: phase covers only " + std::to_string(hi - lo) +
                                " rad; sweep at least ±0.5 rad around rest");

  CalibrationResult result;
  result.samples_used = used.size();
  const Eigen::Index n = static_cast<Eigen::Index>(used.size());
  Eigen::VectorXd y(n);
  for (Eigen::Index r = 0; r < n; ++r) y(r) = load_force_n[used[static_cast<std::size_t>(r)]];

  std::vector<double> friction_by_order;
  for (int order : options.orders) {
    // Columns: φ^0 … φ^order, then sign(ṗ) for the friction the sweep drags along.
    Eigen::MatrixXd a(n, order + 2);
    for (Eigen::Index r = 0; r < n; ++r) {
      const std::size_t i = used[static_cast<std::size_t>(r)];
      double pk = 1.0;
      for (int k = 0; k <= order; ++k, pk *= phase_rad[i]) a(r, k) = pk;
      a(r, order + 1) = nut_vel_m_s[i] > 0.0 ? 1.0 : -1.0;
    }
    const Eigen::VectorXd x = a.colPivHouseholderQr().solve(y);
    const double rmse = std::sqrt((a * x - y).squaredNorm() / static_cast<double>(n));
    OrderFit fit{order, rmse, {}};
    fit.model.coeffs_ascending.assign(x.data(), x.data() + order + 1);
    result.table.push_back(fit);
    friction_by_order.push_back(x(order + 1));
  }
  std::size_t chosen = result.table.size() - 1;
  for (std::size_t k = 0; k < result.table.size(); ++k) {
    double best_higher = result.table[k].rmse_n;
    for (std::size_t j = k; j < result.table.size(); ++j)
      best_higher = std::min(best_higher, result.table[j].rmse_n);
    if (result.table[k].rmse_n - best_higher <=
        options.order_gain_fraction * result.table[k].rmse_n) {
      chosen = k;
      break;
    }
  }
  result.chosen_order = result.table[chosen].order;
  result.coulomb_n = friction_by_order[chosen];
  result.calibration.polynomial = result.table[chosen].model;

  std::vector<double> ph, f;
  for (std::size_t i : used) {
    ph.push_back(phase_rad[i]);
    f.push_back(load_force_n[i] - (nut_vel_m_s[i] > 0.0 ? 1.0 : -1.0) * result.coulomb_n);
  }
  result.calibration.periodic = PeriodicForceModel::fit(ph, f, options.periodic_harmonics);
  result.calibration.derive_limits();
  return result;
}

}  // namespace maglead
