// Each law of the simulated plant against docs/effects.md. The plant is run substep by
// substep; between two substeps its own velocity change gives the net force it applied, which
// must equal the spec's formula, written out here at the state the step started from:
//
//   M p̈ = F_m(φ)·gain(t, p, θ) + F_ext + extra(p, v) − dir·F_k(dir, |v|)     (sliding)
//   stuck while |F_m·gain + F_ext + extra| ≤ F_k(dir, 0)                       (F_k(0) = F_s)
//
// and, where the library unit's law is exact, the nominal model plus
// maglead::effects::find(id)->force_n with the spec's parameter names. Each test also evaluates
// a wrong form of its law (the plant's old one, or "effect off") on the same run and requires it
// to miss by a clear margin, so a change of the law's form fails the test. The plant code itself
// never calls effects/.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "maglead/effects/effect.hpp"
#include "maglead/plant/scenario.hpp"
#include "maglead/plant/simulated_actuator.hpp"

using namespace maglead;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTol_n = 1e-6;  // the identity holds to rounding (forces ~10 N)

// A model of the net force on the nut, one hook per part of the balance.
struct Model {
  PlantParams plant;  // the nominal machine: true coupling curve, F_c, C, M, stroke
  std::function<double(const PlantTruth&)> coupling;             // F_m on the nut
  std::function<double(const PlantTruth&, double accel)> extra;  // other forces (incl. −C v)
  std::function<double(double dir, double speed, const PlantTruth&)> friction;  // F_k; at 0: F_s
  double mass = 0;
};

double base_coupling_n(const PlantParams& p, const PlantTruth& s) {
  return -p.coupling.load_force_n(phase_rad(s.screw_angle_rad, s.nut_pos_m, p.actuator.lead_m));
}

Model nominal(const PlantParams& p) {
  Model m;
  m.plant = p;
  m.coupling = [p](const PlantTruth& s) { return base_coupling_n(p, s); };
  m.extra = [c = p.actuator.viscous_n_s_per_m](const PlantTruth& s, double) {
    return -c * s.nut_vel_m_s;
  };
  m.friction = [fc = p.actuator.coulomb_n](double, double, const PlantTruth&) { return fc; };
  m.mass = p.actuator.nut_mass_kg;
  return m;
}

// The nominal model plus one library unit with the spec's parameters: its force_n while the nut
// moves, its breakaway_extra_n at break-away.
Model library(const PlantParams& p, const std::string& id, const effects::Params& params) {
  const effects::Effect* unit = effects::find(id);
  EXPECT_NE(unit, nullptr) << id;
  Model m = nominal(p);
  auto state = [p](const PlantTruth& s, double accel) {
    effects::State st;
    st.t_s = s.t_s;
    st.p_m = s.nut_pos_m;
    st.v_m_s = s.nut_vel_m_s;
    st.a_m_s2 = accel;
    st.theta_rad = s.screw_angle_rad;
    st.phi_rad = phase_rad(s.screw_angle_rad, s.nut_pos_m, p.actuator.lead_m);
    st.coupling_n = base_coupling_n(p, s);
    st.stroke_min_m = p.actuator.stroke_min_m;
    st.stroke_max_m = p.actuator.stroke_max_m;
    st.lead_m = p.actuator.lead_m;
    st.coulomb_n = p.actuator.coulomb_n;
    st.viscous_n_s_per_m = p.actuator.viscous_n_s_per_m;
    st.nut_mass_kg = p.actuator.nut_mass_kg;
    return st;
  };
  m.extra = [p, unit, params, state](const PlantTruth& s, double accel) {
    return -p.actuator.viscous_n_s_per_m * s.nut_vel_m_s + unit->force_n(params, state(s, accel));
  };
  m.friction = [p, unit, params, state](double dir, double speed, const PlantTruth& s) {
    return p.actuator.coulomb_n +
           (speed == 0.0 ? unit->breakaway_extra_n(params, state(s, 0), dir) : 0.0);
  };
  return m;
}

