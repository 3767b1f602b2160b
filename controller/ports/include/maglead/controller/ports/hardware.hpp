#pragma once
// The hardware port: the seam between the control loop and an actuator. The loop owns time and
// calls these narrow methods: the sensors and the motor command each cycle, the power stage when
// the controller's drive state changes. The controller owns this interface; the simulated plant
// (plant/) and real drivers implement it, and runtime/ chooses one.
#include <cstdint>

namespace maglead {

struct SensorSample {
  std::int64_t motor_counts = 0;   // motor encoder, quadrature counts
  std::int64_t linear_counts = 0;  // nut linear encoder, quadrature counts
  double load_force_n = 0.0;       // load cell if fitted (force on the nut from the load), else NaN
};

enum class HwStatus : std::uint8_t {
  ok,
  sensor_fault,
  drive_fault,
  following_error,  // the drive's motor does not follow the command (the drive itself has no fault)
};

/// What the controller asks of the drive's power stage (CiA 402: the controlword's target).
enum class PowerRequest : std::uint8_t {
  disable,      // power stage off (the controller is ready or disabled)
  enable,       // operation enabled: the motor follows write_motor_angle
  quick_stop,   // the drive stops the motor itself and holds it (the controller's stop bit)
  fault_reset,  // clear the drive's fault after the controller's own reset, then stay disabled
};

/// Why the drive reports drive_fault, as far as the backend can tell (the Modbus edge shows it
/// beside the alarm, so a PLC learns what to check without the serve terminal).
enum class DriveFaultCause : std::uint8_t {
  none,                 // no drive fault, or a backend that cannot tell
  drive_reports_fault,  // the drive itself is in fault; error_code says why
  drive_silent,         // no heartbeat: the drive is off, unpowered or off the bus
  process_data_lost,    // the drive's cyclic data stopped arriving
  bus_off,              // the CAN controller left the bus (wiring, termination, bit rate)
  drive_restarted,      // the drive reset itself while running (a boot-up message)
  enable_timeout,       // an enable request did not reach operation enabled in time
};
struct DriveFaultDetail {
  DriveFaultCause cause = DriveFaultCause::none;
  std::uint16_t error_code = 0;  // the drive's own error code (CiA 402 0x603F or EMCY), 0 none
};

class ActuatorHardware {
 public:
  virtual ~ActuatorHardware() = default;
  /// Latest sensor values at loop time `now_s`. Must not block or allocate.
  virtual HwStatus read_sensors(double now_s, SensorSample& out) noexcept = 0;
  /// Motor position command for the drive's servo [rad at the motor shaft].
  virtual HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept = 0;
  /// Asks the power stage for `request`, from the loop thread, in the cycle before
  /// write_motor_angle. Takes effect over the next cycles: must not block or allocate. A drive
  /// that then does not get there reports drive_fault from read_sensors.
  virtual HwStatus set_power(PowerRequest request) noexcept = 0;
  /// True while a fault reset asked of the power stage is still under way (a drive that keeps
  /// its fault reports it from read_sensors once this ends). Must not block or allocate.
  virtual bool resetting() const noexcept { return false; }
  /// Why read_sensors or a command reports drive_fault now. Must not block or allocate.
  virtual DriveFaultDetail fault_detail() const noexcept { return {}; }
};

}  // namespace maglead
