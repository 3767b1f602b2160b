#pragma once
// The hardware port: the seam between the control loop and an actuator. The loop owns time and
// calls these two narrow methods each cycle. The controller owns this interface; the simulated
// plant (plant/) and real drivers implement it, and runtime/ chooses one.
#include <cstdint>

namespace maglead {

struct SensorSample {
  std::int64_t motor_counts = 0;   // motor encoder, quadrature counts
  std::int64_t linear_counts = 0;  // nut linear encoder, quadrature counts
  double load_force_n = 0.0;       // load cell if fitted (force on the nut from the load), else NaN
};

enum class HwStatus : std::uint8_t { ok, sensor_fault, drive_fault };

class ActuatorHardware {
 public:
  virtual ~ActuatorHardware() = default;
  /// Latest sensor values at loop time `now_s`. Must not block or allocate.
  virtual HwStatus read_sensors(double now_s, SensorSample& out) noexcept = 0;
  /// Motor position command for the drive's servo [rad at the motor shaft].
  virtual HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept = 0;
};

}  // namespace maglead
