// The generated matrix (issue 24): every effect of docs/effects.md at two magnitudes, at 500 Hz,
// 1 kHz and 2 kHz, with two load-cell noise levels, alone and in pairs, on three actuators given
// by their configuration folders: the paper's (config/), another one
// (tests/analysis/other_actuator/: other lead, encoders, mass, friction, a coupling 1.6 times as
// strong, and a calibration polynomial off from that coupling by about 0.05 N) and a third
// (tests/analysis/third_actuator/: 20 mm lead on a direct drive, 512 motor counts, 50 µm linear
// count, 2.5 kg, 20 N·s/m, 12 N, a coupling 0.6 times the paper's, a bench calibration off by
// 0.05 N; the scenarios scale their forces to its safe force). Each case prints one row; the
// suite prints the false-claim count and asserts it is 0.
//
// A claim is false when the analysis names an effect (a finding's id) that is not concealed in
// the plant, unless an alternative it lists (>= 95 %) or an accepted equivalence (offset ~
// asymmetric friction, angle ~ position ripple at one lead) is. A concealed effect not named is
// a miss: printed and counted, and asserted only for the larger magnitude alone on the paper's
// actuator at 1 kHz (the sizes the rest of the suite shows are resolved).
//
// CI runs a representative subset (each effect once alone per actuator, on a rotating rate and
// noise, a chain of pairs, and the full matrix's cases that once made a false claim);
// MAGLEAD_FULL_MATRIX=1 runs every combination,
// MAGLEAD_MATRIX_FILTER=ID only the cases with that effect, MAGLEAD_MATRIX_SCENARIO=S runs
// them all in scenario S, MAGLEAD_MATRIX_SEED=N with seed N (default 5),
// MAGLEAD_MATRIX_KEEP=1 keeps their recordings (the path is printed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "../test_tmp.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/model_file.hpp"
#include "maglead/plant/scenario.hpp"
#include "maglead/settings/settings.hpp"

