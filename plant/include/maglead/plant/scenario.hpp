#pragma once
// Load scenarios for the simulated actuator (issue: foundation). Each drives the plant at the
// sample rate, logs what a test bench would log and streams it as an mls-recording/1.
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "maglead/physics/force_model.hpp"
#include "maglead/plant/simulated_actuator.hpp"

namespace maglead {

struct ScenarioInfo {
  std::string name;
  std::string description;
};
const std::vector<ScenarioInfo>& scenario_list();

/// What a scenario asks of a controller at a sample, as a PLC would: a force [N], or a move to
/// target_m [m] at speed_m_s [m/s] and accel_m_s2 [m/s²]; NaN where it asks neither.
struct ScenarioSetpoint {
  double force_n = std::numeric_limits<double>::quiet_NaN();
  double target_m = std::numeric_limits<double>::quiet_NaN();
  double speed_m_s = 0.0, accel_m_s2 = 0.0;
};

/// The scenarios a controller other than the open loop can run: the force scenarios and the
/// point-to-point moves (one mode each, as a PLC runs them).
bool scenario_takes_controller(const std::string& scenario);

struct ScenarioOptions {
  std::string scenario;
  double duration_s = 30.0;
  std::uint64_t seed = 1;
  PlantParams plant = paper_like_plant();
  ForceCalibration estimator_calibration = paper_calibration();  // for out_force_est_n
  std::function<void(double fraction)> progress;                 // optional, ~100 calls
  /// What commands the screw instead of the open loop (the paper's inverse, the coupling at the
  /// force setpoint; the screw at the move's profile): time [s], this sample's sensor reading
  /// and the setpoint in, the motor angle command [rad at the motor shaft] out (maglead's own
  /// loop: runtime::ScenarioController). Only where scenario_takes_controller; empty: open loop.
  std::function<double(double t_s, const SensorSample& sample, const ScenarioSetpoint& setpoint)>
      controller;
  /// Which controller ran, for the recording's `# controller:` line ("maglead, its force loop");
  /// empty: "open-loop, the paper's inverse" without `controller`.
  std::string controller_name;
};

struct ScenarioSummary {
  std::size_t samples = 0;
  int slips = 0;  // step-outs the plant went through (truth, not logged in the recording)
  std::vector<double> disturbance_times_s;  // starts of external_disturbance pulses (truth)
};

/// Runs the scenario and writes the recording to `out_path`. Throws std::invalid_argument on an
/// unknown scenario (naming it and the known ones) or a non-positive duration.
ScenarioSummary run_scenario(const ScenarioOptions& options, const std::string& out_path);

/// Phase on the stable branch where a periodic coupling curve balances a load force
/// (F̂_s(φ) = load_force_n); used by scenarios to place loads.
double balancing_phase_rad(const PeriodicForceModel& coupling, double load_force_n);

}  // namespace maglead
