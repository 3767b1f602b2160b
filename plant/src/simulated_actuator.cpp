#include "maglead/plant/simulated_actuator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

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
  pos_m_ = nut_pos_m;
  screw_rad_ = screw_angle_rad == -1.0 ? rest_angle_rad(nut_pos_m, a.lead_m) : screw_angle_rad;
  motor_rad_ = motor_cmd_rad_ = screw_rad_ * a.gear_ratio;
  phase_start_ = phase_rad(screw_rad_, pos_m_, a.lead_m);
  const double dt = 1.0 / (a.sample_rate_hz * params_.substeps);
  const auto delay_len = [&](double d) {
    return static_cast<std::size_t>(std::ceil(d / dt)) + 2;
  };
  // Both delay lines share one length and head so one index serves both.
  const std::size_t len = std::max(delay_len(params_.effects.load_cell_delay_s),
                                   delay_len(params_.effects.sensor_delay_s));
  load_delay_.assign(len, 0.0);
  pos_delay_.assign(len, pos_m_);
  if (params_.effects.external_disturbance_n != 0.0) {
    // A few pulses at random times in the first ten minutes; which times is the seed's business.
    std::uniform_real_distribution<double> when(2.0, 600.0);
    for (int i = 0; i < 40; ++i) disturbance_times_s_.push_back(when(rng_));
    std::sort(disturbance_times_s_.begin(), disturbance_times_s_.end());
  }
  truth_ = {0.0, motor_rad_, screw_rad_, pos_m_, 0.0, 0.0, 0.0, 0};
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
    case LoadSetting::Kind::compliant:
      return load_.stiffness_n_per_m * (load_.anchor_pos_m - pos_m_) +
             load_.damping_n_s_per_m * (load_.anchor_vel_m_s - vel_m_s_);
    case LoadSetting::Kind::spring_to_wall:
      return -load_.stiffness_n_per_m * (pos_m_ - load_.anchor_pos_m) -
             load_.damping_n_s_per_m * vel_m_s_;
    case LoadSetting::Kind::constant:
      return load_.force_n - load_.damping_n_s_per_m * vel_m_s_;
  }
  return 0.0;
}