struct Check {
  double worst_n = 0;  // largest miss of the identity, or break-away/stick condition [N]
  int sliding = 0, stuck = 0, breakaways = 0;
};

double substep_s(const PlantParams& p) { return 1.0 / (p.actuator.sample_rate_hz * p.substeps); }

// Compares the model with the plant over a substep-resolved run.
Check check(const std::vector<PlantTruth>& run, const Model& m) {
  Check c;
  const double dt = substep_s(m.plant);
  for (std::size_t k = 0; k + 1 < run.size(); ++k) {
    const auto& a = run[k];
    const auto& b = run[k + 1];
    const double accel = (b.nut_vel_m_s - a.nut_vel_m_s) / dt;
    if (a.nut_vel_m_s == 0.0) {
      const double drive =
          m.coupling(a) + a.load_force_n + m.extra(a, b.nut_vel_m_s == 0.0 ? 0.0 : accel);
      const double dir = drive > 0 ? 1.0 : -1.0;
      const double fs = m.friction(dir, 0.0, a);
      if (b.nut_vel_m_s == 0.0) {  // held: the drive must not exceed the break-away level
        ++c.stuck;
        c.worst_n = std::max(c.worst_n, std::abs(drive) - fs);
      } else {  // broke away: above the level, and the excess accelerates the nut
        ++c.breakaways;
        c.worst_n = std::max(c.worst_n, fs - std::abs(drive));
        c.worst_n = std::max(c.worst_n, std::abs(m.mass * accel - (drive - dir * fs)));
      }
    } else if (b.nut_vel_m_s * a.nut_vel_m_s > 0.0) {
      ++c.sliding;
      const double dir = a.nut_vel_m_s > 0 ? 1.0 : -1.0;
      const double drive = m.coupling(a) + a.load_force_n + m.extra(a, accel);
      const double f = m.friction(dir, std::abs(a.nut_vel_m_s), a);
      c.worst_n = std::max(c.worst_n, std::abs(m.mass * accel - (drive - dir * f)));
    }
    // (sliding → held: the velocity passed zero within the step; nothing to compare)
  }
  return c;
}

// Runs the plant substep by substep, the motor commanded so that the screw's rest angle follows
// `nut_target_m(t)`; returns the plant's truth after every substep.
std::vector<PlantTruth> run(SimulatedActuator& plant, double duration_s,
                            const std::function<double(double)>& nut_target_m) {
  const auto& a = plant.params().actuator;
  const double dt = substep_s(plant.params());
  plant.advance_to(plant.truth().t_s);  // no step: the truth with the current load setting
  std::vector<PlantTruth> out{plant.truth()};
  const double t0 = plant.truth().t_s;
  const auto n = std::llround(duration_s / dt);
  for (long long k = 1; k <= n; ++k) {
    const double t = t0 + static_cast<double>(k) * dt;
    plant.write_motor_angle(rest_angle_rad(nut_target_m(t), a.lead_m) * a.gear_ratio);
    plant.advance_to(t);
    out.push_back(plant.truth());
  }
  return out;
}

// Piecewise-linear nut target through waypoints at `speed`, pausing `pause_s` at each.
std::function<double(double)> path(const std::vector<double>& points, double speed, double pause_s,
                                   double t0 = 0.0) {
  return [=](double t) {
    double tt = t - t0, at = points.front();
    for (std::size_t i = 1; i < points.size(); ++i) {
      if (tt < pause_s) return at;
      tt -= pause_s;
      const double d = std::abs(points[i] - at), T = d / speed;
      if (tt < T) return at + (points[i] > at ? 1.0 : -1.0) * speed * tt;
      tt -= T;
      at = points[i];
    }
    return at;
  };
}