namespace {

using maglead::analysis::AnalysisResult;

// The effect, its plant key, the larger magnitude and the scenario that exercises it.
struct EffectCase {
  std::string id, scenario;
  double magnitude;
  std::vector<std::pair<std::string, double>> extra;  // shape keys (phase, …)
};

const std::vector<EffectCase>& effect_cases() {
  static const std::vector<EffectCase> all = {
      {"coulomb_friction", "position-moves", 2.0, {}},
      {"viscous_friction", "position-moves", 50.0, {}},
      {"asymmetric_friction", "hand-push", 2.0, {}},
      {"stribeck_friction", "hand-push", 4.5, {}},
      {"offset", "hand-push", 2.0, {}},
      {"spring", "position-moves", 300.0, {}},
      {"mass_error", "force-steps", 2.0, {}},
      {"coupling_gain_error", "hand-push", 0.1, {}},
      {"gain_drift", "hand-push", -0.05, {}},
      {"angle_ripple", "position-moves", 0.1, {{"angle_ripple.phase_rad", 0.5}}},
      {"position_ripple", "position-moves", 1.5, {{"position_ripple.phase_rad", 1.0}}},
      {"end_effect", "position-moves", 0.005, {}},
      {"backlash", "force-steps", 0.05, {}},
      {"sensor_delay", "force-steps", 0.010, {}},
      {"load_cell_delay", "force-steps", 0.010, {}},
      {"external_disturbance", "position-moves", 8.0, {}},
  };
  return all;
}

struct Bench {
  std::string name;
  maglead::ActuatorParams act;
  maglead::ForceCalibration cal;
  maglead::analysis::ModelFile model;
  maglead::PlantParams plant;
};

// The actuator of a configuration folder; the plant's true coupling is the paper-like curve
// times `coupling_scale` (a plant's truth is not configuration: the calibration only
// approximates it).
Bench setup_from(const std::string& name, const std::string& dir, double coupling_scale) {
  Bench s;
  s.name = name;
  s.act = maglead::load_actuator_params(dir + "/actuator.toml");
  s.cal = maglead::load_calibration(dir + "/calibration.toml");
  s.model = maglead::analysis::load_model(dir + "/model.toml");
  s.plant = maglead::paper_like_plant();
  s.plant.actuator = s.act;
  auto& c = s.plant.coupling;
  c.mean_n *= coupling_scale;
  for (double& x : c.cos_n) x *= coupling_scale;
  for (double& x : c.sin_n) x *= coupling_scale;
  return s;
}

const Bench& paper() {
  static const Bench s = setup_from("paper", MAGLEAD_CONFIG_DIR, 1.0);
  return s;
}
const Bench& other() {
  static const Bench s = setup_from("other", MAGLEAD_OTHER_ACTUATOR_DIR, 1.6);
  return s;
}
const Bench& third() {
  static const Bench s = setup_from("third", MAGLEAD_THIRD_ACTUATOR_DIR, 0.6);
  return s;
}
const Bench& bench(int index) { return index == 0 ? paper() : index == 1 ? other() : third(); }

struct Case {
  const Bench* setup;
  std::vector<const EffectCase*> effects;
  double scale;  // 1: the larger magnitude, 0.5: the smaller
  double rate_hz, noise_n;
  std::string scenario = {};  // empty: the first effect's
  unsigned seed = 5;          // MAGLEAD_MATRIX_SEED overrides it
};

// Ids that name a concealed effect: its own and its accepted equivalents.
std::set<std::string> accepted(const std::vector<const EffectCase*>& truth) {
  std::set<std::string> ok;
  for (const auto* e : truth) {
    ok.insert(e->id);
    if (e->id == "offset") ok.insert("asymmetric_friction");
    if (e->id == "asymmetric_friction") ok.insert("offset");
    if (e->id == "angle_ripple") ok.insert("position_ripple");
  }
  return ok;
}

struct Outcome {
  int named = 0, missed = 0, false_claims = 0;
  std::string claims;
  std::string again;  // model terms named when analysed again with its corrected model
};

// Issue 43: analysed again with its own corrected model, a recording names no new model term
// (events are the recording's and may recur): the ids of those it does name.
std::string named_again(const maglead::Recording& rec, const AnalysisResult& first,
                        const Bench& setup, const maglead::ActuatorParams& act,
                        const maglead::analysis::AnalysisOptions& aopt) {
  const auto again =
      maglead::analysis::analyze_recording(rec, first.corrected, setup.cal, act, aopt);
  std::string ids;
  for (const auto& e : again.findings.effects)
    if (!e.evidence.events) ids += (ids.empty() ? "" : ", ") + e.id;
  return ids;
}

Outcome judge(const AnalysisResult& r, const std::vector<const EffectCase*>& truth) {
  const auto ok = accepted(truth);
  Outcome o;
  std::set<std::string> seen;
  for (const auto& f : r.findings.effects) {
    o.claims += (o.claims.empty() ? "" : ", ") + f.id;
    bool right = ok.count(f.id) > 0;
    if (right) seen.insert(f.id);
    for (const auto& a : f.alternatives)
      if (a.explains_pct >= 95.0 && ok.count(a.id)) right = true, seen.insert(a.id);
    o.false_claims += right ? 0 : 1;
  }
  for (const auto* e : truth) {
    const auto eq = accepted({e});
    const bool named = std::any_of(eq.begin(), eq.end(), [&](auto& id) { return seen.count(id); });
    (named ? o.named : o.missed) += 1;
  }
  if (o.claims.empty()) o.claims = "nothing";
  return o;
}

Outcome run_case(const Case& c, int index) {
  maglead::ScenarioOptions opt;
  opt.scenario = c.scenario.empty() ? c.effects.front()->scenario : c.scenario;
  // MAGLEAD_MATRIX_SCENARIO=S runs every case in scenario S (mixed-moves: force control, hand
  // pushes and moves in turn, as the practice recordings mix them).
  if (const char* sc = std::getenv("MAGLEAD_MATRIX_SCENARIO")) opt.scenario = sc;
  opt.duration_s = 40.0;
  opt.seed = c.seed;
  // MAGLEAD_MATRIX_SEED=N draws other hand profiles, noise and pulse times.
  if (const char* seed = std::getenv("MAGLEAD_MATRIX_SEED")) opt.seed = std::stoul(seed);
  opt.plant = c.setup->plant;
  opt.plant.actuator.sample_rate_hz = c.rate_hz;
  opt.plant.load_cell_noise_n = c.noise_n;
  opt.estimator_calibration = c.setup->cal;
  for (const auto* e : c.effects) {
    maglead::set_plant_effect(opt.plant.effects, e->id, c.scale * e->magnitude);
    for (const auto& [k, v] : e->extra) maglead::set_plant_effect(opt.plant.effects, k, v);
  }
  const std::string path = test_tmp_dir() + "/matrix_" + std::to_string(index) + ".csv";
  maglead::run_scenario(opt, path);
  auto act = c.setup->act;
  act.sample_rate_hz = c.rate_hz;
  maglead::analysis::AnalysisOptions aopt;
  // analysis_twin_round_trip checks it (and costs twin runs)
  aopt.actuator.twin_force_check = false;
  // MAGLEAD_MATRIX_CALIBRATION_ACCURACY_N=X analyses as `analyze --calibration-accuracy X`.
  if (const char* acc = std::getenv("MAGLEAD_MATRIX_CALIBRATION_ACCURACY_N"))
    aopt.actuator.calibration_accuracy_n = std::stod(acc);
  const auto rec = maglead::read_recording(path);
  const auto r = maglead::analysis::analyze_recording(rec, c.setup->model, c.setup->cal, act, aopt);
  // MAGLEAD_MATRIX_KEEP=1 keeps the recordings, to look at one case with `maglead analyze`.
  const char* keep = std::getenv("MAGLEAD_MATRIX_KEEP");
  if (keep && std::string(keep) == "1")
    std::printf("kept %s\n", path.c_str());
  else
    std::filesystem::remove(path);
  auto o = judge(r, c.effects);
  o.again = named_again(rec, r, *c.setup, act, aopt);
  std::string truth;
  for (const auto* e : c.effects) truth += (truth.empty() ? "" : " + ") + e->id;
  std::printf("| %s | %s ×%.1f | %s | %.0f Hz | %.1f N | %s | %d | %d | %s |\n",
              c.setup->name.c_str(), truth.c_str(), c.scale, opt.scenario.c_str(), c.rate_hz,
              c.noise_n, o.claims.c_str(), o.missed, o.false_claims,
              o.again.empty() ? "nothing" : o.again.c_str());
  return o;
}

// Cases of the full matrix that once made a false claim, run in CI beside the subset: the
// actuator, the concealed effects (joined by '+'), the magnitude, rate and load-cell noise.
struct Regression {
  const char *actuator, *effects;
  double scale, rate_hz, noise_n;
  const char* scenario = "";  // empty: the first effect's
  unsigned seed = 5;
};
const std::vector<Regression>& regressions() {
  static const std::vector<Regression> all = {
      // A load-cell delay under a spring load is viscous friction to the data (the spring's
      // rate is its speed); the delay's column is noisy: listed beside it only if its noise is
      // taken off (stats::partial_r2).
      {"paper", "load_cell_delay", 1.0, 500.0, 0.5},
      {"other", "load_cell_delay", 0.5, 500.0, 0.5},
      // The other actuator's moves at 500 Hz advance a whole number of counts per sample: the
      // rounding is locked, one bias per move the filter keeps (an offset of 0.21 N, a Coulomb
      // level 0.12 N low were named on it): Prepared::locked_floor_n.
      {"other", "viscous_friction", 1.0, 500.0, 0.1},
      {"other", "coulomb_friction+viscous_friction", 1.0, 500.0, 0.1},
      // At 1 kHz its 5 mm/s moves advance a count every other sample: the rounding repeats every
      // two samples and its mean (up to a quarter count) stays; an offset of 0.09 N was named.
      {"other", "end_effect", 0.5, 1000.0, 0.1},
      // The third actuator's nut sticks and breaks away inside the end zone, where the weakened
      // coupling misses 1.1 N at the break-away force for 30-70 ms: a force pulse to the finder,
      // the end effect's law where the nut stood (pulses::unexplained); the law itself is below
      // the 0.5 N load-cell noise's floor and not named.
      {"third", "end_effect", 1.0, 2000.0, 0.5},
      {"third", "position_ripple+end_effect", 1.0, 500.0, 0.5},
      {"third", "end_effect+backlash", 1.0, 2000.0, 0.5},
      // Hand pushes with the screw held cover 2.4 mm of its 20 mm lead: the coupling's force is
      // a function of position there, so a gain error is also a spring with a free rest position
      // (which takes the calibration's few hundredths of a newton too) and a ripple of 10 or 20
      // mm; neither is resolved (Effect::resolved_at, selection's preferred). An angle ripple is a
      // constant gain on a held screw (its sin θ column is zero to rounding: stats::solve).
      {"third", "coupling_gain_error", 0.5, 1000.0, 0.1},
      {"third", "gain_drift+angle_ripple", 1.0, 1000.0, 0.1},
      // Force steps that turn the screw less than a turn: an angle ripple is not seen to repeat;
      // the backlash (a Coulomb level change while sliding against 12 N) is its alternative.
      {"third", "backlash", 0.5, 1000.0, 0.5},
      // Beside a 10 % gain error the bench calibration's error is 10 % larger in the model's
      // force: an offset of 0.057 N explaining 0.076 N was named against the 0.07 N minimum.
      {"third", "mass_error+coupling_gain_error", 1.0, 2000.0, 0.1},
      // In mixed-moves (MAGLEAD_MATRIX_SCENARIO) the same pair: the Coulomb level the selection
      // took for the gain left 0.7 N at force steps, seven pulses to the finder that the gain
      // explains once the Coulomb level is refitted beside it (pulses::unexplained).
      {"third", "mass_error+coupling_gain_error", 1.0, 1000.0, 0.1, "mixed-moves"},
      // A Stribeck hump read from sliding with a Coulomb level 0.11 N above the baseline's
      // beside it: the level is the Stribeck law's coulomb_n, one finding.
      {"other", "stribeck_friction", 0.5, 1000.0, 0.1, "mixed-moves"},
      // Force control and hand pushes in turn: an offset of 0.062 N explained 0.071 N beside a
      // position ripple (the ripple's refit made up the rest), against the 0.07 N minimum. A
      // law's own force must pass the minimum too (NutRules::resolved).
      {"third", "position_ripple", 1.0, 2000.0, 0.1, "mixed"},
      // There an angle ripple seen over part of a screw turn read as direction-dependent
      // friction (30 % of the held-out error) where the ripple explains 99 %: an unseen period
      // takes the pick's place when the pick adds nothing beside it (selection.cpp).
      {"third", "angle_ripple", 1.0, 1000.0, 0.1, "mixed"},
  };
  return all;
}

const EffectCase& effect_case(const std::string& id) {
  for (const auto& e : effect_cases())
    if (e.id == id) return e;
  throw std::invalid_argument("no generated case for " + id);
}

// The regression's case on bench `s`.
Case case_of(const Bench& s, const Regression& r) {
  Case c{&s, {}, r.scale, r.rate_hz, r.noise_n, r.scenario, r.seed};
  const std::string ids = r.effects;
  for (std::size_t at = 0; at != std::string::npos;) {
    const std::size_t plus = ids.find('+', at);
    c.effects.push_back(&effect_case(ids.substr(at, plus == std::string::npos ? plus : plus - at)));
    at = plus == std::string::npos ? plus : plus + 1;
  }
  return c;
}

bool full_matrix() {
  const char* f = std::getenv("MAGLEAD_FULL_MATRIX");
  return f && std::string(f) == "1";
}

std::vector<Case> cases_for(const Bench& s) {
  const std::vector<double> rates = {500.0, 1000.0, 2000.0}, noises = {0.1, 0.5};
  const auto& all = effect_cases();
  std::vector<Case> out;
  int k = 0;
  for (const auto& e : all)
    for (double scale : {1.0, 0.5})
      for (double rate : rates)
        for (double noise : noises) {
          // The subset: one rate and noise per effect and magnitude, rotating.
          const bool pick = full_matrix() || (rate == rates[static_cast<std::size_t>(k) % 3] &&
                                              noise == noises[static_cast<std::size_t>(k / 3) % 2]);
          if (pick) out.push_back({&s, {&e}, scale, rate, noise});
          if (rate == rates.back() && noise == noises.back()) ++k;
        }
  // Pairs: each effect with the next (the first's scenario), at the larger magnitude.
  for (std::size_t i = 0; i < all.size(); ++i) {
    const auto& a = all[i];
    const auto& b = all[(i + 1) % all.size()];
    for (double rate : full_matrix() ? rates : std::vector<double>{1000.0})
      for (double noise : full_matrix() ? noises : std::vector<double>{0.1})
        out.push_back({&s, {&a, &b}, 1.0, rate, noise});
  }
  if (full_matrix()) return out;
  for (const auto& r : regressions())
    if (s.name == r.actuator) out.push_back(case_of(s, r));
  return out;
}

class Matrix : public ::testing::TestWithParam<int> {};

TEST_P(Matrix, NamesNoEffectThatIsNotThere) {
  const Bench& s = bench(GetParam());
  const auto cases = cases_for(s);
  std::printf(
      "| actuator | concealed | scenario | rate | load-cell noise | named | missed | "
      "false | named again |\n|---|---|---|---|---|---|---|---|---|\n");
  int named = 0, missed = 0, false_claims = 0, index = 0, resolved_missed = 0, again = 0;
  const char* only = std::getenv("MAGLEAD_MATRIX_FILTER");  // a substring of an effect id
  for (const auto& c : cases) {
    if (only && std::none_of(c.effects.begin(), c.effects.end(),
                             [&](auto* e) { return e->id.find(only) != std::string::npos; }))
      continue;
    const auto o = run_case(c, index++);
    named += o.named, missed += o.missed, false_claims += o.false_claims;
    again += o.again.empty() ? 0 : 1;
    if (&s == &paper() && c.effects.size() == 1 && c.scale == 1.0 && c.rate_hz == 1000.0)
      resolved_missed += o.missed;
  }
  std::printf(
      "%s actuator: %zu cases (%s), named %d, missed %d, false claims %d, named again with the "
      "corrected model %d\n",
      s.name.c_str(), cases.size(), full_matrix() ? "full matrix" : "CI subset", named, missed,
      false_claims, again);
  EXPECT_EQ(false_claims, 0);
  EXPECT_EQ(again, 0) << "a case's corrected model left a term to name again";
  EXPECT_EQ(resolved_missed, 0) << "a resolved effect alone was not named";
}

INSTANTIATE_TEST_SUITE_P(Actuators, Matrix, ::testing::Values(0, 1, 2),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return p.param == 0 ? "Paper" : p.param == 1 ? "Other" : "Third";
                         });

