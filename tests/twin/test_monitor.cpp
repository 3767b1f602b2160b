// TwinMonitor on the simulated plant (its own dynamics code, not the twin's): force estimate,
// step-out warning and flag, drift detection. Recordings are made here with fixed seeds.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "maglead/plant/scenario.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/recording/recording.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::twin {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TwinMonitorConfig test_config() {
  TwinMonitorConfig c;  // paper defaults: what config/ holds
  c.calibration = paper_calibration();
  return c;
}

/// The scenario's recording as the monitor reads it (through a file, as `twin-check` does).
Recording simulated_recording(const ScenarioOptions& opt, const std::string& tag) {
  const std::string path =
      std::string(MAGLEAD_TEST_TMP) + "/twin_" + tag + "_" + std::to_string(::getpid()) + ".csv";
  run_scenario(opt, path);
  Recording rec = read_recording(path);
  std::remove(path.c_str());
  return rec;
}

struct MonitorRun {
  double mae_twin_n = 0, mae_static_n = 0;
  double first_drift_s = kNaN;
  bool step_out = false, warning = false;
  double max_drift_statistic = 0;
  double healthy_fraction = 0;
  TwinOutputs at_drift{}, last{};
  std::vector<double> known_s;  // drift_known_s at each whole second of the recording
  /// Known-force time the flag had used by time t (s).
  double known_by(double t) const {
    const auto i = static_cast<std::size_t>(std::max(0.0, std::floor(t)));
    return known_s.empty() ? kNaN : known_s[std::min(i, known_s.size() - 1)];
  }
};

MonitorRun run_recording(const std::string& scenario, double duration_s, std::uint64_t seed,
                         double gain_drift_per_min = 0.0, const PlantEffects& effects = {},
                         bool feed_load_cell = true) {
  ScenarioOptions opt;
  opt.scenario = scenario;
  opt.duration_s = duration_s;
  opt.seed = seed;
  opt.plant.effects = effects;
  opt.plant.effects.gain_drift_per_min = gain_drift_per_min;
  const std::string path = std::string(MAGLEAD_TEST_TMP) + "/twin_" + std::to_string(::getpid()) +
                           "_" + scenario + "_" + std::to_string(seed) + ".csv";
  run_scenario(opt, path);
  const Recording rec = read_recording(path);
  const auto& t = rec.column("t_s");
  const auto& th = rec.column("screw_angle_rad");
  const auto& p = rec.column("nut_pos_m");
  const auto& load = rec.column("load_force_n");
  const std::vector<double>* fset = rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr;
  TwinMonitor mon(test_config());
  mon.reset(t[0], th[0], p[0]);
  MonitorRun r;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const auto o =
        mon.step({t[i], th[i], p[i], fset ? (*fset)[i] : kNaN, feed_load_cell ? load[i] : kNaN});
    r.mae_twin_n += std::abs(o.dynamic_output_force_est_n + load[i]);
    r.mae_static_n += std::abs(o.static_output_force_est_n + load[i]);
    if (o.drift_warning && std::isnan(r.first_drift_s)) r.first_drift_s = t[i], r.at_drift = o;
    r.healthy_fraction += o.healthy;
    r.last = o;
    r.step_out |= o.step_out;
    r.warning |= o.step_out_warning;
    r.max_drift_statistic = std::max(r.max_drift_statistic, o.drift_statistic);
    if (t[i] >= static_cast<double>(r.known_s.size())) r.known_s.push_back(o.drift_known_s);
  }
  r.healthy_fraction /= static_cast<double>(t.size());
  std::remove(path.c_str());
  r.mae_twin_n /= static_cast<double>(t.size());
  r.mae_static_n /= static_cast<double>(t.size());
  return r;
}

TEST(TwinMonitor, DynamicEstimateBeatsStaticOnHandPush) {
  // Seed 7 was not used when the observer's load prior was chosen.
  const MonitorRun r = run_recording("hand-push", 20.0, 7);
  std::printf("hand-push seed 7: MAE twin %.2f N, static %.2f N\n", r.mae_twin_n, r.mae_static_n);
  EXPECT_LT(r.mae_twin_n, 0.75 * r.mae_static_n);
  EXPECT_FALSE(r.step_out);
  EXPECT_FALSE(r.warning);
  EXPECT_FALSE(std::isfinite(r.first_drift_s));
}

