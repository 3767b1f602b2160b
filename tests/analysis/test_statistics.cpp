// The statistics both analysis paths use (internal to twin/analysis): the one final fit with
// standard errors (stats::estimate: a constant fitted to four segments, against the jackknife
// computed by hand), the white-noise level of a sensor and the checks of a recording's columns;
// and the actuator's setting aside of the samples hidden stops reach.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "actuator_analysis.hpp"
#include "maglead/recording/recording.hpp"
#include "pulses.hpp"
#include "statistics.hpp"

namespace {

using maglead::sample_rate_hz;
using maglead::analysis::stats::Estimates;
using maglead::analysis::stats::Fit;
using maglead::analysis::stats::fold_of;
using maglead::analysis::stats::fold_starts;
using maglead::analysis::stats::Grams;
using maglead::analysis::stats::logging_step;
using maglead::analysis::stats::Named;
using maglead::analysis::stats::require_analysable;
using maglead::analysis::stats::sensor_noise;
using maglead::analysis::stats::white_noise_sigma;

// Four segments of two samples each; one column of ones, so a fit is the mean residual of the
// segments it uses: 2.5 on all, 16/6, 16/6, 10/6 and 18/6 without each segment in turn.
Grams four_segments() {
  const std::vector<std::vector<double>> r = {{1, 3}, {2, 2}, {4, 6}, {0, 2}};
  Grams g(r.size(), 1);
  const Eigen::VectorXd one = Eigen::VectorXd::Ones(1);
  for (std::size_t f = 0; f < r.size(); ++f)
    for (double v : r[f]) g.add_row(f, one, v, v);
  g.symmetrize();
  return g;
}

// √((K−1)/K Σ(x − x̄)²) over the given leave-one-out values.
double jackknife(const std::vector<double>& x) {
  const auto k = static_cast<double>(x.size());
  double mean = 0;
  for (double v : x) mean += v / k;
  double ss = 0;
  for (double v : x) ss += (v - mean) * (v - mean);
  return std::sqrt((k - 1) / k * ss);
}

// stats::solve's ridge (1e-9 of the diagonal) shrinks each fit by about that share.
void expect_close(double got, double want) { EXPECT_NEAR(got, want, 1e-8 * std::abs(want)); }

TEST(StatsEstimate, FinalFitAndJackknifeErrorsPerGroup) {
  const Grams g = four_segments();
  // Group 0: the mean and twice it; group 1: the mean only where it is below 2.8 (so the fit
  // without the last segment, 3.0, gives no value there and is left out of its error).
  const Estimates est = estimate(g, {0}, [](const Fit& fit) {
    const double m = fit.theta[0];
    std::vector<std::optional<Named>> out{Named{{"mean", m}, {"twice", 2 * m}}};
    out.push_back(m < 2.8 ? std::optional<Named>(Named{{"mean", m}}) : std::nullopt);
    return out;
  });
  ASSERT_EQ(est.values.size(), 2U);
  ASSERT_EQ(est.standard_errors.size(), 2U);
  expect_close(est.fit.theta[0], 2.5);
  ASSERT_TRUE(est.values[0] && est.values[1]);
  expect_close(est.values[0]->at("twice"), 5.0);
  const double all = jackknife({16.0 / 6, 16.0 / 6, 10.0 / 6, 18.0 / 6});
  expect_close(est.standard_errors[0].at("mean"), all);
  expect_close(est.standard_errors[0].at("twice"), 2 * all);
  expect_close(est.standard_errors[1].at("mean"), jackknife({16.0 / 6, 16.0 / 6, 10.0 / 6}));
}

// A column zero to rounding (F_m sin θ on a screw held at θ = 2π) beside a real one: it gets no
// coefficient and the real one the whole fit. Scaled up it would have fit the noise with any value.
TEST(StatsSolve, AColumnZeroToRoundingGetsNoCoefficient) {
  Grams g(2, 2);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  for (int i = 0; i < 200; ++i) {
    const double f = std::sin(0.05 * i) * 10;
    Eigen::VectorXd x(2);
    x << f * std::sin(2 * std::numbers::pi), f;
    const double r = 0.03 * f + noise(rng);
    g.add_row(static_cast<std::size_t>(i % 2), x, r, r);
  }
  g.symmetrize();
  const Fit fit = maglead::analysis::stats::solve(g, {0, 1}, -1);
  EXPECT_EQ(fit.theta[0], 0.0);
  EXPECT_NEAR(fit.theta[1], 0.03, 0.003);  // three standard errors: 0.1 / √(Σf² ≈ 10⁴)
}

// A slow sine with steps (a signal's own structure) under white noise of 0.3: the second
// difference sees the noise, not the signal; the median keeps the few steps out. 5 % is about
// six standard errors of the robust estimate on 20 000 samples.
TEST(WhiteNoiseSigma, ReadsTheNoiseUnderASmoothSignalWithSteps) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<double> y(20000);
  for (std::size_t i = 0; i < y.size(); ++i) {
    const double t = static_cast<double>(i) / 1000.0;
    y[i] =
        5.0 * std::sin(2 * std::numbers::pi * 0.5 * t) + (i % 2000 < 1000 ? 2.0 : 0.0) + noise(rng);
  }
  EXPECT_NEAR(white_noise_sigma(y), 0.3, 0.015);
}