// One case of the matrix, named exactly: every concealed effect, nothing else.
void expect_named_exactly(const Bench& b, const Regression& r) {
  const auto o = run_case(case_of(b, r), 0);
  EXPECT_EQ(o.missed, 0) << o.claims;
  EXPECT_EQ(o.false_claims, 0) << o.claims;
}

// A load-cell delay in a recording that mixes force control, hand pushes and free moves: the
// delay takes 0.5 N from the segments where the load changes; in the unloaded moves its column is
// the load cell's noise, 0.01 N against a 0.022 N error, both below what the recording resolves.
// It does not act there (selection's acts_in asks for a share of the floor's error at least), so
// those segments (0.022 N to 0.024 N) do not break its consistency over the others (it was
// missed at t = 2.8).
TEST(MixedRecordings, ALoadCellDelayIsNamedWhereTheLoadChanges) {
  expect_named_exactly(paper(), {"paper", "load_cell_delay", 1.0, 2000.0, 0.1, "mixed-moves"});
}

// An 8 N pulse against a free move stalls the paper's nut for a few milliseconds; when it ends the
// coupling throws the nut on, and the filtered acceleration lags the jump: a 1.4 N swing to the
// other side, above the filter's own undershoot of the 8.9 N peak but 3 % of its impulse. The
// pulse has one sign by its impulse (pulses::find); it was left out as a misplaced transition.
TEST(MixedRecordings, APulseThatStallsAMovingNutIsAnEvent) {
  expect_named_exactly(paper(), {"paper", "external_disturbance", 1.0, 1000.0, 0.1, "mixed-moves"});
}

