#pragma once
// The paper's static force estimate (eq. 6) and its inverse for force control.
#include <cstddef>
#include <vector>

#include "maglead/physics/force_model.hpp"

namespace maglead {

/// F̂_ext = F̂_s(φ) + F_c·sign(ṗ) (load-cell convention); F̂_out = −F̂_ext. Past the stable
/// branch (a step-out) F̂_s is the calibration's periodic model: bounded, never the polynomial's
/// extrapolation.
class StaticForceEstimator {
 public:
  StaticForceEstimator(ForceCalibration cal, double coulomb_n, double velocity_deadband_m_s);
  double load_force_n(double phase_rad, double nut_vel_m_s) const;
  double output_force_n(double phase_rad, double nut_vel_m_s) const {
    return -load_force_n(phase_rad, nut_vel_m_s);
  }
  const ForceCalibration& calibration() const { return cal_; }

 private:
  ForceCalibration cal_;
  double coulomb_n_;
  double deadband_m_s_;
};

/// Causal nut velocity from a quantized encoder, by timing its edges: at an edge, counts moved
/// over the time since the previous edge; between edges, bounded by one count over the time
/// elapsed, and zero once no edge has come for `hold_s`. A fixed difference window either
/// flickers to zero at slow (hand) speeds or lags at fast ones. No allocation: loop-safe.
class EncoderVelocityEstimator {
 public:
  EncoderVelocityEstimator(double sample_period_s, double count_m, double hold_s = 0.2);
  double update(double pos_m);
  void reset(double pos_m);
  double velocity_m_s() const { return vel_m_s_; }

 private:
  double period_s_, count_m_, hold_s_;
  double t_s_ = 0.0, edge_t_s_ = 0.0, edge_pos_m_ = 0.0, vel_m_s_ = 0.0;
  bool started_ = false;
};

enum class InverseStatus { ok, beyond_safe_limit };
struct PhaseForForce {
  InverseStatus status;
  double phase_rad;  // phase on the stable branch whose static output force is the request
  double limit_n;    // the safe limit in the requested direction (signed)
};
/// The phase that yields a requested output force F_out at standstill (−F̂_s(φ) = F_out), on
/// the stable branch. Requests beyond safe_fraction × peak are refused, not clipped.
PhaseForForce phase_for_output_force(const ForceCalibration& cal, double output_force_n,
                                     double safe_fraction);

/// Offline zero-phase velocity of a sampled position: central difference over ±half_window.
std::vector<double> central_velocity(const std::vector<double>& t_s,
                                     const std::vector<double>& pos_m, std::size_t half_window);

}  // namespace maglead