void SimulatedActuator::step(double dt) noexcept {
  const auto& a = params_.actuator;
  const auto& e = params_.effects;

  // Motor position servo: critically damped second order with a speed limit.
  const double wn = 2.0 * std::numbers::pi * params_.servo_bandwidth_hz;
  const double acc = wn * wn * (motor_cmd_rad_ - motor_rad_) - 2.0 * wn * motor_vel_;
  motor_vel_ = std::clamp(motor_vel_ + acc * dt, -params_.motor_speed_limit_rad_s,
                          params_.motor_speed_limit_rad_s);
  motor_rad_ += motor_vel_ * dt;
  // Gearbox: the screw follows the gear output within the play (a play operator).
  const double gear_out = motor_rad_ / a.gear_ratio;
  const double half_play = 0.5 * e.backlash_rad;
  screw_rad_ = std::clamp(screw_rad_, gear_out - half_play, gear_out + half_play);

  // Coupling strength: drift over time and weakening near the stroke ends.
  double gain = 1.0 + e.gain_drift_per_min * t_s_ / 60.0;
  if (e.end_effect_m > 0.0) {
    const double to_end = std::min(pos_m_ - a.stroke_min_m, a.stroke_max_m - pos_m_);
    gain *= 1.0 - PlantEffects::kEndEffectDepth * std::clamp(1.0 - to_end / e.end_effect_m, 0.0, 1.0);
  }
  const double phi = phase_rad(screw_rad_, pos_m_, a.lead_m);
  const double coupling_n = -gain * params_.coupling.load_force_n(phi);
  const double load_n = external_force_n();
  last_load_n_ = load_n;

  double other_n = e.offset_n + e.angle_ripple_n * std::sin(screw_rad_) +
                   e.position_ripple_n *
                       std::sin(2.0 * std::numbers::pi * pos_m_ / PlantEffects::kPositionRipplePeriod_m) -
                   e.spring_n_per_m * (pos_m_ - 0.5 * (a.stroke_min_m + a.stroke_max_m));
  for (double td : disturbance_times_s_) {
    if (td > t_s_) break;
    if (t_s_ - td < 0.05) other_n += e.external_disturbance_n;
  }
  const double viscous = a.viscous_n_s_per_m + e.viscous_friction_n_s_per_m;
  const double mass = a.nut_mass_kg + e.mass_error_kg;
  const double drive_n = coupling_n + load_n + other_n - viscous * vel_m_s_;

  auto coulomb = [&](double dir) {
    return a.coulomb_n + dir * e.asymmetric_friction_n;
  };
  if (stuck_) {
    const double dir = drive_n > 0.0 ? 1.0 : -1.0;
    const double breakaway = coulomb(dir) + e.stribeck_friction_n;
    if (std::abs(drive_n) <= breakaway) {
      vel_m_s_ = 0.0;
    } else {
      stuck_ = false;
      vel_m_s_ = (drive_n - dir * breakaway) / mass * dt;
    }
  } else {
    const double dir = vel_m_s_ > 0.0 ? 1.0 : -1.0;
    const double speed = std::abs(vel_m_s_) / PlantEffects::kStribeckVelocity_m_s;
    const double friction = coulomb(dir) + e.stribeck_friction_n * std::exp(-speed * speed);
    const double v_new = vel_m_s_ + (drive_n - dir * friction) / mass * dt;
    if (v_new * dir <= 0.0) {
      vel_m_s_ = 0.0;  // came to rest within the step: stick, re-test break-away next step
      stuck_ = true;
    } else {
      vel_m_s_ = v_new;
    }
  }
  pos_m_ += vel_m_s_ * dt;
  t_s_ += dt;

  delay_head_ = (delay_head_ + 1) % load_delay_.size();
  load_delay_[delay_head_] = load_n;
  pos_delay_[delay_head_] = pos_m_;
  truth_.coupling_force_n = coupling_n;
}

void SimulatedActuator::advance_to(double t_s) noexcept {
  const double dt = 1.0 / (params_.actuator.sample_rate_hz * params_.substeps);
  while (t_s_ + 0.5 * dt < t_s) step(dt);
  const auto& a = params_.actuator;
  truth_.t_s = t_s_;
  truth_.motor_angle_rad = motor_rad_;
  truth_.screw_angle_rad = screw_rad_;
  truth_.nut_pos_m = pos_m_;
  truth_.nut_vel_m_s = vel_m_s_;
  truth_.load_force_n = last_load_n_;
  truth_.slips = static_cast<int>(
      std::lround((phase_rad(screw_rad_, pos_m_, a.lead_m) - phase_start_) / (2.0 * std::numbers::pi)));
}

HwStatus SimulatedActuator::read_sensors(double now_s, SensorSample& out) noexcept {
  advance_to(now_s);
  const auto& a = params_.actuator;
  const double dt = 1.0 / (a.sample_rate_hz * params_.substeps);
  const auto delayed = [&](const std::vector<double>& line, double delay_s) {
    const auto lag = static_cast<std::size_t>(std::lround(delay_s / dt));
    return line[(delay_head_ + line.size() - std::min(lag, line.size() - 1)) % line.size()];
  };
  out.motor_counts = motor_counts_from_rad(motor_rad_, a);
  const double pos = params_.effects.sensor_delay_s > 0.0
                         ? delayed(pos_delay_, params_.effects.sensor_delay_s)
                         : pos_m_;
  out.linear_counts = linear_counts_from_m(pos, a);
  const double load = params_.effects.load_cell_delay_s > 0.0
                          ? delayed(load_delay_, params_.effects.load_cell_delay_s)
                          : last_load_n_;
  out.load_force_n = load + params_.load_cell_noise_n * noise_(rng_);
  return HwStatus::ok;
}

}  // namespace maglead