// The analysis's twin check runs the observer without the open-loop twin beside it: the force
// estimate and the drift figures must be the same to the bit, on a recording that sticks, slips
// and is held in force control (mixed-moves has all three).
TEST(TwinMonitor, ForceEstimateDoesNotNeedTheOpenLoopTwin) {
  ScenarioOptions opt;
  opt.scenario = "mixed-moves";
  opt.duration_s = 25.0;
  opt.seed = 4;
  opt.plant.effects.viscous_friction_n_s_per_m = 5.0;
  const Recording rec = simulated_recording(opt, "open_loop");
  const auto& t = rec.column("t_s");
  const auto& th = rec.column("screw_angle_rad");
  const auto& p = rec.column("nut_pos_m");
  const auto& fset = rec.column("force_set_n");
  TwinMonitorConfig without = test_config();
  without.open_loop_twin = false;
  TwinMonitor full(test_config()), observer_only(without);
  std::size_t differ = 0, stuck = 0, predicted = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const TwinInputs in{t[i], th[i], p[i], fset[i], kNaN};
    const auto a = full.step(in), b = observer_only.step(in);
    differ += a.dynamic_output_force_est_n != b.dynamic_output_force_est_n ||
              a.drift_statistic != b.drift_statistic || a.friction_mode != b.friction_mode;
    stuck += a.friction_mode == 0;
    predicted += std::isfinite(b.predicted_nut_pos_m) || std::isfinite(b.residual_pos_m);
  }
  std::printf("%zu samples, %zu stuck: %zu differ\n", t.size(), stuck, differ);
  EXPECT_GT(stuck, t.size() / 10);  // the case holds the stick-slip logic, not only slides
  EXPECT_EQ(differ, 0U);
  EXPECT_EQ(predicted, 0U);  // without the twin nothing claims to be its prediction
}

TEST(TwinMonitor, HealthyForceControlRaisesNothing) {
  const MonitorRun r = run_recording("force-steps", 60.0, 5);
  std::printf(
      "force-steps seed 5: MAE twin %.2f N, static %.2f N, drift statistic max %.2f, "
      "gain %.3f +/- %.3f, healthy %.1f %%\n",
      r.mae_twin_n, r.mae_static_n, r.max_drift_statistic, r.last.drift_gain_estimate,
      r.last.drift_gain_stderr, 100 * r.healthy_fraction);
  EXPECT_FALSE(std::isfinite(r.first_drift_s));
  // The plant is the model: the gain is 1 within a few of its standard errors, and the twin
  // explains the encoders within their resolution nearly all the time.
  ASSERT_TRUE(std::isfinite(r.last.drift_gain_estimate));
  EXPECT_NEAR(r.last.drift_gain_estimate, 1.0, std::max(0.01, 4 * r.last.drift_gain_stderr));
  EXPECT_GE(r.healthy_fraction, 0.99);
  EXPECT_FALSE(r.step_out);
  EXPECT_FALSE(r.warning);
  EXPECT_LT(r.mae_twin_n, r.mae_static_n);
}

// The drift flag reads no load cell: it judges free moves (no contact), where the force the
// model needs is known. The project's plant, 120 s of position-moves (5, 20 and 50 mm/s, a
// constant 2 N load with a 10 N·s/m drag, which the flag's nuisance terms take up).
MonitorRun moves(double gain_drift_per_min, const PlantEffects& e = {}, bool load_cell = false,
                 std::uint64_t seed = 4) {
  return run_recording("position-moves", 120.0, seed, gain_drift_per_min, e, load_cell);
}

/// The warning comes after the reference and within the 30 s of t_cross (when the true
/// change crosses the physical minimum after the reference).
void expect_in_time(const MonitorRun& r, double t_cross, const char* what) {
  const auto& o = r.at_drift;
  std::printf(
      "%s: reference at %.1f s, change crosses the minimum at %.1f s, warning at %.1f s\n"
      "  %s [reason %d]\n",
      what, o.drift_reference_t_s, t_cross, r.first_drift_s, drift_message(o).c_str(),
      static_cast<int>(o.drift_reason));
  ASSERT_TRUE(std::isfinite(r.first_drift_s)) << what;
  EXPECT_LE(r.first_drift_s, t_cross + 30.0) << "seen too late";
  EXPECT_GT(r.first_drift_s, o.drift_reference_t_s);
}

