#include "maglead/runtime/scenario_controller.hpp"

#include <cmath>
#include <stdexcept>

namespace maglead::runtime {
namespace {
constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }
}  // namespace

ScenarioController::ScenarioController(const controller::ControllerConfig& config)
    : ctl_(config, hw_), image_(ctl_.initial_image()) {}

void ScenarioController::post(std::uint16_t control_word) {
  image_.control_word = control_word;
  // One command per cycle, never more than the queue holds: a full queue is a bug here.
  if (!ctl_.post(controller::Command{image_, false}))
    throw std::logic_error("scenario controller: command queue full");
}

bool ScenarioController::take(const ScenarioSetpoint& sp) {
  using registers::Mode;
  if (std::isfinite(sp.force_n) && sp.force_n != applied_.force_n) {
    image_.force_setpoint_n = sp.force_n;
    image_.mode_command = static_cast<std::uint16_t>(Mode::force);
  } else if (std::isfinite(sp.target_m) &&
             (sp.target_m != applied_.target_m || sp.speed_m_s != applied_.speed_m_s)) {
    image_.position_setpoint_m = sp.target_m;
    image_.velocity_limit_m_s = sp.speed_m_s;
    image_.accel_limit_m_s2 = sp.accel_m_s2;
    image_.mode_command = static_cast<std::uint16_t>(Mode::position);
  } else {
    return false;
  }
  applied_ = sp;
  return true;
}

double ScenarioController::motor_angle_rad(double t_s, const SensorSample& sample,
                                           const ScenarioSetpoint& setpoint) {
  hw_.sample = sample;
  const std::uint16_t enable = bit(registers::kEnable);
  // Cycle 0 synchronises (drive ready); cycle 1 enables; then execute edges, one cycle high
  // and one low, whenever the setpoint changes.
  if (cycles_ == 1) {
    post(enable);
  } else if (execute_high_) {
    post(enable);
    execute_high_ = false;
  } else if (cycles_ > 1 && take(setpoint)) {
    post(enable | bit(registers::kExecute));
    execute_high_ = true;
  }
  ctl_.step(t_s);
  ++cycles_;
  return hw_.motor_cmd_rad;
}

}  // namespace maglead::runtime