// A load cell logged in 0.5 N steps with noise of 0.02 N under them: most second differences
// are 0, so the roughness reads no noise, yet the logged value is off the force by the step's
// rounding (uniform, 0.5/√12 = 0.144 N). The floor is at least that, and says it was not measured.
TEST(SensorNoise, AColumnLoggedInCoarseStepsHasItsRoundingAsTheFloor) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<double> y(20000);
  double t_s = 0.0;  // a 0.2 Hz sine of 3 N logged at 1 kHz
  std::generate(y.begin(), y.end(), [&] {
    const double force_n = 3.0 * std::sin(2 * std::numbers::pi * 0.2 * t_s) + noise(rng);
    t_s += 1e-3;
    return std::round(force_n / 0.5) * 0.5;
  });
  EXPECT_EQ(white_noise_sigma(y), 0.0);  // the second differences alone see no noise at all
  EXPECT_NEAR(logging_step(y), 0.5, 1e-12);
  const auto n = sensor_noise(y);
  EXPECT_FALSE(n.measured);
  EXPECT_NEAR(n.sigma, 0.5 / std::sqrt(12.0), 1e-12);
}

// The reader fills a missing row midway between its neighbours, off the logged grid: a few such
// rows leave the step found (not half of it), so the floor is still its rounding.
TEST(SensorNoise, ACoarseColumnWithAFewFilledRowsKeepsItsStep) {
  std::vector<double> y(20000);
  for (std::size_t i = 0; i < y.size(); ++i)
    y[i] = std::round(3.0 * std::sin(2 * std::numbers::pi * 0.2 * 1e-3 * double(i)) / 0.5) * 0.5;
  y[100] = 0.25;  // midway between two steps
  y[5000] = 1.37;
  y[9000] = -2.11;
  EXPECT_NEAR(logging_step(y), 0.5, 1e-12);
  EXPECT_FALSE(sensor_noise(y).measured);
}

// Continuous noise shares no step: the floor is the measured noise, and says so.
TEST(SensorNoise, AContinuousColumnHasItsMeasuredNoise) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<double> y(20000);
  for (auto& v : y) v = noise(rng);
  EXPECT_EQ(logging_step(y), 0.0);
  const auto n = sensor_noise(y);
  EXPECT_TRUE(n.measured);
  EXPECT_NEAR(n.sigma, 0.3, 0.015);  // as WhiteNoiseSigma: six standard errors
  // Logged at 0.01 N, far below the noise: the step is found, the floor is still the noise.
  for (auto& v : y) v = std::round(v / 0.01) * 0.01;
  EXPECT_NEAR(logging_step(y), 0.01, 1e-9);
  EXPECT_TRUE(sensor_noise(y).measured);
}

maglead::Recording two_columns(std::size_t rows) {
  maglead::Recording rec;
  rec.path = "r.csv";
  std::vector<double> t(rows), x(rows, 1.0);
  for (std::size_t i = 0; i < rows; ++i) t[i] = 0.001 * static_cast<double>(i);
  rec.add_column("t_s", t);
  rec.add_column("x", x);
  return rec;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return {};
}