/// A gain falling by loss_per_min from 1 at t = 0: warned within 30 s of crossing 3 % below its
/// value at the reference.
void expect_loss_in_time(const MonitorRun& r, double loss_per_min, const char* what) {
  const double g_ref = 1.0 - loss_per_min * r.at_drift.drift_reference_t_s / 60.0;
  expect_in_time(r, 60.0 * (1.0 - 0.97 * g_ref) / loss_per_min, what);
}

/// A control without drift: compared (the reference formed and later stretches tracked) and
/// never warned.
void expect_quiet_and_tracking(const MonitorRun& r, const char* what) {
  std::printf("%s, no drift: statistic max %.2f; at the end %s\n", what, r.max_drift_statistic,
              drift_figures_text(r.last.drift_now).c_str());
  EXPECT_FALSE(std::isfinite(r.first_drift_s))
      << what << ": " << drift_message(r.at_drift) << " at " << r.first_drift_s;
  EXPECT_EQ(r.last.drift_observability, DriftObservability::tracking)
      << what << ": nothing compared";
}

TEST(TwinMonitor, CouplingLossFlaggedFromFreeMovesWithoutLoadCell) {
  // −5 %/min: 10 % over the two minutes. Warned within 30 s of the gain crossing 3 % below its
  // value at the reference; the moves (one acceleration, speeds where C·v is 0.1 N) cannot tell
  // gain from friction, and the message says so.
  const MonitorRun r = moves(-0.05);
  expect_loss_in_time(r, 0.05, "gain -5 %/min");
  const auto& o = r.at_drift;
  EXPECT_TRUE(o.drift_reason == DriftReason::error_rose ||
              o.drift_reason == DriftReason::gain_fell);
  EXPECT_GT(o.drift_at_warning.zero_load_n, 0.0);  // a weaker coupling: the estimate overstates
  if (!o.drift_at_warning.separable) {
    EXPECT_NE(drift_message(o).find("cannot be told apart"), std::string::npos);
  }
  // The same run with the load cell fed: the same verdict at the same tick (the flag never
  // reads it).
  const MonitorRun with = moves(-0.05, {}, true);
  EXPECT_EQ(with.first_drift_s, r.first_drift_s);
  EXPECT_EQ(with.at_drift.drift_reason, o.drift_reason);
  EXPECT_TRUE(std::isnan(r.last.drift_gain_estimate));  // no load cell, no check gain
}

TEST(TwinMonitor, FastCouplingLossFlaggedWithoutLoadCell) {
  // −20 %/min for 40 s (not flagged before: the fast change inflated the standard errors and the
  // estimate was then not judged at all). Within 30 s of the gain crossing 3 % below its value at
  // the reference.
  const MonitorRun r = run_recording("position-moves", 40.0, 4, -0.20, {}, false);
  expect_loss_in_time(r, 0.20, "gain -20 %/min");
  EXPECT_GT(r.at_drift.drift_at_warning.zero_load_n, 0.0);
}

TEST(TwinMonitor, FrictionRiseFlaggedFromFreeMovesWithoutLoadCell) {
  // +1 N/min: 2 N over the two minutes (the plant's coulomb_drift_n_per_min). Warned within 30 s
  // of the rise crossing 1 N after the reference.
  PlantEffects e;
  e.coulomb_drift_n_per_min = 1.0;
  const MonitorRun r = moves(0.0, e);
  expect_in_time(r, r.at_drift.drift_reference_t_s + 60.0, "friction +1 N/min");
  const auto& o = r.at_drift;
  EXPECT_TRUE(o.drift_reason == DriftReason::error_rose ||
              o.drift_reason == DriftReason::friction_rose);
  // The zero-load figure is the friction change itself (the estimate assumes the old friction),
  // late by about the forgetting time constant.
  const double true_change = (r.first_drift_s - o.drift_reference_t_s) / 60.0;
  EXPECT_GT(o.drift_at_warning.zero_load_n, 0.0);
  EXPECT_LT(o.drift_at_warning.zero_load_n, true_change + 4 * o.drift_at_warning.zero_load_se_n);
}

