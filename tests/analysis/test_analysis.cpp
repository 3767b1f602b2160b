// The analysis on data where the answer is known: recordings from the simulated plant with one
// effect of docs/effects.md switched on that the baseline lacks (fixed seeds, made
// here), controls with nothing concealed, and the real EMPS recording. Only bench columns reach
// the analysis; the effects are named in the spec's ids and parameter names.
//
// Every generated case asserts: the effect is named (as a finding's id, or as an alternative
// that explains >= 95 % of it); nothing else is claimed; its parameters are within a tolerance
// set by the effect's size against what is left unexplained (below); and the held-out error
// falls below half (not for findings made outside the sliding fit: Stribeck friction from
// stuck episodes, events). Cases the analysis does not pass yet are in GeneratedSuiteKnownGaps
// (CMakeLists.txt expects them to fail, so the branch stays green and a fixed gap shows up).
//
// Tolerance of a fitted coefficient c (the law linear in it, y = c·x + r): the least-squares
// error is <x, r>/<x, x>, at most |r|/|x| by Cauchy–Schwarz, i.e. relative to c at most
// rms(r)/rms(c·x) = what is left unexplained / what the effect explains. Both are measured by
// the analysis (held-out RMS after, explained_rms_n); the tolerance is that ratio, and no less
// than 5 %. Shape values the analysis scans on a grid (zone, period, Stribeck velocity) are set
// on a grid point and must come back within one grid step. Effect sizes are chosen to stand
// well above the controls' held-out RMS (0.03–0.06 N), and above the analysis's documented
// floor (a term must explain a tenth of one encoder count's force, about 0.11 N RMS).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>

#include "../../twin/analysis/src/actuator_twin_force.hpp"
#include "../test_tmp.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/analysis/signal.hpp"
#include "maglead/effects/effect.hpp"
#include "maglead/plant/scenario.hpp"
#include "maglead/settings/settings.hpp"