TEST(RequireAnalysable, RefusesShortRecordsMissingColumnsAndNonNumbers) {
  EXPECT_EQ(message_of([] { require_analysable(two_columns(200), {"t_s", "x"}); }), "");
  EXPECT_EQ(message_of([] {
              require_analysable(two_columns(199), {"t_s", "x"});
            }),
            "r.csv: too short to analyse (199 rows; the analysis needs at least 200)");
  EXPECT_NE(message_of([] {
              require_analysable(two_columns(300), {"t_s", "y"});
            }).find("'y'"),
            std::string::npos);
  auto rec = two_columns(300);
  rec.columns[1][5] = std::nan("");
  EXPECT_EQ(message_of([&] {
              require_analysable(rec, {"t_s", "x"});
            }),
            "r.csv: column 'x' is empty in data row 6 (t_s = 0.005 s): the analysis needs a value "
            "in every row of it; fill the gap or drop the row");
}

// The header names the logger's clock; the time stamps only carry its rounding (EMPS: header
// 1000 Hz, a median step of 0.999984 ms over its first steps, mean exactly 1 ms).
TEST(SampleRate, HeaderWinsOverJitteredStampsElseTheMedianStep) {
  auto rec = two_columns(1000);
  for (std::size_t i = 0; i < 1000; ++i) rec.columns[0][i] += (i % 2 ? 2e-8 : -1e-8);
  EXPECT_NEAR(sample_rate_hz(rec), 1000.0, 0.1);
  EXPECT_NE(sample_rate_hz(rec), 1000.0);  // the median step is jittered
  rec.set_meta("sample_rate_hz", "1000");
  EXPECT_EQ(sample_rate_hz(rec), 1000.0);
  rec.set_meta("sample_rate_hz", "fast");
  EXPECT_EQ(message_of([&] { sample_rate_hz(rec); }),
            "r.csv: header sample_rate_hz 'fast' is not a positive number: fix the "
            "'# sample_rate_hz:' line or delete it");
  rec.set_meta("sample_rate_hz", "-5");
  EXPECT_NE(message_of([&] { sample_rate_hz(rec); }), "");
  auto still = two_columns(300);
  still.columns[0].assign(300, 1.0);
  EXPECT_EQ(message_of([&] { sample_rate_hz(still); }), "r.csv: t_s does not advance");
}

// Segments are equal times, not equal sample counts: a logger that sampled the first half ten
// times faster still gets its span cut in the middle.
TEST(Folds, CutTheSpanByTimeNotBySampleCount) {
  std::vector<double> t;
  t.reserve(111);
  for (int i = 0; i < 100; ++i) t.push_back(0.01 * i);      // 0 … 0.99 s, 100 samples
  for (int i = 0; i < 10; ++i) t.push_back(1.0 + 0.1 * i);  // 1.0 … 1.9 s, 10 samples
  t.push_back(2.0);
  const auto starts = fold_starts(t, 0.0, 2.0, 2);
  ASSERT_EQ(starts.size(), 3U);
  EXPECT_EQ(starts[0], 0U);
  EXPECT_EQ(starts[1], 100U);  // by sample count it would be 55
  EXPECT_EQ(starts[2], t.size());
  EXPECT_EQ(fold_of(0.0, 2.0, 4), 0U);
  EXPECT_EQ(fold_of(1.99, 2.0, 4), 3U);
  EXPECT_EQ(fold_of(2.0, 2.0, 4), 3U);  // the last stamp belongs to the last segment
  EXPECT_EQ(fold_of(0.5, 0.0, 4), 0U);  // no span: one segment
  const auto uniform = fold_starts(std::vector<double>{0, 1, 2, 3, 4, 5}, 0.0, 5.0, 3);
  EXPECT_EQ(uniform, (std::vector<std::size_t>{0, 2, 4, 6}));
}