// The third actuator's nut, 2.5 kg against 14 N of friction, slides on 4 % of a mixed recording;
// where it stands the encoders' rounding can hold the phase off by up to half a count (0.0157
// rad): a 0.007 rad backlash was claimed (t 3.7), less than a count (effects: least_counts).
TEST(MixedRecordings, APlayBelowACountOfThePhaseIsNotClaimed) {
  expect_named_exactly(third(), {"third", "coulomb_friction", 1.0, 500.0, 0.1, "mixed"});
}

// A screw free in its bearings floats towards F_m = 0 within its play: where the force crosses
// zero (a hand push let go, a move's start) the read phase is off by all of F_m, not by b/2 of
// the slope. The first-order law missed it there and a coupling gain of 0.987 took up 0.08 N
// beside the play (the other actuator, 0.05 rad, seed 7); the law's float zone takes it.
TEST(MixedRecordings, AScrewFloatingInItsPlayIsBacklashAlone) {
  expect_named_exactly(other(), {"other", "backlash", 1.0, 500.0, 0.1, "mixed-moves", 7});
}

// An 8 N pulse against the paper's nut sliding at 13 mm/s under force control stops it for the
// 50 ms it acts (friction 7.5 N): no sliding sample carries it. The stand held a drive of about
// 12 N where every start from rest broke away below 9 N: a force no input explains held it.
TEST(MixedRecordings, APulseThatStopsASlidingNutIsAnEvent) {
  expect_named_exactly(paper(), {"paper", "external_disturbance", 1.0, 1000.0, 0.1, "mixed"});
}

