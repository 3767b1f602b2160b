// The `maglead` command line end to end, as a user runs it: results and error messages.
#include <gtest/gtest.h>

#include "test_tmp.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

namespace {

struct Run {
  int exit_code;
  std::string out;  // stdout and stderr together
};

Run run(const std::string& args) {
  const std::string cmd =
      std::string(MAGLEAD_BIN) + " " + args + " --config " + MAGLEAD_CONFIG_DIR + " 2>&1";
  Run r{0, ""};
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string tmp(const std::string& name) { return test_tmp_dir() + "/" + name; }

/// `maglead simulate ARGS --out FILE`, FILE in the test's directory.
Run simulate_to(const std::string& args, const std::string& file) {
  return run("simulate " + args + " --out " + tmp(file));
}

double number_after(const std::string& text, const std::string& label) {
  const auto at = text.find(label);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + label.size(), nullptr);
}

}  // namespace

TEST(Cli, HandPushStaticEstimateIsInThePapersNeighbourhood) {
  const auto sim =
      run("simulate --scenario hand-push --duration 30s --seed 1 --out " + tmp("hp.csv"));
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const auto est = run("estimate --recording " + tmp("hp.csv") + " --plot " + tmp("hp.png") +
                       " --out " + tmp("hp_est.csv"));
  ASSERT_EQ(est.exit_code, 0) << est.out;
  const double mae = number_after(est.out, "mean absolute error");
  // The paper reports 2.3 N; friction the estimate cannot see while the nut sticks dominates.
  EXPECT_GT(mae, 1.5) << est.out;
  EXPECT_LT(mae, 3.5) << est.out;
  // --out: every sample, error = estimate - load cell, and the printed figure is its mean |e|.
  std::ifstream series(tmp("hp_est.csv"));
  std::string line;
  double sum_abs = 0.0;
  int rows = 0;
  while (std::getline(series, line)) {
    if (line.empty() || line[0] == '#' || line[0] == 't') continue;
    double t = 0, e = 0, m = 0, err = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &t, &e, &m, &err), 4) << line;
    EXPECT_NEAR(err, e - m, 1e-9);
    sum_abs += std::abs(err);
    ++rows;
  }
  EXPECT_EQ(rows, 30001);
  EXPECT_NEAR(sum_abs / rows, mae, 0.006);

  // The loop's load observer (no load cell) on the same pushes: well below the static estimate
  // (it knows the stick band) and not behind the twin (it shares its edge tracker and stuck-load
  // filter). Measured: 1.09 N observer, 1.20 N twin, 2.2 N static.
  const auto obs = run("estimate --estimator observer --recording " + tmp("hp.csv") + " --plot " +
                       tmp("hp_obs.png"));
  const auto twin = run("estimate --estimator twin --recording " + tmp("hp.csv") + " --plot " +
                        tmp("hp_twin.png"));
  ASSERT_EQ(obs.exit_code, 0) << obs.out;
  ASSERT_EQ(twin.exit_code, 0) << twin.out;
  const double obs_mae = number_after(obs.out, "mean absolute error");
  EXPECT_LT(obs_mae, 0.7 * mae) << obs.out;
  EXPECT_LT(obs_mae, number_after(twin.out, "mean absolute error") + 0.05) << obs.out << twin.out;
  std::ifstream png(tmp("hp.png"), std::ios::binary);
  char sig[8] = {};
  png.read(sig, 8);
  EXPECT_EQ(std::string(sig + 1, 3), "PNG");
}

// Issue 22's bar: the observer within 1.0 N of the load cell on average on the hand-push run
// of seed 11 (measured 0.98 N; 1.01 N with the load prior's earlier 2 s / 2 s come-and-go).
TEST(Cli, HandPushObserverWithinOneNewtonOnSeedEleven) {
  const auto sim =
      run("simulate --scenario hand-push --duration 30s --seed 11 --out " + tmp("hp11.csv"));
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const auto obs = run("estimate --estimator observer --recording " + tmp("hp11.csv") + " --plot " +
                       tmp("hp11.png"));
  ASSERT_EQ(obs.exit_code, 0) << obs.out;
  EXPECT_LE(number_after(obs.out, "mean absolute error"), 1.0) << obs.out;
}

