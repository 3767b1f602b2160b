// PassiveLoadDrift on synthetic force control: a spring the loop presses back and forth is a
// passive load (the same force at the same position every time); the model's force estimate
// grows by g_ref / g as the coupling weakens. A load that is not a function of position (a hand)
// forms no reference; an anchor that moves shifts every window alike and is no drift.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <random>

#include "../../twin/src/passive_drift.hpp"

namespace maglead::twin {
namespace {

struct Load {
  double gain_per_min = 0.0;
  double anchor_m_per_s = 0.0;              // the spring's anchor moving
  bool hand = false;                        // a force that does not depend on the position
  double first_s = 0.0, first_scale = 1.0;  // the estimate scaled so over the first seconds
  double creep_bias_n = 0.0;  // held steps: the estimate's error while the nut creeps to a stop
};

/// The unit as the paper's actuator configures it: 7.5 N friction, 36 N rated, cells of 4 counts.
PassiveDriftSettings settings() {
  PassiveDriftSettings s;
  s.friction_n = 7.5;
  s.rated_n = 36.0;
  s.stroke_min_m = 0.0, s.stroke_max_m = 0.04, s.bin_m = 4 * 21.6e-6;
  s.creep_travel_m = 3 * 21.6e-6;
  return s;
}

/// 120 s of a ±4 mm sweep (0.25 Hz) against a 3000 N/m spring at mid-stroke, 1 kHz, noise
/// 0.2 N on the estimate; the nut sticks where it turns (|v| below 1 mm/s).
PassiveLoadDrift run(const Load& l) {
  PassiveLoadDrift d(settings());
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.2);
  constexpr double kW = 2 * M_PI * 0.25, kA = 0.004, kK = 3000.0;
  for (int k = 0; k < 120000; ++k) {
    const double t = k * 1e-3;
    const double p = 0.02 + kA * std::sin(kW * t), v = kA * kW * std::cos(kW * t);
    const int dir = v > 0 ? 1 : -1;
    const double g = 1.0 + l.gain_per_min * t / 60.0;
    const double load =
        l.hand ? 10.0 * std::sin(2 * M_PI * 0.37 * t) : -kK * (p - 0.02 - l.anchor_m_per_s * t);
    const double scale = t < l.first_s ? l.first_scale : 1.0;
    const double fhat = scale * load / g + dir * (7.5 - 7.5 / g) + noise(rng);
    d.tick(t, 1e-3, std::abs(v) > 1e-3, fhat, dir, p, 0.0);
  }
  return d;
}

/// The rated-force error in units of a warning's margin (sigmas standard errors, at least the
/// minimum change): 1 is where the flag's judgement would start.
double of_margin(const PassiveEstimate& e, const PassiveDriftSettings& s) {
  return std::abs(e.rated_n) / std::max(s.sigmas * e.rated_se_n, s.min_change * s.rated_n);
}

/// A PLC's force steps held, as the live test makes them: the setpoints 5, 10, 15, 20, −5, −10,
/// −15, 12, 8, 3, 0, 18, 6 N for 2.5 s each against a 2000 N/m spring at mid-stroke; the loop
/// takes the nut to each new balance at 20 mm/s and holds it there. Every slide is one step,
/// 0.1–0.7 s long and one way, so no 2 s window goes both ways. The last 0.1 mm of each slide
/// the nut creeps at 1 mm/s (under one encoder count per 20 ms block), where the estimate is off
/// by creep_bias_n along the motion.
PassiveLoadDrift run_holds(const Load& l, double duration_s,
                           const PassiveDriftSettings& s = settings(),
                           double* max_of_margin = nullptr) {
  PassiveLoadDrift d(s);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.2);
  constexpr double kK = 2000.0, kV = 0.02, kCreepV = 0.001, kCreep_m = 1e-4, kDt = 1e-3;
  constexpr double kSet[] = {5, 10, 15, 20, -5, -10, -15, 12, 8, 3, 0, 18, 6};
  double p = 0.02;
  for (int k = 0; k < static_cast<int>(duration_s / kDt); ++k) {
    const double t = k * kDt;
    const double set = kSet[static_cast<std::size_t>(t / 2.5) % std::size(kSet)];
    const double anchor = 0.02 + l.anchor_m_per_s * t, to = anchor + set / kK;
    const double left = std::abs(to - p), speed = left > kCreep_m ? kV : kCreepV;
    const double v = left > speed * kDt ? std::copysign(speed, to - p) : 0.0;
    p = v != 0.0 ? p + v * kDt : to;
    const int dir = v > 0 ? 1 : -1;
    const double g = 1.0 + l.gain_per_min * t / 60.0;
    const double creep = speed == kCreepV ? l.creep_bias_n * dir : 0.0;
    const double fhat = -kK * (p - anchor) / g + dir * (7.5 - 7.5 / g) + creep + noise(rng);
    d.tick(t, kDt, v != 0.0, fhat, dir, p, 0.0);
    if (max_of_margin != nullptr && d.updated())
      *max_of_margin = std::max(*max_of_margin, of_margin(d.estimate(), s));
  }
  return d;
}

TEST(PassiveLoadDrift, SpringRevisitedShowsTheCouplingWeaken) {
  const PassiveLoadDrift d = run({-0.05});
  ASSERT_TRUE(d.tracking());
  const PassiveEstimate& e = d.estimate();
  ASSERT_TRUE(e.scatter_measured);
  // About −9 % since the reference at 4 s, as a mean over the 8 s memory: a few % less.
  EXPECT_LT(e.gain_change, -0.06);
  EXPECT_GT(e.gain_change, -0.10);
  EXPECT_GT(e.rated_n, 4 * e.rated_se_n);
  // Zero load: α·F_c ≈ 0.6 N with the friction unchanged (within 0.15 N: the step's and the
  // stiffness's means weight the windows by their own variances, so their times differ a little).
  EXPECT_NEAR(e.zero_load_n, -e.gain_change * 7.5, 0.15);
}