// A payload on a vertical axis: offset 2.5 N along +p on the moves (with the scenario's own 2 N
// load, the coupling force differs by ~5 N between the directions). A gain loss of 7 % over the
// 63 s is flagged within 30 s of crossing 3 % and not named friction; a friction rise of 2 N/min
// under the same offset is flagged and not named gain.
TEST(TwinMonitor, OffsetLoadGainLossAndFrictionRiseWithoutLoadCell) {
  PlantEffects e;
  e.offset_n = 2.5;
  const MonitorRun gain = run_recording("position-moves", 63.0, 4, -0.0667, e, false);
  expect_loss_in_time(gain, 0.0667, "offset 2.5 N, gain -6.67 %/min");
  EXPECT_TRUE(gain.at_drift.drift_reason == DriftReason::gain_fell ||
              gain.at_drift.drift_reason == DriftReason::error_rose);
  EXPECT_GT(gain.at_drift.drift_at_warning.zero_load_n, 0.0);
  e.coulomb_drift_n_per_min = 2.0;
  const MonitorRun friction = run_recording("position-moves", 63.0, 4, 0.0, e, false);
  std::printf("offset 2.5 N, friction +2 N/min: warning at %.1f s, %s [reason %d]\n",
              friction.first_drift_s, drift_message(friction.at_drift).c_str(),
              static_cast<int>(friction.at_drift.drift_reason));
  ASSERT_TRUE(std::isfinite(friction.first_drift_s));
  EXPECT_NE(friction.at_drift.drift_reason, DriftReason::gain_fell);
  EXPECT_NE(friction.at_drift.drift_reason, DriftReason::gain_rose);
}

// Force control against a spring: no free move, but the spring is a passive load the loop
// revisits (the same force at the same position), so the flag maps the force estimate over
// position and compares later visits with the map (twin/src/passive_drift.cpp). 120 s of
// force-steps (steps, ramps, a 0.2-2 Hz sweep) losing 5 %/min: flagged within 30 s of the gain
// crossing 3 % below its value at the reference, named as gain (the load's range of forces tells
// gain from friction).
TEST(TwinMonitor, ForceStepsDriftFlaggedFromAPassiveLoadWithoutLoadCell) {
  const MonitorRun r = run_recording("force-steps", 120.0, 5, -0.05, {}, false);
  expect_loss_in_time(r, 0.05, "force-steps, gain -5 %/min");
  const auto& f = r.at_drift.drift_at_warning;
  EXPECT_TRUE(f.separable);
  EXPECT_EQ(r.at_drift.drift_reason, DriftReason::gain_fell);
  EXPECT_LT(f.gain_change, -0.01);
  EXPECT_GT(f.rated_n, 0.0);  // a weaker coupling: the estimate overstates
  // The same verdict with the load cell fed: Replay.EveryTickOnceAndTheFlagIgnoresTheLoadCell
  // (force steps too, tick by tick).
}

// The controls: the same force-steps without drift are compared (the map forms and later
// windows are judged against it) and not warned; a hand pushing the nut past a held screw is no
// passive load pressed by the loop: not observable, no warning.
TEST(TwinMonitor, ForceStepsAndHandPushesWithoutDriftRaiseNoDriftWarning) {
  const MonitorRun steps = run_recording("force-steps", 120.0, 5, 0.0, {}, false);
  expect_quiet_and_tracking(steps, "force-steps 120 s");
  EXPECT_GT(steps.max_drift_statistic, 0.0) << "never judged";
  const MonitorRun hand = run_recording("hand-push", 60.0, 3, 0.0, {}, false);
  EXPECT_FALSE(std::isfinite(hand.first_drift_s)) << drift_message(hand.at_drift);
  EXPECT_EQ(hand.last.drift_observability, DriftObservability::none);
}

// A PLC's force steps held 2.5 s each (`simulate --scenario force-holds`, 2000 N/m): the nut
// slides one way at each step for a fraction of a second, so no 2 s window goes both ways. Such a
// window, compared within the map's own stretch, takes the step as its intercept (the load is
// where the map found it); with an offset of its own it resolved no step and 150 s formed no
// reference. −5 %/min flagged within 30 s of the crossing, as gain; the control never warns.
TEST(TwinMonitor, HeldForceStepsDriftFlaggedWithoutLoadCell) {
  const MonitorRun r = run_recording("force-holds", 100.0, 1, -0.05, {}, false);
  expect_loss_in_time(r, 0.05, "force-holds, gain -5 %/min");
  EXPECT_EQ(r.at_drift.drift_reason, DriftReason::gain_fell);
  const MonitorRun control = run_recording("force-holds", 150.0, 1, 0.0, {}, false);
  expect_quiet_and_tracking(control, "force-holds 150 s");
}