// The model file serves the observer: a coupling that ripples 10 % once per screw turn, or is
// half as strong within 5 mm of the stroke's ends, named by `analyze` on a recording with moves
// and fed back with `estimate --model`: the observer's drive follows it (measured against the
// load cell 0.97 -> 0.61 N and 0.54 -> 0.38 N; without the term in the observer the corrected
// model changed nothing, a ratio of 1).
void expect_the_observer_follows(const std::string& effect, const std::string& scenario) {
  const std::string rec = effect + ".csv", out = tmp(effect + "_an");
  const auto sim = simulate_to("--scenario " + scenario + " --duration 40s --seed 3 --effect " +
                                   effect + "=" + (effect == "end_effect" ? "0.005" : "0.1"),
                               rec);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const auto an = run("analyze --no-twin-check --recording " + tmp(rec) + " --out " + out);
  ASSERT_EQ(an.exit_code, 0) << an.out;
  ASSERT_NE(an.out.find(effect), std::string::npos) << an.out;
  const std::string est =
      "estimate --estimator observer --recording " + tmp(rec) + " --plot " + tmp(effect + ".png");
  const auto before = run(est);
  const auto after = run(est + " --model " + out + "/model_corrected.toml");
  ASSERT_EQ(after.exit_code, 0) << after.out;
  EXPECT_LE(number_after(after.out, "mean absolute error"),
            0.8 * number_after(before.out, "mean absolute error"))
      << before.out << after.out;
}

TEST(Cli, TheObserverFollowsTheRippleTheAnalysisNamed) {
  expect_the_observer_follows("angle_ripple", "mixed-moves");
}
TEST(Cli, TheObserverFollowsTheEndEffectTheAnalysisNamed) {
  expect_the_observer_follows("end_effect", "position-moves");
}

// Issue 23: a friction rise is a plant condition from the command line (friction_drift, N/min,
// as `serve --sim-effect` takes it too), and the drift flag sees it without a load cell: +1 N/min
// on the moves is warned while it could be a 3 % error at the rated force (33.8 s, 0.56 N in),
// never named a gain loss (the moves do not separate the two).
TEST(Cli, FrictionDriftFromTheCommandLineIsFlaggedWithoutLoadCell) {
  const auto sim = simulate_to(
      "--scenario position-moves --duration 60s --seed 4 --effect friction_drift=1", "fd.csv");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const auto chk = run("twin-check --no-load-cell --recording " + tmp("fd.csv"));
  ASSERT_EQ(chk.exit_code, 0) << chk.out;
  const double warned_s = number_after(chk.out, "drift warning: at t =");
  EXPECT_GT(warned_s, 5.0) << chk.out;   // after a reference, not at the start
  EXPECT_LT(warned_s, 60.0) << chk.out;  // before 1 N; the issue allows up to 30 s after it
  EXPECT_EQ(chk.out.find("coupling gain fell"), std::string::npos) << chk.out;
  const auto bad =
      run("simulate --scenario position-moves --duration 1s --effect "
          "friction_drift=nan --out " +
          tmp("fd_bad.csv"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.out.find("friction_drift"), std::string::npos) << bad.out;
}

// A load cell reading 0 N throughout is unwired or stuck: estimate refuses it and says so,
// without advising another unit or calibration.
TEST(Cli, EstimateAgainstAConstantLoadCellAdvisesItsWiring) {
  ASSERT_EQ(run("simulate --scenario hand-push --duration 20s --seed 1 --out " + tmp("hp0.csv"))
                .exit_code,
            0);
  std::ifstream in(tmp("hp0.csv"));
  std::ofstream out(tmp("hp0_const.csv"));
  std::string line;
  std::size_t load_column = std::string::npos;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || load_column == std::string::npos) {
      out << line << "\n";
      // The header names the columns: find load_force_n's place among them.
      if (!line.empty() && line[0] != '#' && load_column == std::string::npos) {
        std::size_t col = 0;
        for (std::size_t at = 0, next; at != std::string::npos; at = next, ++col) {
          next = line.find(',', at);
          if (line.substr(at, next == std::string::npos ? next : next - at) == "load_force_n")
            load_column = col;
          if (next != std::string::npos) ++next;
        }
      }
      continue;
    }
    std::size_t at = 0;
    for (std::size_t col = 0; col < load_column; ++col) at = line.find(',', at) + 1;
    const std::size_t end = line.find(',', at);
    line.replace(at, end == std::string::npos ? std::string::npos : end - at, "0");
    out << line << "\n";
  }
  out.close();
  ASSERT_NE(load_column, std::string::npos);
  const auto est = run("estimate --recording " + tmp("hp0_const.csv"));
  EXPECT_NE(est.exit_code, 0) << est.out;
  EXPECT_NE(est.out.find("reads a constant 0 N"), std::string::npos) << est.out;
  EXPECT_NE(est.out.find("check its wiring"), std::string::npos) << est.out;
  EXPECT_EQ(est.out.find("--calibration"), std::string::npos) << est.out;
}

