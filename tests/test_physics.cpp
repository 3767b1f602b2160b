// Ties the physics core to the paper (eq. 2, 3, 6, 7) and to the signs of docs/conventions.md.
#include <gtest/gtest.h>

#include "test_tmp.hpp"

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

#include "maglead/physics/actuator.hpp"
#include "maglead/physics/calibration.hpp"
#include "maglead/physics/edge_tracker.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/physics/stick_filter.hpp"
#include "maglead/settings/settings.hpp"

using namespace maglead;
constexpr double kPi = std::numbers::pi;

TEST(PaperCalibration, Eq7AtQuarterLeadMatchesThePaper) {
  const auto cal = paper_calibration();
  // docs/conventions.md: eq. 7 at φ = ±π/2 gives about −44.6 N / +46.2 N.
  EXPECT_NEAR(cal.polynomial.load_force_n(kPi / 2), -44.6, 0.1);
  EXPECT_NEAR(cal.polynomial.load_force_n(-kPi / 2), 46.3, 0.15);
  EXPECT_NEAR(cal.polynomial.load_force_n(0.0), -4.28, 1e-12);
}

TEST(PaperCalibration, PeriodicModelFollowsPolynomialOnStableBranchAndRepeats) {
  const auto cal = paper_calibration();
  for (double p = -1.4; p <= 1.4; p += 0.05)
    EXPECT_NEAR(cal.periodic.load_force_n(p), cal.polynomial.load_force_n(p), 1.0) << p;
  for (double p = -3.0; p <= 3.0; p += 0.37)
    EXPECT_NEAR(cal.periodic.load_force_n(p), cal.periodic.load_force_n(p + 2 * kPi), 1e-9);
}

TEST(PaperCalibration, StableBranchAndPeaks) {
  const auto cal = paper_calibration();
  EXPECT_GT(cal.stable_max_rad, 1.2);
  EXPECT_LE(cal.stable_max_rad, kPi / 2);
  EXPECT_LT(cal.stable_min_rad, -1.2);
  EXPECT_NEAR(cal.peak_push_n, 45.3, 0.5);  // paper: about 44.5 N measured
  EXPECT_NEAR(cal.peak_pull_n, -46.3, 0.5);
}

TEST(PaperCalibration, PeriodicPeakIsTheLargestForceOverALead) {
  PeriodicForceModel m;
  m.mean_n = 2.0;
  m.cos_n = {-10.0};
  m.sin_n = {0.0};
  EXPECT_NEAR(m.peak_n(), 12.0, 1e-9);   // at φ = ±π: 2 + 10
  const auto cal = paper_calibration();  // past the stable branch it stays near the paper's peaks
  EXPECT_NEAR(cal.periodic.peak_n(), std::max(cal.peak_push_n, -cal.peak_pull_n), 3.0);
}

TEST(Phase, ScrewAheadOfNutIsPositiveAndPullsTheNutForward) {
  const double lead = 0.006;
  EXPECT_DOUBLE_EQ(phase_rad(0.0, 0.0, lead), 0.0);
  // One lead of nut travel is one screw turn.
  EXPECT_NEAR(rest_angle_rad(lead, lead), 2 * kPi, 1e-12);
  const double phi = phase_rad(0.3, 0.0, lead);
  EXPECT_GT(phi, 0.0);
  // F_m = −F̂_s: positive (along +p) for the screw ahead, beyond the eq. 7 offset.
  EXPECT_GT(-paper_calibration().polynomial.load_force_n(phi), 0.0);
  // Unwrapped: several turns stay continuous.
  EXPECT_NEAR(phase_rad(10 * kPi + 0.1, 5 * lead, lead), 0.1, 1e-9);
}