// Force control and hand pushes in turn (`simulate --scenario mixed`: 8 s of force steps, ramps
// and a sweep against a spring, 9 s of hand pushes with the screw held; the spring re-engages
// where the hand left the nut, 1.4 mm away each time). The passive load's evidence spans the hand
// segments: its map stays in the first stretch's frame and each later stretch is compared with
// its own offset. −10.6 %/min is 9 % over the 51 s.
TEST(TwinMonitor, MixedForceStepsAndHandPushesDriftFlaggedWithoutLoadCell) {
  const MonitorRun r = run_recording("mixed", 51.0, 1, -0.106, {}, false);
  expect_loss_in_time(r, 0.106, "mixed, gain -10.6 %/min");
  EXPECT_EQ(r.at_drift.drift_reason, DriftReason::gain_fell);
  EXPECT_LT(r.at_drift.drift_at_warning.gain_change, -0.01);
}

TEST(TwinMonitor, MixedForceStepsAndHandPushesWithoutDriftRaiseNoDriftWarning) {
  const MonitorRun r = run_recording("mixed", 51.0, 1, 0.0, {}, false);
  std::printf("mixed 51 s, no drift: statistic max %.2f; at the end %s\n", r.max_drift_statistic,
              drift_figures_text(r.last.drift_now).c_str());
  EXPECT_FALSE(std::isfinite(r.first_drift_s)) << drift_message(r.at_drift);
  EXPECT_EQ(r.last.drift_observability, DriftObservability::tracking) << "nothing compared";
  EXPECT_GT(r.max_drift_statistic, 0.0) << "never judged";
  // And "none" because it saw none, not because it could not see: at the end the gain change is
  // known to better than the minimum change at the flag's significance, and within it.
  const auto& f = r.last.drift_now;
  const TwinMonitorConfig c = test_config();
  ASSERT_TRUE(f.separable);
  EXPECT_LE(c.drift_sigmas * f.gain_change_se, c.drift_min_change);
  EXPECT_LE(std::abs(f.gain_change), c.drift_sigmas * f.gain_change_se);
}

// A statistic past its margin warns even when the recording ends, or the force-control stretch
// stops, before two seconds of clock have passed: the window of force control that moved it past
// is itself those seconds of evidence. Mixed, −6 %/min, 41 s: the statistic passes the margin
// (1.18) with the window that closes at 40 s; the recording ends at 41 s.
TEST(TwinMonitor, MixedDriftPastItsMarginAtTheEndWarns) {
  const MonitorRun r = run_recording("mixed", 41.0, 1, -0.06, {}, false);
  expect_loss_in_time(r, 0.06, "mixed 41 s, gain -6 %/min");
  EXPECT_EQ(r.at_drift.drift_reason, DriftReason::gain_fell);
  EXPECT_GE(r.max_drift_statistic, 1.0);
}

// Hand pushes, free moves and force control in turn (`simulate --scenario mixed-moves`: 6 s of
// force control against a spring, 8 s of hand pushes with the screw held, 7 s of point-to-point
// moves with nothing touching the nut). Each segment starts where the last left the nut, so the
// spring's anchor moves by up to the stroke between force-control segments. A direction-
// independent load of 2.5 N throughout, no load cell. −6.67 %/min: flagged within 30 s of the
// gain crossing 3 % below its value at the reference, named as gain.
TEST(TwinMonitor, HandMovesAndForceControlDriftFlaggedWithoutLoadCell) {
  PlantEffects e;
  e.offset_n = 2.5;
  const MonitorRun r = run_recording("mixed-moves", 84.0, 1, -0.0667, e, false);
  expect_loss_in_time(r, 0.0667, "mixed-moves, offset 2.5 N, -6.67 %/min");
  EXPECT_EQ(r.at_drift.drift_reason, DriftReason::gain_fell);
  EXPECT_LT(r.at_drift.drift_at_warning.gain_change, -0.01);
}

// The control: the same, without drift, compared and not warned.
TEST(TwinMonitor, HandMovesAndForceControlWithoutDriftRaiseNoDriftWarning) {
  PlantEffects e;
  e.offset_n = 2.5;
  const MonitorRun r = run_recording("mixed-moves", 126.0, 1, 0.0, e, false);
  std::printf("mixed-moves 126 s, offset 2.5 N, no drift: statistic max %.2f; at the end %s\n",
              r.max_drift_statistic, drift_figures_text(r.last.drift_now).c_str());
  EXPECT_FALSE(std::isfinite(r.first_drift_s)) << drift_message(r.at_drift);
  EXPECT_EQ(r.last.drift_observability, DriftObservability::tracking) << "nothing compared";
  EXPECT_GT(r.max_drift_statistic, 0.0) << "never judged";
}