double path_duration(const std::vector<double>& points, double speed, double pause_s) {
  double T = pause_s;
  for (std::size_t i = 1; i < points.size(); ++i)
    T += std::abs(points[i] - points[i - 1]) / speed + pause_s;
  return T;
}

// A plant with one --effect setting (and its shape keys), no load-cell noise.
PlantParams plant_with(std::initializer_list<std::pair<const char*, double>> keys) {
  PlantParams p = paper_like_plant();
  p.load_cell_noise_n = 0.0;
  for (const auto& [k, v] : keys) set_plant_effect(p.effects, k, v);
  return p;
}

// One run through `points` with a light constant load and damper (like position-moves).
std::vector<PlantTruth> moves(const PlantParams& p, std::vector<double> points, double speed,
                              double pause_s = 0.05, double hold_s = 0.0) {
  SimulatedActuator plant(p, 1, points.front());
  LoadSetting load;
  load.kind = LoadSetting::Kind::constant;
  load.force_n = -2.0;
  load.damping_n_s_per_m = 10.0;
  plant.set_load(load);
  if (hold_s > 0) plant.advance_to(hold_s);
  return run(plant, path_duration(points, speed, pause_s), path(points, speed, pause_s, hold_s));
}

// The law holds on the run (spec formula and library unit), the wrong form misses, and the run
// exercised sliding, sticking and break-away.
void expect_law(const std::vector<PlantTruth>& r, const Model& spec, const Model& lib,
                const Model& wrong, double wrong_by_n = 0.05) {
  const Check cs = check(r, spec);
  EXPECT_LT(cs.worst_n, kTol_n) << "spec formula";
  EXPECT_GT(cs.sliding, 1000);
  EXPECT_GT(cs.breakaways, 0);
  EXPECT_LT(check(r, lib).worst_n, kTol_n) << "library unit";
  EXPECT_GT(check(r, wrong).worst_n, wrong_by_n) << "a wrong form of the law must not fit";
}

// ----------------------------------------------------------------- friction and mass

TEST(PlantLaws, NominalMachineHasOnlyThePapersForces) {
  const auto p = plant_with({});
  const auto r = moves(p, {0.010, 0.030, 0.010}, 0.02);
  const Check c = check(r, nominal(p));
  EXPECT_LT(c.worst_n, kTol_n);
  EXPECT_GT(c.sliding, 10000);
  EXPECT_GT(c.stuck, 100);
  EXPECT_GT(c.breakaways, 1);
}

TEST(PlantLaws, CoulombFrictionIsTheNominalPlusTheValue) {
  const auto p = plant_with({{"coulomb_friction", 2.0}});
  const auto r = moves(p, {0.010, 0.025, 0.010}, 0.02);
  Model spec = nominal(p);
  spec.friction = [](double, double, const PlantTruth&) { return 7.5 + 2.0; };
  expect_law(r, spec, library(p, "coulomb_friction", {{"coulomb_n", 9.5}}), nominal(p));
}

TEST(PlantLaws, ViscousFrictionAddsToC) {
  const auto p = plant_with({{"viscous_friction", 50.0}});
  const auto r = moves(p, {0.010, 0.025, 0.010}, 0.02);
  Model spec = nominal(p);
  spec.extra = [](const PlantTruth& s, double) { return -(2.0 + 50.0) * s.nut_vel_m_s; };
  expect_law(r, spec, library(p, "viscous_friction", {{"viscous_n_s_per_m", 52.0}}), nominal(p));
}

TEST(PlantLaws, AsymmetricFrictionHasOneLevelPerDirection) {
  const auto p = plant_with({{"asymmetric_friction", 2.0}});
  const auto r = moves(p, {0.010, 0.025, 0.010, 0.025}, 0.02);
  Model spec = nominal(p);
  spec.friction = [](double dir, double, const PlantTruth&) { return dir > 0 ? 9.5 : 5.5; };
  Model symmetric = nominal(p);  // the same mean level both ways
  expect_law(r, spec,
             library(p, "asymmetric_friction", {{"coulomb_pos_n", 9.5}, {"coulomb_neg_n", 5.5}}),
             symmetric);
}