namespace {

using maglead::analysis::AnalysisResult;
using maglead::analysis::EffectFinding;
using maglead::analysis::parameter_value;
using maglead::analysis::Parameters;

bool has(const Parameters& p, const std::string& name) {
  return std::any_of(p.begin(), p.end(), [&](const auto& q) { return q.name == name; });
}

std::string text(const Parameters& p) {
  std::string s;
  for (const auto& q : p) s += (s.empty() ? "" : ", ") + q.name + " = " + std::to_string(q.value);
  return "{" + s + "}";
}

std::string events_text(const AnalysisResult& r) {
  std::string s;
  for (const auto& e : r.findings.events)
    s += (s.empty() ? "" : ", ") + e.type + " at " + std::to_string(e.t_s) + " s";
  return "[" + s + "]";
}

constexpr double kPi = std::numbers::pi;

struct Key {
  std::string name;  // a plant --effect key
  double value;
};

struct Generated {
  AnalysisResult result;
  maglead::ScenarioSummary truth;
};

maglead::ActuatorParams actuator() { return {}; }

AnalysisResult analyze(const maglead::Recording& rec) {
  const auto act = actuator();
  maglead::analysis::AnalysisOptions opt;
  // analysis_twin_round_trip checks it through the command line
  opt.actuator.twin_force_check = false;
  return maglead::analysis::analyze_recording(
      rec, maglead::analysis::actuator_model_from_config(act),
      maglead::load_calibration(std::string(MAGLEAD_CONFIG_DIR) + "/calibration.toml"), act, opt);
}

std::string named_as(const AnalysisResult& r);

// Issue 43: the corrected model is what the data support, so analysing the same recording again
// with it names no new model term (events are the recording's, not the model's: they may recur).
void expect_nothing_new_with_the_corrected_model(const maglead::Recording& rec,
                                                 const AnalysisResult& first,
                                                 const std::string& scenario) {
  const auto act = actuator();
  maglead::analysis::AnalysisOptions opt;
  opt.actuator.twin_force_check = false;
  const auto again = maglead::analysis::analyze_recording(
      rec, first.corrected,
      maglead::load_calibration(std::string(MAGLEAD_CONFIG_DIR) + "/calibration.toml"), act, opt);
  for (const auto& e : again.findings.effects)
    EXPECT_TRUE(e.evidence.events.has_value())
        << scenario << ": analysed again with its corrected model, " << e.id
        << " is named: " << e.summary << " (first: " << named_as(first) << ")";
}

// Seed 5 unless MAGLEAD_SUITE_SEED says otherwise (to see that a case is not one seed's luck).
Generated run(const std::string& scenario, double duration_s, const std::vector<Key>& keys,
              std::optional<std::uint64_t> given_seed = std::nullopt) {
  std::uint64_t seed = 5;
  if (const char* env = std::getenv("MAGLEAD_SUITE_SEED")) seed = std::stoull(env);
  if (given_seed) seed = *given_seed;
  maglead::ScenarioOptions opt;
  opt.scenario = scenario;
  opt.duration_s = duration_s;
  opt.seed = seed;
  for (const auto& k : keys) maglead::set_plant_effect(opt.plant.effects, k.name, k.value);
  const std::string path = test_tmp_dir() + "/" + scenario + ".csv";
  const auto summary = maglead::run_scenario(opt, path);
  // Only what a bench logs: the recording holds no truth columns.
  const auto rec = maglead::read_recording(path);
  for (const auto& n : rec.names)
    EXPECT_TRUE(n == "t_s" || n == "motor_angle_rad" || n == "screw_angle_rad" ||
                n == "nut_pos_m" || n == "load_force_n" || n == "out_force_est_n" ||
                n == "force_set_n" || n == "pos_set_m")
        << n;
  auto result = analyze(rec);
  std::filesystem::remove(path);
  expect_nothing_new_with_the_corrected_model(rec, result, scenario);
  return {std::move(result), summary};
}

// A generated recording read back (`seed`, the effects `keys`), its file removed.
maglead::Recording generated(const std::string& scenario, double duration_s,
                             const std::vector<Key>& keys, std::uint64_t seed) {
  maglead::ScenarioOptions opt;
  opt.scenario = scenario;
  opt.duration_s = duration_s;
  opt.seed = seed;
  for (const auto& k : keys) maglead::set_plant_effect(opt.plant.effects, k.name, k.value);
  const std::string path = test_tmp_dir() + "/" + scenario + "_recorded.csv";
  maglead::run_scenario(opt, path);
  auto rec = maglead::read_recording(path);
  std::filesystem::remove(path);
  return rec;
}

// The same with seed 5 and one effect.
maglead::Recording recorded(const std::string& scenario, double duration_s, const Key& effect) {
  return generated(scenario, duration_s, {effect}, 5);
}

std::vector<double>& load_cell(maglead::Recording& rec) {
  const auto at = std::find(rec.names.begin(), rec.names.end(), "load_force_n");
  return rec.columns[static_cast<std::size_t>(at - rec.names.begin())];
}

// The finding that names `id`: its own id, or an alternative explaining >= 95 % of it.
// `params` receives the parameters given for `id`.
const EffectFinding* finding(const AnalysisResult& r, const std::string& id, Parameters* params) {
  for (const auto& e : r.findings.effects) {
    if (e.id == id) {
      *params = e.parameters;
      return &e;
    }
    for (const auto& a : e.alternatives)
      if (a.id == id && a.explains_pct >= 95.0) {
        *params = a.parameters;
        return &e;
      }
  }
  return nullptr;
}

double heldout_before(const AnalysisResult& r) {
  return r.findings.validation.front().heldout_rms_n;
}
double heldout_after(const AnalysisResult& r) { return r.findings.validation.back().heldout_rms_n; }

std::string named_as(const AnalysisResult& r) {
  std::string s;
  for (const auto& e : r.findings.effects) {
    if (!s.empty()) s += ", ";
    s += e.id;
    if (!e.alternatives.empty()) {
      s += " (or";
      for (const auto& a : e.alternatives) {
        char pct[32];
        std::snprintf(pct, sizeof pct, " %.0f %%", a.explains_pct);
        s += " " + a.id + pct;
      }
      s += ")";
    }
  }
  return s.empty() ? "nothing" : s;
}

std::string join(const std::vector<double>& v) {
  std::string s;
  for (double x : v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.5g", x);
    s += (s.empty() ? "" : " / ") + std::string(b);
  }
  return s.empty() ? "–" : s;
}

// One row of the README table, printed by the test.
void row(const std::string& effect, const std::string& scenario, const std::vector<double>& truth,
         const std::vector<double>& found, const AnalysisResult& r) {
  std::printf("| %s | %s | %s | %s | %s | %.3f | %.3f |\n", effect.c_str(), scenario.c_str(),
              join(truth).c_str(), join(found).c_str(), named_as(r).c_str(), heldout_before(r),
              heldout_after(r));
}

// How a parameter's tolerance follows (see the top of the file).
struct Param {
  enum Kind { coefficient, grid, factor, angle, offset_over, absolute };
  std::string name;  // the spec's parameter name
  double truth;
  Kind kind = coefficient;
  double x = 0;  // coefficient: the nominal the fit adds to (the coefficient is truth − x);
                 // grid: the grid step; factor: the grid's ratio; offset_over: the stiffness
                 // that turns a force offset into this parameter; absolute: the tolerance
};

Param coef(std::string name, double truth, double nominal = 0) {
  return {std::move(name), truth, Param::coefficient, nominal};
}
Param on_grid(std::string name, double truth, double step) {
  return {std::move(name), truth, Param::grid, step};
}
Param on_log_grid(std::string name, double truth, double ratio) {
  return {std::move(name), truth, Param::factor, ratio};
}
Param phase(std::string name, double truth) { return {std::move(name), truth, Param::angle, 0}; }

// Relative tolerance of a fitted coefficient: unexplained / explained, at least 5 %.
double coefficient_tol(const AnalysisResult& r, const EffectFinding& f) {
  const double explained = f.evidence.explained_rms_n.value_or(0.0);
  if (!(explained > 0)) return 0.05;
  return std::max(0.05, heldout_after(r) / explained);
}

// The effect is named, nothing else is, its parameters are right and the held-out error falls.
void expect_found(const AnalysisResult& r, const std::string& effect, const std::string& scenario,
                  const std::vector<Param>& params, bool heldout_falls = true) {
  Parameters p;
  const EffectFinding* f = finding(r, effect, &p);
  std::vector<double> truth, found;
  for (const auto& q : params) {
    truth.push_back(q.truth);
    found.push_back(f && has(p, q.name) ? parameter_value(p, q.name) : NAN);
  }
  row(effect, scenario, truth, found, r);
  ASSERT_NE(f, nullptr) << effect << " not named; found: " << named_as(r);
  EXPECT_EQ(r.findings.effects.size(), 1u) << "claimed beyond " << effect << ": " << named_as(r);
  const double rel = coefficient_tol(r, *f);
  for (const auto& q : params) {
    ASSERT_TRUE(has(p, q.name)) << effect << ": no " << q.name << " in " << text(p);
    const double v = parameter_value(p, q.name);
    if (q.kind == Param::factor) {
      EXPECT_TRUE(v >= q.truth / q.x * 0.999 && v <= q.truth * q.x * 1.001)
          << effect << " " << q.name << " = " << v << ", not within a factor " << q.x << " of "
          << q.truth;
      continue;
    }
    double tol = 0;
    switch (q.kind) {
      case Param::coefficient:
        tol = rel * std::abs(q.truth - q.x);
        break;
      case Param::grid:
        tol = q.x;
        break;
      case Param::angle:
        tol = std::asin(std::min(1.0, rel));
        break;
      case Param::offset_over:
        tol = heldout_after(r) / q.x;
        break;
      case Param::absolute:
        tol = q.x;
        break;
      case Param::factor:
        break;
    }
    const double d = q.kind == Param::angle ? std::remainder(v - q.truth, 2 * kPi) : v - q.truth;
    EXPECT_LE(std::abs(d), tol) << effect << " " << q.name << " = " << v << ", true " << q.truth
                                << " (tolerance " << tol << ")";
  }
  if (heldout_falls) {
    EXPECT_LT(heldout_after(r), 0.5 * heldout_before(r)) << "held-out error must fall";
  }
}

// ------------------------------------------------------------------------- controls

void expect_nothing(const AnalysisResult& r, const std::string& scenario) {
  row("(control)", scenario, {}, {}, r);
  // A control the analysis could not judge proves nothing about false claims.
  EXPECT_NE(r.headline.rfind(maglead::analysis::kNotJudged, 0), 0u)
      << scenario << ": " << r.headline;
  EXPECT_TRUE(r.findings.effects.empty()) << scenario << ": " << named_as(r);
  EXPECT_TRUE(r.findings.events.empty()) << scenario << ": " << events_text(r);
}

TEST(GeneratedSuite, ControlHandPushNamesNothing) {
  expect_nothing(run("hand-push", 40.0, {}).result, "hand-push");
}
// Both paths list the best candidate left out the same way: why, the force it would explain and
// its parameters (the actuator once gave only its gain and parameters).
void expect_best_left_out_explained(const AnalysisResult& r) {
  ASSERT_FALSE(r.findings.not_selected.empty());
  const auto& n = r.findings.not_selected.front();
  const std::string why = n.reason.value_or("");
  EXPECT_NE(why.find("best remaining candidate"), std::string::npos) << n.id;
  // The rule named is the one its own figures fail (defaults: 1 % held out, t 3, or a localized
  // gain): a gain and a consistency that both pass leave the force it explains as the reason.
  const double g = n.heldout_gain_pct;
  const bool consistent =
      n.t_stat >= 3.0 ||
      (g >= maglead::analysis::rules::kLocalizedGainFactor &&
       n.worst_segment_pct.value_or(-1e9) > maglead::analysis::rules::kLocalizedWorstSegmentPct);
  const char* rule = g < 1.0       ? "held-out gain"
                     : !consistent ? "not consistent over the segments"
                                   : "not one the recording resolves";
  EXPECT_NE(why.find(rule), std::string::npos) << n.id << ": " << why;
  EXPECT_TRUE(n.explained_rms_n && std::isfinite(*n.explained_rms_n) && *n.explained_rms_n >= 0)
      << n.id;
  EXPECT_TRUE(n.parameters && !n.parameters->empty()) << n.id;
}

TEST(GeneratedSuite, ControlPositionMovesNamesNothing) {
  const auto r = run("position-moves", 40.0, {}).result;
  expect_nothing(r, "position-moves");
  expect_best_left_out_explained(r);
}
TEST(GeneratedSuite, ControlForceStepsNamesNothing) {
  expect_nothing(run("force-steps", 40.0, {}).result, "force-steps");
}
// 20 s: the sweep at 0.62 mm/s, above the analysis's sliding speed (at 40 s it is not judged).
TEST(GeneratedSuite, ControlStaticCalibrationNamesNothing) {
  expect_nothing(run("static-calibration", 20.0, {}).result, "static-calibration");
}

// ------------------------------------------------------------------------- friction and mass

TEST(GeneratedSuite, CoulombFriction) {
  const auto g = run("position-moves", 40.0, {{"coulomb_friction", 2.0}});
  expect_found(g.result, "coulomb_friction", "position-moves", {coef("coulomb_n", 9.5, 7.5)});
}

TEST(GeneratedSuite, ViscousFriction) {
  const auto g = run("position-moves", 40.0, {{"viscous_friction", 50.0}});
  expect_found(g.result, "viscous_friction", "position-moves",
               {coef("viscous_n_s_per_m", 52.0, 2.0)});
}

// improvement_pct is a finding's part in the final model: with one term, what the final model
// removes of the baseline's held-out mean square error (the validation's first and last steps).
TEST(GeneratedSuite, ImprovementIsTheTermsPartInTheFinalModel) {
  const auto g = run("position-moves", 40.0, {{"viscous_friction", 50.0}});
  ASSERT_EQ(g.result.findings.effects.size(), 1U) << named_as(g.result);
  const double before = heldout_before(g.result), after = heldout_after(g.result);
  EXPECT_NEAR(g.result.findings.effects[0].improvement_pct,
              100.0 * (1.0 - after * after / (before * before)), 1e-6);
}

TEST(GeneratedSuite, AsymmetricFrictionOrItsOffset) {
  // F_c+ 9.5 N, F_c− 5.5 N: with Coulomb friction the same as 7.5 N and an offset of −2 N.
  const auto g = run("hand-push", 40.0, {{"asymmetric_friction", 2.0}});
  expect_found(g.result, "asymmetric_friction", "hand-push",
               {coef("coulomb_pos_n", 9.5, 7.5), coef("coulomb_neg_n", 5.5, 7.5)});
}

// F_s 12 N over F_c 7.5 N, v_s 2 mm/s (on the analysis's grid, steps of a factor 2). The
// break-away level is read at release, when the nut has crossed one encoder count: one count's
// coupling force (about 1.1 N at φ = 0) is the resolution. No held-out gain is required: the
// analysis finds Stribeck friction from stuck episodes, which the sliding fit leaves out.
const std::vector<Param> kStribeck = {{"breakaway_n", 12.0, Param::absolute, 1.1},
                                      {"coulomb_n", 7.5, Param::absolute, 1.1},
                                      on_log_grid("stribeck_velocity_m_s", 0.002, 2.0)};

TEST(GeneratedSuite, StribeckFrictionInMovesWithStops) {
  // The nut stick-slips through the slow moves (stuck ~34 ms, slipping ~5 ms, about 300 releases
  // each way), which the 20 Hz filter shows as a steady 4 mm/s. The break-away test names
  // stribeck_friction; the sliding fit is then made without the samples those stops reach (else
  // the slips' accelerations read as mass_error, 1.6 kg). No sample is left: the Stribeck
  // velocity is not determined, and the finding says so.
  const auto g = run("position-moves", 40.0, {{"stribeck_friction", 4.5}});
  expect_found(g.result, "stribeck_friction", "position-moves", kStribeck, false);
  const auto& f = g.result.findings.effects.front();
  EXPECT_NE(f.note.find("not determined"), std::string::npos) << f.note;
  EXPECT_NE(f.note.find("stops its filtered speed hides"), std::string::npos) << f.note;
}

TEST(GeneratedSuite, StribeckBreakAwayWithinTwoStandardErrorsAndTheCalibrationBound) {
  // The break-away is read through the calibrated coupling: its stated uncertainty, two standard
  // errors over the releases plus the calibration bound, covers the true 10.5 N in at least 85 %
  // of seeds (issue 43's coverage aim; the read sits 0.05-0.12 N high, what the release-lag
  // correction leaves).
  constexpr int kSeeds = 20;
  int covered = 0;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
    const auto g = run("mixed-moves", 40.0, {{"stribeck_friction", 3.0}}, seed);
    Parameters p;
    const auto* f = finding(g.result, "stribeck_friction", &p);
    ASSERT_NE(f, nullptr) << "seed " << seed << ": " << named_as(g.result);
    const double v = parameter_value(p, "breakaway_n");
    const double se = parameter_value(f->standard_errors, "breakaway_n");
    const double cal = parameter_value(f->calibration_errors, "breakaway_n");
    const bool in = std::abs(v - 10.5) <= 2.0 * se + cal;
    covered += in ? 1 : 0;
    std::printf("seed %llu: breakaway %.3f ± %.3f N, calibration ± %.3f N (true 10.5 N)%s\n",
                static_cast<unsigned long long>(seed), v, se, cal, in ? "" : ": not covered");
  }
  std::printf("covered %d of %d\n", covered, kSeeds);
  EXPECT_GE(covered, 17);  // 85 % of 20
}

