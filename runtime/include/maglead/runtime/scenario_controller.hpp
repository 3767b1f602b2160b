#pragma once
// maglead's own controller driving a simulated scenario (`simulate --controller maglead`): the
// 1 kHz loop on the scenario's clock, fed the scenario's sensor samples, its force setpoints
// given as a PLC gives them (enable once, then an execute edge for each new setpoint).
#include <limits>

#include "maglead/controller/controller.hpp"

namespace maglead::runtime {

class ScenarioController {
 public:
  /// Throws std::invalid_argument on an inconsistent configuration (as the Controller does).
  explicit ScenarioController(const controller::ControllerConfig& config);
  ScenarioController(const ScenarioController&) = delete;
  ScenarioController& operator=(const ScenarioController&) = delete;

  /// One loop cycle at t_s on this sample, towards the output force `force_set_n` [N]; the
  /// motor angle command [rad at the motor shaft].
  double motor_angle_rad(double t_s, const SensorSample& sample, double force_set_n);

 private:
  /// The scenario's sample in, the loop's motor command out.
  struct SampleHardware final : ActuatorHardware {
    SensorSample sample;
    double motor_cmd_rad = 0.0;
    HwStatus read_sensors(double, SensorSample& out) noexcept override {
      out = sample;
      return HwStatus::ok;
    }
    HwStatus write_motor_angle(double angle_rad) noexcept override {
      motor_cmd_rad = angle_rad;
      return HwStatus::ok;
    }
    HwStatus set_power(PowerRequest) noexcept override { return HwStatus::ok; }
  };
  void post(std::uint16_t control_word);

  SampleHardware hw_;
  controller::Controller ctl_;
  controller::CommandImage image_;
  long cycles_ = 0;
  bool execute_high_ = false;
  double applied_n_ = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace maglead::runtime
