// The analysis on data where the answer is known: recordings from the simulated plant with one
// or two effects switched on that the baseline lacks (fixed seeds, made here), a control with
// nothing concealed, and the real EMPS recording. Only bench columns reach the analysis.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/signal.hpp"
#include "maglead/plant/scenario.hpp"

namespace {

using maglead::analysis::AnalysisResult;
using Json = nlohmann::json;

struct Concealed {
  std::string name;
  double value;
};

AnalysisResult run(const std::string& scenario, double duration_s,
                   const std::vector<Concealed>& effects, std::uint64_t seed = 5) {
  maglead::ScenarioOptions opt;
  opt.scenario = scenario;
  opt.duration_s = duration_s;
  opt.seed = seed;
  std::string tag = scenario;
  for (const auto& e : effects) {
    maglead::set_plant_effect(opt.plant.effects, e.name, e.value);
    tag += "_" + e.name;
  }
  const std::string path = testing::TempDir() + "/analysis_" + tag + ".csv";
  maglead::run_scenario(opt, path);
  // Only what a bench logs: the recording holds no truth columns.
  const auto rec = maglead::read_recording(path);
  for (const auto& n : rec.names)
    EXPECT_TRUE(n == "t_s" || n == "motor_angle_rad" || n == "screw_angle_rad" ||
                n == "nut_pos_m" || n == "load_force_n" || n == "out_force_est_n" ||
                n == "force_set_n" || n == "pos_set_m")
        << n;
  const maglead::ActuatorParams act;
  auto result = maglead::analysis::analyze_recording(
      rec, maglead::analysis::actuator_model_from_config(act),
      maglead::load_calibration(std::string(MAGLEAD_CONFIG_DIR) + "/calibration.toml"), act, {});
  std::filesystem::remove(path);
  return result;
}

// The finding that names `id`, as the chosen term or as an alternative of a combined finding.
const Json* finding(const AnalysisResult& r, const std::string& id, Json* params) {
  for (const auto& e : r.json["effects"]) {
    if (e["id"] == id) {
      *params = e["parameters"];
      return &e;
    }
    if (e.contains("alternatives"))
      for (const auto& a : e["alternatives"])
        if (a["id"] == id) {
          *params = a["parameters"];
          return &e;
        }
  }
  return nullptr;
}

double heldout_before(const AnalysisResult& r) { return r.json["validation"].front()["heldout_rms"]; }
double heldout_after(const AnalysisResult& r) { return r.json["validation"].back()["heldout_rms"]; }

// One row of the README table, printed by the test.
void row(const std::string& effect, const std::string& scenario, double truth, double found,
         const AnalysisResult& r, const std::string& named) {
  std::printf("| %s | %s | %g | %.4g | %s | %.3f | %.3f |\n", effect.c_str(), scenario.c_str(),
              truth, found, named.c_str(), heldout_before(r), heldout_after(r));
}

std::string named_as(const AnalysisResult& r) {
  std::string s;
  for (const auto& e : r.json["effects"]) {
    if (!s.empty()) s += ", ";
    s += e["id"].get<std::string>();
    if (e.contains("alternatives")) {
      s += " (or";
      for (const auto& a : e["alternatives"]) s += " " + a["id"].get<std::string>();
      s += ")";
    }
  }
  return s.empty() ? "nothing" : s;
}

// Checks the effect is found, its parameter within `tol` (relative), held-out error falls.
void expect_found(const AnalysisResult& r, const std::string& effect, const std::string& scenario,
                  const std::string& key, double truth, double tol_rel) {
  Json params;
  const Json* e = finding(r, effect, &params);
  ASSERT_NE(e, nullptr) << effect << " not named; found: " << named_as(r);
  ASSERT_TRUE(params.contains(key)) << params.dump();
  const double found = params[key].get<double>();
  row(effect, scenario, truth, found, r, named_as(r));
  EXPECT_NEAR(found, truth, tol_rel * std::abs(truth)) << effect << " " << key;
  EXPECT_LT(heldout_after(r), 0.6 * heldout_before(r)) << "held-out error must fall";
}

TEST(GeneratedSuite, ControlsWithNothingConcealedYieldNoEffect) {
  for (const char* sc : {"hand-push", "position-moves", "force-steps"}) {
    const auto r = run(sc, 40.0, {});
    EXPECT_TRUE(r.json["effects"].empty()) << sc << ": " << named_as(r);
    EXPECT_TRUE(r.json["nothing_missing"].get<bool>());
    row("(control)", sc, 0, 0, r, named_as(r));
  }
}

TEST(GeneratedSuite, OffsetIsOneFindingWithDirectionDependentFriction) {
  const auto r = run("hand-push", 40.0, {{"offset", 2.0}});
  expect_found(r, "offset", "hand-push", "offset_n", 2.0, 0.1);
  // A constant force and direction-dependent Coulomb friction look the same while the nut moves.
  ASSERT_FALSE(r.json["effects"].empty());
  EXPECT_FALSE(r.json["effects"][0]["identifiable"].get<bool>());
  Json p;
  EXPECT_NE(finding(r, "asymmetric_friction", &p), nullptr);
}

TEST(GeneratedSuite, AsymmetricFrictionIsNamedAsTheAlternativeOfAnOffset) {
  const auto r = run("hand-push", 40.0, {{"asymmetric_friction", 2.0}});
  expect_found(r, "asymmetric_friction", "hand-push", "coulomb_asymmetry_n", 2.0, 0.1);
}

TEST(GeneratedSuite, ViscousFrictionWithSensorDelayAsAlternative) {
  const auto r = run("position-moves", 40.0, {{"viscous_friction", 50.0}});
  expect_found(r, "viscous_friction", "position-moves", "change_n_s_per_m", 50.0, 0.15);
}

TEST(GeneratedSuite, SensorDelayIsFoundAsOneFindingWithViscousFriction) {
  const auto r = run("position-moves", 40.0, {{"sensor_delay", 0.002}});
  expect_found(r, "sensor_delay", "position-moves", "delay_s", 0.002, 0.15);
}

TEST(GeneratedSuite, GainDriftGrowsOverTime) {
  const auto r = run("hand-push", 60.0, {{"gain_drift", -0.05}});
  expect_found(r, "gain_drift", "hand-push", "gain_drift_per_min", -0.05, 0.25);
}

TEST(GeneratedSuite, AngleRippleIsOneFindingWithPositionRippleWhileTheNutTracks) {
  const auto r = run("position-moves", 40.0, {{"angle_ripple", 1.5}});
  expect_found(r, "angle_ripple", "position-moves", "amplitude_n", 1.5, 0.1);
  Json p;
  EXPECT_NE(finding(r, "position_ripple", &p), nullptr) << "must be named as the alternative";
  EXPECT_FALSE(r.json["effects"][0]["identifiable"].get<bool>());
}

TEST(GeneratedSuite, PositionRippleWithItsPeriod) {
  const auto r = run("position-moves", 40.0, {{"position_ripple", 1.5}});
  expect_found(r, "position_ripple", "position-moves", "amplitude_n", 1.5, 0.1);
  Json p;
  finding(r, "position_ripple", &p);
  EXPECT_NEAR(p["period_m"].get<double>(), 0.005, 0.0002);
}

TEST(GeneratedSuite, EndEffectNearTheStrokeEnds) {
  const auto r = run("position-moves", 40.0, {{"end_effect", 0.004}});
  expect_found(r, "end_effect", "position-moves", "depth", 0.5, 0.2);
  Json p;
  finding(r, "end_effect", &p);
  EXPECT_NEAR(p["distance_m"].get<double>(), 0.004, 0.0015);
}

TEST(GeneratedSuite, SpringTowardsMidStroke) {
  const auto r = run("position-moves", 40.0, {{"spring", 300.0}});
  expect_found(r, "spring", "position-moves", "spring_n_per_m", 300.0, 0.05);
  // The corrected twin, re-simulated with SUNDIALS from measured states, tracks the nut better.
  const auto& tw = r.json["twin_simulation"];
  ASSERT_TRUE(tw["available"].get<bool>()) << tw.dump();
  std::printf("twin re-simulation (spring): baseline %.2f um, corrected %.2f um RMS position error\n",
              tw["baseline_rms_position_error_m"].get<double>() * 1e6,
              tw["corrected_rms_position_error_m"].get<double>() * 1e6);
  EXPECT_LT(tw["corrected_rms_position_error_m"].get<double>(),
            0.7 * tw["baseline_rms_position_error_m"].get<double>());
}

TEST(GeneratedSuite, BacklashInTheGearbox) {
  const auto r = run("force-steps", 40.0, {{"backlash", 0.05}});
  expect_found(r, "backlash", "force-steps", "backlash_rad", 0.05, 0.15);
}

TEST(GeneratedSuite, ExternalDisturbancePulsesAreEvents) {
  const auto r = run("position-moves", 60.0, {{"external_disturbance", 8.0}});
  expect_found(r, "external_disturbance", "position-moves", "amplitude_n", 8.0, 0.2);
  int pulses = 0;
  for (const auto& e : r.json["events"]) pulses += e["type"] == "isolated_disturbance";
  EXPECT_GE(pulses, 2);
}

TEST(GeneratedSuite, TwoEffectsAtOnce) {
  const auto r = run("position-moves", 40.0, {{"spring", 300.0}, {"position_ripple", 1.5}});
  expect_found(r, "spring", "position-moves", "spring_n_per_m", 300.0, 0.05);
  expect_found(r, "position_ripple", "position-moves", "amplitude_n", 1.5, 0.1);
}

TEST(GeneratedSuite, StepOutIsAnEventWithItsTime) {
  // The plant's scenarios keep the nut on its branch, so the slip is made in the recording:
  // from t = 10 s the encoder reads one lead less, as after the nut fell back one period.
  maglead::ScenarioOptions opt;
  opt.scenario = "position-moves";
  opt.duration_s = 20.0;
  const std::string path = testing::TempDir() + "/analysis_stepout.csv";
  maglead::run_scenario(opt, path);
  auto rec = maglead::read_recording(path);
  std::filesystem::remove(path);
  const auto& t = rec.column("t_s");
  auto& p = rec.columns[static_cast<std::size_t>(
      std::find(rec.names.begin(), rec.names.end(), "nut_pos_m") - rec.names.begin())];
  for (std::size_t i = 0; i < p.size(); ++i)
    if (t[i] >= 10.0) p[i] -= 0.006;
  const maglead::ActuatorParams act;
  const auto r = maglead::analysis::analyze_recording(
      rec, maglead::analysis::actuator_model_from_config(act), maglead::paper_calibration(), act, {});
  int slips = 0;
  for (const auto& e : r.json["events"])
    if (e["type"] == "step_out") {
      ++slips;
      EXPECT_NEAR(e["t_s"].get<double>(), 10.0, 0.01);
      EXPECT_EQ(e["leads"].get<int>(), 1);
    }
  EXPECT_EQ(slips, 1);
  Json params;
  EXPECT_NE(finding(r, "step_out", &params), nullptr);
}

TEST(Emps, FindsCoulombOffsetThenDirectionDependentFriction) {
  const std::string path = MAGLEAD_EMPS_CSV;
  // The recording is part of the repository (data/emps/): missing, it is a failure, not a skip.
  ASSERT_TRUE(std::filesystem::exists(path)) << "EMPS recording not found at " << path;
  const auto rec = maglead::read_recording(path);
  const auto model =
      maglead::analysis::load_model(std::string(MAGLEAD_CONFIG_DIR) + "/emps_baseline.toml");
  const auto r = maglead::analysis::analyze_recording(rec, model, maglead::paper_calibration(),
                                                      maglead::ActuatorParams{}, {});
  const auto& e = r.json["effects"];
  ASSERT_GE(e.size(), 3u) << e.dump();
  EXPECT_EQ(e[0]["id"], "coulomb_friction");
  EXPECT_EQ(e[1]["id"], "offset");
  EXPECT_EQ(e[2]["id"], "asymmetric_friction");
  const auto& v = r.json["validation"];
  const double sym = v[2]["fitted_relative_error_pct"], asym = v[3]["fitted_relative_error_pct"];
  std::printf("EMPS relative error: baseline %.3f %%, symmetric %.3f %% (published 4.08), "
              "direction-dependent %.3f %% (published 3.11), final %.3f %%, full rate %.3f %%\n",
              v[0]["fitted_relative_error_pct"].get<double>(), sym, asym,
              r.json["final"]["relative_error_pct"].get<double>(),
              r.json["final"]["full_rate"]["relative_error_pct"].get<double>());
  // Published: 4.08 % and 3.11 %. The symmetric stage lands at 4.13 % here (see the report).
  EXPECT_LT(sym, 4.2);
  EXPECT_LE(asym, 3.11);
  EXPECT_LE(r.json["final"]["relative_error_pct"].get<double>(), 3.11);
  // Physically plausible values, close to the benchmark's.
  EXPECT_NEAR(e[0]["parameters"]["coulomb_n"].get<double>(), 20.4, 1.0);
  EXPECT_NEAR(e[2]["parameters"]["equivalent_viscous_pos_n_s_per_m"].get<double>(), 166.7, 10.0);
  EXPECT_NEAR(e[2]["parameters"]["equivalent_viscous_neg_n_s_per_m"].get<double>(), 240.4, 10.0);
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