TEST(GeneratedSuite, StribeckFrictionAndViscousFrictionInMovesWithStops) {
  // The pair: the hidden stops also hid the viscous slope (its kinetic level read 9.3 N instead);
  // without them the sliding samples name viscous friction and the kinetic level is nominal.
  const auto g =
      run("position-moves", 40.0, {{"stribeck_friction", 4.5}, {"viscous_friction", 50.0}});
  Parameters p;
  const auto* viscous = finding(g.result, "viscous_friction", &p);
  row("stribeck_friction + viscous_friction", "position-moves", {52.0},
      {viscous ? parameter_value(p, "viscous_n_s_per_m") : NAN}, g.result);
  ASSERT_NE(viscous, nullptr) << named_as(g.result);
  EXPECT_NEAR(parameter_value(p, "viscous_n_s_per_m"), 52.0,
              coefficient_tol(g.result, *viscous) * 50.0);
  ASSERT_NE(finding(g.result, "stribeck_friction", &p), nullptr) << named_as(g.result);
  EXPECT_NEAR(parameter_value(p, "breakaway_n"), 12.0, 1.1);
  EXPECT_NEAR(parameter_value(p, "coulomb_n"), 7.5, 1.1);
  EXPECT_EQ(g.result.findings.effects.size(), 2u) << named_as(g.result);
}

TEST(GeneratedSuite, WeakStribeckFrictionInMovesWithStops) {
  // F_s 9.5 N: the nut slides between fewer stops. The samples left fit every Stribeck velocity
  // up to 8 mm/s alike (the slow ones lay next to the stops): not determined, the middle of
  // those, not the smallest scanned.
  const auto g = run("position-moves", 40.0, {{"stribeck_friction", 2.0}});
  expect_found(g.result, "stribeck_friction", "position-moves",
               {{"breakaway_n", 9.5, Param::absolute, 1.1},
                {"coulomb_n", 7.5, Param::absolute, 1.1},
                on_log_grid("stribeck_velocity_m_s", 0.002, 2.0)},
               false);
}

TEST(GeneratedSuite, StribeckFrictionUnderForceSteps) {
  // Force control stick-slips too: a few sliding samples remain (under the selection's 50),
  // and the Stribeck velocity is the middle of those they allow.
  const auto g = run("force-steps", 40.0, {{"stribeck_friction", 4.5}});
  expect_found(g.result, "stribeck_friction", "force-steps", kStribeck, false);
}

TEST(GeneratedSuite, StribeckFrictionUnderHandPushes) {
  // No sample slides (screw held, small motions): the break-away test names it, and the
  // Stribeck velocity, which nothing here determines, is the middle of the scanned range.
  const auto g = run("hand-push", 40.0, {{"stribeck_friction", 4.5}});
  expect_found(g.result, "stribeck_friction", "hand-push", kStribeck, false);
}

TEST(GeneratedSuite, MassErrorOfATwoKilogramPayload) {
  // The force-steps sweep and steps accelerate the nut against the spring; 2 kg on the 0.12 kg
  // nut explains about 0.16 N RMS, above the analysis's floor.
  const auto g = run("force-steps", 40.0, {{"mass_error", 2.0}});
  expect_found(g.result, "mass_error", "force-steps", {coef("nut_mass_kg", 2.12, 0.12)});
}

TEST(GeneratedSuite, MassErrorOfAOneKilogramPayload) {
  // Half of that: it explains about 0.075 N, above the floor the recording resolves (one count's
  // rounding and the load-cell noise after the filter, 0.065 N here) and the stated minimum.
  // What is left is that floor, so the held-out error cannot halve (0.090 → 0.049 N): the
  // selection's own consistency test (t >= 3 over the segments) is the evidence here.
  const auto g = run("force-steps", 40.0, {{"mass_error", 1.0}});
  expect_found(g.result, "mass_error", "force-steps", {coef("nut_mass_kg", 1.12, 0.12)}, false);
}

// The same two kilograms logged at 100 Hz: the nut rings on its coupling near 100 Hz, above that
// rate's Nyquist frequency, so what looks like its acceleration is partly the aliased ring (a
// maglead-controlled recording at 100 Hz read as a 7.8 kg nut on a plant with none). The mass is
// then not judged, and the headline says so with the rate that would judge it.
TEST(GeneratedSuite, AMassIsNotJudgedWhereTheNutsRingAliases) {
  auto rec = recorded("force-steps", 40.0, {"mass_error", 2.0});
  constexpr std::size_t kEvery = 10;  // 1 kHz to 100 Hz
  for (auto& c : rec.columns) {
    std::vector<double> kept;
    for (std::size_t i = 0; i < c.size(); i += kEvery) kept.push_back(c[i]);
    c = std::move(kept);
  }
  rec.set_meta("sample_rate_hz", "100");
  const auto r = analyze(rec);
  for (const auto& e : r.findings.effects) EXPECT_NE(e.id, "mass_error");
  std::printf("100 Hz: %s\n", r.headline.c_str());
  EXPECT_NE(r.headline.find("not judged: mass_error (the nut rings on its coupling at"),
            std::string::npos)
      << r.headline;
  EXPECT_NE(r.headline.find("record at"), std::string::npos) << r.headline;
}

// ------------------------------------------------------------------------- forces on the nut

TEST(GeneratedSuite, OffsetOrDirectionDependentFriction) {
  const auto g = run("hand-push", 40.0, {{"offset", 2.0}});
  expect_found(g.result, "offset", "hand-push", {coef("offset_n", 2.0)});
  Parameters p;
  EXPECT_NE(finding(g.result, "asymmetric_friction", &p), nullptr) << "the pair of the spec";
}

// The stated minimum is the user's when given: a calibration known to 0.3 N cannot tell a 0.15 N
// offset from its own error, so the offset the default minimum (0.046 N) names is not a finding,
// and the summary prints the minimum it was held to.
TEST(GeneratedSuite, AStatedCalibrationAccuracyIsTheMinimum) {
  const auto rec = recorded("position-moves", 30.0, {"offset", 0.15});
  const auto act = actuator();
  const auto cal = maglead::load_calibration(std::string(MAGLEAD_CONFIG_DIR) + "/calibration.toml");
  maglead::analysis::AnalysisOptions o;
  o.actuator.twin_force_check = false;
  const auto model = maglead::analysis::actuator_model_from_config(act);
  const auto by_default = maglead::analysis::analyze_recording(rec, model, cal, act, o);
  Parameters p;
  const auto* named = finding(by_default, "offset", &p);
  ASSERT_NE(named, nullptr) << named_as(by_default);
  EXPECT_NE(named->summary.find("minimum 0.070 N"), std::string::npos) << named->summary;
  o.actuator.calibration_accuracy_n = 0.3;
  const auto stated = maglead::analysis::analyze_recording(rec, model, cal, act, o);
  EXPECT_EQ(finding(stated, "offset", &p), nullptr) << named_as(stated);
}