TEST(Cli, CalibrationOnStaticRunPicksOrderFiveAndWritesALoadableFile) {
  ASSERT_EQ(
      run("simulate --scenario static-calibration --duration 30s --seed 2 --out " + tmp("cal.csv"))
          .exit_code,
      0);
  const auto cal = run("calibrate --recording " + tmp("cal.csv") + " --out " + tmp("cal.toml"));
  ASSERT_EQ(cal.exit_code, 0) << cal.out;
  EXPECT_NE(cal.out.find("chosen order 5"), std::string::npos) << cal.out;
  // The written calibration is usable by the estimator.
  const auto est = run("estimate --recording " + tmp("cal.csv") + " --calibration " +
                       tmp("cal.toml") + " --plot " + tmp("cal.png"));
  EXPECT_EQ(est.exit_code, 0) << est.out;
}

TEST(Cli, EveryScenarioRunsAndEffectsAreAccepted) {
  for (const char* s : {"force-steps", "position-moves"}) {
    const auto r = run(std::string("simulate --scenario ") + s + " --duration 5s --out " +
                       tmp("s.csv") + " --effect viscous_friction=3 --effect backlash=0.01");
    EXPECT_EQ(r.exit_code, 0) << r.out;
  }
}

TEST(Cli, BadWordsGiveAClearErrorAndNonZeroExit) {
  auto r = run("simulate --scenario moonwalk --out " + tmp("x.csv"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("moonwalk"), std::string::npos) << r.out;
  r = run("simulate --scenario hand-push --effect warp_drive=1 --out " + tmp("x.csv"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("warp_drive"), std::string::npos) << r.out;
  r = run("simulate --scenario hand-push --effect offset=lots --out " + tmp("x.csv"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("lots"), std::string::npos) << r.out;
  r = run("simulate --scenario hand-push --duration soon --out " + tmp("x.csv"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("soon"), std::string::npos) << r.out;
}

TEST(Cli, BrokenRecordingsNameFileLineAndColumn) {
  const std::string missing = tmp("missing.csv"), text = tmp("text.csv"), back = tmp("back.csv");
  std::ofstream(missing) << "# format: mls-recording/1\nt_s,screw_angle_rad,nut_pos_m\n0,0,0\n";
  std::ofstream(text) << "t_s,screw_angle_rad,nut_pos_m,load_force_n\n0,0,0,0\n0.001,0,zero,0\n";
  std::ofstream(back) << "t_s,screw_angle_rad,nut_pos_m,load_force_n\n0.002,0,0,0\n0.001,0,0,0\n";
  auto r = run("estimate --recording " + missing);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("missing.csv:2"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("load_force_n"), std::string::npos) << r.out;
  r = run("estimate --recording " + text);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("text.csv:3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("column 3 (nut_pos_m)"), std::string::npos) << r.out;
  r = run("calibrate --recording " + back + " --out " + tmp("never.toml"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("back.csv:3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("time decreases"), std::string::npos) << r.out;
  EXPECT_FALSE(std::ifstream(tmp("never.toml")).good());  // nothing written on bad input
}