TEST(Encoders, CountsToAnglesAndPositions) {
  ActuatorParams a;
  EXPECT_NEAR(motor_angle_rad_from_counts(4096, a), 2 * kPi, 1e-12);
  EXPECT_NEAR(screw_angle_rad_from_motor_rad(2 * kPi * 6.6, a), 2 * kPi, 1e-12);
  EXPECT_NEAR(nut_pos_m_from_counts(1, a), 21.6e-6, 0.05e-6);
  EXPECT_EQ(linear_counts_from_m(nut_pos_m_from_counts(1234, a) + 1e-9, a), 1234);
  EXPECT_EQ(motor_counts_from_rad(-1e-9, a), -1);  // floor, like an encoder edge
  // One linear count is about 0.023 rad of phase (docs/conventions.md).
  EXPECT_NEAR(rest_angle_rad(a.linear_count_m, a.lead_m), 0.0226, 0.0005);
}

TEST(StaticEstimator, Eq6AddsCoulombInTheDirectionOfMotion) {
  StaticForceEstimator est(paper_calibration(), 7.5, 1e-4);
  const double fs = paper_calibration().polynomial.load_force_n(0.5);
  EXPECT_DOUBLE_EQ(est.load_force_n(0.5, 0.01), fs + 7.5);
  EXPECT_DOUBLE_EQ(est.load_force_n(0.5, -0.01), fs - 7.5);
  EXPECT_DOUBLE_EQ(est.load_force_n(0.5, 0.0), fs);
  EXPECT_DOUBLE_EQ(est.output_force_n(0.5, 0.0), -fs);
}

// After a step-out the phase sits leads away from the stable branch, where the polynomial's
// extrapolation reads millions of newtons: the estimate is the coupling's periodic law there,
// within the coupling's peaks, and the same a whole lead (2π) on.
TEST(StaticEstimator, PastTheStableBranchIsTheCouplingsPeriodicLaw) {
  const auto cal = paper_calibration();
  StaticForceEstimator est(cal, 0.0, 1e-4);
  const double slack_n = 0.05 * (cal.peak_push_n - cal.peak_pull_n);  // the periodic fit's error
  for (double phi = -40.0; phi <= 40.0; phi += 0.37) {
    const double f = est.output_force_n(phi, 0.0);
    EXPECT_LE(f, cal.peak_push_n + slack_n) << phi;
    EXPECT_GE(f, cal.peak_pull_n - slack_n) << phi;
  }
  const double slipped = 0.3 - 10 * std::numbers::pi;  // five leads away from 0.3 rad
  EXPECT_NEAR(est.output_force_n(slipped, 0.0), est.output_force_n(0.3, 0.0), slack_n);
  EXPECT_DOUBLE_EQ(est.output_force_n(0.3, 0.0), -cal.polynomial.load_force_n(0.3));
}

TEST(InverseEstimate, RoundTripsOnTheStableBranch) {
  const auto cal = paper_calibration();
  for (double f = -36.0; f <= 36.0; f += 3.0) {
    const auto r = phase_for_output_force(cal, f, 0.8);
    ASSERT_EQ(r.status, InverseStatus::ok) << f;
    EXPECT_NEAR(-cal.polynomial.load_force_n(r.phase_rad), f, 1e-6);
    EXPECT_GE(r.phase_rad, cal.stable_min_rad);
    EXPECT_LE(r.phase_rad, cal.stable_max_rad);
  }
  EXPECT_GT(phase_for_output_force(cal, 20.0, 0.8).phase_rad,
            phase_for_output_force(cal, 10.0, 0.8).phase_rad);
}

TEST(InverseEstimate, RefusesBeyondTheSafeFraction) {
  const auto cal = paper_calibration();
  const auto r = phase_for_output_force(cal, 0.81 * cal.peak_push_n, 0.8);
  EXPECT_EQ(r.status, InverseStatus::beyond_safe_limit);
  EXPECT_NEAR(r.limit_n, 0.8 * cal.peak_push_n, 1e-9);
  EXPECT_EQ(phase_for_output_force(cal, 0.81 * cal.peak_pull_n, 0.8).status,
            InverseStatus::beyond_safe_limit);
  EXPECT_EQ(phase_for_output_force(cal, NAN, 0.8).status, InverseStatus::beyond_safe_limit);
}