TEST(GeneratedSuite, SpringTowardsMidStroke) {
  const auto g = run("position-moves", 40.0, {{"spring", 300.0}});
  // rest_position_m = mid-stroke + (force at mid-stroke)/k: a force offset's error over k.
  expect_found(
      g.result, "spring", "position-moves",
      {coef("stiffness_n_per_m", 300.0), {"rest_position_m", 0.020, Param::offset_over, 300.0}});
}

TEST(GeneratedSuite, PositionRippleWithItsPeriodAndPhase) {
  const auto g =
      run("position-moves", 40.0, {{"position_ripple", 1.5}, {"position_ripple.phase_rad", 1.0}});
  // Period 5 mm on the analysis's grid (4, 5, 6 mm around it); the phase within the angle
  // whose sine is the amplitude's relative tolerance.
  expect_found(
      g.result, "position_ripple", "position-moves",
      {coef("amplitude_n", 1.5), on_grid("period_m", 0.005, 0.001), phase("phase_rad", 1.0)});
}

// ------------------------------------------------------------------------- laws that scale F_m

TEST(GeneratedSuite, CouplingGainError) {
  const auto g = run("hand-push", 40.0, {{"coupling_gain_error", 0.1}});
  expect_found(g.result, "coupling_gain_error", "hand-push", {coef("gain", 1.1, 1.0)});
}

TEST(GeneratedSuite, GainDriftOverTime) {
  const auto g = run("hand-push", 60.0, {{"gain_drift", -0.05}});
  expect_found(g.result, "gain_drift", "hand-push", {coef("gain_change_per_min", -0.05)});
}

TEST(GeneratedSuite, AngleRippleOrPositionRippleWhileTheNutTracks) {
  // a = 0.1 of F_m (about 10 N while moving: 1 N), ψ = 0.5 rad.
  const auto g =
      run("position-moves", 40.0, {{"angle_ripple", 0.1}, {"angle_ripple.phase_rad", 0.5}});
  expect_found(g.result, "angle_ripple", "position-moves",
               {coef("relative_amplitude", 0.1), phase("phase_rad", 0.5)});
}

TEST(GeneratedSuite, EndEffectNearTheStrokeEnds) {
  // The fit has it exactly (D 0.50, z 5 mm, 98 % of the held-out error), but the nut is near an
  // end in only some of the ten segments, so the gains' t over segments is 2.0 < 3: nothing is
  // named. Zone 5 mm (grid 4, 5, 6 mm), D 0.5: the nut goes to 2 mm and 38 mm from the ends.
  const auto g = run("position-moves", 40.0, {{"end_effect", 0.005}});
  expect_found(g.result, "end_effect", "position-moves",
               {coef("max_reduction", 0.5), on_grid("zone_m", 0.005, 0.001)});
  // The zone is scanned on a grid: "(no standard error)" in the text, and no key in the JSON
  // (its jackknife spread is rounding, 1e-18).
  for (const auto& e : g.result.findings.effects) {
    if (e.id == "end_effect") {
      EXPECT_FALSE(has(e.standard_errors, "zone_m")) << e.summary;
    }
  }
}

TEST(GeneratedSuite, BacklashInTheGearbox) {
  const auto g = run("force-steps", 40.0, {{"backlash", 0.05}});
  expect_found(g.result, "backlash", "force-steps", {coef("backlash_rad", 0.05)});
}

// ------------------------------------------------------------------------- sensors

// A friction drift leaves 1.2 N RMS the library does not explain, over a load cell noise of
// 0.1 N. Logged in 0.5 N steps, the load cell's second differences are mostly 0 and its noise
// is not measurable: the floor is the step's rounding (0.5/√12 = 0.144 N), and the misfit, eight
// times it, is still said, never "nothing missing".
TEST(GeneratedSuite, ALoadCellLoggedInCoarseStepsKeepsItsMisfit) {
  auto rec = generated("mixed-moves", 40.0, {{"friction_drift", 3.0}}, 2);
  constexpr double kStepN = 0.5;
  for (auto& v : load_cell(rec)) v = std::round(v / kStepN) * kStepN;
  const auto r = analyze(rec);
  EXPECT_EQ(r.headline.rfind("nothing missing", 0), std::string::npos) << r.headline;
  EXPECT_NE(r.headline.find("a misfit of"), std::string::npos) << r.headline;
  EXPECT_NE(r.headline.find("noise floor not measurable below the 0.5 N logging step"),
            std::string::npos)
      << r.headline;
  ASSERT_TRUE(r.findings.noise_step_n.has_value());
  EXPECT_NEAR(*r.findings.noise_step_n, kStepN, 1e-9);
  EXPECT_NEAR(r.findings.noise_floor_n, kStepN / std::sqrt(12.0), 1e-9);
}

// The same coarse load cell with a few rows missing from the file: the reader fills them by
// interpolation, off the 0.5 N grid, and the step is still found and the misfit still said.
TEST(GeneratedSuite, ACoarseLoadCellWithRowsFilledKeepsItsStep) {
  auto rec = generated("mixed-moves", 40.0, {{"friction_drift", 3.0}}, 2);
  constexpr double kStepN = 0.5;
  auto& load = load_cell(rec);
  for (auto& v : load) v = std::round(v / kStepN) * kStepN;
  // Rows whose neighbours differ, so the filled value falls between two steps.
  std::vector<std::size_t> drop;
  for (std::size_t i = 1000; i + 1 < load.size() && drop.size() < 3; i += 1)
    if (load[i - 1] != load[i + 1] && (drop.empty() || i > drop.back() + 5000)) drop.push_back(i);
  ASSERT_EQ(drop.size(), 3u);
  for (auto i = drop.rbegin(); i != drop.rend(); ++i)
    for (auto& c : rec.columns) c.erase(c.begin() + static_cast<std::ptrdiff_t>(*i));
  const std::string path = test_tmp_dir() + "/coarse_filled.csv";
  maglead::write_recording(path, rec);
  const auto filled = maglead::read_recording(path);
  std::filesystem::remove(path);
  ASSERT_FALSE(filled.warnings.empty());  // the reader filled the rows
  const auto r = analyze(filled);
  EXPECT_EQ(r.headline.find("nothing missing"), std::string::npos) << r.headline;
  ASSERT_TRUE(r.findings.noise_step_n.has_value());
  EXPECT_NEAR(*r.findings.noise_step_n, kStepN, 1e-9);
  EXPECT_NE(r.headline.find("a misfit of"), std::string::npos) << r.headline;
}

// A load cell that reads one value over the whole recording (unplugged, stuck) carries no load:
// the analysis judges nothing against it, and says why.
TEST(GeneratedSuite, ALoadCellReadingAConstantIsNotJudged) {
  auto rec = generated("mixed-moves", 20.0, {{"external_disturbance", 8.0}}, 1);
  for (auto& v : load_cell(rec)) v = 0.0;
  try {
    analyze(rec);
    FAIL() << "a constant load cell must not be judged";
  } catch (const maglead::LoadCellUnitError& e) {
    EXPECT_NE(std::string(e.what()).find("not judged: the load cell reads a constant 0 N"),
              std::string::npos)
        << e.what();
  }
}

// A 2 s move goes one way: friction, an offset and a coupling gain differ by the direction of
// travel only, and eight laws fit a 2 N Coulomb friction alike. Not judged, with the laws; the
// same friction over 40 s of moves both ways is found.
TEST(GeneratedSuite, AOneWayMoveWithLawsAlikeIsNotJudged) {
  const auto one_way =
      analyze(generated("position-moves", 2.0, {{"coulomb_friction", 2.0}}, 1)).headline;
  EXPECT_EQ(one_way.rfind("not judged: the nut slides in one direction of travel only", 0), 0u)
      << one_way;
  EXPECT_NE(one_way.find("coulomb_friction"), std::string::npos) << one_way;
  const auto both_ways =
      analyze(generated("position-moves", 40.0, {{"coulomb_friction", 2.0}}, 1)).headline;
  EXPECT_EQ(both_ways.rfind("found: ", 0), 0u) << both_ways;
}

TEST(GeneratedSuite, SensorDelay) {
  // Both encoders 10 ms late: the motion is late against the load cell; the sweep's force rate
  // (up to 250 N/s) makes that up to 2.5 N.
  const auto g = run("force-steps", 40.0, {{"sensor_delay", 0.010}});
  expect_found(g.result, "sensor_delay", "force-steps", {coef("delay_s", 0.010)});
}

