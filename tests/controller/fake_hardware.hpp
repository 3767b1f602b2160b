#pragma once
// A fake actuator for the controller's hardware seam: the simulated plant behind it, with
// sensor and drive faults injected on request (a stroke-limit hit needs no injection: the
// plant is physical, a free nut in force mode runs into the end). It records every motor command,
// so a test can tell whether the motor was stopped (commands constant, or none at all) after a
// fault.
#include <cstdint>
#include <vector>

#include "maglead/controller/ports/hardware.hpp"
#include "maglead/plant/simulated_actuator.hpp"

namespace maglead::testing {

class FaultInjectingHardware final : public ActuatorHardware {
 public:
  enum class Fault : std::uint8_t {
    none,
    sensor,          // read_sensors reports sensor_fault (encoder or load cell lost)
    drive_on_read,   // read_sensors reports drive_fault (the drive's own fault output)
    drive_on_write,  // write_motor_angle reports drive_fault (the drive refused the command)
  };

  explicit FaultInjectingHardware(SimulatedActuator& plant) : plant_(plant) {
    commands_.reserve(1 << 16);
    power_requests_.reserve(256);
  }

  /// Injects `fault` from the next access on, until inject(Fault::none).
  void inject(Fault fault) { fault_ = fault; }
  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override {
    ++reads_;
    const HwStatus s = plant_.read_sensors(now_s, out);
    if (fault_ == Fault::sensor) return HwStatus::sensor_fault;
    if (fault_ == Fault::drive_on_read) return HwStatus::drive_fault;
    return s;
  }
  HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept override {
    if (fault_ == Fault::drive_on_write) {
      ++refused_writes_;
      return HwStatus::drive_fault;  // the drive did not take it: the plant keeps the last command
    }
    if (commands_.size() < commands_.capacity()) commands_.push_back(motor_angle_cmd_rad);
    return plant_.write_motor_angle(motor_angle_cmd_rad);
  }
  HwStatus set_power(PowerRequest request) noexcept override {
    if (power_requests_.size() < power_requests_.capacity()) power_requests_.push_back(request);
    return plant_.set_power(request);
  }
  /// Every power request the controller made, in order.
  const std::vector<PowerRequest>& power_requests() const { return power_requests_; }

  /// Motor commands the plant accepted, in order.
  const std::vector<double>& commands() const { return commands_; }
  std::uint64_t reads() const { return reads_; }
  std::uint64_t refused_writes() const { return refused_writes_; }
  SimulatedActuator& plant() { return plant_; }

 private:
  SimulatedActuator& plant_;
  Fault fault_ = Fault::none;
  std::vector<double> commands_;
  std::vector<PowerRequest> power_requests_;
  std::uint64_t reads_ = 0, refused_writes_ = 0;
};

}  // namespace maglead::testing