TEST(PlantLaws, StribeckFrictionFallsWithTheSquareOfSpeed) {
  // Slow moves with pauses: stick-slip, so the run crosses the Stribeck region many times.
  const auto p =
      plant_with({{"stribeck_friction", 4.5}, {"stribeck_friction.stribeck_velocity_m_s", 0.003}});
  const auto r = moves(p, {0.010, 0.014, 0.010, 0.014}, 0.002, 0.2);
  auto fk = [](double speed) {  // F_c + (F_s − F_c) exp(−(v/v_s)²), F_s = 12 N
    const double x = speed / 0.003;
    return 7.5 + (12.0 - 7.5) * std::exp(-x * x);
  };
  Model spec = nominal(p);
  spec.friction = [fk](double, double speed, const PlantTruth&) { return fk(speed); };
  Model not_squared = nominal(p);
  not_squared.friction = [](double, double speed, const PlantTruth&) {
    return 7.5 + 4.5 * std::exp(-speed / 0.003);
  };
  expect_law(r, spec,
             library(p, "stribeck_friction",
                     {{"breakaway_n", 12.0}, {"coulomb_n", 7.5}, {"stribeck_velocity_m_s", 0.003}}),
             not_squared);
  // The run covered the region where the law differs from Coulomb's.
  int slow = 0;
  for (const auto& s : r) slow += s.nut_vel_m_s != 0.0 && std::abs(s.nut_vel_m_s) < 0.003;
  EXPECT_GT(slow, 500);
}

// Break-away thresholds directly: the screw where F_m = 0, a constant load just below and just
// above F_s in each direction.
bool moves_under(const PlantParams& p, double load_n) {
  // Screw at the coupling's zero: F_m = 0 while the nut has not moved.
  SimulatedActuator held(
      p, 1, 0.02, rest_angle_rad(0.02, p.actuator.lead_m) + balancing_phase_rad(p.coupling, 0.0));
  LoadSetting load;
  load.kind = LoadSetting::Kind::constant;
  load.force_n = load_n;
  held.set_load(load);
  held.advance_to(0.05);
  return held.truth().nut_pos_m != 0.02;
}

TEST(PlantLaws, StuckWhileTheNetForceIsWithinTheBreakAwayLevel) {
  const auto stribeck = plant_with({{"stribeck_friction", 4.5}});
  EXPECT_FALSE(moves_under(stribeck, 11.95));
  EXPECT_TRUE(moves_under(stribeck, 12.05));
  EXPECT_FALSE(moves_under(stribeck, -11.95));
  EXPECT_TRUE(moves_under(stribeck, -12.05));
  const auto asym = plant_with({{"asymmetric_friction", 2.0}});
  EXPECT_FALSE(moves_under(asym, 9.45));
  EXPECT_TRUE(moves_under(asym, 9.55));
  EXPECT_FALSE(moves_under(asym, -5.45));
  EXPECT_TRUE(moves_under(asym, -5.55));
}

TEST(PlantLaws, MassErrorAddsToTheMovingMass) {
  const auto p = plant_with({{"mass_error", 0.05}});
  const auto r = moves(p, {0.010, 0.025, 0.010}, 0.02);
  Model spec = nominal(p);
  spec.mass = 0.12 + 0.05;
  expect_law(r, spec, library(p, "mass_error", {{"nut_mass_kg", 0.17}}), nominal(p));
}

// ----------------------------------------------------------------- additive forces

TEST(PlantLaws, OffsetIsAConstantForceAlongPlusP) {
  const auto p = plant_with({{"offset", 3.0}});
  const auto r = moves(p, {0.010, 0.025, 0.010}, 0.02);
  Model spec = nominal(p);
  spec.extra = [](const PlantTruth& s, double) { return -2.0 * s.nut_vel_m_s + 3.0; };
  expect_law(r, spec, library(p, "offset", {{"offset_n", 3.0}}), nominal(p));
}