// An 8 N pulse on a nut standing between moves or under a hand throws it to its next stand in a
// few milliseconds (the paper's: 14 counts at 28.6 s, seed 4; the other's, 4 N friction, at
// 500 Hz): no sliding sample carries it, and the pulse holds the stand it reaches. From stand to
// stand the recorded forces did none of the friction's work over the travel, where every other
// jump shows it (add_throws); both were missed (nothing named).
TEST(MixedRecordings, APulseThatThrowsAStandingNutIsAnEvent) {
  expect_named_exactly(paper(),
                       {"paper", "external_disturbance", 1.0, 1000.0, 0.1, "mixed-moves", 4});
  expect_named_exactly(other(),
                       {"other", "external_disturbance", 1.0, 500.0, 0.1, "mixed-moves", 4});
}

// Stick-slip stops a sliding nut too, but friction holds no more there than the break-away the
// starts from rest show: no pulse (taking the largest drive of each stand instead of what it held
// for most of it claimed one here).
TEST(StickSlip, ItsStallsAreNotPulses) {
  expect_named_exactly(paper(), {"paper", "stribeck_friction", 1.0, 1000.0, 0.5});
}

// The third actuator's Coulomb level 1 N up in `mixed` (seed 7): an offset of 0.075 ± 0.013 N
// (t 6.2) was named beside it, above the calibration's stated accuracy (0.070 N) only within its
// own error. Less one standard error a finding's force must still beat that minimum.
TEST(MixedRecordings, AnOffsetWithinItsErrorOfTheMinimumIsNotClaimed) {
  expect_named_exactly(third(), {"third", "coulomb_friction", 0.5, 500.0, 0.1, "mixed", 7});
}

// The other actuators' calibrations are off from their plants' couplings by a few hundredths of
// a newton, as the fixtures say: the suite runs on the calibrations it claims to.
class Calibration : public ::testing::TestWithParam<int> {};

TEST_P(Calibration, IsOffByAFewHundredthsOfANewton) {
  const auto& s = bench(GetParam());
  double worst = 0, ss = 0;
  int n = 0;
  for (double phi = -1.5; phi <= 1.5; phi += 0.01, ++n) {
    const double d = s.cal.polynomial.load_force_n(phi) - s.plant.coupling.load_force_n(phi);
    worst = std::max(worst, std::abs(d));
    ss += d * d;
  }
  const double rms = std::sqrt(ss / n);
  std::printf("%s calibration off by %.3f N RMS, at most %.3f N\n", s.name.c_str(), rms, worst);
  EXPECT_GT(rms, 0.03);
  EXPECT_LT(worst, 0.08);
}

INSTANTIATE_TEST_SUITE_P(Actuators, Calibration, ::testing::Values(1, 2),
                         [](const ::testing::TestParamInfo<int>& p) {
                           return p.param == 1 ? "Other" : "Third";
                         });

// A scenario on the bench's plant and calibration, seed 5.
maglead::ScenarioOptions scenario_on(const Bench& s, const std::string& scenario,
                                     double duration_s) {
  maglead::ScenarioOptions opt;
  opt.scenario = scenario;
  opt.duration_s = duration_s;
  opt.seed = 5;
  opt.plant = s.plant;
  opt.estimator_calibration = s.cal;
  return opt;
}

// The scenarios' hand pushes (up to 35 N) and force setpoints (up to 30 N) were written for the
// paper's actuator; on the third (safe force 0.8 × 27.2 N) the hand loaded the nut with 38 N,
// beyond the coupling's peak (only the 12 N friction held it in step). They scale to the
// configured safe force: the load stays below the calibrated peak and the nut never steps out.
TEST(ThirdActuator, ScenariosScaleTheirForcesToItsSafeForce) {
  const auto& s = third();
  const double peak_cal_n = std::min(std::abs(s.cal.peak_push_n), std::abs(s.cal.peak_pull_n));
  for (const std::string scenario : {"hand-push", "force-steps"}) {
    const auto opt = scenario_on(s, scenario, 20.0);
    const std::string path = test_tmp_dir() + "/scaled_" + scenario + ".csv";
    const auto summary = maglead::run_scenario(opt, path);
    const auto rec = maglead::read_recording(path);
    std::filesystem::remove(path);
    double peak_n = 0;
    for (double f : rec.column("load_force_n")) peak_n = std::max(peak_n, std::abs(f));
    std::printf("%s: peak load %.1f N (calibrated peak %.1f N), %d step-outs\n", scenario.c_str(),
                peak_n, peak_cal_n, summary.slips);
    EXPECT_EQ(summary.slips, 0) << scenario;
    EXPECT_LT(peak_n, peak_cal_n) << scenario;
  }
}

}  // namespace