/// Seconds from the gain crossing 3 % below its value at t = 0 (stricter than from the
/// reference) to the warning, printed; NaN when not warned.
double crossing_to_warning_s(const MonitorRun& r, double loss_per_min, const char* what) {
  const double t_cross = 60.0 * 0.03 / loss_per_min;
  const double delay_s = r.first_drift_s - t_cross;
  std::printf("%s: 3 %% crossed at %.1f s, warning at %.1f s: %+.1f s after the crossing\n  %s\n",
              what, t_cross, r.first_drift_s, delay_s, drift_message(r.at_drift).c_str());
  return delay_s;
}

// A slow drift over mixed moves (`simulate --scenario mixed-moves`, no offset): the gain falls by
// 6 % over 154 s, crossing 3 % at 76.9 s, and is flagged within 30 s of that crossing. Seeds
// change the hand segments, and with them where the spring's anchor lies in each force segment.
TEST(TwinMonitor, MixedMovesSlowDriftFlaggedWithin30sOfTheCrossing) {
  constexpr double kLossPerMin = 0.06 * 60.0 / 154.0;
  for (const std::uint64_t seed : {2, 3}) {
    const MonitorRun r = run_recording("mixed-moves", 154.0, seed, -kLossPerMin, {}, false);
    const std::string what = "mixed-moves 154 s, gain -6 %, seed " + std::to_string(seed);
    ASSERT_TRUE(std::isfinite(r.first_drift_s)) << what << ": not flagged";
    EXPECT_LE(crossing_to_warning_s(r, kLossPerMin, what.c_str()), 30.0) << what;
    EXPECT_TRUE(r.at_drift.drift_reason == DriftReason::gain_fell ||
                r.at_drift.drift_reason == DriftReason::error_rose)
        << what;
  }
}

// Documents a known lag (issue 44, item 2): the same scenario losing 10 % over 154 s crosses 3 %
// at 46.2 s and is flagged at 86.0 s (+39.8 s), seeds 1-7 alike (a seed changes the hand
// segments only). Why: the force segments of 42-48 s and 63-69 s press the spring with the nut
// at 33-39 mm, within the end zone (one lead of the 40 mm stroke end) where no tick is evidence
// (an end effect the model lacks would read as drift there when compared at a shift), so their
// windows keep 17 blocks (20 ms each) at 33-34 mm per segment instead of about 120; the free
// moves meet their conditions first at 39-41 s and again only at 60-62 s, the third pass-to-pass
// difference at 78.8 s. From the crossing to 30 s after it the flag gains 4.1 s of known-force
// time: 0.7 s of those blocks, 3.4 s of free moves whose scatter is not yet measured. Asserted:
// flagged, as a weaker coupling, within the run; the lag is printed (once within 30 s, make it
// the 30 s assertion of MixedMovesSlowDriftFlaggedWithin30sOfTheCrossing).
TEST(TwinMonitor, MixedMovesFasterDriftFlaggedLateKnownGap) {
  constexpr double kLossPerMin = 0.10 * 60.0 / 154.0;
  const double t_cross = 60.0 * 0.03 / kLossPerMin;
  for (const std::uint64_t seed : {2, 3}) {
    const MonitorRun r = run_recording("mixed-moves", 154.0, seed, -kLossPerMin, {}, false);
    const std::string what = "mixed-moves 154 s, gain -10 %, seed " + std::to_string(seed);
    ASSERT_TRUE(std::isfinite(r.first_drift_s)) << what << ": not flagged";
    crossing_to_warning_s(r, kLossPerMin, (what + " (known lag)").c_str());
    std::printf("  known-force time used: %.1f s at the crossing, %.1f s 30 s after it\n",
                r.known_by(t_cross), r.known_by(t_cross + 30.0));
    EXPECT_GT(r.at_drift.drift_at_warning.zero_load_n, 0.0);  // a weaker coupling: overstated
  }
}