TEST(Calibration, RecoversAKnownQuinticWithFrictionAndPicksOrderFive) {
  const PolynomialForceModel truth{{-4.28, -47.6, 2.59, 8.51, -0.209, -0.378}};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<double> ph, vel, f;
  for (int i = 0; i < 20000; ++i) {
    const double p = 1.5 * std::sin(i * 0.001);
    const double v = std::cos(i * 0.001);
    ph.push_back(p);
    vel.push_back(v * 1e-3);
    f.push_back(truth.load_force_n(p) + (v > 0 ? 7.5 : -7.5) + noise(rng));
  }
  const auto r = calibrate_static_force(ph, vel, f);
  EXPECT_EQ(r.chosen_order, 5);
  EXPECT_NEAR(r.coulomb_n, 7.5, 0.05);
  for (double p = -1.4; p <= 1.4; p += 0.1)
    EXPECT_NEAR(r.calibration.polynomial.load_force_n(p), truth.load_force_n(p), 0.1);
  ASSERT_EQ(r.table.size(), 5u);
  EXPECT_GT(r.table[0].rmse_n, 3.0);          // a line cannot follow the curve
  EXPECT_NEAR(r.table[2].rmse_n, 0.3, 0.02);  // order 5 is down to the noise
}

TEST(Calibration, RefusesTooLittleData) {
  std::vector<double> ph(100, 0.1), vel(100, 1e-3), f(100, 1.0);
  EXPECT_THROW(calibrate_static_force(ph, vel, f), std::invalid_argument);
  std::vector<double> ph2(5000), vel2(5000, 1e-3), f2(5000, 0.0);
  for (int i = 0; i < 5000; ++i) ph2[i] = 0.2 * std::sin(i * 0.01);  // only ±0.2 rad
  EXPECT_THROW(calibrate_static_force(ph2, vel2, f2), std::invalid_argument);
}

TEST(VelocityEstimator, FollowsSlowAndFastQuantizedMotionAndStops) {
  const ActuatorParams a;
  for (double speed : {0.2e-3, 2e-3, 50e-3}) {
    EncoderVelocityEstimator v(1e-3, a.linear_count_m);
    double last = 0;
    for (int k = 0; k < 2000; ++k) {
      const double p = nut_pos_m_from_counts(linear_counts_from_m(speed * k * 1e-3, a), a);
      last = k == 0 ? (v.reset(p), 0.0) : v.update(p);
    }
    EXPECT_NEAR(last, speed, 0.25 * speed) << speed;  // within a count's timing jitter
  }
  EncoderVelocityEstimator v(1e-3, a.linear_count_m);
  v.reset(0.0);
  v.update(a.linear_count_m);
  for (int k = 0; k < 300; ++k) v.update(a.linear_count_m);
  EXPECT_EQ(v.velocity_m_s(), 0.0);  // no edge for longer than the hold: standing still
}

