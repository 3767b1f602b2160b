#pragma once
// The hardware backend "cia402": the controller's hardware port on a CiA 402 drive through the
// CANopen master. read_sensors() takes the drive's TPDOs (motor position, the nut's encoder)
// and write_motor_angle() sends the target with SYNC, so the command of a cycle leaves in that
// cycle; set_power() sets the controlword's aim (enable, disable, quick stop, fault reset), which
// the master reaches one CiA 402 transition per cycle. With can = "sim" the drive is the simulated
// CiA 402 drive on the virtual bus, moved to the loop's time each cycle: the whole product runs
// through the CANopen path without a drive.
#include <cstdint>
#include <memory>
#include <string>

#include "maglead/canopen/master.hpp"
#include "maglead/controller/ports/hardware.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/plant/simulated_actuator.hpp"

namespace maglead::canopen {

class SimulatedCia402Drive;

struct Cia402BackendOptions {
  std::string can = "sim";  // a SocketCAN interface (can0), or "sim"
  DriveConfig drive;
  double sim_drop_fraction = 0.0;  // sim: share of frames lost on the virtual bus
  double sim_silence_at_s = -1.0;  // sim: the drive falls silent this long after start; < 0 never
  std::uint64_t sim_seed = 1;      // sim: the virtual bus's seed for lost frames
  // An enable request reaches operation enabled by then (and the drive stays there while it
  // holds), else drive_fault.
  double enable_timeout_s = 0.5;
  // A fault reset brings the drive out of fault by then; until then its fault is not reported.
  double reset_timeout_s = 0.5;
};

/// The drive's position unit and the second encoder's resolution mapped onto the actuator's
/// counts (ActuatorParams::motor_counts_per_rev, linear_count_m).
struct Cia402Scaling {
  double motor_counts_per_drive_count = 1.0;
  double linear_counts_per_encoder_count = 1.0;
  double drive_counts_per_rad = 4096.0 / 6.283185307179586;
};
Cia402Scaling cia402_scaling(const DriveConfig& drive, const ActuatorParams& actuator);

class Cia402Hardware final : public ActuatorHardware {
 public:
  /// Opens the bus (or builds the simulated drive around `plant`, which "sim" needs), starts
  /// the master and waits for the drive's first process data; the drive stays disabled until
  /// set_power(enable). Throws std::runtime_error when any of it fails (a missing interface by
  /// name, with how to bring one up).
  Cia402Hardware(const ActuatorParams& actuator, const Cia402BackendOptions& options,
                 std::unique_ptr<SimulatedActuator> plant);
  ~Cia402Hardware() override;
  Cia402Hardware(const Cia402Hardware&) = delete;
  Cia402Hardware& operator=(const Cia402Hardware&) = delete;

  HwStatus read_sensors(double now_s, SensorSample& out) noexcept override;
  HwStatus write_motor_angle(double motor_angle_cmd_rad) noexcept override;
  HwStatus set_power(PowerRequest request) noexcept override;
  bool resetting() const noexcept override { return resetting_; }
  DriveFaultDetail fault_detail() const noexcept override;

  const Cia402Master& master() const { return *master_; }
  /// An enable request that did not reach operation enabled in time (or lost it): drive_fault
  /// with the drive itself not in fault. Cleared by a fault reset.
  bool enable_timed_out() const noexcept { return enable_timed_out_; }
  /// The identity line printed at start: vendor, product, revision, serial, name; bus load.
  std::string describe() const;
  /// The simulated actuator inside the simulated drive ("sim" only, else null): for tests.
  const SimulatedActuator* simulated_plant() const { return plant_.get(); }
  /// The same, to set its load: a test's way to the load cell and the load it checks against.
  SimulatedActuator* simulated_plant() { return plant_.get(); }
  /// The simulated drive ("sim" only, else null): for tests to inject its faults.
  SimulatedCia402Drive* simulated_drive();

 private:
  struct Sim;
  void await_process_data(double timeout_s);
  void wait_cycle(double until_s);
  void supervise_power(double bus_now_s) noexcept;
  HwStatus status() const noexcept;
  HwStatus command_status() const noexcept;

  Cia402BackendOptions opt_;
  Cia402Scaling scale_;
  std::unique_ptr<SimulatedActuator> plant_;
  std::unique_ptr<Sim> sim_;
  std::unique_ptr<CanBus> socket_;
  std::unique_ptr<Cia402Master> master_;
  double loop_to_bus_s_ = 0.0;  // sim: the bus's time at the loop's zero
  bool loop_started_ = false;
  bool transmit_pending_ = false;  // read_sensors ran and the cycle's RPDO and SYNC are still due
  bool silence_set_ = false;
  PowerRequest wanted_ = PowerRequest::disable;  // the controller's last request
  bool resetting_ = false;                       // a fault reset the drive has not finished
  bool enable_timed_out_ = false;
  double bus_now_s_ = 0.0;
  double power_since_s_ = 0.0;  // when the current request began, or enabled was last seen
};

}  // namespace maglead::canopen
