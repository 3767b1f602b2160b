// twin::replay_monitor / replay_windows: the one replay of a recording through the twin, used by
// twin-check, the anomaly report and the analysis. Recordings are made here with fixed seeds.
#include <gtest/gtest.h>

#include <unistd.h>
#include <limits>

#include <cmath>
#include <stdexcept>
#include <string>

#include "maglead/plant/scenario.hpp"
#include "maglead/recording/recording.hpp"
#include "maglead/twin/replay.hpp"

namespace maglead::twin {
namespace {

TwinMonitorConfig paper_config() {
  TwinMonitorConfig c;
  c.calibration = paper_calibration();
  return c;
}

Recording simulate(const std::string& scenario, double duration_s, double gain_drift_per_min) {
  ScenarioOptions opt;
  opt.scenario = scenario;
  opt.duration_s = duration_s;
  opt.seed = 7;
  opt.plant.effects.gain_drift_per_min = gain_drift_per_min;
  const std::string path = std::string(MAGLEAD_TEST_TMP) + "/replay_" + std::to_string(::getpid()) +
                           "_" + scenario + ".csv";
  run_scenario(opt, path);
  return read_recording(path);
}

TEST(Replay, RefusesWhatCannotBeReplayed) {
  const std::vector<double> one{0.0}, two{0.0, 0.001}, still{0.0, 0.0}, three{0.0, 0.001, 0.002};
  const auto nothing = [](std::size_t, const TwinOutputs&) {};
  EXPECT_THROW(replay_monitor(paper_config(), {one, one, one, {}, {}}, nothing),
               std::invalid_argument);
  EXPECT_THROW(replay_monitor(paper_config(), {two, three, two, {}, {}}, nothing),
               std::invalid_argument);
  EXPECT_THROW(replay_monitor(paper_config(), {still, still, still, {}, {}}, nothing),
               std::invalid_argument);
  EXPECT_THROW(replay_monitor(paper_config(), {two, two, two, {}, one}, nothing),
               std::invalid_argument);
}

// Every sample is one tick; the drift flag never reads the load cell (its verdict and what it can
// observe are the same without it), while the load-cell check sees the coupling lose 20 %/min
// only where one is given.
TEST(Replay, EveryTickOnceAndTheFlagIgnoresTheLoadCell) {
  const Recording rec = simulate("force-steps", 30.0, -0.2);
  const ReplaySignals with_load{rec.column("t_s"), rec.column("screw_angle_rad"),
                                rec.column("nut_pos_m"), rec.column("force_set_n"),
                                rec.column("load_force_n")};
  std::size_t ticks = 0;
  std::vector<int> flag_with;
  double g_with = std::numeric_limits<double>::quiet_NaN();
  replay_monitor(paper_config(), with_load, [&](std::size_t i, const TwinOutputs& out) {
    EXPECT_EQ(i, ticks++);
    flag_with.push_back(out.drift_warning * 4 + static_cast<int>(out.drift_observability));
    if (std::isfinite(out.drift_gain_estimate)) g_with = out.drift_gain_estimate;
  });
  EXPECT_EQ(ticks, rec.rows());
  EXPECT_LT(g_with, 0.97) << "the load-cell check sees the coupling weaken";
  ReplaySignals without_load = with_load;
  without_load.load_force_n = {};
  std::vector<int> flag_without;
  bool gain_without = false;
  replay_monitor(paper_config(), without_load, [&](std::size_t, const TwinOutputs& out) {
    flag_without.push_back(out.drift_warning * 4 + static_cast<int>(out.drift_observability));
    gain_without = gain_without || std::isfinite(out.drift_gain_estimate);
  });
  EXPECT_EQ(flag_with, flag_without);
  EXPECT_FALSE(gain_without) << "no load cell: no load-cell check";
}

// Open-loop windows from measured states: the nominal model tracks the plant, a model without
// the guide's friction strays further.
TEST(Replay, WindowsTellAMissingFrictionApart) {
  const Recording rec = simulate("hand-push", 8.0, 0.0);
  const auto& t = rec.column("t_s");
  const auto& p = rec.column("nut_pos_m");
  std::vector<double> v(p.size(), 0.0);
  for (std::size_t i = 1; i + 1 < p.size(); ++i)
    v[i] = (p[i + 1] - p[i - 1]) / (t[i + 1] - t[i - 1]);
  const ReplaySignals s{t, rec.column("screw_angle_rad"), p, {}, rec.column("load_force_n")};
  const ActuatorParams act;
  TwinModel nominal;
  TwinModel frictionless = nominal;
  frictionless.coulomb_n = 0.0;
  const auto good =
      replay_windows(NutModel(act, paper_calibration().periodic, nominal), s, v, 20, 100);
  const auto bad =
      replay_windows(NutModel(act, paper_calibration().periodic, frictionless), s, v, 20, 100);
  EXPECT_EQ(good.failures, 0);
  EXPECT_TRUE(std::isfinite(good.rms_position_error_m));
  EXPECT_LT(2.0 * good.rms_position_error_m, bad.rms_position_error_m)
      << good.rms_position_error_m << " m against " << bad.rms_position_error_m << " m";
}

}  // namespace
}  // namespace maglead::twin
