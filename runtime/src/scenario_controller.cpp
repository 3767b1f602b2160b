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

double ScenarioController::motor_angle_rad(double t_s, const SensorSample& sample,
                                           double force_set_n) {
  hw_.sample = sample;
  const std::uint16_t enable = bit(registers::kEnable);
  // Cycle 0 synchronises (drive ready); cycle 1 enables; then execute edges, one cycle high
  // and one low, whenever the setpoint changes.
  if (cycles_ == 1) {
    post(enable);
  } else if (execute_high_) {
    post(enable);
    execute_high_ = false;
  } else if (cycles_ > 1 && std::isfinite(force_set_n) && force_set_n != applied_n_) {
    image_.force_setpoint_n = force_set_n;
    image_.mode_command = static_cast<std::uint16_t>(registers::Mode::force);
    post(enable | bit(registers::kExecute));
    execute_high_ = true;
    applied_n_ = force_set_n;
  }
  ctl_.step(t_s);
  ++cycles_;
  return hw_.motor_cmd_rad;
}

}  // namespace maglead::runtime
