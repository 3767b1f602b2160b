#pragma once
// The nut's friction and the other forces of its balance that no sensor measures, as the
// controller's force loop and load observer use them (docs/conventions.md):
//   M p̈ = F_m(φ) + F_offset − F_f + F_ext,   F_out = −F_ext.
// Filled from the model file (twin::friction_model) so the loop compensates with the same
// terms the twin runs and `maglead analyze` corrects; defaults from the [actuator] table.
#include <algorithm>
#include <cmath>

#include "maglead/physics/actuator.hpp"

namespace maglead {

struct FrictionModel {
  double coulomb_pos_n = 7.5, coulomb_neg_n = 7.5;      // kinetic level moving +p / −p
  double breakaway_pos_n = 7.5, breakaway_neg_n = 7.5;  // static level (≥ kinetic)
  double stribeck_velocity_m_s = 0.0;                   // 0: kinetic level at any speed
  double viscous_pos_n_s_per_m = 2.0, viscous_neg_n_s_per_m = 2.0;
  double offset_n = 0.0;  // constant force on the nut along +p (gravity, a cable)
  double nut_mass_kg = 0.12;

  /// Friction magnitude at sliding velocity v (its sign is the direction), viscous excluded:
  /// F_k + (F_s − F_k) exp(−(v/v_s)²).
  double kinetic_n(double v_m_s) const noexcept {
    const bool pos = v_m_s >= 0.0;
    const double fk = pos ? coulomb_pos_n : coulomb_neg_n;
    const double fs = pos ? breakaway_pos_n : breakaway_neg_n;
    if (!(stribeck_velocity_m_s > 0.0)) return fk;
    const double x = v_m_s / stribeck_velocity_m_s;
    return fk + (fs - fk) * std::exp(-x * x);
  }
  /// The signed friction force F_f while sliding at v ≠ 0 (opposes the motion with a + sign in
  /// the balance above), viscous included.
  double sliding_n(double v_m_s) const noexcept {
    const double dir = v_m_s >= 0.0 ? 1.0 : -1.0;
    const double c = v_m_s >= 0.0 ? viscous_pos_n_s_per_m : viscous_neg_n_s_per_m;
    return dir * kinetic_n(v_m_s) + c * v_m_s;
  }
  /// Break-away level for motion in direction dir (+1 / −1).
  double breakaway_n(int dir) const noexcept {
    return dir >= 0 ? breakaway_pos_n : breakaway_neg_n;
  }
  /// True when every level is finite and non-negative and break-away ≥ kinetic.
  bool valid() const noexcept {
    const double v[] = {
        coulomb_pos_n,         coulomb_neg_n,         breakaway_pos_n,       breakaway_neg_n,
        stribeck_velocity_m_s, viscous_pos_n_s_per_m, viscous_neg_n_s_per_m, nut_mass_kg};
    const bool finite = std::all_of(std::begin(v), std::end(v),
                                    [](double x) { return std::isfinite(x) && x >= 0.0; });
    return finite && std::isfinite(offset_n) && breakaway_pos_n >= coulomb_pos_n &&
           breakaway_neg_n >= coulomb_neg_n;
  }
};

/// Coulomb friction, viscous friction and mass of the [actuator] table, nothing else.
inline FrictionModel friction_from_actuator(const ActuatorParams& a) {
  FrictionModel f;
  f.coulomb_pos_n = f.coulomb_neg_n = f.breakaway_pos_n = f.breakaway_neg_n = a.coulomb_n;
  f.viscous_pos_n_s_per_m = f.viscous_neg_n_s_per_m = a.viscous_n_s_per_m;
  f.nut_mass_kg = a.nut_mass_kg;
  return f;
}

}  // namespace maglead
