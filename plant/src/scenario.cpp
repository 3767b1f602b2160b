#include "maglead/plant/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

#include "maglead/physics/estimator.hpp"
#include "maglead/recording/recording.hpp"

namespace maglead {

const std::vector<ScenarioInfo>& scenario_list() {
  static const std::vector<ScenarioInfo> list = {
      {"static-calibration",
       "screw held, a stiff stage sweeps the nut slowly through the stable branch (paper IV.B)"},
      {"hand-push",
       "screw held, a compliant hand pushes the nut back and forth, peaks up to ~35 N (Fig. 11)"},
      {"force-steps",
       "force control against a spring load: setpoint steps, ramps and a sine sweep (open loop, "
       "the paper's inverse, unless --controller maglead)"},
      {"force-holds",
       "force control against a 2000 N/m spring: setpoints held 2.5 s each, as a PLC steps them "
       "(5, 10, 15, 20, -5, -10, -15, 12, 8, 3, 0, 18, 6 N, repeated; open loop unless "
       "--controller maglead)"},
      {"position-moves",
       "moves across the stroke at 5, 20 and 50 mm/s with a light load (open loop unless "
       "--controller maglead)"},
      {"mixed",
       "alternating: force control against a spring (8 s of steps, ramps, sweep), then hand "
       "pushes with the screw held (9 s); the spring re-engages where the hand left the nut"},
      {"mixed-moves",
       "alternating: force control against a spring (6 s), hand pushes with the screw held (8 s), "
       "free point-to-point moves with no load (7 s); each starts where the last left the nut"},
  };
  return list;
}

double balancing_phase_rad(const PeriodicForceModel& coupling, double load_force_n) {
  double lo = -std::numbers::pi / 2, hi = std::numbers::pi / 2;  // F̂_s falls from lo to hi
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (coupling.load_force_n(mid) > load_force_n)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

namespace {

constexpr double kMidStroke_m = 0.020;

double triangle(double x) {  // period 1, range −1 … 1, starts at 0 rising
  const double f = x - std::floor(x);
  if (f < 0.25) return 4 * f;
  if (f < 0.75) return 2 - 4 * f;
  return 4 * f - 4;
}

/// Smooth pushes with random peaks and mostly alternating direction, like a hand.
struct HandProfile {
  std::vector<double> start_s, length_s, peak_n;
  /// force_scale: the pushes' share of the 12–35 N below (an actuator whose safe force is less).
  HandProfile(double duration_s, std::mt19937_64& rng, double force_scale = 1.0) {
    std::uniform_real_distribution<double> len(1.2, 2.8), peak(12.0, 35.0), gap(0.0, 0.6),
        coin(0.0, 1.0);
    double t = 0.5, sign = 1.0;
    while (t < duration_s) {
      start_s.push_back(t);
      length_s.push_back(len(rng));
      peak_n.push_back(force_scale * sign * peak(rng));
      t += length_s.back() + gap(rng);
      if (coin(rng) < 0.75) sign = -sign;
    }
  }
  /// until_s: pushes that would not end by then are not made (a hand segment that ends).
  double force_n(double t, double until_s = std::numeric_limits<double>::infinity()) const {
    for (std::size_t i = 0; i < start_s.size(); ++i) {
      const double tau = (t - start_s[i]) / length_s[i];
      if (tau >= 0.0 && tau < 1.0 && start_s[i] + length_s[i] <= until_s) {
        const double s = std::sin(std::numbers::pi * tau);
        return peak_n[i] * s * s;
      }
    }
    return 0.0;
  }
};

double force_setpoint_n(double t, double duration) {
  const double x = t / duration;
  if (x < 0.4) {  // steps
    static constexpr double steps[] = {0.0, 5.0, 15.0, 25.0, 10.0, -10.0, -25.0, 0.0};
    const auto i = std::min<std::size_t>(static_cast<std::size_t>(x / 0.4 * 8), 7);
    return steps[i];
  }
  if (x < 0.65) {  // ramps 0 → 30 → −30 → 0
    const double r = (x - 0.4) / 0.25;
    return 30.0 * triangle(r);
  }
  // sine sweep, 0.2 → 2 Hz, 20 N
  const double t0 = 0.65 * duration, span = 0.35 * duration;
  const double tau = t - t0;
  const double f0 = 0.2, f1 = 2.0;
  const double phase = 2 * std::numbers::pi * (f0 * tau + 0.5 * (f1 - f0) / span * tau * tau);
  return 20.0 * std::sin(phase);
}

/// A PLC's force steps: each setpoint held, the loop landing on it and then holding (the nut
/// slides only briefly after each step, as `serve` in force mode does against its spring).
double held_setpoint_n(double t) {
  static constexpr double steps[] = {5.0,  10.0, 15.0, 20.0, -5.0, -10.0, -15.0,
                                     12.0, 8.0,  3.0,  0.0,  18.0, 6.0};
  constexpr double hold_s = 2.5;
  const auto i = static_cast<std::size_t>(std::floor(t / hold_s)) % std::size(steps);
  return steps[i];
}

/// Trapezoidal point-to-point moves across the stroke at several speeds.
struct MoveProfile {
  struct Move {
    double t0, from, to, v, a;
  };
  std::vector<Move> moves;
  double start_m = kMidStroke_m;
  MoveProfile() = default;
  /// Moves starting at t0_s from from_m, the first to target `first`. whole_only: only moves that
  /// end (with their 0.5 s pause) by t0_s + duration_s are made (a move segment that ends).
  explicit MoveProfile(double duration_s, double t0_s = 0.0, double from_m = kMidStroke_m,
                       std::size_t first = 0, bool whole_only = false)
      : start_m(from_m) {
    const double targets[] = {0.035, 0.005, 0.030, 0.010, 0.038, 0.002, 0.020};
    const double speeds[] = {0.005, 0.020, 0.050};
    double t = t0_s + 0.5, at = from_m;
    const double end_s = t0_s + duration_s;
    for (std::size_t i = first; t < end_s; ++i) {
      if (whole_only && i >= first + 21) break;  // every target at every speed tried
      const double to = targets[i % 7], v = speeds[i % 3], a = 0.5;
      const double d = std::abs(to - at);
      const double t_move = d / v + v / a;
      if (whole_only && t + t_move + 0.5 > end_s) continue;  // try the next, perhaps shorter
      moves.push_back({t, at, to, v, a});
      t += t_move + 0.5;
      at = to;
    }
  }
  /// The move under way or last made at t (nullptr before the first).
  const Move* move_at(double t) const {
    const Move* at = nullptr;
    for (const auto& m : moves) {
      if (t < m.t0) break;
      at = &m;
    }
    return at;
  }
  double pos_m(double t) const {
    double p = start_m;
    for (const auto& m : moves) {
      if (t < m.t0) break;
      const double d = std::abs(m.to - m.from), dir = m.to > m.from ? 1.0 : -1.0;
      const double v = std::min(m.v, std::sqrt(d * m.a));
      const double ta = v / m.a, tc = d / v - ta, tau = t - m.t0;
      double s;
      if (tau < ta)
        s = 0.5 * m.a * tau * tau;
      else if (tau < ta + tc)
        s = 0.5 * m.a * ta * ta + v * (tau - ta);
      else if (tau < 2 * ta + tc)
        s = d - 0.5 * m.a * (2 * ta + tc - tau) * (2 * ta + tc - tau);
      else
        s = d;
      p = m.from + dir * s;
    }
    return p;
  }
};

/// A hand pushing the nut through a compliant rod with the screw held at screw_rad: the rod's far
/// end where the nut would balance the hand's force, plus the rod's compression. The hand's
/// profile starts at t0_s and makes only pushes that end within until_s of it.
LoadSetting hand_load(const HandProfile& hand, const PeriodicForceModel& coupling, double screw_rad,
                      double lead_m, double t, double t0_s = 0.0,
                      double until_s = std::numeric_limits<double>::infinity()) {
  constexpr double k_hand = 1500.0, c_hand = 10.0;
  auto anchor = [&](double tt) {
    const double f = hand.force_n(tt - t0_s, until_s);
    const double phi = balancing_phase_rad(coupling, f);
    return (screw_rad - phi) * lead_m / (2 * std::numbers::pi) + f / k_hand;
  };
  LoadSetting load;
  load.kind = LoadSetting::Kind::compliant;
  load.stiffness_n_per_m = k_hand;
  load.damping_n_s_per_m = c_hand;
  load.anchor_pos_m = anchor(t);
  load.anchor_vel_m_s = (anchor(t + 1e-3) - load.anchor_pos_m) / 1e-3;
  return load;
}

/// The mixed scenarios' schedule: force-control, hand and (mixed-moves) free-move segments in
/// turn.
struct MixedSchedule {
  enum class Segment : std::uint8_t { force, hand, moves };
  double force_s = 8.0, hand_s = 9.0, moves_s = 0.0;
  double period_s() const { return force_s + hand_s + moves_s; }
  double start_s(double t) const { return std::floor(t / period_s()) * period_s(); }
  Segment at(double t) const {
    const double u = t - start_s(t);
    if (u < force_s) return Segment::force;
    return u < force_s + hand_s ? Segment::hand : Segment::moves;
  }
  double hand_t0_s(double t) const { return start_s(t) + force_s; }
  double moves_t0_s(double t) const { return start_s(t) + force_s + hand_s; }
  /// Every other force segment runs its profile mirrored: the nut, left where each segment
  /// ends, does not walk to a stroke end over a long run.
  double sign(double t) const { return std::fmod(std::floor(t / period_s()), 2.0) == 0 ? 1 : -1; }
};

/// One run of a scenario: the plant, what loads it and what commands its screw, sample by sample.
class ScenarioRun {
 public:
  explicit ScenarioRun(const ScenarioOptions& opt)
      : opt_(opt),
        act_(opt.plant.actuator),
        rng_(opt.seed),
        plant_(opt.plant, opt.seed * 7919 + 17, kMidStroke_m),
        screw0_(rest_angle_rad(kMidStroke_m, act_.lead_m)),
        mixed_(opt.scenario == "mixed" || opt.scenario == "mixed-moves"),
        holds_(opt.scenario == "force-holds"),
        force_mode_(opt.scenario == "force-steps" || holds_ || mixed_),
        move_mode_(opt.scenario == "position-moves"),
        schedule_(opt.scenario == "mixed-moves" ? MixedSchedule{6.0, 8.0, 7.0} : MixedSchedule{}),
        force_scale_(force_scale(opt)),
        hand_(opt.duration_s, rng_, force_scale_),
        moves_(opt.duration_s),
        estimator_(opt.estimator_calibration, act_.coulomb_n, 1e-5),
        velocity_(1.0 / act_.sample_rate_hz, act_.linear_count_m) {
    // Sweep amplitude reaching |φ| ≈ 1.5 rad whatever the lead; whole cycles at about 0.5 mm/s.
    const double cycles = std::max(1.0, std::round(opt.duration_s * 0.5e-3 / (4 * sweep_amp_m_)));
    sweep_period_s_ = opt.duration_s / cycles;
  }

  std::vector<std::string> column_names() const {
    std::vector<std::string> names = {"t_s",       "motor_angle_rad", "screw_angle_rad",
                                      "nut_pos_m", "load_force_n",    "out_force_est_n"};
    if (force_mode_) names.emplace_back("force_set_n");
    if (move_mode_) names.emplace_back("pos_set_m");
    return names;
  }

  /// Sample k: load the plant, read it, command the screw; the row in column_names()' order.
  std::size_t step(std::size_t k, double* row) {
    const double t = static_cast<double>(k) * (1.0 / act_.sample_rate_hz);
    plant_.set_load(load_at(t));
    plant_.read_sensors(t, s_);
    const double motor = motor_angle_rad_from_counts(s_.motor_counts, act_);
    const double screw = screw_angle_rad_from_motor_rad(motor, act_);
    const double pos = nut_pos_m_from_counts(s_.linear_counts, act_);
    const double vel = k == 0 ? (velocity_.reset(pos), 0.0) : velocity_.update(pos);
    const double est = estimator_.output_force_n(phase_rad(screw, pos, act_.lead_m), vel);
    const Command cmd = command_at(t, pos);
    plant_.write_motor_angle(cmd.screw_rad * act_.gear_ratio);
    last_screw_cmd_ = cmd.screw_rad;
    last_segment_ = mixed_ ? schedule_.at(t) : Segment::force;
    std::size_t c = 0;
    row[c++] = static_cast<double>(k) / act_.sample_rate_hz;  // 0.026, not 0.026000000000000002
    row[c++] = motor;
    row[c++] = screw;
    row[c++] = pos;
    row[c++] = s_.load_force_n;
    row[c++] = est;
    if (force_mode_) row[c++] = cmd.force_set_n;
    if (move_mode_) row[c++] = cmd.pos_set_m;
    return c;
  }

  ScenarioSummary summary(std::size_t samples) const {
    ScenarioSummary summary{samples, plant_.truth().slips, {}};
    for (double t : plant_.disturbance_times_s())
      if (t < opt_.duration_s) summary.disturbance_times_s.push_back(t);
    return summary;
  }

 private:
  // The sweep's phase amplitude (1.55 mm at a 6 mm lead), in metres at the configured lead.
  static constexpr double kSweepAmp_rad = 1.6231562043547265;
  // The largest force the scenarios ask of the nut (a hand's push; setpoints reach 30 N).
  static constexpr double kLargestForce_n = 35.0;

  /// The scenarios' forces were written for an actuator whose safe force reaches
  /// kLargestForce_n; a weaker one (configuration: calibration peaks × safe fraction) gets them
  /// scaled down to its safe force, so that it still slides, stops and pushes without stepping out.
  static double force_scale(const ScenarioOptions& opt) {
    const auto& cal = opt.estimator_calibration;
    const double safe_n = opt.plant.actuator.safe_force_fraction *
                          std::min(std::abs(cal.peak_push_n), std::abs(cal.peak_pull_n));
    return std::min(1.0, safe_n / kLargestForce_n);
  }

  using Segment = MixedSchedule::Segment;
  struct Command {
    double screw_rad, force_set_n = 0.0, pos_set_m = 0.0;
  };

  /// A move segment's moves: from the nut's position, each segment's list begun further on.
  void start_moves(double t) {
    const auto segment = static_cast<std::size_t>(std::floor(t / schedule_.period_s()));
    segment_moves_ = MoveProfile(schedule_.moves_s, schedule_.moves_t0_s(t),
                                 plant_.truth().nut_pos_m, 3 * segment, true);
  }

  LoadSetting load_at(double t) {
    const auto& S = opt_.scenario;
    LoadSetting load;
    if (S == "static-calibration") {
      load.kind = LoadSetting::Kind::compliant;
      load.stiffness_n_per_m = 5e5;
      load.damping_n_s_per_m = 300;
      load.anchor_pos_m = kMidStroke_m + sweep_amp_m_ * triangle(t / sweep_period_s_);
      load.anchor_vel_m_s = (sweep_amp_m_ * triangle((t + 1e-4) / sweep_period_s_) -
                             sweep_amp_m_ * triangle(t / sweep_period_s_)) /
                            1e-4;
      load.anchor_at_s = t;
    } else if (S == "hand-push") {
      load = hand_load(hand_, opt_.plant.coupling, screw0_, act_.lead_m, t);
    } else if (mixed_ && schedule_.at(t) == Segment::hand) {
      if (last_segment_ != Segment::hand) screw_hold_ = last_screw_cmd_;
      load = hand_load(hand_, opt_.plant.coupling, screw_hold_, act_.lead_m, t,
                       schedule_.hand_t0_s(t), schedule_.hand_s);
    } else if (mixed_ && schedule_.at(t) == Segment::moves) {
      // Free moves, nothing touching the nut; they start where the hand left it.
      if (last_segment_ != Segment::moves) start_moves(t);
    } else if (force_mode_) {
      // The mixed scenarios' spring is anchored where the nut was when force control began.
      if (mixed_ && last_segment_ != Segment::force) spring_anchor_m_ = plant_.truth().nut_pos_m;
      load.kind = LoadSetting::Kind::spring_to_wall;
      // force-holds: the spring `serve` simulates by default (the live test's load).
      load.stiffness_n_per_m = holds_ ? 2000.0 : 3000.0;
      load.damping_n_s_per_m = 5.0;
      load.anchor_pos_m = mixed_ ? spring_anchor_m_ : kMidStroke_m;
    } else {
      load.kind = LoadSetting::Kind::constant;
      load.force_n = -2.0;
      load.damping_n_s_per_m = 10.0;
    }
    return load;
  }

  Command command_at(double t, double pos_m) const {
    const double L = act_.lead_m;
    constexpr double kNoSetpoint = std::numeric_limits<double>::quiet_NaN();  // logged empty
    if (mixed_ && schedule_.at(t) == Segment::hand) return {screw_hold_, kNoSetpoint};
    if (mixed_ && schedule_.at(t) == Segment::moves)
      return {rest_angle_rad(segment_moves_.pos_m(t), L), kNoSetpoint};
    if (force_mode_) {
      const double set =
          force_scale_ * (mixed_ ? schedule_.sign(t) *
                                       force_setpoint_n(t - schedule_.start_s(t), schedule_.force_s)
                          : holds_ ? held_setpoint_n(t)
                                   : force_setpoint_n(t, opt_.duration_s));
      if (!mixed_ && opt_.controller) {
        ScenarioSetpoint sp;
        sp.force_n = set;
        return {opt_.controller(t, s_, sp) / act_.gear_ratio, set};
      }
      const auto inv = phase_for_output_force(opt_.estimator_calibration, set, 0.9);
      return {rest_angle_rad(pos_m, L) + inv.phase_rad, set};
    }
    if (move_mode_) {
      const double set = moves_.pos_m(t);
      if (opt_.controller)
        return {opt_.controller(t, s_, move_setpoint(t)) / act_.gear_ratio, 0.0, set};
      return {rest_angle_rad(set, L), 0.0, set};
    }
    return {screw0_};
  }

  /// The move a PLC gives at t: the target, speed and acceleration of the move under way.
  ScenarioSetpoint move_setpoint(double t) const {
    ScenarioSetpoint sp;
    if (const auto* m = moves_.move_at(t)) {
      sp.target_m = m->to;
      sp.speed_m_s = m->v;
      sp.accel_m_s2 = m->a;
    }
    return sp;
  }

  const ScenarioOptions& opt_;
  const ActuatorParams& act_;
  std::mt19937_64 rng_;
  SimulatedActuator plant_;
  const double screw0_;
  const bool mixed_, holds_, force_mode_, move_mode_;
  const MixedSchedule schedule_;
  const double force_scale_;
  HandProfile hand_;
  MoveProfile moves_, segment_moves_;
  StaticForceEstimator estimator_;
  EncoderVelocityEstimator velocity_;
  double sweep_period_s_ = 1.0;
  const double sweep_amp_m_ = kSweepAmp_rad * act_.lead_m / (2 * std::numbers::pi);
  // The mixed scenario's state: the spring's anchor and the screw angle held during a hand
  // segment.
  double spring_anchor_m_ = kMidStroke_m, screw_hold_ = screw0_, last_screw_cmd_ = screw0_;
  Segment last_segment_ = Segment::force;
  SensorSample s_;
};

void check_options(const ScenarioOptions& opt) {
  const auto& list = scenario_list();
  if (std::none_of(list.begin(), list.end(), [&](auto& s) { return s.name == opt.scenario; })) {
    std::string known;
    for (const auto& s : list) known += (known.empty() ? "" : ", ") + s.name;
    throw std::invalid_argument("unknown scenario '" + opt.scenario + "' (known: " + known + ")");
  }
  if (!(opt.duration_s > 0.0) || opt.duration_s > 24 * 3600.0)
    throw std::invalid_argument("duration must be between 0 and 24 h");
  if (opt.controller && !scenario_takes_controller(opt.scenario))
    throw std::invalid_argument(
        "a scenario's own controller runs force-holds, force-steps and position-moves; '" +
        opt.scenario + "' runs open loop");
}

}  // namespace

bool scenario_takes_controller(const std::string& scenario) {
  return scenario == "force-holds" || scenario == "force-steps" || scenario == "position-moves";
}

ScenarioSummary run_scenario(const ScenarioOptions& opt, const std::string& out_path) {
  check_options(opt);
  const auto& act = opt.plant.actuator;
  const double fs = act.sample_rate_hz;
  ScenarioRun run(opt);
  const std::vector<std::pair<std::string, std::string>> meta = {
      {"sample_rate_hz", std::to_string(fs)},
      {"source", "maglead simulate"},
      {"system", "simulated magnetic lead-screw actuator"},
      {"scenario", opt.scenario},
      {"controller", !opt.controller_name.empty() ? opt.controller_name
                     : opt.controller             ? "a scenario controller"
                                                  : "open-loop, the paper's inverse"},
      {"seed", std::to_string(opt.seed)},
      {"lead_m", std::to_string(act.lead_m)},
      {"gear_ratio", std::to_string(act.gear_ratio)},
  };
  RecordingWriter writer(out_path, meta, run.column_names(), WriteMode::whole);  // whole or none
  const auto n = static_cast<std::size_t>(std::llround(opt.duration_s * fs)) + 1;
  double row[8];
  std::size_t next_progress = 0;
  for (std::size_t k = 0; k < n; ++k) {
    writer.write_row(row, run.step(k, row));
    if (opt.progress && k >= next_progress) {
      opt.progress(static_cast<double>(k) / static_cast<double>(n));
      next_progress += n / 100 + 1;
    }
  }
  writer.close();
  if (opt.progress) opt.progress(1.0);
  return run.summary(n);
}

}  // namespace maglead