// Every effect of docs/effects.md that is not a drift (of the size found on the bench), on the
// moves: no warning, and the flag really compared (reference formed), so "none" means "none".
// With a 5 % angle ripple the reference forms late (45 s) and too few passes of one condition
// follow within the minute to measure their scatter: compared, not judged, and the test says so.
// Two are not compared, and say so: with Stribeck friction the nut stick-slips through the
// moves (the screw does not drive it smoothly, so no stretch passes as free), and a 0.9 N ripple
// every 5 mm leaves the reference short of its precision in a minute.
struct Control {
  const char* name;
  double PlantEffects::*field;
  double value;
  bool compared = true;
  bool judged = true;  // compared, and the scatter between passes measured within the minute
};
const Control kControls[] = {
    {"none", &PlantEffects::offset_n, 0.0},
    {"coulomb_friction +1.5 N", &PlantEffects::coulomb_friction_n, 1.5},
    {"viscous_friction +5 N s/m", &PlantEffects::viscous_friction_n_s_per_m, 5.0},
    {"asymmetric_friction 1.5 N", &PlantEffects::asymmetric_friction_n, 1.5},
    {"stribeck_friction 4 N", &PlantEffects::stribeck_friction_n, 4.0, false},
    {"offset -3.5 N", &PlantEffects::offset_n, -3.5},
    {"spring 200 N/m", &PlantEffects::spring_n_per_m, 200.0},
    {"mass_error +0.05 kg", &PlantEffects::mass_error_kg, 0.05},
    {"coupling_gain_error -5 %", &PlantEffects::coupling_gain_error, -0.05},
    {"angle_ripple 5 %", &PlantEffects::angle_ripple, 0.05, true, false},
    {"position_ripple 0.9 N", &PlantEffects::position_ripple_n, 0.9, false},
    {"end_effect 5 mm", &PlantEffects::end_effect_zone_m, 0.005},
    {"backlash 0.09 rad", &PlantEffects::backlash_rad, 0.09},
    {"sensor_delay 2 ms", &PlantEffects::sensor_delay_s, 0.002},
    {"load_cell_delay 5 ms", &PlantEffects::load_cell_delay_s, 0.005},
    {"external_disturbance 5 N pulses", &PlantEffects::external_disturbance_n, 5.0},
};

/// A control's recording without load cell through the monitor: printed, and no warning expected.
MonitorRun run_control(const Control& c, const char* scenario, double duration_s,
                       std::uint64_t seed) {
  PlantEffects e;
  e.*(c.field) = c.value;
  MonitorRun r = run_recording(scenario, duration_s, seed, 0.0, e, false);
  std::printf("%s %.0f s, %s: statistic max %.2f, %.1f s of known-force stretches; at the end %s\n",
              scenario, duration_s, c.name, r.max_drift_statistic, r.last.drift_known_s,
              drift_figures_text(r.last.drift_now).c_str());
  EXPECT_FALSE(std::isfinite(r.first_drift_s))
      << drift_message(r.at_drift) << " at " << r.first_drift_s;
  return r;
}

class NoDriftControl : public ::testing::TestWithParam<int> {};

TEST_P(NoDriftControl, NoWarningOnMoves) {
  const Control& c = kControls[GetParam()];
  const MonitorRun r =
      run_control(c, "position-moves", 60.0, 11 + static_cast<std::uint64_t>(GetParam()));
  if (c.compared) {
    EXPECT_EQ(r.last.drift_observability, DriftObservability::tracking) << "nothing compared";
    EXPECT_TRUE(std::isfinite(r.last.drift_now.zero_load_n)) << "no figures: nothing compared";
    if (c.judged) {
      EXPECT_GT(r.max_drift_statistic, 0.0) << "never judged";
    } else {
      EXPECT_EQ(r.max_drift_statistic, 0.0) << "now judged: update";
    }
  } else {
    EXPECT_NE(r.last.drift_observability, DriftObservability::tracking) << "now compared: update";
  }
  EXPECT_FALSE(r.step_out);
}

INSTANTIATE_TEST_SUITE_P(TwinMonitor, NoDriftControl,
                         ::testing::Range(0, static_cast<int>(std::size(kControls))));

// The non-drift effects that warned falsely on 126 s of mixed-moves (seed 2, no load cell) while
// a window compared at the shift of a moved anchor counted as precise as one with the shift known
// (issue 23): an error tied to the nut's absolute position read as gain there.
const Control kMixedControls[] = {
    {"coulomb_friction +1.5 N", &PlantEffects::coulomb_friction_n, 1.5},
    {"position_ripple 0.9 N", &PlantEffects::position_ripple_n, 0.9},
    {"end_effect 5 mm", &PlantEffects::end_effect_zone_m, 0.005},
    {"sensor_delay 2 ms", &PlantEffects::sensor_delay_s, 0.002},
};

class MixedMovesNoDriftControl : public ::testing::TestWithParam<int> {};