namespace {

maglead::analysis::AnalysisResult analyze_generated(
    const std::string& scenario, const maglead::ForceCalibration& cal,
    const std::vector<std::pair<std::string, double>>& keys, const Bench& s = paper()) {
  auto opt = scenario_on(s, scenario, 40.0);
  for (const auto& [k, v] : keys) maglead::set_plant_effect(opt.plant.effects, k, v);
  const std::string path = test_tmp_dir() + "/single_" + scenario + ".csv";
  maglead::run_scenario(opt, path);
  maglead::analysis::AnalysisOptions aopt;
  aopt.actuator.twin_force_check = false;
  auto r = maglead::analysis::analyze_recording(maglead::read_recording(path), s.model, cal, s.act,
                                                aopt);
  std::filesystem::remove(path);
  return r;
}

// The first finding: its id, the value of `param` and that value's standard error (printed).
struct Named {
  std::string id;
  double value, se;
};
Named first_finding(const AnalysisResult& r, const std::string& param) {
  const auto& e = r.findings.effects.at(0);
  std::printf("%s: %s\n", e.id.c_str(), e.summary.c_str());
  return {e.id, maglead::analysis::parameter_value(e.parameters, param),
          maglead::analysis::parameter_value(e.standard_errors, param, -1.0)};
}

// Issue 43, item 5: over 20 seeds per effect the truth lies within two standard errors, the
// calibration's share and 1 % of the value (the bound a user is told to read) in at least 85 %
// of the runs; a run that does not name the effect counts as a miss. Printed per effect.
TEST(Uncertainty, CoversTheTruthOverTwentySeeds) {
  struct Truth {
    const char* effect;
    double added;
    const char* param;
    double value;
    const char* scenario = "position-moves";
  };
  const auto& s = paper();
  for (const Truth& c :
       {Truth{"viscous_friction", 20.0, "viscous_n_s_per_m", 22.0},
        Truth{"coulomb_friction", 2.0, "coulomb_n", 9.5}, Truth{"offset", 1.0, "offset_n", 1.0},
        Truth{"coupling_gain_error", -0.05, "gain", 0.95},
        Truth{"spring", 300.0, "stiffness_n_per_m", 300.0},
        Truth{"position_ripple", 1.0, "amplitude_n", 1.0},
        Truth{"mass_error", 2.0, "nut_mass_kg", 2.12, "mixed-moves"}}) {
    int covered = 0, named = 0, stat_only = 0;
    constexpr int kSeeds = 20;
    for (int seed = 1; seed <= kSeeds; ++seed) {
      auto opt = scenario_on(s, c.scenario, 40.0);
      opt.seed = static_cast<std::uint64_t>(seed);
      maglead::set_plant_effect(opt.plant.effects, c.effect, c.added);
      const std::string path = test_tmp_dir() + "/cover_" + std::to_string(seed) + ".csv";
      maglead::run_scenario(opt, path);
      maglead::analysis::AnalysisOptions aopt;
      aopt.actuator.twin_force_check = false;
      const auto r = maglead::analysis::analyze_recording(maglead::read_recording(path), s.model,
                                                          s.cal, s.act, aopt);
      std::filesystem::remove(path);
      for (const auto& e : r.findings.effects) {
        if (e.id != c.effect) continue;
        const double v = maglead::analysis::parameter_value(e.parameters, c.param);
        const double se = maglead::analysis::parameter_value(e.standard_errors, c.param);
        const double cal = maglead::analysis::parameter_value(e.calibration_errors, c.param);
        const double off = std::abs(v - c.value);
        ++named;
        stat_only += off <= 2 * se + 0.01 * std::abs(c.value);
        covered += off <= 2 * se + cal + 0.01 * std::abs(c.value);
      }
    }
    std::printf("%s: named %d/%d, truth within 2 SE + 1 %%: %d, + the calibration's share: %d\n",
                c.effect, named, kSeeds, stat_only, covered);
    EXPECT_GE(covered, kSeeds * 85 / 100) << c.effect;
  }
}

// A calibration three times too strong (a wrong file, a unit slip) makes the missing force
// follow the coupling with a gain of about 0.33: a broken magnet, not a finding. It is reported
// as what no library effect explains plausibly, with where and what to check.
TEST(Plausibility, AGainOutsideItsPhysicalRangeIsNotAFinding) {
  const auto r = analyze_generated("hand-push", maglead::scaled(paper().cal, 3.0), {});
  for (const auto& e : r.findings.effects) EXPECT_NE(e.id, "coupling_gain_error");
  ASSERT_TRUE(r.findings.unexplained.has_value()) << "the implausible fit must be reported";
  const auto& u = *r.findings.unexplained;
  std::printf("%s\n  where: %s\n  check: %s\n", u.message.c_str(), u.where.c_str(),
              u.check.c_str());
  EXPECT_EQ(u.id, "coupling_gain_error");
  EXPECT_NEAR(maglead::analysis::parameter_value(u.parameters, "gain"), 1.0 / 3.0, 0.05);
  EXPECT_NE(u.message.find("no library effect explains this plausibly"), std::string::npos);
}

// A recording where the nut never slides says so, and still names what its stuck episodes tell.
TEST(StickSlip, ARecordingThatBarelySlidesSaysSo) {
  const auto r = analyze_generated("hand-push", paper().cal, {{"stribeck_friction", 4.5}});
  std::printf("%s\n", r.findings.sliding_note.c_str());
  EXPECT_FALSE(r.findings.sliding_note.empty());
  ASSERT_EQ(r.findings.effects.size(), 1u);
  EXPECT_EQ(r.findings.effects[0].id, "stribeck_friction");
  EXPECT_FALSE(r.findings.effects[0].summary.empty());
  // The break-away is read late by what rose while the nut crossed its first count: the note
  // says by how much it was corrected.
  EXPECT_NE(r.findings.effects[0].note.find("corrected for what rose"), std::string::npos)
      << r.findings.effects[0].note;
  // The Stribeck velocity is scanned on a grid: its summary says "(no standard error)" and it
  // has no standard_errors key (its jackknife spread is rounding); every key left is stated.
  const auto& e = r.findings.effects[0];
  EXPECT_NE(e.summary.find("(no standard error)"), std::string::npos) << e.summary;
  for (const auto& se : e.standard_errors) {
    EXPECT_NE(se.name, "stribeck_velocity_m_s") << e.summary;
    EXPECT_FALSE(maglead::analysis::value_with_error(
                     maglead::analysis::parameter_value(e.parameters, se.name), se.value)
                     .empty())
        << se.name;
  }
}

// Where the nut barely slides, the releases still tell a force the load cell does not see: it
// lowers the break-away read in +p and raises it in −p by as much (2 N here: 2.6 N against 6.4 N
// of excess). Before, only the Stribeck hump (the two sides' mean) was named.
TEST(StickSlip, AnOffsetIsReadFromTheReleasesWhereTheNutBarelySlides) {
  const auto r =
      analyze_generated("hand-push", paper().cal, {{"stribeck_friction", 4.5}, {"offset", 2.0}});
  EXPECT_FALSE(r.findings.sliding_note.empty());
  ASSERT_EQ(r.findings.effects.size(), 2u);
  EXPECT_EQ(r.findings.effects[0].id, "stribeck_friction");
  const auto& e = r.findings.effects[1];
  std::printf("%s: %s\n", e.id.c_str(), e.summary.c_str());
  ASSERT_EQ(e.id, "offset");
  const double offset_n = maglead::analysis::parameter_value(e.parameters, "offset_n");
  const double se_n = maglead::analysis::parameter_value(e.standard_errors, "offset_n", -1.0);
  EXPECT_GT(se_n, 0.0);
  EXPECT_NEAR(offset_n, 2.0, 3 * se_n + 0.1);  // + the first-count lag's model error
  // The hump is the two sides' mean, which the offset leaves alone.
  EXPECT_NEAR(maglead::analysis::parameter_value(r.findings.effects[0].parameters, "breakaway_n"),
              7.5 + 4.5, 0.5);
}

// The backward check (the one selection's, as on an axis) drops a term the others explain: it
// adds nothing taken last. Not one that removes most of the error: beside a coupling gain error
// it is collinear with, a gain drift taken last removed 56 % of the held-out error (the coupling
// error 94 %) but at t < 3, a segment where the pair trade places; both were dropped once.
TEST(BackwardCheck, KeepsCollinearTermsThatEachRemoveMostOfTheError) {
  const Case c{
      &paper(), {&effect_case("gain_drift"), &effect_case("angle_ripple")}, 1.0, 500.0, 0.1};
  const auto o = run_case(c, 0);
  EXPECT_EQ(o.false_claims, 0);
  EXPECT_EQ(o.missed, 0) << "named: " << o.claims;
}

// On moves against high friction the coupling force is mostly the friction, so a coupling gain
// and the friction levels share it: on the third actuator more Coulomb and viscous friction was
// named as a gain of 0.87, which the friction terms taken after it pulled to 0.37 in the final
// fit (and a mass error beside them). A term outside its physical range in the final fit is
// refused and the rest chosen again without it: the friction is named with its true values.
TEST(Plausibility, ATermOutsideItsRangeInTheFinalFitIsRefused) {
  const Case c{&third(),
               {&effect_case("coulomb_friction"), &effect_case("viscous_friction")},
               1.0,
               1000.0,
               0.1};
  const auto o = run_case(c, 0);
  EXPECT_EQ(o.missed, 0) << o.claims;
  EXPECT_EQ(o.claims.find("coupling_gain_error"), std::string::npos) << o.claims;
  EXPECT_EQ(o.claims.find("mass_error"), std::string::npos) << o.claims;
}

// A law with compact support changes the force only where it acts: on the third actuator a 40 %
// weaker coupling within 5 mm of the stroke's ends (3 % of the sliding samples) explains less
// than the stated minimum as an RMS over the whole recording, and far more in its zones, where
// the floors are set against it. Measured over the whole recording, it was never named.
TEST(ThirdActuator, AnEndEffectIsMeasuredInItsZones) {
  const auto r =
      analyze_generated("position-moves", third().cal,
                        {{"end_effect", 0.005}, {"end_effect.max_reduction", 0.4}}, third());
  ASSERT_EQ(r.findings.effects.size(), 1u);
  const auto [id, reduction, se] = first_finding(r, "max_reduction");
  ASSERT_EQ(id, "end_effect");
  EXPECT_NEAR(reduction, 0.4, 3 * se + 0.02);
  const auto& ev = r.findings.effects[0].evidence;
  EXPECT_LT(*ev.explained_rms_n, *ev.minimum_n);
  ASSERT_TRUE(ev.acting_share_pct.has_value());
  EXPECT_LT(*ev.acting_share_pct, 10.0);
  EXPECT_GT(*ev.explained_rms_n / std::sqrt(*ev.acting_share_pct / 100.0), 3 * *ev.minimum_n);
}

// Late encoders on a heavy nut: read at t, the balance holds at t − τ except for the load cell,
// so the missing force is −τ dF_ext/dt, which the balance gives as τ (k φ̇ − M p⃛ − C p̈). On the
// third actuator's 2.5 kg nut the inertial part is as large as the coupling part: with the
// coupling part alone the delay was named as Coulomb and Stribeck friction. The calibration is
// the paper's scaled as the plant's coupling is (0.6), so that its own error (0.05 N in the
// fixture) does not decide what is named.
TEST(ThirdActuator, SensorDelayOnAHeavyNutIsNamedWithItsDelay) {
  const auto cal = maglead::scaled(paper().cal, 0.6);
  const auto r = analyze_generated("force-steps", cal, {{"sensor_delay", 0.010}}, third());
  ASSERT_EQ(r.findings.effects.size(), 1u);
  const auto [id, tau, se] = first_finding(r, "delay_s");
  ASSERT_EQ(id, "sensor_delay");
  EXPECT_GT(se, 0.0);
  EXPECT_LT(se, 0.002);
  // The law is first order in τ: on a component at ω the true missing force is
  // F(t − τ) − F(t), whose part along −τ dF/dt is sin(ωτ)/(ωτ) of it. The analysis's low-pass
  // (20 Hz, the actuator default) keeps ω ≤ 2π·20 Hz, so τ may come out low by up to that factor
  // (0.76 at 10 ms), never high; beyond it, two standard errors.
  const double x = 2 * std::numbers::pi * 20.0 * 0.010;
  EXPECT_GE(tau, 0.010 * std::sin(x) / x - 2 * se);
  EXPECT_LE(tau, 0.010 + 2 * se);
}

// The third actuator's load cell 5 ms late (`mixed`, 1 kHz, 0.5 N noise): a play of 0.0166 ±
// 0.0019 rad was named in the delay's place, one count of the phase (0.0157 rad) only within its
// own error. A value's least count must be reached less its standard error, as a finding's force
// must beat the stated minimum by its own (rule 10).
TEST(MixedRecordings, APlayWithinItsErrorOfOneCountIsNotClaimed) {
  expect_named_exactly(third(), {"third", "load_cell_delay", 0.5, 1000.0, 0.5, "mixed"});
}

// A play on the third actuator (`mixed`, 1 kHz, seed 7) was named with an offset of 0.081 ±
// 0.012 N beside it: past the calibration's accuracy (0.070 N) in the selection, within its own
// error in the final fit. Refused there, a spring of 8.6 ± 9.0 N/m took its place, an offset
// with a slope no data showed. In the final fit a term's own force less its jackknife error must
// reach the minimum, and a magnitude must be beyond zero by its error: the play alone.
TEST(MixedRecordings, NeitherAnOffsetNorASpringWithinTheirErrorBesideAPlay) {
  expect_named_exactly(third(), {"third", "backlash", 1.0, 1000.0, 0.1, "mixed", 7});
}

// The other actuator's force loop reading its encoders 5 ms late (`mixed`, 1 kHz) makes the nut
// ring on its coupling (71 Hz) faster than the filter, running back and forth each cycle while
// the filtered speed says it slides: its friction averages to less than F_c sign(v), the less the
// slower. Fitted there, the delay read 7.2 ms and a Coulomb level 0.09 N low was named beside it.
// Those samples take no part in the fits: the delay alone, within the first-order law's bound
// (the ThirdActuator test above) and two standard errors.
TEST(MixedRecordings, ANutRingingOnItsCouplingIsNotSlidingOneWay) {
  expect_named_exactly(other(), {"other", "sensor_delay", 0.5, 1000.0, 0.1, "mixed"});
  const auto r = analyze_generated("mixed", other().cal, {{"sensor_delay", 0.005}}, other());
  ASSERT_EQ(r.findings.effects.size(), 1u);
  const auto [id, tau, se] = first_finding(r, "delay_s");
  ASSERT_EQ(id, "sensor_delay");
  const double x = 2 * std::numbers::pi * 20.0 * 0.005;
  EXPECT_GE(tau, 0.005 * std::sin(x) / x - 2 * se);
  EXPECT_LE(tau, 0.005 + 2 * se);
}

// Each fitted parameter carries its standard error, and the summary prints the value at the
// digits that error allows.
TEST(Uncertainty, ParametersCarryTheirStandardErrorAtItsDigits) {
  const auto r = analyze_generated("hand-push", paper().cal, {{"coupling_gain_error", 0.1}});
  ASSERT_FALSE(r.findings.effects.empty());
  const auto [id, gain, se] = first_finding(r, "gain");
  ASSERT_EQ(id, "coupling_gain_error");
  EXPECT_GT(se, 0.0);
  EXPECT_LT(se, 0.02);
  // The true gain lies within four standard errors, plus 0.005 for the plant's coupling curve
  // (a periodic fit) against the calibration polynomial: a bias no standard error covers.
  EXPECT_NEAR(gain, 1.1, 4 * se + 0.005);
  const auto& e = r.findings.effects[0];
  EXPECT_NE(e.summary.find("gain 1.0"), std::string::npos) << e.summary;
  EXPECT_NE(e.summary.find(" ± 0.00"), std::string::npos) << e.summary;
}

}  // namespace