TEST(CalibrationFile, RoundTripsAndRejectsBadContent) {
  const std::string path = test_tmp_dir() + "/cal.toml";
  const auto cal = paper_calibration();
  save_calibration(path, cal);
  const auto back = load_calibration(path);
  for (double p = -3; p <= 3; p += 0.25) {
    EXPECT_NEAR(back.polynomial.load_force_n(p), cal.polynomial.load_force_n(p), 1e-6);
    EXPECT_NEAR(back.periodic.load_force_n(p), cal.periodic.load_force_n(p), 1e-6);
  }
  {
    std::ofstream bad(path);
    bad << "[calibration]\npolynomial_coeffs_ascending = [1.0, \"x\"]\n";
  }
  try {
    load_calibration(path);
    FAIL() << "accepted a non-numeric coefficient";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("polynomial_coeffs_ascending"), std::string::npos);
  }
  {
    // Found by fuzz_config: finite coefficients whose curve overflows at the branch's edge.
    std::ofstream bad(path);
    bad << "[calibration]\npolynomial_coeffs_ascending = [-4.28, -47.6, 1e308, 8.51, -8.209]\n"
        << "periodic_mean_n = 0\nperiodic_cos_n = [1.0]\nperiodic_sin_n = [1.0]\n";
  }
  try {
    load_calibration(path);
    FAIL() << "accepted a curve whose peak overflows";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not a finite number"), std::string::npos);
  }
  {
    std::ofstream bad(path);
    bad << "[actuator]\nlead_m = -1\n";
  }
  try {
    load_actuator_params(path);
    FAIL() << "accepted a negative lead";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("lead_m"), std::string::npos);
  }
  // Lengths typed in millimetres: refused at the key, with the value in metres to write.
  for (const auto& [line, said] :
       {std::pair{"lead_m = 6",
                  "[actuator] lead_m = 6 cannot be metres (no lead screw "
                  "advances a metre per turn); likely millimetres: write 0.006"},
        {"stroke_max_m = 40", "[actuator] stroke_max_m = 40 cannot be metres"},
        {"linear_count_m = 0.0216", "[actuator] linear_count_m = 0.0216 cannot be metres"}}) {
    std::ofstream(path) << "[actuator]\n" << line << "\n";
    try {
      load_actuator_params(path);
      ADD_FAILURE() << "accepted " << line;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path + ":2:"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(said), std::string::npos) << e.what();
    }
  }
  // The file's other tables are checked by whoever reads it, not only by serve: a misspelt key
  // under [control] or [reference_move], or a misspelt table, is refused at its line.
  for (const auto& [text, said] :
       {std::pair{"[control]\nstroke_maxx_m = 0.04\n",
                  ":3:17: [control] unknown key 'stroke_maxx_m'"},
        {"[reference_move]\nslow_ms = 0.01\n", ":3:11: [reference_move] unknown key 'slow_ms'"},
        {"[reference_move]\nslow_m_s = 5\n", ":3:12: [reference_move] slow_m_s must be"},
        {"[contrl]\nreached_dwell_s = 1\n", "actuator.toml unknown key 'contrl'"}}) {
    std::ofstream(path) << "[actuator]\n" << text;
    try {
      load_actuator_params(path);
      ADD_FAILURE() << "accepted " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(said), std::string::npos) << e.what();
    }
  }
}

namespace {
// A nut at constant speed v from 0, read by an encoder of count q at 1 kHz, `round` or floor;
// stopped after stop_s. Returns the tracker after each sample through `check`.
template <class Check>
void track(double v, double q, bool round, double stop_s, double end_s, Check check) {
  EdgeTracker tr({q, 2.0, 0.010});
  const auto read = [&](double p) { return (round ? std::round(p / q) : std::floor(p / q)) * q; };
  tr.reset(0.0, read(0.3 * q));
  for (int i = 1; i <= static_cast<int>(end_s * 1000); ++i) {
    const double t = i * 1e-3;
    // At rest for 0.1 s after the reset, then off at v (a real start: the break-away).
    const double p = 0.3 * q + v * std::clamp(t - 0.1, 0.0, stop_s - 0.1);
    check(t, p, tr.update(t, read(p)), tr);
  }
}
}  // namespace

TEST(EdgeTracker, SpeedAndPositionFromEdgesWhateverTheRounding) {
  const double q = 2e-5;
  for (const bool round : {true, false}) {
    for (const double v : {0.4e-3, 5e-3, -2e-3}) {
      double worst_pos = 0, worst_vel = 0;
      track(v, q, round, 10.0, 0.5, [&](double t, double p, EdgeEvent, const EdgeTracker& tr) {
        if (t < 0.2) return;  // a few edges in
        // Inside its count the nut is where the tracker says, to a fraction of a count;
        // floor and rounding differ by half a count in the reading, not in the tracker.
        const double off = round ? 0.0 : 0.5 * q;
        worst_pos = std::max(worst_pos, std::abs(tr.position_m() + off - p));
        worst_vel = std::max(worst_vel, std::abs(tr.velocity_m_s() - v));
      });
      EXPECT_LT(worst_pos, 0.5 * q) << "v " << v << " round " << round;
      // An edge is timed to one 1 ms sample; the speed over one interval to 1 ms in that interval.
      const double interval_s = q / std::abs(v);
      EXPECT_LT(worst_vel, std::abs(v) * (1e-3 / interval_s + 0.02)) << "v " << v << " " << round;
    }
  }
}

