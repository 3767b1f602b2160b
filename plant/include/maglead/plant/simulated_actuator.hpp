#pragma once
// The simulated actuator: plays the real machine for the controller, tests and recordings.
// Deliberately independent of the twin's dynamics code (a fixed-step stick-slip integrator of
// its own), so that comparing the twin with it proves something.
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "maglead/controller/ports/hardware.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"

namespace maglead {

/// Physics beyond the paper's model, with the ids and laws of docs/effects.md. Each is
/// off at its default. Where the spec's parameter is a total (C, F_c, M, g) the plant's value is
/// the change from the nominal actuator, so 0 always means "off"; the comments give the spec's
/// parameter in terms of these fields (nominal values from ActuatorParams).
struct PlantEffects {
  double coulomb_friction_n = 0.0;          // coulomb_n = F_c + this (kinetic and break-away)
  double viscous_friction_n_s_per_m = 0.0;  // viscous_n_s_per_m = C + this
  double asymmetric_friction_n = 0.0;       // coulomb_pos_n F_c + this, coulomb_neg_n F_c − this
  double stribeck_friction_n = 0.0;         // breakaway_n = F_c + this; kinetic falls to F_c …
  double stribeck_velocity_m_s = 2e-3;      // … with stribeck_velocity_m_s (v_s)
  double offset_n = 0.0;                    // offset_n: constant force on the nut along +p
  double spring_n_per_m = 0.0;              // stiffness_n_per_m; rest_position_m = mid-stroke
  double mass_error_kg = 0.0;               // nut_mass_kg = M + this
  double coupling_gain_error = 0.0;         // gain = 1 + this
  double gain_drift_per_min = 0.0;          // gain_change_per_min (r): F_m × (1 + r t/60)
  double angle_ripple = 0.0;                // relative_amplitude (a): F_m × (1 + a sin(θ + ψ))
  double angle_ripple_phase_rad = 0.0;      // phase_rad (ψ)
  double position_ripple_n = 0.0;           // amplitude_n: + A sin(2πp/λ + ψ)
  double position_ripple_period_m = 5e-3;   // period_m (λ)
  double position_ripple_phase_rad = 0.0;   // phase_rad (ψ)
  double end_effect_zone_m = 0.0;           // zone_m (z): F_m × (1 − D s(x)), see effects.md
  double end_effect_max_reduction = 0.5;    // max_reduction (D)
  double backlash_rad = 0.0;                // backlash_rad (b): gear play, at the screw
  double sensor_delay_s = 0.0;              // delay_s: linear and motor encoder readings lag
  double load_cell_delay_s = 0.0;           // delay_s: the load-cell reading lags
  double external_disturbance_n = 0.0;      // force_n of 50 ms pulses at random times
  // Not an effect of the library (the --effect key friction_drift, N/min): a friction that
  // rises in time (wear, temperature), F_c + coulomb_friction_n + this·t/60, for the drift flag.
  double coulomb_drift_n_per_min = 0.0;
};

/// Sets the effect `name` (an id, or ID.PARAMETER for a shape parameter such as
/// angle_ripple.phase_rad) to `value`; throws std::invalid_argument naming the bad word.
void set_plant_effect(PlantEffects& effects, const std::string& name, double value);
/// Refuses effects whose total (the nominal actuator's value plus the change) has no physical
/// meaning: a negative friction or viscous coefficient, a mass at or below zero, and force
/// effects many times `coupling_peak_n` (the coupling's largest force; 0 skips that check).
/// Throws std::invalid_argument naming the effect, the value, the range and its unit.
void check_plant_totals(const PlantEffects& effects, const ActuatorParams& actuator,
                        double coupling_peak_n = 0.0);
/// An --effect key: its name, the unit of its value ("1" for a ratio) and what it changes.
struct PlantEffectKey {
  std::string name, unit, meaning;
};
/// Every effect key, for --help and error messages.
std::vector<PlantEffectKey> plant_effect_keys();

struct PlantParams {
  ActuatorParams actuator;
  PeriodicForceModel coupling;  // true F̂_s(φ) of this plant (load convention), periodic
  double servo_bandwidth_hz = 40.0;
  double motor_speed_limit_rad_s = 1000.0;
  double load_cell_noise_n = 0.1;
  int substeps = 20;
  PlantEffects effects;
};
/// A paper-like plant: coupling close to eq. 7 on the stable branch, periodic beyond.
PlantParams paper_like_plant();

/// What the nut is attached to; scenarios change it between ticks.
struct LoadSetting {
  enum class Kind : std::uint8_t { none, compliant, spring_to_wall, constant } kind = Kind::none;
  double stiffness_n_per_m = 0.0;  // compliant: stage / hand stiffness; spring: spring rate
  double damping_n_s_per_m = 0.0;
  double anchor_pos_m = 0.0;  // compliant: where the stage / hand is; spring: free length
  double anchor_vel_m_s = 0.0;
  // Compliant: the time anchor_pos_m is for; the anchor moves on at anchor_vel_m_s around it,
  // also inside the sample interval (NaN: it stands where set until the next setting). A stiff
  // stage set once per sample and held would step, and a reading at each step's end would alias
  // its sawtooth (stiffness × speed × period) into a force against the motion.
  double anchor_at_s = std::numeric_limits<double>::quiet_NaN();
  double force_n = 0.0;  // constant: force along +p
};

/// The plant's state at one instant t_s (every field at that same instant).
struct PlantTruth {
  double t_s, motor_angle_rad, screw_angle_rad, nut_pos_m, nut_vel_m_s, load_force_n;
  double coupling_force_n;  // F_m on the nut along +p, with every law that scales it
  int slips;                // completed step-outs so far (signed count of leads)
};

class SimulatedActuator final : public ActuatorHardware {
 public:
  SimulatedActuator(PlantParams params, std::uint64_t seed, double nut_pos_m = 0.02,
                    double screw_angle_rad = -1.0);  // default: screw at rest w.r.t. the nut
  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override;
  HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept override;
  /// The simulated servo is always powered: ready and stopped hold the last command.
  HwStatus set_power(PowerRequest) noexcept override { return HwStatus::ok; }