TEST(PlantLaws, SpringPullsTowardsMidStroke) {
  const auto p = plant_with({{"spring", 300.0}});
  const auto r = moves(p, {0.005, 0.035, 0.005}, 0.05);
  Model spec = nominal(p);
  spec.extra = [](const PlantTruth& s, double) {
    return -2.0 * s.nut_vel_m_s - 300.0 * (s.nut_pos_m - 0.020);
  };
  expect_law(r, spec,
             library(p, "spring", {{"stiffness_n_per_m", 300.0}, {"rest_position_m", 0.020}}),
             nominal(p));
}

TEST(PlantLaws, PositionRippleIsFixedAlongTheStroke) {
  const auto p = plant_with({{"position_ripple", 1.5},
                             {"position_ripple.period_m", 0.004},
                             {"position_ripple.phase_rad", 0.3}});
  const auto r = moves(p, {0.010, 0.022, 0.010}, 0.02);
  Model spec = nominal(p);
  spec.extra = [](const PlantTruth& s, double) {
    return -2.0 * s.nut_vel_m_s + 1.5 * std::sin(2 * kPi * s.nut_pos_m / 0.004 + 0.3);
  };
  Model default_period = nominal(p);
  default_period.extra = [](const PlantTruth& s, double) {
    return -2.0 * s.nut_vel_m_s + 1.5 * std::sin(2 * kPi * s.nut_pos_m / 0.005 + 0.3);
  };
  expect_law(r, spec,
             library(p, "position_ripple",
                     {{"amplitude_n", 1.5}, {"period_m", 0.004}, {"phase_rad", 0.3}}),
             default_period);
}

// ----------------------------------------------------------------- laws that scale F_m

TEST(PlantLaws, CouplingGainErrorScalesTheCoupling) {
  const auto p = plant_with({{"coupling_gain_error", 0.1}});
  const auto r = moves(p, {0.010, 0.025, 0.010}, 0.02);
  Model spec = nominal(p);
  spec.coupling = [p](const PlantTruth& s) { return 1.1 * base_coupling_n(p, s); };
  expect_law(r, spec, library(p, "coupling_gain_error", {{"gain", 1.1}}), nominal(p));
}

TEST(PlantLaws, GainDriftIsLinearInMinutesFromTheStart) {
  // Held still for 30 s, then moved: the coupling is 1 + r t/60 of its strength.
  const auto p = plant_with({{"gain_drift", -0.05}});
  const auto r = moves(p, {0.010, 0.025, 0.010}, 0.02, 0.05, 30.0);
  Model spec = nominal(p);
  spec.coupling = [p](const PlantTruth& s) {
    return (1.0 - 0.05 * s.t_s / 60.0) * base_coupling_n(p, s);
  };
  Model per_second = nominal(p);  // r taken per second instead of per minute
  per_second.coupling = [p](const PlantTruth& s) {
    return (1.0 - 0.05 * s.t_s / 1.0) * base_coupling_n(p, s);
  };
  expect_law(r, spec, library(p, "gain_drift", {{"gain_change_per_min", -0.05}}), per_second);
  EXPECT_GT(check(r, nominal(p)).worst_n, 0.1);  // and without the drift it does not fit either
}