TEST_P(MixedMovesNoDriftControl, NoWarningAtAMovedAnchor) {
  const MonitorRun r = run_control(kMixedControls[GetParam()], "mixed-moves", 126.0, 2);
  EXPECT_EQ(r.last.drift_observability, DriftObservability::tracking) << "nothing compared";
}

INSTANTIATE_TEST_SUITE_P(TwinMonitor, MixedMovesNoDriftControl,
                         ::testing::Range(0, static_cast<int>(std::size(kMixedControls))));

TEST(TwinMonitor, DriftWarningLatchesUntilCleared) {
  // −10 %/min on the moves: the warning comes, stays set while the run goes on, and
  // clear_drift() (what a fault_reset edge does) clears it and restarts the reference.
  ScenarioOptions opt;
  opt.scenario = "position-moves";
  opt.duration_s = 90.0;
  opt.seed = 8;
  opt.plant.effects.gain_drift_per_min = -0.10;
  const Recording rec = simulated_recording(opt, "latch");
  const auto& t = rec.column("t_s");
  TwinMonitor mon(test_config());
  mon.reset(t[0], rec.column("screw_angle_rad")[0], rec.column("nut_pos_m")[0]);
  double t_warn = kNaN;
  bool dropped = false, cleared = false, after_clear = false;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const auto o =
        mon.step({t[i], rec.column("screw_angle_rad")[i], rec.column("nut_pos_m")[i], kNaN});
    if (o.drift_warning && std::isnan(t_warn)) t_warn = t[i];
    if (std::isfinite(t_warn) && !cleared) dropped |= !o.drift_warning;
    if (std::isfinite(t_warn) && !cleared && t[i] > t_warn + 5.0) {
      mon.clear_drift();
      cleared = true;
      continue;
    }
    if (cleared && !after_clear) {
      after_clear = true;
      EXPECT_FALSE(o.drift_warning);
      EXPECT_EQ(o.drift_reason, DriftReason::none);
      EXPECT_NE(o.drift_observability, DriftObservability::tracking);
    }
  }
  ASSERT_TRUE(std::isfinite(t_warn));
  EXPECT_FALSE(dropped);  // latched
  EXPECT_TRUE(after_clear);
}

TEST(TwinMonitor, OverloadRampIsWarnedBeforeStepOutAndFlagged) {
  // Screw held; a load pulls the nut along −p, rising at 15 N/s past the coupling's peak.
  PlantParams plant = paper_like_plant();
  const ActuatorParams& act = plant.actuator;
  SimulatedActuator sim(plant, 99, 0.02);
  TwinMonitor mon(test_config());
  const double screw_motor = rest_angle_rad(0.02, act.lead_m) * act.gear_ratio;
  double t_warn = kNaN, t_flag = kNaN, t_slip = kNaN;
  SensorSample s;
  for (int k = 0; k <= 5000; ++k) {
    const double t = k * 1e-3;
    LoadSetting load;
    load.kind = LoadSetting::Kind::constant;
    load.force_n = -15.0 * t;
    load.damping_n_s_per_m = 5.0;
    sim.set_load(load);
    sim.read_sensors(t, s);
    sim.write_motor_angle(screw_motor);
    const double screw =
        screw_angle_rad_from_motor_rad(motor_angle_rad_from_counts(s.motor_counts, act), act);
    const double pos = nut_pos_m_from_counts(s.linear_counts, act);
    if (k == 0) mon.reset(t, screw, pos);
    const auto o = mon.step({t, screw, pos, kNaN});
    if (o.step_out_warning && std::isnan(t_warn)) t_warn = t;
    if (o.step_out && std::isnan(t_flag)) t_flag = t;
    if (sim.truth().slips != 0 && std::isnan(t_slip)) t_slip = t;
  }
  std::printf("overload ramp: warning %.3f s, step-out flag %.3f s, plant slipped a lead %.3f s\n",
              t_warn, t_flag, t_slip);
  ASSERT_TRUE(std::isfinite(t_slip));  // the plant really stepped out
  ASSERT_TRUE(std::isfinite(t_flag));
  ASSERT_TRUE(std::isfinite(t_warn));
  EXPECT_LE(t_flag, t_slip);
  EXPECT_GE(t_flag - t_warn, 0.040);  // a warning worth having: at least 40 ms ahead
  // … and not a warning that is always on: the load was still below 75 % of the peak then.
  EXPECT_GT(15.0 * t_warn, 0.75 * paper_calibration().peak_push_n);
}

}  // namespace
}  // namespace maglead::twin