  void set_load(const LoadSetting& load) { load_ = load; }
  void advance_to(double t_s) noexcept;
  const PlantTruth& truth() const { return truth_; }
  const PlantParams& params() const { return params_; }
  /// Starts of the external_disturbance pulses (50 ms each); empty when that effect is off.
  const std::vector<double>& disturbance_times_s() const { return disturbance_times_s_; }

 private:
  void step(double dt) noexcept;
  double external_force_n() const noexcept;
  /// The laws that scale F_m (gain error, drift, angle ripple, end effect) at one state.
  double coupling_gain(double t_s, double nut_pos_m, double screw_angle_rad) const noexcept;
  /// F_m on the nut along +p at one state (the plant's true coupling times coupling_gain).
  double coupling_force_n(double t_s, double nut_pos_m, double screw_angle_rad) const noexcept;
  /// Screw angle for a motor angle and nut position: the gear output, or with backlash the
  /// point of the play where the coupling's torque puts it (see simulated_actuator.cpp).
  double screw_angle_at(double motor_rad, double nut_pos_m) const noexcept;
  /// A delay line's value `delay_s` ago, interpolated between substeps.
  double delayed(const std::vector<double>& line, double delay_s) const noexcept;

  PlantParams params_;
  LoadSetting load_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
  double t_s_ = 0.0;
  double motor_cmd_rad_ = 0.0;
  double motor_rad_ = 0.0, motor_vel_ = 0.0;
  double screw_rad_ = 0.0;
  double pos_m_ = 0.0, vel_m_s_ = 0.0;
  bool stuck_ = true;
  double load_n_ = 0.0;             // F_ext at the current state
  double coupling_zero_rad_ = 0.0;  // φ at which the true coupling force is zero (stable branch)
  double phase_start_ = 0.0;
  std::vector<double> disturbance_times_s_;
  // Delay lines for sensors, sampled every substep (ring buffers, allocated once).
  std::vector<double> load_delay_, pos_delay_, motor_delay_;
  std::size_t delay_head_ = 0;
  PlantTruth truth_{};
};

}  // namespace maglead
