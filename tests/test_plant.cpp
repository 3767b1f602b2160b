// The simulated actuator: stick-slip, step-out, quantization, effects, and that the paper's
// calibration procedure run on it recovers its curve.
#include <gtest/gtest.h>

#include "test_tmp.hpp"

#include <cmath>
#include <numbers>

#include "maglead/physics/calibration.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/plant/scenario.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/recording/recording.hpp"

using namespace maglead;

TEST(Plant, StictionHoldsTheNutAgainstTheCalibrationOffset) {
  // At φ = 0 the paper-like coupling pushes ~4.3 N, below the 7.5 N static friction.
  SimulatedActuator plant(paper_like_plant(), 1, 0.02);
  SensorSample s;
  plant.read_sensors(1.0, s);
  EXPECT_EQ(plant.truth().nut_vel_m_s, 0.0);
  EXPECT_NEAR(plant.truth().nut_pos_m, 0.02, 1e-12);
}

TEST(Plant, NutFollowsTheScrewWithoutLoad) {
  SimulatedActuator plant(paper_like_plant(), 1, 0.02);
  const auto& a = plant.params().actuator;
  SensorSample s;
  for (int k = 1; k <= 2000; ++k) {  // 2 s at 5 mm/s
    const double target = 0.02 + 5e-3 * std::min(k, 1000) * 1e-3;
    plant.write_motor_angle(rest_angle_rad(target, a.lead_m) * a.gear_ratio);
    plant.read_sensors(k * 1e-3, s);
  }
  // Friction leaves a phase lag of at most the break-away force's phase (~0.2 rad ≈ 0.2 mm).
  EXPECT_NEAR(plant.truth().nut_pos_m, 0.025, 0.25e-3);
  EXPECT_NEAR(nut_pos_m_from_counts(s.linear_counts, a), plant.truth().nut_pos_m, a.linear_count_m);
}

TEST(Plant, OverloadStepsOutByOneLead) {
  // A stiff stage holds the nut while the screw turns on: the coupling must slip.
  SimulatedActuator plant(paper_like_plant(), 1, 0.02);
  LoadSetting wall;
  wall.kind = LoadSetting::Kind::compliant;
  wall.stiffness_n_per_m = 2e5;
  wall.damping_n_s_per_m = 200;
  wall.anchor_pos_m = 0.02;
  plant.set_load(wall);
  const auto& a = plant.params().actuator;
  SensorSample s;
  const double screw0 = rest_angle_rad(0.02, a.lead_m);
  for (int k = 1; k <= 1500; ++k) {  // screw advances 1.5 turns
    plant.write_motor_angle((screw0 + 2 * std::numbers::pi * 1.5 * k / 1500.0) * a.gear_ratio);
    plant.read_sensors(k * 1e-3, s);
  }
  plant.read_sensors(2.0, s);
  EXPECT_EQ(plant.truth().slips, 1);
  EXPECT_LT(std::abs(plant.truth().nut_pos_m - 0.02), 0.5e-3);
}

TEST(Plant, UnknownEffectAndScenarioNameTheBadWord) {
  PlantEffects e;
  try {
    set_plant_effect(e, "warp_drive", 1.0);
    FAIL();
  } catch (const std::invalid_argument& ex) {
    EXPECT_NE(std::string(ex.what()).find("warp_drive"), std::string::npos);
  }
  set_plant_effect(e, "offset", 3.0);
  EXPECT_EQ(e.offset_n, 3.0);
  ScenarioOptions o;
  o.scenario = "moonwalk";
  EXPECT_THROW(run_scenario(o, test_tmp_dir() + "/x.csv"), std::invalid_argument);
}

TEST(Plant, OffsetEffectShowsOnTheLoadCellWhileHeld) {
  // A constant +3 N on the nut: held by the stage, the load cell must supply −3 N more.
  ScenarioOptions o;
  o.scenario = "static-calibration";
  o.duration_s = 12;
  const std::string base = test_tmp_dir() + "/cal_base.csv";
  const std::string off = test_tmp_dir() + "/cal_off.csv";
  run_scenario(o, base);
  o.plant.effects.offset_n = 3.0;
  run_scenario(o, off);
  const auto a = read_recording(base), b = read_recording(off);
  double diff = 0;
  for (std::size_t i = 0; i < a.rows(); ++i)
    diff += b.column("load_force_n")[i] - a.column("load_force_n")[i];
  EXPECT_NEAR(diff / static_cast<double>(a.rows()), -3.0, 0.3);
}

TEST(PlantCalibration, RecoversThePlantCurveWithinEncoderResolution) {
  ScenarioOptions o;
  o.scenario = "static-calibration";
  o.duration_s = 30;
  o.seed = 5;
  const std::string path = test_tmp_dir() + "/cal.csv";
  run_scenario(o, path);
  const auto rec = read_recording(path);
  const auto& t = rec.column("t_s");
  const auto& pos = rec.column("nut_pos_m");
  const auto& screw = rec.column("screw_angle_rad");
  std::vector<double> phase(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) phase[i] = phase_rad(screw[i], pos[i], 0.006);
  const auto r =
      calibrate_static_force(phase, central_velocity(t, pos, 50), rec.column("load_force_n"));
  EXPECT_GE(r.chosen_order, 5);  // the paper picks 5; 7 would be "similar"
  EXPECT_LE(r.chosen_order, 7);
  EXPECT_NEAR(r.coulomb_n, 7.5, 0.5);
  // One linear count is 0.0226 rad: at the curve's steepest (47.6 N/rad) about 1.1 N.
  const double one_count_n = 47.6 * 2 * std::numbers::pi * o.plant.actuator.linear_count_m / 0.006;
  for (double p = -1.3; p <= 1.3; p += 0.05)
    EXPECT_NEAR(r.calibration.polynomial.load_force_n(p), o.plant.coupling.load_force_n(p),
                one_count_n)
        << "phase " << p;
}