TEST(PlantLaws, AngleRippleScalesTheCouplingOncePerScrewTurn) {
  const auto p = plant_with({{"angle_ripple", 0.1}, {"angle_ripple.phase_rad", 0.7}});
  const auto r = moves(p, {0.010, 0.022, 0.010}, 0.02);  // two screw turns each way
  Model spec = nominal(p);
  spec.coupling = [p](const PlantTruth& s) {
    return base_coupling_n(p, s) * (1.0 + 0.1 * std::sin(s.screw_angle_rad + 0.7));
  };
  // The old plant's form: the same number as an additive force in N.
  Model additive = nominal(p);
  additive.coupling = [p](const PlantTruth& s) {
    return base_coupling_n(p, s) + 0.1 * std::sin(s.screw_angle_rad + 0.7);
  };
  Model no_phase = nominal(p);
  no_phase.coupling = [p](const PlantTruth& s) {
    return base_coupling_n(p, s) * (1.0 + 0.1 * std::sin(s.screw_angle_rad));
  };
  expect_law(r, spec, library(p, "angle_ripple", {{"relative_amplitude", 0.1}, {"phase_rad", 0.7}}),
             additive, 0.3);
  EXPECT_GT(check(r, no_phase).worst_n, 0.3);
}

TEST(PlantLaws, EndEffectWeakensTheCouplingBySmoothstepNearBothEnds) {
  const auto p = plant_with({{"end_effect", 0.005}, {"end_effect.max_reduction", 0.3}});
  auto smooth = [](const PlantTruth& s) {
    const double d = std::min(s.nut_pos_m - 0.0, 0.040 - s.nut_pos_m);
    const double x = std::clamp((0.005 - d) / 0.005, 0.0, 1.0);
    return x * x * (3 - 2 * x);
  };
  Model spec = nominal(p);
  spec.coupling = [p, smooth](const PlantTruth& s) {
    return base_coupling_n(p, s) * (1 - 0.3 * smooth(s));
  };
  Model linear = nominal(p);  // the old plant's form: a linear ramp over the zone
  linear.coupling = [p](const PlantTruth& s) {
    const double d = std::min(s.nut_pos_m, 0.040 - s.nut_pos_m);
    return base_coupling_n(p, s) * (1 - 0.3 * std::clamp((0.005 - d) / 0.005, 0.0, 1.0));
  };
  const effects::Params lib = {{"max_reduction", 0.3}, {"zone_m", 0.005}};
  for (const auto& pts :
       {std::vector<double>{0.008, 0.0008, 0.008}, std::vector<double>{0.032, 0.0392, 0.032}}) {
    const auto r = moves(p, pts, 0.02);
    expect_law(r, spec, library(p, "end_effect", lib), linear);
  }
}

// ----------------------------------------------------------------- backlash

TEST(PlantLaws, BacklashScrewSitsWhereTheTorquePutsItWithinThePlay) {
  // The motor holds a gear output angle g; the screw is at the coupling's rest angle (F_m = 0)
  // clamped to g ± b/2, i.e. on the side set by the transmitted torque.
  const auto p = plant_with({{"backlash", 0.3}});
  const auto& a = p.actuator;
  const double phi0 = balancing_phase_rad(p.coupling, 0.0);  // where F_m = 0
  for (double off : {-0.4, -0.15, -0.05, 0.0, 0.05, 0.15, 0.4}) {
    const double pos = 0.02, rest = rest_angle_rad(pos, a.lead_m) + phi0;
    const double gear = rest + off;  // the gear output, off from where the screw wants to be
    SimulatedActuator plant(p, 1, pos, gear);
    SensorSample s;
    plant.read_sensors(0.01, s);
    ASSERT_EQ(plant.truth().nut_vel_m_s, 0.0) << off;  // |F_m| ≤ 0.15 rad·48 N/rad < F_c
    EXPECT_NEAR(plant.truth().screw_angle_rad, std::clamp(rest, gear - 0.15, gear + 0.15), 1e-9)
        << off;
    // The motor encoder reads the motor, not the screw.
    EXPECT_NEAR(screw_angle_rad_from_motor_rad(motor_angle_rad_from_counts(s.motor_counts, a), a),
                gear, 2 * kPi / a.motor_counts_per_rev / a.gear_ratio)
        << off;
  }
  // Under load the screw lags the motor by b/2 while F_m > 0 and leads by b/2 while F_m < 0.
  for (double load_n : {-20.0, 20.0}) {
    SimulatedActuator plant(p, 1, 0.02);
    LoadSetting l;
    l.kind = LoadSetting::Kind::constant;
    l.force_n = load_n;
    l.damping_n_s_per_m = 20.0;
    plant.set_load(l);
    plant.advance_to(0.5);
    const auto& t = plant.truth();
    const double gear = t.motor_angle_rad / a.gear_ratio;
    EXPECT_EQ(t.coupling_force_n > 0, load_n < 0);
    EXPECT_NEAR(t.screw_angle_rad, gear - 0.15 * (t.coupling_force_n > 0 ? 1.0 : -1.0), 1e-12)
        << load_n;
  }
  // And the dynamics use that screw angle.
  const auto r = moves(p, {0.010, 0.022, 0.010}, 0.02);
  const Check c = check(r, nominal(p));
  EXPECT_LT(c.worst_n, kTol_n);
  int at_edge = 0;
  for (const auto& s : r)
    at_edge +=
        std::abs(std::abs(s.screw_angle_rad - s.motor_angle_rad / a.gear_ratio) - 0.15) < 1e-12;
  EXPECT_GT(at_edge, 1000);
}