TEST(GeneratedSuite, LoadCellDelay) {
  const auto g = run("force-steps", 40.0, {{"load_cell_delay", 0.010}});
  expect_found(g.result, "load_cell_delay", "force-steps", {coef("delay_s", 0.010)});
}

// ------------------------------------------------------------------------- events

TEST(GeneratedSuite, ExternalDisturbancePulsesAreEvents) {
  const auto g = run("position-moves", 60.0, {{"external_disturbance", 8.0}});
  ASSERT_GE(g.truth.disturbance_times_s.size(), 2u) << "the seed must give pulses in the run";
  expect_found(g.result, "external_disturbance", "position-moves", {}, false);
  // The force reported is the peak of the residual, which the analysis low-passes (4th-order
  // Butterworth at 20 Hz, zero phase) and keeps every `decimation`-th sample of. The plant's
  // pulse is 8 N for 50 ms; the same filter makes it a peak of `hi` (its overshoot included),
  // and a sample grid can miss the top by up to half a step: `lo`. Around that, what the
  // corrected model leaves unexplained: three times its held-out RMS (the measure the suite's
  // coefficient tolerances use; a pulse near a stick or reversal rides on friction misfit).
  const double fs_hz = 1000.0, pulse_n = 8.0, pulse_s = 0.050;
  const int decim = g.result.findings.method.decimation;
  std::vector<double> pulse(1000, 0.0);
  for (std::size_t k = 400; k < 400 + static_cast<std::size_t>(pulse_s * fs_hz); ++k)
    pulse[k] = pulse_n;
  const auto filtered = maglead::analysis::filtfilt_butter4(pulse, 20.0, fs_hz);
  const auto top = std::max_element(filtered.begin(), filtered.end());
  const double hi = *top;
  const double lo = std::min(*(top - decim / 2), *(top + decim / 2));
  const double noise = 3.0 * heldout_after(g.result);
  std::printf("pulse of %.1f N seen as %.2f .. %.2f N, +/- %.2f N unexplained\n", pulse_n, lo, hi,
              noise);
  // Every event reported is a true pulse, at its time, with its force.
  // A pulse that comes while the nut sticks is taken up by static friction and leaves no trace
  // in the force balance, so not every pulse need be seen; most must.
  std::size_t seen = 0;
  for (const auto& e : g.result.findings.events) {
    if (e.type != "external_disturbance") continue;
    ++seen;
    const double t = e.t_s;
    EXPECT_TRUE(std::any_of(g.truth.disturbance_times_s.begin(), g.truth.disturbance_times_s.end(),
                            [&](double p) { return std::abs(p - t) < 0.05; }))
        << "event at " << t << " s is no pulse";
    const double f = e.force_n.value_or(0.0);
    std::printf("  event at %.3f s: %.2f N\n", t, f);
    EXPECT_GE(f, lo - noise) << "at " << t;
    EXPECT_LE(f, hi + noise) << "at " << t;
  }
  EXPECT_GE(2 * seen, g.truth.disturbance_times_s.size() + 1) << "most pulses reported";
}

// An 8 N pulse on a nut standing between moves or under a hand (7.5 N friction) throws it 8 to
// 15 counts to its next stand within 5 ms: no sliding sample shows it, and the stand it reaches is
// held by the pulse. From stand to stand the recorded forces must do the friction's work (7.5 N
// per metre of travel, the level every other jump of the recording shows); these did none. Seed
// 5 puts pulses at 14.16 s (under a hand) and 28.56 s (between pushes), both throws, and 17.86 s
// (in a move, in the residual). Without the jumps' balance only the one in the move was reported.
TEST(GeneratedSuite, ExternalDisturbanceThrowingAStandingNutIsAnEvent) {
  const auto g = run("mixed-moves", 40.0, {{"external_disturbance", 8.0}});
  std::size_t seen = 0;
  for (const auto& e : g.result.findings.events) {
    if (e.type != "external_disturbance") continue;
    ++seen;
    const double f = e.force_n.value_or(0.0);
    std::printf("  event at %.3f s for %.3f s: %.2f N\n", e.t_s, e.duration_s.value_or(0.0), f);
    EXPECT_TRUE(std::any_of(g.truth.disturbance_times_s.begin(), g.truth.disturbance_times_s.end(),
                            [&](double p) { return std::abs(p - e.t_s) < 0.05; }))
        << "event at " << e.t_s << " s is no pulse";
    // The shortfall is the pulse's force while it pushed the nut along its jump.
    EXPECT_NEAR(f, 8.0, 1.0) << "at " << e.t_s;
  }
  for (double p : g.truth.disturbance_times_s) std::printf("  pulse at %.3f s\n", p);
  EXPECT_EQ(seen, g.truth.disturbance_times_s.size()) << "every pulse reported";
}

// A hand pushes the nut on a held screw (like hand-push); one push exceeds what the coupling
// holds (about 44.5 N), the nut steps out by one lead, the hand follows it. `overload` false: the
// same pushes, all within the coupling's strength (the control).
struct StepOutRun {
  maglead::Recording rec;
  std::vector<double> slip_times_s;  // true: the phase passed ±π from its branch
  std::vector<int> leads;
};

StepOutRun step_out_recording(bool overload) {
  auto params = maglead::paper_like_plant();
  const auto& act = params.actuator;
  const double L = act.lead_m, p0 = 0.020;
  maglead::SimulatedActuator plant(params, 11, p0);
  const double screw0 = maglead::rest_angle_rad(p0, L);
  constexpr double k_hand = 1500.0, c_hand = 100.0;
  // Pushes of 2 s, alternating, peaks 20 … 30 N; the eighth pulls −56 N if overloading: past
  // the coupling's peak and static friction (45 + 7.5 N) the nut slips a lead, which relaxes
  // the hand by 9 N (1500 N/m × 6 mm); the hand's damping keeps the nut from running on.
  auto push = [](double t) { return static_cast<int>(t / 2.2); };
  auto hand_n = [&](double t) {
    const int i = push(t);
    const double tau = (t - 2.2 * i) / 2.0;
    if (tau >= 1.0) return 0.0;
    double peak = (i % 2 ? -1.0 : 1.0) * (20.0 + 2.0 * (i % 6));
    if (i == 7 && overload) peak = -56.0;
    const double s = std::sin(kPi * tau);
    return peak * s * s;
  };
  StepOutRun out;
  std::vector<std::vector<double>> cols(5);
  maglead::SensorSample s;
  double branch = maglead::phase_rad(plant.truth().screw_angle_rad, p0, L);
  int slips_before_push = 0, last_push = -1;
  for (int k = 0; k <= 30000; ++k) {
    const double t = k * 1e-3;
    const double f = hand_n(t);
    const double phi = maglead::balancing_phase_rad(params.coupling, f);
    // The hand holds the nut where the coupling balances its force, on the branch the nut was
    // on when the push began (it follows a slipped nut from the next push on).
    if (push(t) != last_push) last_push = push(t), slips_before_push = plant.truth().slips;
    const double anchor = (screw0 - phi) * L / (2 * kPi) - slips_before_push * L + f / k_hand;
    maglead::LoadSetting load;
    load.kind = maglead::LoadSetting::Kind::compliant;
    load.stiffness_n_per_m = k_hand;
    load.damping_n_s_per_m = c_hand;
    load.anchor_pos_m = anchor;
    plant.set_load(load);
    plant.read_sensors(t, s);
    const double true_phi =
        maglead::phase_rad(plant.truth().screw_angle_rad, plant.truth().nut_pos_m, L);
    if (std::abs(true_phi - branch) > kPi) {
      const double nb = branch + 2 * kPi * std::round((true_phi - branch) / (2 * kPi));
      out.slip_times_s.push_back(t);
      out.leads.push_back(static_cast<int>(std::lround((nb - branch) / (2 * kPi))));
      branch = nb;
    }
    const double motor = maglead::motor_angle_rad_from_counts(s.motor_counts, act);
    cols[0].push_back(t);
    cols[1].push_back(motor);
    cols[2].push_back(maglead::screw_angle_rad_from_motor_rad(motor, act));
    cols[3].push_back(maglead::nut_pos_m_from_counts(s.linear_counts, act));
    cols[4].push_back(s.load_force_n);
  }
  out.rec.path = overload ? "step-out (generated)" : "step-out control (generated)";
  out.rec.metadata = {{"sample_rate_hz", "1000"}, {"lead_m", "0.006"}, {"gear_ratio", "6.6"}};
  out.rec.names = {"t_s", "motor_angle_rad", "screw_angle_rad", "nut_pos_m", "load_force_n"};
  out.rec.columns = std::move(cols);
  return out;
}

