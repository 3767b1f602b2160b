#pragma once
// Coupling force models in the load-cell convention of docs/conventions.md: F̂_s(φ) is the force
// on the nut from the load that holds it still at phase φ, so the magnetic force is F_m ≈ −F̂_s.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace maglead {

/// F̂_s(φ) = Σ c_k φ^k, valid on the calibrated range only (not periodic).
struct PolynomialForceModel {
  std::vector<double> coeffs_ascending;  // c_0, c_1, … [N / rad^k]
  double load_force_n(double phase_rad) const;
  double slope_n_per_rad(double phase_rad) const;
  int order() const { return static_cast<int>(coeffs_ascending.size()) - 1; }
};

/// F̂_s(φ) = a_0 + Σ_k a_k cos kφ + b_k sin kφ: periodic in φ with one lead, so it also
/// describes the coupling past the stable branch (step-out).
struct PeriodicForceModel {
  double mean_n = 0.0;
  std::vector<double> cos_n;  // a_1 … a_K
  std::vector<double> sin_n;  // b_1 … b_K
  double load_force_n(double phase_rad) const;
  double slope_n_per_rad(double phase_rad) const;
  /// The largest |F̂_s| over a lead: the coupling's peak force in either direction.
  double peak_n() const;
  /// Least-squares fit to samples; `ridge` damps harmonics the samples cannot determine
  /// (calibration covers only half a period).
  static PeriodicForceModel fit(const std::vector<double>& phase_rad,
                                const std::vector<double>& load_force_n, int harmonics,
                                double ridge = 1e-3);
};

/// A full force calibration: polynomial for estimation on the stable branch, periodic model
/// fitted to the same data for use beyond it, and the stable branch it is valid on.
struct ForceCalibration {
  PolynomialForceModel polynomial;
  PeriodicForceModel periodic;
  double stable_min_rad = -1.5707963267948966;  // edges of the stable branch (F̂_s extrema)
  double stable_max_rad = 1.5707963267948966;
  double peak_push_n = 0.0;  // largest output force F_out = −F̂_s on the stable branch (>0)
  double peak_pull_n = 0.0;  // largest output force in −p direction (<0)
  std::string source;        // where it came from (paper, a recording …)

  /// Fills stable_*, peak_* from the polynomial (extrema of F̂_s around φ = 0).
  void derive_limits();
  /// F̂_s at any phase: the polynomial on the stable branch, the periodic model past it (a
  /// step-out carries φ leads away, where the polynomial means nothing), so it is bounded.
  double load_force_n(double phase_rad) const {
    return on_stable_branch(phase_rad) ? polynomial.load_force_n(phase_rad)
                                       : periodic.load_force_n(phase_rad);
  }
  double slope_n_per_rad(double phase_rad) const {
    return on_stable_branch(phase_rad) ? polynomial.slope_n_per_rad(phase_rad)
                                       : periodic.slope_n_per_rad(phase_rad);
  }
  bool on_stable_branch(double phase_rad) const {
    return phase_rad >= stable_min_rad && phase_rad <= stable_max_rad;
  }
};

/// The paper's calibration (eq. 7) with a periodic model fitted to it.
ForceCalibration paper_calibration();

/// The coupling as a model file states it beyond the calibration: a gain (coupling_gain_error),
/// a ripple once per screw turn (angle_ripple) and a weaker coupling near the stroke's ends
/// (end_effect): F_m = g (1 + a sin(θ + ψ)) (1 − D s(x)) F_cal(φ), s(x) = x²(3 − 2x),
/// x = clip((z − d)/z, 0, 1), d the nut's distance to the nearer stroke end.
struct CouplingModel {
  double gain = 1.0;
  double angle_ripple = 0.0, angle_ripple_phase_rad = 0.0;
  double end_zone_m = 0.0, end_max_reduction = 0.0;  // z and D; z = 0: no end effect
  bool valid() const noexcept {
    return gain > 0 && std::isfinite(gain) && std::abs(angle_ripple) < 1 &&
           std::isfinite(angle_ripple_phase_rad) && end_zone_m >= 0 && end_max_reduction >= 0 &&
           end_max_reduction < 1;
  }
  double factor(double screw_angle_rad, double end_distance_m) const noexcept {
    double f = gain * (1.0 + angle_ripple * std::sin(screw_angle_rad + angle_ripple_phase_rad));
    if (end_zone_m > 0) {
      const double x = std::clamp((end_zone_m - end_distance_m) / end_zone_m, 0.0, 1.0);
      f *= 1.0 - end_max_reduction * x * x * (3.0 - 2.0 * x);
    }
    return f;
  }
};

/// `gain` times a calibration (a coupling g times as strong: the model's coupling_gain_error).
ForceCalibration scaled(ForceCalibration cal, double gain);

}  // namespace maglead
