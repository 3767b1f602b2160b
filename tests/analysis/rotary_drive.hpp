#pragma once
// A generated rotary drive (a servo motor with its load), made here for the tests: nothing in it
// comes from a recording. J θ̈ = τ − b θ̇ − c sign θ̇ − τ_0, the torque τ from a PD position loop
// at 1 kHz that follows a reference sweeping hundreds of radians (a multi-turn absolute
// encoder, so the angle reaches thousands of radians), integrated at 10 kHz with stiction
// (stuck while |τ − τ_0| ≤ c), the angle logged at 2^17 counts per turn and the torque with
// noise. The columns are the rotary axis's: t_s, angle_rad, drive_torque_n_m, ref_angle_rad.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "maglead/recording/recording.hpp"

namespace maglead::test {

struct RotaryDrive {
  double inertia_kg_m2 = 1.2e-3;        // J: motor and load
  double viscous_n_m_s_per_rad = 2e-3;  // b
  double coulomb_n_m = 0.08;            // c
  double offset_n_m = 0.0;            // τ_0: a constant load torque (gravity on a balanced arm: 0)
  double noise_n_m = 0.005;           // RMS of the logged torque's noise
  double counts_per_turn = 131072.0;  // 2^17
  double duration_s = 40.0;
  double start_rad = 3000.0;  // where the absolute encoder starts: beyond any length's bound
  unsigned seed = 1;
  // > 0: point-to-point moves (move_s each, to random targets) with this long a stop after each,
  // the PD holding the shaft against stiction; 0: the sweep of three sines below.
  double dwell_s = 0.0;
  double move_s = 1.5;
  // > 0: the drive adds a torque step of this size (either sign, drawn from its own generator) for
  // 0.3–0.6 s once every step_every_s, as a feed-forward would; the loop works against it.
  double torque_step_n_m = 0.0;
  double step_every_s = 2.0;
  // The moves' and the sweep's lengths are scaled by this (1e-3: millimetres of a linear axis from
  // the radians of a shaft); `linear` logs the columns of a linear axis (pos_m, drive_force_n,
  // ref_pos_m, '# axis: linear'), the same law read as M p̈ = F − C ṗ − F_c sign ṗ.
  double length_scale = 1.0;
  bool linear = false;
};

// The reference: a sum of three sines of random phase (0.2–1.3 Hz; speeds up to about
// 400 rad/s, accelerations up to about 1500 rad/s²), so every reversal passes at an acceleration
// whose feed-forward torque is far beyond c. With dwell_s the shaft stops after each move and
// the PD holds it against stiction with any torque up to c, which no sliding law gives: the axis
// path leaves such holds out of the fit (docs/analysis.md, a rotary axis).
struct Sine {
  double amplitude_rad, rate_rad_s, phase_rad;
};

inline std::vector<Sine> rotary_sines(std::mt19937& rng) {
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  const double w = 2 * std::numbers::pi;
  return {{200.0, w * 0.2, phase(rng)}, {40.0, w * 0.7, phase(rng)}, {8.0, w * 1.3, phase(rng)}};
}

// Reference angle, speed and acceleration at t.
inline void reference_at(const std::vector<Sine>& sines, double start_rad, double t, double* ref,
                         double scale = 1.0) {
  ref[0] = start_rad, ref[1] = 0.0, ref[2] = 0.0;
  for (const Sine& s : sines) {
    const double x = s.rate_rad_s * t + s.phase_rad;
    const double a = scale * s.amplitude_rad;
    ref[0] += a * (std::sin(x) - std::sin(s.phase_rad));
    ref[1] += a * s.rate_rad_s * std::cos(x);
    ref[2] -= a * s.rate_rad_s * s.rate_rad_s * std::sin(x);
  }
}

// Point-to-point moves: minimum-jerk profiles from one target to the next (50–200 rad either
// way), each followed by a stop.
struct Moves {
  std::vector<double> targets_rad;  // targets_rad[k] is where move k starts
  double move_s = 1.5, dwell_s = 1.0;
};

inline Moves rotary_moves(const RotaryDrive& d, std::mt19937& rng) {
  std::uniform_real_distribution<double> length(50.0 * d.length_scale, 200.0 * d.length_scale);
  Moves m{{d.start_rad}, d.move_s, d.dwell_s};
  const auto count = static_cast<int>(d.duration_s / (d.move_s + d.dwell_s)) + 2;
  for (int k = 0; k < count; ++k)
    m.targets_rad.push_back(m.targets_rad.back() + (k % 2 == 0 ? 1.0 : -1.0) * length(rng));
  return m;
}

inline void reference_at(const Moves& m, double t, double* ref) {
  const double cycle = m.move_s + m.dwell_s;
  const auto k = static_cast<std::size_t>(t / cycle);
  const double a = m.targets_rad[k], b = m.targets_rad[k + 1];
  const double u = std::min(1.0, (t - static_cast<double>(k) * cycle) / m.move_s);
  const double T = m.move_s, d = b - a;
  ref[0] = a + d * u * u * u * (10 - 15 * u + 6 * u * u);
  ref[1] = d * 30 * u * u * (1 - u) * (1 - u) / T;
  ref[2] = d * 60 * u * (1 - u) * (1 - 2 * u) / (T * T);
}

// The drive's torque steps (torque_step_n_m): one of either sign for 0.3–0.6 s at a random time
// in every step_every_s, from a generator of their own (the other draws stay as they were).
struct TorqueSteps {
  std::vector<double> from_s, to_s, torque_n_m;
  double at(double t) const {
    for (std::size_t k = 0; k < from_s.size(); ++k)
      if (t >= from_s[k] && t < to_s[k]) return torque_n_m[k];
    return 0.0;
  }
};

inline TorqueSteps torque_steps(const RotaryDrive& d) {
  TorqueSteps s;
  if (!(d.torque_step_n_m > 0)) return s;
  std::mt19937 rng(d.seed + 1000003u);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (double t0 = 0.0; t0 + d.step_every_s <= d.duration_s; t0 += d.step_every_s) {
    const double len = 0.3 + 0.3 * unit(rng), at = t0 + (d.step_every_s - len) * unit(rng);
    s.from_s.push_back(at);
    s.to_s.push_back(at + len);
    s.torque_n_m.push_back(unit(rng) < 0.5 ? -d.torque_step_n_m : d.torque_step_n_m);
  }
  return s;
}

// An empty recording with the header and columns of the drive's kind.
inline Recording drive_columns(const RotaryDrive& d, bool axis_header) {
  Recording rec;
  rec.path = d.linear ? "generated linear axis" : "generated rotary drive";
  if (axis_header) rec.metadata = {{"axis", d.linear ? "linear" : "rotary"}};
  rec.metadata.emplace_back("sample_rate_hz", "1000");
  rec.names =
      d.linear ? std::vector<std::string>{"t_s", "pos_m", "drive_force_n", "ref_pos_m"}
               : std::vector<std::string>{"t_s", "angle_rad", "drive_torque_n_m", "ref_angle_rad"};
  rec.columns.assign(4, {});
  return rec;
}

/// The recording (`# axis: rotary` in its header unless `axis_header` is false).
inline Recording rotary_recording(const RotaryDrive& d, bool axis_header = true) {
  std::mt19937 rng(d.seed);
  const auto sines = rotary_sines(rng);
  const Moves moves =
      d.dwell_s > 0 ? rotary_moves(d, rng) : Moves{};  // the sweep's draws as before
  const auto reference = [&](double t, double* ref) {
    if (d.dwell_s > 0)
      reference_at(moves, t, ref);
    else
      reference_at(sines, d.start_rad, t, ref, d.length_scale);
  };
  const TorqueSteps steps = torque_steps(d);
  std::normal_distribution<double> noise(0.0, d.noise_n_m);
  constexpr int kSubsteps = 10;
  constexpr double kDt_s = 1e-3, kBandwidth_rad_s = 2 * std::numbers::pi * 30.0;
  const double kp = d.inertia_kg_m2 * kBandwidth_rad_s * kBandwidth_rad_s;
  const double kd = 2 * 0.7 * d.inertia_kg_m2 * kBandwidth_rad_s;
  const double count_rad = 2 * std::numbers::pi / d.counts_per_turn;
  Recording rec = drive_columns(d, axis_header);
  double start[3];
  reference(0.0, start);
  // The shaft is already on the reference (no start-up transient: the logger starts mid-run).
  double theta = d.start_rad, omega = start[1], last_q = d.start_rad - start[1] * kDt_s;
  for (int k = 0; k * kDt_s < d.duration_s; ++k) {
    const double t = k * kDt_s;
    double ref[3];
    reference(t, ref);
    const double q = std::round(theta / count_rad) * count_rad;  // the encoder's count
    const double speed = (q - last_q) / kDt_s;
    last_q = q;
    // The drive's torque: PD on the counted angle with the reference's acceleration fed forward.
    const double tau =
        kp * (ref[0] - q) + kd * (ref[1] - speed) + d.inertia_kg_m2 * ref[2] + steps.at(t);
    rec.columns[0].push_back(t);
    rec.columns[1].push_back(q);
    rec.columns[2].push_back(tau + noise(rng));
    rec.columns[3].push_back(ref[0]);
    for (int s = 0; s < kSubsteps; ++s) {
      const double h = kDt_s / kSubsteps, drive = tau - d.offset_n_m;
      if (omega == 0.0 && std::abs(drive) <= d.coulomb_n_m) continue;  // stuck
      const double friction =
          d.viscous_n_m_s_per_rad * omega +
          d.coulomb_n_m * (omega != 0.0 ? std::copysign(1.0, omega) : std::copysign(1.0, drive));
      const double next = omega + h * (drive - friction) / d.inertia_kg_m2;
      omega = (omega != 0.0 && next * omega < 0.0) ? 0.0 : next;  // stops rather than reverses
      theta += h * omega;
    }
  }
  return rec;
}

}  // namespace maglead::test