// ----------------------------------------------------------------- sensor delays

struct Logged {
  std::vector<double> pos, motor, load;  // truth after every substep
  std::vector<SensorSample> read;        // every 1 ms, at substep 20 k
};

Logged log_run(const PlantParams& p) {
  // Moves against a compliant stage (the load changes as the nut moves).
  SimulatedActuator plant(p, 1, 0.010);
  LoadSetting l;
  l.kind = LoadSetting::Kind::compliant;
  l.stiffness_n_per_m = 1500.0;
  l.damping_n_s_per_m = 5.0;
  l.anchor_pos_m = 0.015;
  plant.set_load(l);
  const auto& a = p.actuator;
  const double dt = substep_s(p);
  const auto target = path({0.010, 0.020, 0.012}, 0.03, 0.05);
  Logged g;
  for (int k = 0; k <= 20 * 900; ++k) {
    const double t = dt * k;
    if (k % 20 == 0) {  // a control tick: new command, sensors read
      plant.write_motor_angle(rest_angle_rad(target(t), a.lead_m) * a.gear_ratio);
      SensorSample s;
      plant.read_sensors(t, s);
      g.read.push_back(s);
    } else {
      plant.advance_to(t);
    }
    g.pos.push_back(plant.truth().nut_pos_m);
    g.motor.push_back(plant.truth().motor_angle_rad);
    g.load.push_back(plant.truth().load_force_n);
  }
  return g;
}

// How many readings miss the true value `lag` substeps earlier (linear between substeps); for
// the encoders the count must be the nearest one to that value.
int misses(const Logged& g, const ActuatorParams& a, double lag, char what) {
  int n = 0;
  for (std::size_t k = 0; k < g.read.size(); ++k) {
    const double at = 20.0 * static_cast<double>(k) - lag;
    if (at < 200) continue;  // before the delay line has history
    const auto j = static_cast<std::size_t>(std::floor(at));
    const double f = at - std::floor(at);
    auto value = [&](const std::vector<double>& x) { return x[j] + f * (x[j + 1] - x[j]); };
    const auto& s = g.read[k];
    auto outside = [](double c, std::int64_t count) {
      return std::abs(c - static_cast<double>(count)) > 0.5 + 1e-6;
    };
    if (what == 'p')
      n += outside(value(g.pos) / a.linear_count_m, s.linear_counts);
    else if (what == 'm')
      n += outside(value(g.motor) * a.motor_counts_per_rev / (2 * kPi), s.motor_counts);
    else
      n += std::abs(s.load_force_n - value(g.load)) > 1e-9;
  }
  return n;
}