// The samples a hidden stop reaches (its window's ends included) leave the sample set in place,
// the locked floor follows the samples left, and putting them back restores every sample and
// the floor exactly.
TEST(StopSamples, TakenOutInPlaceAndPutBackExactly) {
  namespace act = maglead::analysis::actuator;
  act::ActuatorPrepared P;
  P.count_force_n = 0.4;
  P.floor_n = 0.1;
  P.locked_period = {2, 5};
  for (int i = 0; i < 20; ++i) {
    maglead::effects::State s;
    s.t_s = 0.1 * i;
    s.v_m_s = 0.001 * i;
    P.states.push_back(s);
    P.residual.push_back(1.0 + i);
    P.locked_run.push_back(i < 8 ? 0 : (i < 12 ? -1 : 1));
  }
  P.stops = {{0.25, 0.5}, {1.2, 1.3}};  // samples 3, 4, 5 and 12, 13 (t = 1.2, 1.3)
  act::put_back(P, {});                 // nothing aside: the locked floor as prepare sets it
  const act::ActuatorPrepared before = P;
  const auto aside = act::take_stops(P);
  EXPECT_EQ(aside.at, (std::vector<std::size_t>{3, 4, 5, 12, 13}));
  ASSERT_EQ(P.states.size(), 15U);
  EXPECT_DOUBLE_EQ(P.residual[3], 7.0);                      // sample 6 closed up behind sample 2
  EXPECT_DOUBLE_EQ(P.states[9].t_s, before.states[14].t_s);  // and 14 behind 11
  EXPECT_NE(P.locked_floor_n, before.locked_floor_n);
  act::put_back(P, aside);
  ASSERT_EQ(P.states.size(), before.states.size());
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    EXPECT_EQ(P.states[i].t_s, before.states[i].t_s) << i;
    EXPECT_EQ(P.states[i].v_m_s, before.states[i].v_m_s) << i;
    EXPECT_EQ(P.residual[i], before.residual[i]) << i;
    EXPECT_EQ(P.locked_run[i], before.locked_run[i]) << i;
  }
  EXPECT_EQ(P.locked_floor_n, before.locked_floor_n);
  EXPECT_EQ(P.locked_share, before.locked_share);
}

// 40 s at 100 Hz of the states `at(t)` with the force `law(state)` missing, 1.3 N more for a
// quarter second at t = 10 s (a pulse no law explains) and 0.02 N of noise. The finder sees two
// pulses (the law's and that one); only the one at t = 10 s is left once the library's laws in
// `form` are asked, beside the model's columns `model`.
void expect_only_the_pulse_no_law_explains(
    const std::function<maglead::effects::State(double)>& at,
    const std::function<double(const maglead::effects::State&)>& law, maglead::analysis::Form form,
    const std::vector<int>& model = {}) {
  namespace ma = maglead::analysis;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<double> t, r;
  std::vector<maglead::effects::State> st;
  for (int k = 0; k <= 4000; ++k) {
    st.push_back(at(k * 0.01));
    t.push_back(st.back().t_s);
    const bool hit = t.back() >= 10.0 && t.back() < 10.25;
    r.push_back(law(st.back()) + (hit ? 1.3 : 0.0) + noise(rng));
  }
  ma::pulses::Floors f;
  f.filter_hz = 20.0;
  f.fs_hz = 100.0;
  f.step_s = 0.01;
  f.span_s = 40.0;
  const auto found = ma::pulses::find(t, r, f);
  ASSERT_EQ(found.size(), 2u);
  const auto kept =
      ma::pulses::unexplained(t, r, st, form, ma::candidate_columns(form, {}), model, f, found);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_NEAR(kept[0].t_s, 10.0, 0.02);
  EXPECT_NEAR(kept[0].peak_n, 1.3, 0.1);
}

}  // namespace

