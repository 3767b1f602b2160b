#pragma once
// Static-force calibration (paper IV.B): least-squares polynomial fits of load force against
// phase with the order comparison of the paper's Fig. 10, and automatic order choice.
#include <vector>

#include "maglead/physics/force_model.hpp"

namespace maglead {

struct OrderFit {
  int order;
  double rmse_n;
  PolynomialForceModel model;
};

struct CalibrationOptions {
  std::vector<int> orders{1, 3, 5, 7, 9};
  // An order is good enough once no higher order lowers its RMSE by more than this fraction.
  // The paper picks 5 because 5, 7 and 9 hardly differ while 3 → 5 still gains; a relative
  // rule says the same whatever the noise level of the bench.
  double order_gain_fraction = 0.03;
  int periodic_harmonics = 3;
  // Samples slower than this are dropped from the fit: their friction force is unknown
  // (anything within ±F_c while the nut sticks).
  double min_speed_m_s = 2e-4;
};

struct CalibrationResult {
  std::vector<OrderFit> table;
  int chosen_order = 0;
  double coulomb_n = 0.0;  // friction fitted jointly (the hysteresis of the sweep)
  std::size_t samples_used = 0;
  ForceCalibration calibration;
};

/// Fits F_load = F̂_s(φ) + F_c·sign(ṗ) for each order. Throws std::invalid_argument if there are
/// too few usable samples or they cover too little of the stable branch.
CalibrationResult calibrate_static_force(const std::vector<double>& phase_rad,
                                         const std::vector<double>& nut_vel_m_s,
                                         const std::vector<double>& load_force_n,
                                         const CalibrationOptions& options = {});

}  // namespace maglead
