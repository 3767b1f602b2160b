#pragma once
// Actuator geometry, sensors and nominal dynamics (docs/conventions.md, "The machine"), and the
// conversions between encoder counts, angles and positions.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>

namespace maglead {

struct ActuatorParams {
  double lead_m = 0.006;                    // nut travel per screw turn (paper)
  double gear_ratio = 6.6;                  // motor : screw (paper)
  double motor_counts_per_rev = 4096.0;     // quadrature counts per motor turn (assumed)
  double linear_count_m = 0.0254 / 1176.0;  // 21.6 µm per linear-encoder count (paper)
  double nut_mass_kg = 0.12;                // assumed
  double viscous_n_s_per_m = 2.0;           // assumed
  double coulomb_n = 7.5;                   // paper
  double stroke_min_m = 0.0;                // assumed
  double stroke_max_m = 0.040;              // assumed
  double sample_rate_hz = 1000.0;           // assumed
  double safe_force_fraction = 0.8;         // largest commandable |F_out| / peak force
};

inline double motor_angle_rad_from_counts(std::int64_t counts, const ActuatorParams& a) {
  return 2.0 * std::numbers::pi * static_cast<double>(counts) / a.motor_counts_per_rev;
}
inline double screw_angle_rad_from_motor_rad(double motor_angle_rad, const ActuatorParams& a) {
  return motor_angle_rad / a.gear_ratio;
}
inline double nut_pos_m_from_counts(std::int64_t counts, const ActuatorParams& a) {
  return static_cast<double>(counts) * a.linear_count_m;
}
/// Quantizes like an incremental encoder (floor: the count changes on crossing an edge).
inline std::int64_t motor_counts_from_rad(double motor_angle_rad, const ActuatorParams& a) {
  return static_cast<std::int64_t>(
      std::floor(motor_angle_rad * a.motor_counts_per_rev / (2.0 * std::numbers::pi)));
}
inline std::int64_t linear_counts_from_m(double nut_pos_m, const ActuatorParams& a) {
  return static_cast<std::int64_t>(std::floor(nut_pos_m / a.linear_count_m));
}

/// Screw angle at which the coupling is at rest for a nut position (paper eq. 2).
inline double rest_angle_rad(double nut_pos_m, double lead_m) {
  return 2.0 * std::numbers::pi * nut_pos_m / lead_m;
}
/// Phase difference φ = θ − 2πp/L (paper eq. 3), continuous angles in, unwrapped φ out.
inline double phase_rad(double screw_angle_rad, double nut_pos_m, double lead_m) {
  return screw_angle_rad - rest_angle_rad(nut_pos_m, lead_m);
}

}  // namespace maglead