TEST(GeneratedSuite, StepOutIsAnEventWithItsTime) {
  const auto run_ = step_out_recording(true);
  ASSERT_FALSE(run_.slip_times_s.empty()) << "the plant must step out";
  const auto r = analyze(run_.rec);
  std::vector<double> times;
  std::vector<int> leads;
  for (const auto& e : r.findings.events)
    if (e.type == "step_out") {
      times.push_back(e.t_s);
      leads.push_back(e.leads.value_or(0));
    }
  row("step_out [t_s]", "hand overload", run_.slip_times_s, times, r);
  // One event per slip of the plant, at its time: the raw phase passes ±π within a sample or
  // two of the truth (one encoder count is 0.023 rad; the phase moves radians per millisecond
  // while the nut slips).
  ASSERT_EQ(times.size(), run_.slip_times_s.size()) << events_text(r);
  for (std::size_t i = 0; i < times.size(); ++i) {
    EXPECT_NEAR(times[i], run_.slip_times_s[i], 0.002) << "slip " << i;
    EXPECT_EQ(leads[i], run_.leads[i]) << "slip " << i;
  }
  Parameters params;
  ASSERT_NE(finding(r, "step_out", &params), nullptr);
  EXPECT_EQ(static_cast<int>(parameter_value(params, "count")), static_cast<int>(times.size()));
  EXPECT_EQ(r.findings.effects.size(), 1u) << named_as(r);
}

// Without a screw-angle column the analysis takes the motor's through the header's gear ratio
// (angle_column's own buffer, not the recording's column): the same step-outs at the same times.
TEST(GeneratedSuite, MotorAngleAloneGivesTheSameStepOuts) {
  const auto run_ = step_out_recording(true);
  maglead::Recording motor_only = run_.rec;
  motor_only.names.erase(motor_only.names.begin() + 2);  // screw_angle_rad
  motor_only.columns.erase(motor_only.columns.begin() + 2);
  const auto step_outs = [](const AnalysisResult& r) {
    std::vector<std::pair<double, int>> out;
    for (const auto& e : r.findings.events)
      if (e.type == "step_out") out.emplace_back(e.t_s, e.leads.value_or(0));
    return out;
  };
  const auto with_screw = step_outs(analyze(run_.rec));
  const auto with_motor = step_outs(analyze(motor_only));
  ASSERT_FALSE(with_screw.empty());
  ASSERT_EQ(with_motor.size(), with_screw.size());
  for (std::size_t i = 0; i < with_screw.size(); ++i) {
    EXPECT_NEAR(with_motor[i].first, with_screw[i].first, 1e-9) << "step-out " << i;
    EXPECT_EQ(with_motor[i].second, with_screw[i].second) << "step-out " << i;
  }
}

TEST(GeneratedSuite, ControlStepOutHandNamesNothing) {
  const auto run_ = step_out_recording(false);
  ASSERT_TRUE(run_.slip_times_s.empty());
  expect_nothing(analyze(run_.rec), "hand (no overload)");
}

// The forward selection takes Coulomb friction, an offset (the published symmetric model, 4.08 %)
// and direction-dependent friction (3.11 %); once that is in, its levels per direction span
// the first two, which add nothing taken last: the backward check drops them (the offset was
// kept at 0.01 ± 0.16 N before it) and the same model is stated by direction-dependent friction
// alone, at the same error.
TEST(Emps, DirectionDependentFrictionSpansTheCoulombAndOffsetTakenFirst) {
  const std::string path = MAGLEAD_EMPS_CSV;
  // The recording is part of the repository (data/emps/): missing, it is a failure, not a skip.
  ASSERT_TRUE(std::filesystem::exists(path)) << "EMPS recording not found at " << path;
  const auto rec = maglead::read_recording(path);
  const auto model =
      maglead::analysis::load_model(std::string(MAGLEAD_CONFIG_DIR) + "/emps_baseline.toml");
  const auto r = maglead::analysis::analyze_recording(rec, model, maglead::paper_calibration(),
                                                      maglead::ActuatorParams{}, {});
  const auto& e = r.findings.effects;
  ASSERT_GE(e.size(), 1u) << named_as(r);
  EXPECT_EQ(e[0].id, "asymmetric_friction");
  for (const auto& f : e) {  // every term is named physics of the effect library
    EXPECT_NE(maglead::effects::find(f.id), nullptr) << f.id;
    EXPECT_NE(f.id, "offset");
    EXPECT_NE(f.id, "coulomb_friction");
  }
  const auto& v = r.findings.validation;
  ASSERT_GE(v.size(), 4u);
  EXPECT_EQ(v[1].model, "+ coulomb_friction");
  EXPECT_EQ(v[2].model, "+ offset");
  EXPECT_EQ(v[3].model, "+ asymmetric_friction");
  int dropped = 0;
  for (const auto& n : r.findings.not_selected)
    if ((n.id == "offset" || n.id == "coulomb_friction") &&
        n.reason.value_or("").find("backward check") != std::string::npos)
      ++dropped;
  EXPECT_EQ(dropped, 2);
  // Its part in the final model: the terms taken before it were dropped, so without it the
  // model loses nearly all the baseline's held-out error it removed (98 %), not the 2 % it cut
  // when it joined.
  EXPECT_GT(e[0].improvement_pct, 90.0);
  expect_best_left_out_explained(r);
  const double sym = v[2].fitted_relative_error_pct.value_or(NAN),
               asym = v[3].fitted_relative_error_pct.value_or(NAN);
  std::printf(
      "EMPS relative error: baseline %.3f %%, symmetric %.3f %% (published 4.08), "
      "direction-dependent %.3f %% (published 3.11), final %.3f %%, full rate %.3f %%\n",
      v[0].fitted_relative_error_pct.value_or(NAN), sym, asym,
      r.findings.final_fit.relative_error_pct, r.findings.final_fit.full_rate_relative_error_pct);
  // Published: 4.08 % and 3.11 %. The symmetric stage lands at 4.13 % here (see the report).
  EXPECT_LT(sym, 4.2);
  EXPECT_LE(asym, 3.11);
  // The aim, direct ≤ 3.0 % (3.030 % while the filter's edge padding flipped the
  // first samples' curvature).
  EXPECT_LE(r.findings.final_fit.relative_error_pct, 3.0);
  // Physically plausible values, close to the benchmark's direction-dependent model.
  EXPECT_NEAR(parameter_value(e[0].parameters, "coulomb_pos_n", NAN), 20.14, 1.0);
  EXPECT_NEAR(parameter_value(e[0].parameters, "coulomb_neg_n", NAN), 20.63, 1.0);
  EXPECT_NEAR(parameter_value(e[0].parameters, "viscous_pos_n_s_per_m", NAN), 166.7, 10.0);
  EXPECT_NEAR(parameter_value(e[0].parameters, "viscous_neg_n_s_per_m", NAN), 240.4, 10.0);

  // The corrected model is the model: analysed again with it, the same recording gives the
  // reported final error (the same model on the same samples: equal up to rounding) and nothing
  // new is missing.
  const std::string corrected =
      testing::TempDir() + "/emps_corrected_" + std::to_string(::getpid()) + ".toml";
  maglead::analysis::save_model(corrected, r.corrected, "test");
  const auto again = maglead::analysis::analyze_recording(
      rec, maglead::analysis::load_model(corrected), maglead::paper_calibration(),
      maglead::ActuatorParams{}, {});
  EXPECT_NEAR(again.findings.baseline.relative_error_pct, r.findings.final_fit.relative_error_pct,
              1e-9);
  EXPECT_NEAR(again.findings.baseline.full_rate_relative_error_pct,
              r.findings.final_fit.full_rate_relative_error_pct, 1e-9);
  EXPECT_TRUE(again.findings.effects.empty()) << named_as(again);
  std::filesystem::remove(corrected);
}

// Rows [from, to) of a recording, with its header.
maglead::Recording rows_of(const maglead::Recording& rec, std::size_t from, std::size_t to) {
  maglead::Recording part = rec;
  for (auto& c : part.columns)
    c = std::vector<double>(c.begin() + static_cast<std::ptrdiff_t>(from),
                            c.begin() + static_cast<std::ptrdiff_t>(to));
  return part;
}

// The cross-test (a model corrected on the estimation record, run on the validation
// record, ≤ 5.5 %) cannot be run here: the validation record is not in the repository. Its
// nearest honest stand-in: the model corrected on the first half of the estimation record,
// fixed as written (no term refitted), predicts the second half. Measured 4.05 % (the second
// half fitted on itself: 4.00 %); the bar is the issue's.
TEST(Emps, AModelCorrectedOnTheFirstHalfPredictsTheSecond) {
  const auto rec = maglead::read_recording(MAGLEAD_EMPS_CSV);
  const std::size_t half = rec.rows() / 2;
  const auto model =
      maglead::analysis::load_model(std::string(MAGLEAD_CONFIG_DIR) + "/emps_baseline.toml");
  const auto analyze = [](const maglead::Recording& r, const maglead::analysis::ModelFile& m) {
    return maglead::analysis::analyze_recording(r, m, maglead::paper_calibration(),
                                                maglead::ActuatorParams{}, {});
  };
  const auto first = analyze(rows_of(rec, 0, half), model);
  const auto second = analyze(rows_of(rec, half, rec.rows()), first.corrected);
  EXPECT_TRUE(first.corrected.fit.empty()) << "the corrected model is run as written, not refitted";
  const double cross = second.findings.baseline.relative_error_pct;
  std::printf("EMPS first half %.3f %% direct, second half with that model %.3f %%\n",
              first.findings.final_fit.relative_error_pct, cross);
  EXPECT_LE(cross, 5.5);
}

