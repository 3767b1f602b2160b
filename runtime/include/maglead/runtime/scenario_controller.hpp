#pragma once
// maglead's own controller driving a simulated scenario (`simulate --controller maglead`): the
// 1 kHz loop on the scenario's clock, fed the scenario's sensor samples, its setpoints given as
// a PLC gives them (enable once, then an execute edge for each new force setpoint or move).
#include "maglead/controller/controller.hpp"
#include "maglead/plant/scenario.hpp"

namespace maglead::runtime {

class ScenarioController {
 public:
  /// Throws std::invalid_argument on an inconsistent configuration (as the Controller does).
  explicit ScenarioController(const controller::ControllerConfig& config);
  ScenarioController(const ScenarioController&) = delete;
  ScenarioController& operator=(const ScenarioController&) = delete;

  /// One loop cycle at t_s on this sample, towards the setpoint (a force, or a move); the motor
  /// angle command [rad at the motor shaft].
  double motor_angle_rad(double t_s, const SensorSample& sample, const ScenarioSetpoint& setpoint);

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
  /// The setpoint into the command image when it is new (true: execute it).
  bool take(const ScenarioSetpoint& setpoint);

  SampleHardware hw_;
  controller::Controller ctl_;
  controller::CommandImage image_;
  long cycles_ = 0;
  bool execute_high_ = false;
  ScenarioSetpoint applied_;
};

}  // namespace maglead::runtime