TEST(PassiveLoadDrift, NoDriftNoChange) {
  const PassiveLoadDrift d = run({});
  ASSERT_TRUE(d.tracking());
  const PassiveEstimate& e = d.estimate();
  EXPECT_NEAR(e.gain_change, 0.0, 4 * e.gain_change_se + 0.002);
  EXPECT_NEAR(e.rated_n, 0.0, 4 * e.rated_se_n + 0.05);
}

TEST(PassiveLoadDrift, AMovingAnchorIsNoDrift) {
  const PassiveLoadDrift d = run({0.0, 2e-5});  // 2.4 mm (7 N) over the run
  ASSERT_TRUE(d.tracking());
  EXPECT_LT(std::abs(d.estimate().rated_n), 0.03 * 36.0);
}

// The first 4 s (the map's windows) estimate 5 % more force than the rest (a motion unlike the
// later one, as the step responses before a sweep of a recording with backlash): the window that
// checks the map disagrees by more than a warning's margin, the map is dropped and formed again;
// without the check the whole run would read as a 5 % gain rise.
TEST(PassiveLoadDrift, AMapLaterVisitsDoNotConfirmIsDropped) {
  const PassiveLoadDrift d = run({0.0, 0.0, false, 4.0, 1.05});
  ASSERT_TRUE(d.tracking());
  EXPECT_GT(d.reference_t(), 4.0);
  EXPECT_NEAR(d.estimate().gain_change, 0.0, 0.01);
}

// Held force steps (run_holds): each window slides one way only. Within the stretch the map was
// formed in, the spring's anchor is where the map found it, so such a window is compared with no
// offset of its own and its intercept is the step between the directions (−Δ₀·dir); with an own
// offset, as a window that went both ways has, no window resolved the step, the map was never
// checked and 120 s formed no reference.
TEST(PassiveLoadDrift, HeldForceStepsShowTheCouplingWeaken) {
  const PassiveLoadDrift d = run_holds({-0.05}, 120.0);
  ASSERT_TRUE(d.reference());
  ASSERT_TRUE(d.tracking());
  const PassiveEstimate& e = d.estimate();
  ASSERT_TRUE(e.scatter_measured);
  std::printf(
      "held steps, -5 %%/min, 120 s: reference %.1f s, gain %+.3f +- %.3f, zero load "
      "%+.2f +- %.2f N, rated %+.2f +- %.2f N\n",
      d.reference_t(), e.gain_change, e.gain_change_se, e.zero_load_n, e.zero_load_se_n, e.rated_n,
      e.rated_se_n);
  // About −9 % by the end since a reference at ~5 s, as a mean over the 8 s memory: a few % less.
  EXPECT_LT(e.gain_change, -0.05);
  EXPECT_GT(e.gain_change, -0.11);
  EXPECT_GT(e.rated_n, 4 * e.rated_se_n);
  EXPECT_GT(e.rated_n, 0.03 * 36.0);
}

TEST(PassiveLoadDrift, HeldForceStepsNoDriftNoChange) {
  const PassiveLoadDrift d = run_holds({}, 120.0);
  ASSERT_TRUE(d.tracking());
  const PassiveEstimate& e = d.estimate();
  ASSERT_TRUE(e.scatter_measured);
  EXPECT_NEAR(e.gain_change, 0.0, 4 * e.gain_change_se + 0.002);
  EXPECT_NEAR(e.rated_n, 0.0, 4 * e.rated_se_n + 0.05);
  EXPECT_NEAR(e.zero_load_n, 0.0, 4 * e.zero_load_se_n + 0.05);
}

// The loop's held steps end in a creep to the balance where the nut crosses under three encoder
// counts per block: the position's quantization, times the coupling's stiffness, is no longer
// averaged out of the estimate, and the loop stops at the same balance every cycle, so the error
// repeats (the in-process loop, DriftForceLoop: −0.5 N in the last blocks of the 12 → 8 N slide,
// the map's cells there from a slide passing through). A slide's creeping tail is dropped: the
// control stays well inside the margin, and with the tail kept it reaches the margin.
TEST(PassiveLoadDrift, HeldForceStepsCreepToAStopIsNoDrift) {
  const Load creep{.creep_bias_n = 0.5};
  double dropped = 0.0, kept = 0.0;
  const PassiveLoadDrift d = run_holds(creep, 120.0, settings(), &dropped);
  ASSERT_TRUE(d.tracking());
  PassiveDriftSettings keep = settings();
  keep.creep_travel_m = 0.0;
  run_holds(creep, 120.0, keep, &kept);
  std::printf("creep to a stop: rated-force error at most %.2f of the margin (%.2f with it kept)\n",
              dropped, kept);
  EXPECT_LT(dropped, 0.5);
  const PassiveEstimate& e = d.estimate();
  EXPECT_NEAR(e.gain_change, 0.0, 4 * e.gain_change_se + 0.002);
  EXPECT_NEAR(e.rated_n, 0.0, 4 * e.rated_se_n + 0.05);
}

TEST(PassiveLoadDrift, AForceThatIgnoresThePositionFormsNoReference) {
  const PassiveLoadDrift d = run({-0.05, 0.0, true});
  EXPECT_TRUE(d.seen());
  EXPECT_FALSE(d.reference());
  EXPECT_FALSE(d.tracking());
}

}  // namespace
}  // namespace maglead::twin