// Digits after the decimal point of a printed number ("0.0016" → 4, "241" → 0).
int decimals(const std::string& number) {
  const auto dot = number.find('.');
  return dot == std::string::npos ? 0 : static_cast<int>(number.size() - dot - 1);
}

// Every parameter with an error is printed in `summary` as "name value ± error": the error to at
// most two significant digits, the value to the error's decimal place, both the numbers rounded.
void expect_printed_at_its_digits(const std::string& summary, const Parameters& values,
                                  const Parameters& errors) {
  for (const auto& p : values) {
    const double se = parameter_value(errors, p.name, NAN);
    // A grid value has no standard error and no key for one: the text says so.
    if (!std::isfinite(se) || !(se > 1e-9 * std::abs(p.value))) {
      EXPECT_NE(summary.find(p.name + " "), std::string::npos) << summary;
      EXPECT_NE(summary.find("(no standard error)"), std::string::npos) << summary;
      continue;
    }
    const auto at = summary.find(p.name + " ");
    ASSERT_NE(at, std::string::npos) << p.name << " not in '" << summary << "'";
    std::istringstream in(summary.substr(at + p.name.size() + 1));
    std::string value, pm, error;
    in >> value >> pm >> error;
    if (!error.empty() && error.back() == ',') error.pop_back();
    ASSERT_EQ(pm, "±") << summary;
    EXPECT_EQ(decimals(value), decimals(error)) << summary;
    std::string significant = error;
    std::erase(significant, '.');
    significant.erase(0, significant.find_first_not_of('0'));
    EXPECT_LE(significant.size(), 2u) << p.name << ": error " << error << " in " << summary;
    const double unit = std::pow(10.0, -decimals(error));
    EXPECT_NEAR(std::stod(value), p.value, 0.5 * unit + 1e-12) << summary;
    EXPECT_NEAR(std::stod(error), se, 0.5 * unit + 1e-12) << summary;
  }
}

// Every fitted parameter of the EMPS axis (the baseline's totals and each finding's) carries a
// finite positive standard error from the held-out segments, and is printed at the digits it
// allows, in analysis.json's summary as `maglead analyze` prints it.
TEST(Emps, EveryParameterHasAStandardErrorAndItsDigits) {
  const auto rec = maglead::read_recording(MAGLEAD_EMPS_CSV);
  const auto model =
      maglead::analysis::load_model(std::string(MAGLEAD_CONFIG_DIR) + "/emps_baseline.toml");
  const auto r = maglead::analysis::analyze_recording(rec, model, maglead::paper_calibration(),
                                                      maglead::ActuatorParams{}, {});
  ASSERT_GE(r.findings.effects.size(), 2u) << named_as(r);
  std::vector<std::pair<std::string, const EffectFinding*>> all;
  for (const auto* fit : {&r.findings.baseline, &r.findings.final_fit}) {
    const auto& values = fit->fitted_parameters.value();
    ASSERT_EQ(values.size(), 2u);  // mass and viscous friction: emps_baseline.toml fits them
    for (const auto& p : values) {
      const double se = parameter_value(fit->standard_errors, p.name, NAN);
      EXPECT_TRUE(std::isfinite(se) && se > 0) << p.name << " ± " << se;
    }
    expect_printed_at_its_digits(fit->summary, values, fit->standard_errors);
    std::printf("fitted: %s\n", fit->summary.c_str());
  }
  for (const auto& e : r.findings.effects) {
    for (const auto& p : e.parameters) {
      if (p.name == "period_m") continue;  // position_ripple's period: a grid value, no error
      const double se = parameter_value(e.standard_errors, p.name, NAN);
      EXPECT_TRUE(std::isfinite(se) && se > 0) << e.id << " " << p.name << " ± " << se;
    }
    expect_printed_at_its_digits(e.summary, e.parameters, e.standard_errors);
    std::printf("%s: %s\n", e.id.c_str(), e.summary.c_str());
  }
}

// A generated force-driven axis (a drive pushing a carriage against mass, friction and a return
// spring, the force logged with noise), with force pulses of `pulse_n` for 60 ms at `pulses_s`.
constexpr double kMass_kg = 10.0, kViscous = 50.0, kCoulomb_n = 5.0;
constexpr double kStiffness = 200.0, kRest_m = 0.02;
maglead::Recording generated_axis(const std::vector<double>& pulses_s, double pulse_n = 0.0,
                                  double mass_kg = kMass_kg) {
  maglead::Recording rec;
  rec.path = "generated axis";
  std::vector<double> t, pos, force;
  std::srand(7);
  for (int i = 0; i < 30000; ++i) {
    const double ts = i * 1e-3, w1 = 2 * M_PI * 0.2, w2 = 2 * M_PI * 0.7;
    const double p = 0.1 * std::sin(w1 * ts) + 0.03 * std::sin(w2 * ts + 1.0);
    const double v = 0.1 * w1 * std::cos(w1 * ts) + 0.03 * w2 * std::cos(w2 * ts + 1.0);
    const double a = -0.1 * w1 * w1 * std::sin(w1 * ts) - 0.03 * w2 * w2 * std::sin(w2 * ts + 1.0);
    const double noise = 0.2 * (std::rand() / static_cast<double>(RAND_MAX) - 0.5);
    double pulse = 0.0;
    for (double t0 : pulses_s) pulse += ts >= t0 && ts < t0 + 0.060 ? pulse_n : 0.0;
    t.push_back(ts);
    pos.push_back(p);
    force.push_back(mass_kg * a + kViscous * v + kCoulomb_n * (v > 0 ? 1 : -1) +
                    kStiffness * (p - kRest_m) + noise + pulse);
  }
  rec.names = {"t_s", "pos_m", "drive_force_n"};
  rec.columns = {t, pos, force};
  return rec;
}

maglead::analysis::ModelFile axis_model() {
  maglead::analysis::ModelFile model;
  model.system = "axis";
  model.fit = {"nut_mass_kg", "viscous_n_s_per_m", "coulomb_n"};
  return model;
}

// The axis path names the spring the effect unit states, in the unit's parameter names, from the
// units' axis columns (the same law the twin runs).
TEST(Axis, GeneratedSpringIsNamedWithTheUnitsParameters) {
  const auto rec = generated_axis({});
  maglead::analysis::ModelFile model = axis_model();
  const auto r = maglead::analysis::analyze_recording(rec, model, maglead::paper_calibration(),
                                                      maglead::ActuatorParams{}, {});
  ASSERT_EQ(r.findings.effects.size(), 1u) << named_as(r);
  const auto& e = r.findings.effects[0];
  EXPECT_EQ(e.id, "spring");
  EXPECT_NEAR(parameter_value(e.parameters, "stiffness_n_per_m", NAN), kStiffness,
              0.02 * kStiffness);
  EXPECT_NEAR(parameter_value(e.parameters, "rest_position_m", NAN), kRest_m, 2e-3);
  // The standard error from the held-out segments is honest: the truth lies within 3 of them.
  const double k_se = parameter_value(e.standard_errors, "stiffness_n_per_m", NAN);
  EXPECT_TRUE(std::isfinite(k_se) && k_se > 0) << k_se;
  EXPECT_LE(std::abs(parameter_value(e.parameters, "stiffness_n_per_m", NAN) - kStiffness),
            3 * k_se)
      << e.summary;
  std::printf("generated spring: %s (true stiffness %g N/m, rest %g m)\n", e.summary.c_str(),
              kStiffness, kRest_m);
  const auto& base = r.findings.final_fit.fitted_parameters.value();
  EXPECT_NEAR(parameter_value(base, "nut_mass_kg", NAN), kMass_kg, 0.05 * kMass_kg);
  EXPECT_NEAR(parameter_value(base, "coulomb_n", NAN), kCoulomb_n, 0.3);
  // The corrected model holds the spring as a term and the fitted totals as values: analysed
  // with it, nothing is missing.
  ASSERT_NE(r.corrected.find("spring"), nullptr);
  EXPECT_NEAR(r.corrected.nut_mass_kg, kMass_kg, 0.05 * kMass_kg);
  const auto again = maglead::analysis::analyze_recording(
      rec, r.corrected, maglead::paper_calibration(), maglead::ActuatorParams{}, {});
  EXPECT_TRUE(again.findings.effects.empty()) << named_as(again);
}

