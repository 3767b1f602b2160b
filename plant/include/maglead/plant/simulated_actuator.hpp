#pragma once
// The simulated actuator: plays the real machine for the controller, tests and recordings.
// Deliberately independent of the twin's dynamics code (a fixed-step stick-slip integrator of
// its own), so that comparing the twin with it proves something.
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/plant/hardware.hpp"

namespace maglead {

/// Physics beyond the paper's model, each off at 0 and given by one physical parameter.
struct PlantEffects {
  double viscous_friction_n_s_per_m = 0.0;  // extra viscous friction
  double stribeck_friction_n = 0.0;         // break-away excess over Coulomb, decays with speed
  double asymmetric_friction_n = 0.0;       // Coulomb +this moving +p, −this moving −p
  double offset_n = 0.0;                    // constant force on the nut along +p (gravity …)
  double gain_drift_per_min = 0.0;          // relative change of coupling strength per minute
  double angle_ripple_n = 0.0;              // force ripple once per screw turn, amplitude
  double position_ripple_n = 0.0;           // force ripple fixed to nut position (guide), amp.
  double backlash_rad = 0.0;                // gearbox play, at the screw
  double end_effect_m = 0.0;                // coupling weakens within this distance of an end
  double load_cell_delay_s = 0.0;           // load-cell signal delay
  double sensor_delay_s = 0.0;              // linear-encoder signal delay
  double spring_n_per_m = 0.0;              // spring pulling the nut to mid-stroke
  double mass_error_kg = 0.0;               // extra moving mass
  double external_disturbance_n = 0.0;      // brief force pulses at random times, amplitude

  static constexpr double kStribeckVelocity_m_s = 2e-3;
  static constexpr double kPositionRipplePeriod_m = 5e-3;
  static constexpr double kEndEffectDepth = 0.5;  // coupling fraction lost right at the end
};

/// Sets the effect `name` to `value`; throws std::invalid_argument naming the bad word.
void set_plant_effect(PlantEffects& effects, const std::string& name, double value);
/// Effect names with units and meaning, for --help and error messages.
std::vector<std::pair<std::string, std::string>> plant_effect_help();

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
  double anchor_pos_m = 0.0;       // compliant: where the stage / hand is; spring: free length
  double anchor_vel_m_s = 0.0;
  double force_n = 0.0;            // constant: force along +p
};

struct PlantTruth {
  double t_s, motor_angle_rad, screw_angle_rad, nut_pos_m, nut_vel_m_s, load_force_n;
  double coupling_force_n;  // F_m on the nut along +p
  int slips;                // completed step-outs so far (signed count of leads)
};

class SimulatedActuator final : public ActuatorHardware {
 public:
  SimulatedActuator(PlantParams params, std::uint64_t seed, double nut_pos_m = 0.02,
                    double screw_angle_rad = -1.0);  // default: screw at rest w.r.t. the nut
  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override;
  HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept override;

  void set_load(const LoadSetting& load) { load_ = load; }
  void advance_to(double t_s) noexcept;
  const PlantTruth& truth() const { return truth_; }
  const PlantParams& params() const { return params_; }

 private:
  void step(double dt) noexcept;
  double external_force_n() const noexcept;

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
  double last_load_n_ = 0.0;
  double phase_start_ = 0.0;
  std::vector<double> disturbance_times_s_;
  // Delay lines for sensors, sampled every substep (ring buffers, allocated once).
  std::vector<double> load_delay_, pos_delay_;
  std::size_t delay_head_ = 0;
  PlantTruth truth_{};
};

}  // namespace maglead