// A nut runs a triangle between 3.5 and 36.5 mm, pushing a steady 1 N through a coupling that
// weakens in the 5 mm end zones (end_effect, D = 0.5): 0.1 N missing at each end, under the
// finder's threshold, except at t = 16 s, where it pushes 12 N (a release at the end stop, say)
// and 1.3 N go missing for a quarter second: a pulse to the finder, and the end effect's law
// where the nut stood, which the other visits show. A 1.3 N pulse mid-stroke at t = 10 s is one
// no law explains: it stays.
TEST(Pulses, APulseALibraryLawExplainsIsNotADisturbance) {
  const auto* end = maglead::effects::find("end_effect");
  ASSERT_NE(end, nullptr);
  const auto at = [](double t_s) {
    maglead::effects::State s;
    s.t_s = t_s;
    const double u = std::fmod(t_s, 8.0) / 4.0;  // 0 → 2 over a period
    s.p_m = 0.0035 + 0.033 * (u <= 1.0 ? u : 2.0 - u);
    s.v_m_s = (u <= 1.0 ? 1.0 : -1.0) * 0.033 / 4.0;
    s.coupling_n = std::abs(t_s - 16.0) < 1.0 ? 12.0 : 1.0;
    return s;
  };
  expect_only_the_pulse_no_law_explains(
      at,
      [&](const maglead::effects::State& s) {
        double x = 0;
        end->regressors(0.005, s, &x);
        return 0.5 * x;
      },
      maglead::analysis::Form::nut);
}

// A coupling 10 % stronger than modelled, on a nut sliding back and forth against 7.5 N of
// friction with a load swinging ±1 N: while it slides, the gain's force is mostly 0.1 × 7.5 N in
// the direction of motion, and the selection took a Coulomb level in its place (the data cannot
// tell them apart there). What is left is 0.1 × the load, at most 0.1 N, except for a quarter
// second at t = 16 s where the load is 12 N: 1.2 N go missing, a pulse to the finder and the
// gain's force once the Coulomb level is refitted beside it (the gain alone on the residual
// fits almost nothing: its column is ±7.5 N where the residual is ±0.1 N). The 1.3 N at
// t = 10 s stays.
TEST(Pulses, APulseALawExplainsBesideTheModelsTermsIsNotADisturbance) {
  namespace ma = maglead::analysis;
  const auto at = [](double t_s) {
    maglead::effects::State s;
    s.t_s = t_s;
    const double u = std::fmod(t_s, 8.0) / 4.0;
    s.p_m = 0.0035 + 0.033 * (u <= 1.0 ? u : 2.0 - u);
    s.v_m_s = (u <= 1.0 ? 1.0 : -1.0) * 0.033 / 4.0;
    const double load_n =
        t_s >= 16.0 && t_s < 16.25 ? 12.0 : std::sin(2.0 * std::numbers::pi * t_s / 5.0);
    s.coupling_n = 7.5 * (s.v_m_s > 0 ? 1.0 : -1.0) + load_n;
    return s;
  };
  const auto law = [](const maglead::effects::State& s) {
    return 0.1 * (s.coupling_n - 7.5 * (s.v_m_s > 0 ? 1.0 : -1.0));
  };
  const auto cand = ma::candidate_columns(ma::Form::nut, {});
  const auto* coulomb = cand.of(maglead::effects::find("coulomb_friction"));
  ASSERT_NE(coulomb, nullptr);
  expect_only_the_pulse_no_law_explains(at, law, ma::Form::nut, coulomb->idx);
}

// The same check on an axis (its units' axis regressors): a carriage crawls back and forth at
// 8 mm/s against 12 N·s/m more viscous friction than modelled (0.1 N missing, under the
// finder's threshold), except for a quarter second at 100 mm/s at t = 16 s: 1.2 N go missing, a
// pulse to the finder and the viscous law's force at that speed. The 1.3 N at t = 10 s stays.
TEST(Pulses, OnAnAxisAPulseALibraryLawExplainsIsNotADisturbance) {
  const auto at = [](double t_s) {
    maglead::effects::State s;
    s.t_s = t_s;
    const bool out = std::fmod(t_s, 8.0) < 4.0, fast = t_s >= 16.0 && t_s < 16.25;
    s.v_m_s = (out ? 1.0 : -1.0) * (fast ? 0.1 : 0.008);
    s.p_m = 0.02 + 0.008 * (out ? std::fmod(t_s, 4.0) : 4.0 - std::fmod(t_s, 4.0));
    return s;
  };
  expect_only_the_pulse_no_law_explains(
      at, [](const maglead::effects::State& s) { return -12.0 * s.v_m_s; },
      maglead::analysis::Form::axis);
}