// The plausible ranges are in the actuator's own scales (its largest drive force, its fastest
// speed), not one actuator's size: on a 60 kg carriage analysed with a model whose mass is 40 kg
// (the corrected model of another load), the changed mass is named (a range in kilograms up to
// 20, the paper actuator's scale, had called it implausible and said nothing was missing).
TEST(Axis, AHeavyCarriagesChangedMassIsNamedWithTheModelItWasGiven) {
  constexpr double kHeavy_kg = 60.0;
  const auto rec = generated_axis({}, 0.0, kHeavy_kg);
  const auto first = maglead::analysis::analyze_recording(
      rec, axis_model(), maglead::paper_calibration(), maglead::ActuatorParams{}, {});
  auto model = first.corrected;
  ASSERT_NEAR(model.nut_mass_kg, kHeavy_kg, 0.05 * kHeavy_kg) << named_as(first);
  model.nut_mass_kg = 40.0;
  const auto r = maglead::analysis::analyze_recording(rec, model, maglead::paper_calibration(),
                                                      maglead::ActuatorParams{}, {});
  ASSERT_EQ(r.findings.effects.size(), 1u) << named_as(r);
  const auto& e = r.findings.effects[0];
  EXPECT_EQ(e.id, "mass_error");
  const double m = parameter_value(e.parameters, "nut_mass_kg", NAN);
  EXPECT_NEAR(m, kHeavy_kg, 3 * parameter_value(e.standard_errors, "nut_mass_kg", NAN) + 0.1)
      << e.summary;
}

// A drive force logged with the wrong sign is missing force no library effect explains
// plausibly (every law would need a negative mass or friction): the axis says so, as the
// actuator does, with what to check, instead of naming an effect or "nothing is missing".
TEST(Axis, AForceOfTheWrongSignIsNotExplainedPlausibly) {
  const auto rec = generated_axis({});
  const auto first = maglead::analysis::analyze_recording(
      rec, axis_model(), maglead::paper_calibration(), maglead::ActuatorParams{}, {});
  auto flipped = rec;
  for (double& f : flipped.columns[2]) f = -f;
  const auto r = maglead::analysis::analyze_recording(
      flipped, first.corrected, maglead::paper_calibration(), maglead::ActuatorParams{}, {});
  EXPECT_TRUE(r.findings.effects.empty()) << named_as(r);
  EXPECT_FALSE(r.findings.nothing_missing.value_or(true));
  ASSERT_TRUE(r.findings.unexplained.has_value()) << r.findings.conclusion;
  const auto& u = *r.findings.unexplained;
  EXPECT_NE(u.message.find("no library effect explains this plausibly"), std::string::npos);
  EXPECT_NE(u.check.find("sign of drive_force_n"), std::string::npos) << u.check;
  std::printf("%s\n  where: %s\n", u.message.c_str(), u.where.c_str());
}

// The one pulse finder on the axis: force pulses no motion explains are reported in the
// actuator's one form, external_disturbance events at their times with their force (the
// residual is band-limited by the decimation, so the peak is read within a third) and one
// external_disturbance finding with their count, which the corrected model does not take up;
// a recording without them has none.
TEST(Axis, IsolatedForcePulsesAreEventsAtTheirTimes) {
  const std::vector<double> at_s = {8.3, 21.7};
  const double pulse_n = 10.0;
  const auto model = axis_model();
  const auto r = maglead::analysis::analyze_recording(generated_axis(at_s, pulse_n), model,
                                                      maglead::paper_calibration(),
                                                      maglead::ActuatorParams{}, {});
  ASSERT_EQ(r.findings.events.size(), at_s.size()) << events_text(r);
  for (std::size_t k = 0; k < at_s.size(); ++k) {
    const auto& e = r.findings.events[k];
    EXPECT_EQ(e.type, "external_disturbance");
    EXPECT_NEAR(e.t_s, at_s[k], 0.1) << events_text(r);
    EXPECT_NEAR(e.force_n.value_or(0), pulse_n, pulse_n / 3) << events_text(r);
  }
  Parameters p;
  ASSERT_NE(finding(r, "external_disturbance", &p), nullptr) << named_as(r);
  EXPECT_EQ(maglead::analysis::parameter_value(p, "count"), static_cast<double>(at_s.size()));
  EXPECT_EQ(r.corrected.find("external_disturbance"), nullptr) << "an event is no force law";
  const auto clean = maglead::analysis::analyze_recording(
      generated_axis({}), model, maglead::paper_calibration(), maglead::ActuatorParams{}, {});
  EXPECT_TRUE(clean.findings.events.empty()) << events_text(clean);
}

TEST(Signal, ButterworthPassesLowAndStopsHighFrequencies) {
  std::vector<double> lo(4000), hi(4000);
  for (std::size_t i = 0; i < lo.size(); ++i) {
    lo[i] = std::sin(2 * M_PI * 5.0 * static_cast<double>(i) / 1000.0);
    hi[i] = std::sin(2 * M_PI * 300.0 * static_cast<double>(i) / 1000.0);
  }
  const auto a = maglead::analysis::filtfilt_butter4(lo, 100, 1000);
  const auto b = maglead::analysis::filtfilt_butter4(hi, 100, 1000);
  for (std::size_t i = 500; i < 3500; ++i) {
    EXPECT_NEAR(a[i], lo[i], 1e-3);  // zero phase: no lag at all
    EXPECT_LT(std::abs(b[i]), 1e-3);
  }
  EXPECT_THROW(maglead::analysis::filtfilt_butter4(lo, 600, 1000), std::invalid_argument);
}

// A recording that starts and ends accelerating keeps its acceleration at the edges through the
// zero-phase filter: the padding continues the signal's curvature (an odd reflection flipped it,
// and the first sample read no acceleration at all).
TEST(Signal, ZeroPhaseFilterKeepsAnAccelerationAtTheEdges) {
  const double a_m_s2 = 0.4, v0_m_s = 0.05, dt = 1e-3;
  std::vector<double> p(2000);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double t = static_cast<double>(i) * dt;
    p[i] = v0_m_s * t + 0.5 * a_m_s2 * t * t;
  }
  for (double cutoff_hz : {100.0, 25.0}) {
    const auto a = maglead::analysis::central_diff2(
        maglead::analysis::filtfilt_butter4(p, cutoff_hz, 1000), dt);
    for (std::size_t i : {std::size_t{0}, std::size_t{1}, p.size() - 1})
      EXPECT_NEAR(a[i], a_m_s2, 0.01 * a_m_s2) << cutoff_hz << " Hz, sample " << i;
  }
}

TEST(BadInput, MissingColumnNamesFileAndColumn) {
  const std::string path = testing::TempDir() + "/analysis_bad.csv";
  {
    std::FILE* f = std::fopen(path.c_str(), "w");
    std::fputs("# format: mls-recording/1\nt_s,nut_pos_m\n0,0\n0.001,0\n", f);
    std::fclose(f);
  }
  const auto rec = maglead::read_recording(path);
  const maglead::ActuatorParams act;
  try {
    maglead::analysis::analyze_recording(rec, maglead::analysis::actuator_model_from_config(act),
                                         maglead::paper_calibration(), act, {});
    FAIL() << "must throw";
  } catch (const maglead::RecordingError& e) {
    EXPECT_NE(std::string(e.what()).find("analysis_bad.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("load_force_n"), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(TwinCheck, ScoresTheWholeRecordingOrWindowsSpreadOverIt) {
  using maglead::analysis::actuator::scoring_windows;
  // Up to the budget: every sample, one window.
  const auto whole = scoring_windows(60000, 65536, 8);
  ASSERT_EQ(whole.size(), 1u);
  EXPECT_EQ(whole[0].begin, 0u);
  EXPECT_EQ(whole[0].end, 60000u);
  // An hour at 1 kHz: eight windows from the start to the end, equally long and equally spaced,
  // the budget in all.
  const std::size_t n = 3600000;
  const auto w = scoring_windows(n, 65536, 8);
  ASSERT_EQ(w.size(), 8u);
  EXPECT_EQ(w.front().begin, 0u);
  EXPECT_EQ(w.back().end, n);
  std::size_t total = 0;
  for (std::size_t k = 0; k < w.size(); ++k) {
    EXPECT_EQ(w[k].end - w[k].begin, 65536u / 8);
    total += w[k].end - w[k].begin;
    if (k > 0) {
      EXPECT_GE(w[k].begin, w[k - 1].end);  // no sample scored twice
      const auto gap = w[k].begin - w[k - 1].begin, first = w[1].begin - w[0].begin;
      EXPECT_LE(gap > first ? gap - first : first - gap, 1u);
    }
  }
  EXPECT_LE(total, 65536u);
}