TEST(PlantLaws, SensorDelayDelaysBothEncodersPurely) {
  const auto p = plant_with({{"sensor_delay", 0.0025}});  // 50 substeps
  const auto g = log_run(p);
  EXPECT_EQ(misses(g, p.actuator, 50, 'p'), 0);
  EXPECT_EQ(misses(g, p.actuator, 50, 'm'), 0);
  EXPECT_EQ(misses(g, p.actuator, 0, 'l'), 0);     // the load cell is not delayed
  EXPECT_GT(misses(g, p.actuator, 40, 'p'), 100);  // …and the delay is not shorter
  EXPECT_GT(misses(g, p.actuator, 60, 'm'), 100);  // …or longer
  EXPECT_GT(misses(g, p.actuator, 0, 'm'), 100);   // the angle lags too, not only the position
  // Not a whole number of substeps: linear between them.
  const auto q = plant_with({{"sensor_delay", 0.001225}});  // 24.5 substeps
  const auto h = log_run(q);
  EXPECT_EQ(misses(h, q.actuator, 24.5, 'p'), 0);
  EXPECT_EQ(misses(h, q.actuator, 24.5, 'm'), 0);
}

TEST(PlantLaws, LoadCellDelayDelaysTheForceReadingPurely) {
  const auto p = plant_with({{"load_cell_delay", 0.003}});  // 60 substeps
  const auto g = log_run(p);
  EXPECT_EQ(misses(g, p.actuator, 60, 'l'), 0);
  EXPECT_EQ(misses(g, p.actuator, 0, 'p'), 0);  // the encoders are not delayed
  EXPECT_EQ(misses(g, p.actuator, 0, 'm'), 0);
  EXPECT_GT(misses(g, p.actuator, 59, 'l'), 100);
  EXPECT_GT(misses(g, p.actuator, 61, 'l'), 100);
  const auto q = plant_with({{"load_cell_delay", 0.001225}});
  EXPECT_EQ(misses(log_run(q), q.actuator, 24.5, 'l'), 0);
}

TEST(PlantLaws, EffectKeysUseTheSpecsIdsAndCheckTheirRanges) {
  PlantEffects e;
  set_plant_effect(e, "angle_ripple", 0.05);
  set_plant_effect(e, "angle_ripple.phase_rad", -1.2);
  set_plant_effect(e, "end_effect", 0.005);
  set_plant_effect(e, "end_effect.max_reduction", 0.25);
  EXPECT_EQ(e.angle_ripple, 0.05);
  EXPECT_EQ(e.angle_ripple_phase_rad, -1.2);
  EXPECT_EQ(e.end_effect_zone_m, 0.005);
  EXPECT_EQ(e.end_effect_max_reduction, 0.25);
  EXPECT_THROW(set_plant_effect(e, "angle_ripple", 1.5),
               std::invalid_argument);  // not in N any more
  EXPECT_THROW(set_plant_effect(e, "end_effect.max_reduction", 2.0), std::invalid_argument);
  EXPECT_THROW(set_plant_effect(e, "backlash", -0.1), std::invalid_argument);
  EXPECT_THROW(set_plant_effect(e, "angle_ripple.amplitude", 0.1), std::invalid_argument);
  // Every plant id is an id of the spec's library, but friction_drift: a plant condition for the
  // drift flag (a friction rising in time), which the analysis's vocabulary does not have.
  for (const auto& k : plant_effect_keys()) {
    const std::string& key = k.name;
    EXPECT_FALSE(k.unit.empty()) << key << ": every key names its unit (\"1\" for a ratio)";
    if (key == "friction_drift") continue;
    const std::string id = key.substr(0, key.find('.'));
    EXPECT_NE(effects::find(id), nullptr) << key;
    if (key.find('.') != std::string::npos) {
      bool named = false;
      for (const auto& ps : effects::find(id)->params())
        named |= ps.name == key.substr(key.find('.') + 1);
      EXPECT_TRUE(named) << key << ": the shape key must carry the spec's parameter name";
    }
  }
}

}  // namespace
