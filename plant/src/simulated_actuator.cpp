#include "maglead/plant/simulated_actuator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "maglead/plant/scenario.hpp"

namespace maglead {

PlantParams paper_like_plant() {
  // The plant's "true" coupling: a periodic curve fitted to eq. 7 on the stable branch, so it
  // calibrates like the paper's prototype and still steps out past a quarter lead.
  PlantParams p;
  std::vector<double> ph, f;
  const PolynomialForceModel eq7{{-4.28, -47.6, 2.59, 8.51, -0.209, -0.378}};
  for (double x = -std::numbers::pi / 2; x <= std::numbers::pi / 2; x += 0.005) {
    ph.push_back(x);
    f.push_back(eq7.load_force_n(x));
  }
  p.coupling = PeriodicForceModel::fit(ph, f, 3, 1e-4);
  return p;
}

SimulatedActuator::SimulatedActuator(PlantParams params, std::uint64_t seed, double nut_pos_m,
                                     double screw_angle_rad)
    : params_(std::move(params)), rng_(seed) {
  const auto& a = params_.actuator;
  check_plant_totals(params_.effects, a, params_.coupling.peak_n());
  coupling_zero_rad_ = balancing_phase_rad(params_.coupling, 0.0);  // where F_m = 0
  pos_m_ = nut_pos_m;
  screw_rad_ = screw_angle_rad == -1.0 ? rest_angle_rad(nut_pos_m, a.lead_m) : screw_angle_rad;
  motor_rad_ = motor_cmd_rad_ = screw_rad_ * a.gear_ratio;  // the gear output is at the screw
  screw_rad_ = screw_angle_at(motor_rad_, pos_m_);          // … or where the play puts it
  phase_start_ = phase_rad(screw_rad_, pos_m_, a.lead_m);
  const double dt = 1.0 / (a.sample_rate_hz * params_.substeps);
  const auto delay_len = [&](double d) { return static_cast<std::size_t>(std::ceil(d / dt)) + 2; };
  // The delay lines share one length and head so one index serves them all.
  const std::size_t len = std::max(delay_len(params_.effects.load_cell_delay_s),
                                   delay_len(params_.effects.sensor_delay_s));
  load_delay_.assign(len, 0.0);
  pos_delay_.assign(len, pos_m_);
  motor_delay_.assign(len, motor_rad_);
  if (params_.effects.external_disturbance_n != 0.0) {
    // A few pulses at random times in the first ten minutes; which times is the seed's business.
    std::uniform_real_distribution<double> when(2.0, 600.0);
    for (int i = 0; i < 40; ++i) disturbance_times_s_.push_back(when(rng_));
    std::sort(disturbance_times_s_.begin(), disturbance_times_s_.end());
  }
  truth_ = {
      0.0, motor_rad_, screw_rad_, pos_m_, 0.0, 0.0, coupling_force_n(0.0, pos_m_, screw_rad_), 0};
}

HwStatus SimulatedActuator::write_motor_angle(double motor_angle_cmd_rad) noexcept {
  if (!std::isfinite(motor_angle_cmd_rad)) return HwStatus::drive_fault;
  motor_cmd_rad_ = motor_angle_cmd_rad;
  return HwStatus::ok;
}

double SimulatedActuator::external_force_n() const noexcept {
  switch (load_.kind) {
    case LoadSetting::Kind::none:
      return 0.0;
    case LoadSetting::Kind::compliant: {
      const double moved_m = std::isfinite(load_.anchor_at_s)
                                 ? load_.anchor_vel_m_s * (t_s_ - load_.anchor_at_s)
                                 : 0.0;
      return load_.stiffness_n_per_m * (load_.anchor_pos_m + moved_m - pos_m_) +
             load_.damping_n_s_per_m * (load_.anchor_vel_m_s - vel_m_s_);
    }
    case LoadSetting::Kind::spring_to_wall:
      return -load_.stiffness_n_per_m * (pos_m_ - load_.anchor_pos_m) -
             load_.damping_n_s_per_m * vel_m_s_;
    case LoadSetting::Kind::constant:
      return load_.force_n - load_.damping_n_s_per_m * vel_m_s_;
  }
  return 0.0;
}

// The laws of docs/effects.md that scale the coupling force F_m.
double SimulatedActuator::coupling_gain(double t_s, double nut_pos_m,
                                        double screw_angle_rad) const noexcept {
  const auto& a = params_.actuator;
  const auto& e = params_.effects;
  // coupling_gain_error, angle_ripple and end_effect: the law the controller's observer serves
  // from a model file; gain_drift (1 + r t/60, t from the start) on top.
  const CouplingModel coupling{1.0 + e.coupling_gain_error, e.angle_ripple,
                               e.angle_ripple_phase_rad, e.end_effect_zone_m,
                               e.end_effect_max_reduction};
  const double end_distance_m = std::min(nut_pos_m - a.stroke_min_m, a.stroke_max_m - nut_pos_m);
  return coupling.factor(screw_angle_rad, end_distance_m) *
         (1.0 + e.gain_drift_per_min * t_s / 60.0);
}

double SimulatedActuator::coupling_force_n(double t_s, double nut_pos_m,
                                           double screw_angle_rad) const noexcept {
  const double phi = phase_rad(screw_angle_rad, nut_pos_m, params_.actuator.lead_m);
  return -coupling_gain(t_s, nut_pos_m, screw_angle_rad) * params_.coupling.load_force_n(phi);
}

// Backlash: the screw has no inertia of its own and no friction, so it sits where the torque
// on it balances. The coupling's reaction pulls it towards the angle at which F_m = 0; within
// the play nothing holds it elsewhere, and at the edge of the play the gear does. Hence: the
// rest angle clamped to gear output ± b/2, i.e. while F_m > 0 (torque transmitted towards +p)
// the screw lags the gear output by b/2, while F_m < 0 it leads by b/2.
double SimulatedActuator::screw_angle_at(double motor_rad, double nut_pos_m) const noexcept {
  const auto& a = params_.actuator;
  const double gear_out = motor_rad / a.gear_ratio;
  const double half_play = 0.5 * params_.effects.backlash_rad;
  if (half_play <= 0.0) return gear_out;
  const double two_pi = 2.0 * std::numbers::pi;
  double rest = rest_angle_rad(nut_pos_m, a.lead_m) + coupling_zero_rad_;
  rest += two_pi * std::round((gear_out - rest) / two_pi);  // the zero on the gear's branch
  return std::clamp(rest, gear_out - half_play, gear_out + half_play);
}

void SimulatedActuator::step(double dt) noexcept {
  const auto& a = params_.actuator;
  const auto& e = params_.effects;

  // Forces on the nut at the state at the start of the step (t, p, v, θ).
  const double coupling_n = coupling_force_n(t_s_, pos_m_, screw_rad_);
  const double load_n = external_force_n();
  double other_n =
      e.offset_n +
      e.position_ripple_n * std::sin(2.0 * std::numbers::pi * pos_m_ / e.position_ripple_period_m +
                                     e.position_ripple_phase_rad) -
      e.spring_n_per_m * (pos_m_ - 0.5 * (a.stroke_min_m + a.stroke_max_m));
  for (double td : disturbance_times_s_) {
    if (td > t_s_) break;
    if (t_s_ - td < 0.05) other_n += e.external_disturbance_n;
  }
  const double viscous = a.viscous_n_s_per_m + e.viscous_friction_n_s_per_m;
  const double mass = a.nut_mass_kg + e.mass_error_kg;
  const double drive_n = coupling_n + load_n + other_n - viscous * vel_m_s_;

  // Friction: kinetic level F_k(v) per direction (Coulomb, asymmetric, Stribeck); the nut
  // breaks away when |drive| exceeds F_k(0) = F_s and sticks when its velocity passes zero.
  auto kinetic = [&](double dir, double speed) {
    const double coulomb =
        std::max(0.0, a.coulomb_n + e.coulomb_friction_n + dir * e.asymmetric_friction_n +
                          e.coulomb_drift_n_per_min * t_s_ / 60.0);
    const double r = speed / e.stribeck_velocity_m_s;
    return coulomb + e.stribeck_friction_n * std::exp(-r * r);
  };
  if (stuck_) {
    const double dir = drive_n > 0.0 ? 1.0 : -1.0;
    const double breakaway = kinetic(dir, 0.0);
    if (std::abs(drive_n) <= breakaway) {
      vel_m_s_ = 0.0;
    } else {
      stuck_ = false;
      vel_m_s_ = (drive_n - dir * breakaway) / mass * dt;
    }
  } else {
    const double dir = vel_m_s_ > 0.0 ? 1.0 : -1.0;
    const double v_new = vel_m_s_ + (drive_n - dir * kinetic(dir, std::abs(vel_m_s_))) / mass * dt;
    if (v_new * dir <= 0.0) {
      vel_m_s_ = 0.0;  // came to rest within the step: stick, re-test break-away next step
      stuck_ = true;
    } else {
      vel_m_s_ = v_new;
    }
  }
  pos_m_ += vel_m_s_ * dt;
  t_s_ += dt;

  // Motor position servo: critically damped second order with a speed limit.
  const double wn = 2.0 * std::numbers::pi * params_.servo_bandwidth_hz;
  const double acc = wn * wn * (motor_cmd_rad_ - motor_rad_) - 2.0 * wn * motor_vel_;
  motor_vel_ = std::clamp(motor_vel_ + acc * dt, -params_.motor_speed_limit_rad_s,
                          params_.motor_speed_limit_rad_s);
  motor_rad_ += motor_vel_ * dt;
  screw_rad_ = screw_angle_at(motor_rad_, pos_m_);
  load_n_ = external_force_n();

  delay_head_ = (delay_head_ + 1) % load_delay_.size();
  load_delay_[delay_head_] = load_n_;
  pos_delay_[delay_head_] = pos_m_;
  motor_delay_[delay_head_] = motor_rad_;
}

void SimulatedActuator::advance_to(double t_s) noexcept {
  const double dt = 1.0 / (params_.actuator.sample_rate_hz * params_.substeps);
  while (t_s_ + 0.5 * dt < t_s) step(dt);
  const auto& a = params_.actuator;
  load_n_ = external_force_n();  // the load setting may have changed since the last step
  truth_.t_s = t_s_;
  truth_.motor_angle_rad = motor_rad_;
  truth_.screw_angle_rad = screw_rad_;
  truth_.nut_pos_m = pos_m_;
  truth_.nut_vel_m_s = vel_m_s_;
  truth_.load_force_n = load_n_;
  truth_.coupling_force_n = coupling_force_n(t_s_, pos_m_, screw_rad_);
  truth_.slips = static_cast<int>(std::lround(
      (phase_rad(screw_rad_, pos_m_, a.lead_m) - phase_start_) / (2.0 * std::numbers::pi)));
}

double SimulatedActuator::delayed(const std::vector<double>& line, double delay_s) const noexcept {
  const double dt = 1.0 / (params_.actuator.sample_rate_hz * params_.substeps);
  const double lag = std::clamp(delay_s / dt, 0.0, static_cast<double>(line.size() - 2));
  const auto k = static_cast<std::size_t>(std::floor(lag));
  const double frac = lag - static_cast<double>(k);
  const std::size_t n = line.size();
  const double newer = line[(delay_head_ + n - k) % n];
  const double older = line[(delay_head_ + 2 * n - k - 1) % n];
  return newer + frac * (older - newer);
}

HwStatus SimulatedActuator::read_sensors(double now_s, SensorSample& out) noexcept {
  advance_to(now_s);
  const auto& a = params_.actuator;
  const auto& e = params_.effects;
  // Pure delays: a reading at t is the true value at t − τ (interpolated between substeps).
  const double motor =
      e.sensor_delay_s > 0.0 ? delayed(motor_delay_, e.sensor_delay_s) : motor_rad_;
  const double pos = e.sensor_delay_s > 0.0 ? delayed(pos_delay_, e.sensor_delay_s) : pos_m_;
  const double load =
      e.load_cell_delay_s > 0.0 ? delayed(load_delay_, e.load_cell_delay_s) : load_n_;
  // Both encoders' zeros sit half a count below the origin, so a count reads the nearest
  // multiple of the resolution. With an edge at the origin every reading would lie half a count
  // low on average: for the linear encoder 0.011 rad of φ, a 0.5 N error of any calibration not
  // made through this encoder (the paper's eq. 7 in config/calibration.toml is in true φ).
  out.motor_counts = motor_counts_from_rad(motor + std::numbers::pi / a.motor_counts_per_rev, a);
  out.linear_counts = linear_counts_from_m(pos + 0.5 * a.linear_count_m, a);
  out.load_force_n = load + params_.load_cell_noise_n * noise_(rng_);
  return HwStatus::ok;
}

}  // namespace maglead