TEST(EdgeTracker, SeesTheStopWithinTwoEdgeIntervals) {
  const double q = 2e-5, v = 1e-3;  // an edge every 20 ms
  double stopped_at = -1;
  int starts = 0;
  track(v, q, true, 0.3, 0.6, [&](double t, double, EdgeEvent ev, const EdgeTracker& tr) {
    if (ev == EdgeEvent::started) ++starts;
    if (ev == EdgeEvent::stopped) {
      stopped_at = t;
      EXPECT_FALSE(tr.moving());
    }
  });
  EXPECT_EQ(starts, 1);
  ASSERT_GT(stopped_at, 0.3);
  EXPECT_LT(stopped_at, 0.3 + 3 * q / v);  // the last edge, then two intervals of quiet
}

TEST(StickFilter, KeepsItsMassInTheBandAndLeavesTheEdgeItStartedAt) {
  // A load that is always acting: a brisk walk, no pull.
  const UnheldLoadPrior walk{.walk_n2_per_s = 50.0, .relax_s = 0.0, .absent_s = 0.0};
  StickFilter f;
  // A load known at the top of the band, then free to move: paths that would have reached the
  // edge broke loose (they did not), so the estimate moves inward, and stays inside.
  f.start(-8.0, 8.0, 7.9, 0.3, 0.0, walk);
  const double m0 = f.estimate();
  EXPECT_NEAR(m0, 7.9, 0.25);
  double prev = m0;
  for (int i = 0; i < 500; ++i) {
    f.step(0.0, 7.9, walk, 1e-3);
    EXPECT_LE(f.estimate(), prev + 1e-9);
    prev = f.estimate();
  }
  EXPECT_LT(prev, m0 - 2.0);
  EXPECT_GT(prev, -8.0);
  EXPECT_EQ(f.absent_probability(), 0.0);
  // A drive change the friction takes up shifts the whole distribution (no walk, no pull).
  StickFilter g;
  g.start(-8.0, 8.0, 0.0, 0.3, 0.0, walk);
  g.step(2.0, 0.0, {.walk_n2_per_s = 1e-12, .relax_s = 0.0, .absent_s = 0.0}, 1e-3);
  EXPECT_NEAR(g.estimate(), 2.0, 0.05);
}

TEST(StickFilter, ALoadThatStoppedAtRestStaysAtRestUntilTheBandRulesItOut) {
  const UnheldLoadPrior hand{};  // comes and goes
  // The slide left the load near where loads rest (0), just inside the band's top edge: most
  // likely nothing acts, and the estimate stays at rest while the walk alone would push it
  // inward (away from the edge the nut did not break loose at).
  StickFilter f;
  f.start(-15.0, 0.5, 0.2, 0.3, 0.0, hand);
  EXPECT_GT(f.absent_probability(), 0.5);
  for (int i = 0; i < 500; ++i) f.step(0.0, 0.0, hand, 1e-3);
  EXPECT_NEAR(f.estimate(), 0.0, 0.05);
  StickFilter w;
  const UnheldLoadPrior walk{.absent_s = 0.0};
  w.start(-15.0, 0.5, 0.2, 0.3, 0.0, walk);
  for (int i = 0; i < 500; ++i) w.step(0.0, 0.0, walk, 1e-3);
  EXPECT_LT(w.estimate(), -0.5);
  // The drive falls by 1 N: in the filter's frame (load − drive) everything shifts up by 1 N and
  // rest lies outside the band: a load at rest would have broken the nut loose, so something
  // acts, and the estimate stays inside the band.
  f.step(1.0, 1.0, hand, 1e-3);
  EXPECT_EQ(f.absent_probability(), 0.0);
  EXPECT_LT(f.estimate(), 0.5);
  // A load stopped far from rest (a push held) is acting, whatever the prior's share.
  StickFilter p;
  p.start(-30.0, -14.0, -29.0, 0.3, 0.0, hand);
  EXPECT_EQ(p.absent_probability(), 0.0);
  EXPECT_NEAR(p.estimate(), -29.0, 0.25);
}
