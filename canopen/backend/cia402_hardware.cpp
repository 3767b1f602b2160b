#include "maglead/canopen/cia402_hardware.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <thread>

#include "maglead/canopen/simulated_drive.hpp"
#include "maglead/canopen/socketcan_bus.hpp"
#include "maglead/canopen/virtual_bus.hpp"

namespace maglead::canopen {

struct Cia402Hardware::Sim {
  Sim(SimulatedActuator& plant, const Cia402BackendOptions& o, const SimulatedDriveOptions& d)
      : bus(bus_options(o)), drive(bus, plant, d), port(bus.attach(0)) {}
  static VirtualBusOptions bus_options(const Cia402BackendOptions& o) {
    VirtualBusOptions b;
    b.drop_fraction = o.sim_drop_fraction;
    b.seed = o.sim_seed;
    return b;
  }
  VirtualCanBus bus;
  SimulatedCia402Drive drive;
  VirtualCanPort& port;
};

namespace {

DriveRequest drive_request(PowerRequest request) noexcept {
  switch (request) {
    case PowerRequest::enable:
      return DriveRequest::enabled;
    case PowerRequest::quick_stop:
      return DriveRequest::quick_stop;
    case PowerRequest::fault_reset:
      return DriveRequest::fault_reset;
    case PowerRequest::disable:
      break;
  }
  return DriveRequest::disabled;
}

}  // namespace

Cia402Scaling cia402_scaling(const DriveConfig& drive, const ActuatorParams& actuator) {
  Cia402Scaling s;
  s.motor_counts_per_drive_count = actuator.motor_counts_per_rev / drive.counts_per_motor_turn;
  s.linear_counts_per_encoder_count = drive.second_encoder_m_per_count / actuator.linear_count_m;
  s.drive_counts_per_rad = drive.counts_per_motor_turn / (2.0 * std::numbers::pi);
  return s;
}

Cia402Hardware::Cia402Hardware(const ActuatorParams& actuator, const Cia402BackendOptions& options,
                               std::unique_ptr<SimulatedActuator> plant)
    : opt_(options), scale_(cia402_scaling(options.drive, actuator)), plant_(std::move(plant)) {
  check_drive_config(opt_.drive);
  if (!(std::abs(opt_.drive.loop_period_s * actuator.sample_rate_hz - 1.0) < 1e-9))
    throw std::invalid_argument("cia402: the drive's loop period must be the loop's (" +
                                std::to_string(1.0 / actuator.sample_rate_hz) + " s)");
  CanBus* bus = nullptr;
  if (opt_.can == "sim") {
    if (!plant_) throw std::invalid_argument("cia402 --can sim needs the simulated actuator");
    if (!(opt_.sim_drop_fraction >= 0.0 && opt_.sim_drop_fraction < 1.0))
      throw std::invalid_argument("cia402: the simulated bus's drop fraction must lie in [0, 1)");
    SimulatedDriveOptions d;
    d.node_id = opt_.drive.node_id;
    d.counts_per_motor_turn = opt_.drive.counts_per_motor_turn;
    d.second_encoder_index = opt_.drive.second_encoder_index;
    d.second_encoder_sub = opt_.drive.second_encoder_sub;
    sim_ = std::make_unique<Sim>(*plant_, opt_, d);
    bus = &sim_->port;
  } else {
    auto socket = std::make_unique<SocketCanBus>(opt_.can, opt_.drive.bitrate_bit_s);
    socket->set_receive_filter(drive_receive_filter(opt_.drive.node_id));
    socket_ = std::move(socket);
    bus = socket_.get();
  }
  master_ = std::make_unique<Cia402Master>(*bus, opt_.drive);
  master_->start();
  await_process_data(opt_.drive.boot_timeout_s);
}

Cia402Hardware::~Cia402Hardware() {
  // Leaving, the power stage goes off (disable voltage) rather than holding a position that no
  // SYNC will update any more.
  if (master_) {
    master_->request(DriveRequest::disabled);
    master_->transmit();
  }
}

void Cia402Hardware::wait_cycle(double until_s) {
  if (sim_) {
    sim_->bus.advance_to(until_s);
    return;
  }
  const double wait_s = until_s - socket_->now_s();
  if (wait_s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait_s));
}

void Cia402Hardware::await_process_data(double timeout_s) {
  // Set-up, before the loop runs: cycles on the bus's clock until the drive's TPDOs say where
  // it stands, so the loop's first cycle has its positions. The drive stays disabled: the
  // controller's enable powers it. A drive in fault is the controller's to reset.
  CanBus& bus = sim_ ? static_cast<CanBus&>(sim_->port) : *socket_;
  const double period_s = opt_.drive.loop_period_s;
  const double deadline_s = bus.now_s() + timeout_s;
  master_->request(DriveRequest::disabled);
  while (master_->feedback().state == DriveState::unknown) {
    const MasterFault f = master_->fault();
    if (bus.now_s() > deadline_s || (f != MasterFault::none && f != MasterFault::drive_fault))
      throw std::runtime_error(std::string("cia402: no process data from the drive within ") +
                               std::to_string(timeout_s) + " s (" + master_->alarm_text() + ")");
    wait_cycle(bus.now_s() + period_s);
    master_->cycle(bus.now_s());
  }
}

HwStatus Cia402Hardware::set_power(PowerRequest request) noexcept {
  if (request == PowerRequest::fault_reset) {
    // The drive leaves fault for switch on disabled and stays disabled until an enable.
    resetting_ = true;
    enable_timed_out_ = false;
    wanted_ = PowerRequest::disable;
    master_->request(DriveRequest::fault_reset);
  } else {
    wanted_ = request;
    if (!resetting_) master_->request(drive_request(request));  // else once the reset is done
  }
  power_since_s_ = bus_now_s_;
  return command_status();
}

void Cia402Hardware::supervise_power(double bus_now_s) noexcept {
  const bool in_fault = master_->fault() != MasterFault::none;
  if (resetting_) {
    if (!in_fault) {
      resetting_ = false;
      master_->request(drive_request(wanted_));
      power_since_s_ = bus_now_s;
    } else if (bus_now_s - power_since_s_ > opt_.reset_timeout_s) {
      resetting_ = false;  // the drive kept its fault: reported again
    }
    return;
  }
  if (wanted_ != PowerRequest::enable || in_fault ||
      master_->feedback().state == DriveState::operation_enabled) {
    power_since_s_ = bus_now_s;
    return;
  }
  if (bus_now_s - power_since_s_ > opt_.enable_timeout_s) enable_timed_out_ = true;
}

HwStatus Cia402Hardware::status() const noexcept {
  const MasterFault f = master_->fault();
  // During a reset the drive's fault is the one being cleared, not a new one.
  const bool held_off = resetting_ && f == MasterFault::drive_fault;
  if ((f != MasterFault::none && !held_off) || enable_timed_out_) return HwStatus::drive_fault;
  // Bit 13 means following error only in operation enabled (cyclic synchronous position).
  const DriveFeedback& fb = master_->feedback();
  const bool following_error =
      fb.state == DriveState::operation_enabled && (fb.statusword & sw_following_error) != 0;
  return following_error ? HwStatus::following_error : HwStatus::ok;
}

DriveFaultDetail Cia402Hardware::fault_detail() const noexcept {
  const DriveFeedback& fb = master_->feedback();
  // An EMCY is unconfirmed and may be lost; 0x603F in the TPDO says the same every cycle.
  const std::uint16_t code =
      fb.error_code != 0 ? fb.error_code : master_->last_emergency().error_code;
  const MasterFault f = master_->fault();
  // A silent drive's PDOs time out before its heartbeat does: the silence is the cause.
  if (master_->heartbeat_lost() && f != MasterFault::bus_off)
    return {DriveFaultCause::drive_silent, 0};
  switch (f) {
    case MasterFault::drive_fault:
      return {DriveFaultCause::drive_reports_fault, code};
    case MasterFault::heartbeat_lost:
      return {DriveFaultCause::drive_silent, 0};
    case MasterFault::pdo_timeout:
      return {DriveFaultCause::process_data_lost, 0};
    case MasterFault::bus_off:
      return {DriveFaultCause::bus_off, 0};
    case MasterFault::drive_restarted:
      return {DriveFaultCause::drive_restarted, 0};
    case MasterFault::none:
      break;
  }
  return {enable_timed_out_ ? DriveFaultCause::enable_timeout : DriveFaultCause::none, 0};
}

HwStatus Cia402Hardware::command_status() const noexcept {
  // A following error is read_sensors' to report; a command is refused only by a drive fault.
  return status() == HwStatus::drive_fault ? HwStatus::drive_fault : HwStatus::ok;
}

HwStatus Cia402Hardware::read_sensors(double now_s, SensorSample& out) noexcept {
  if (sim_) {
    // The loop's first cycle one period after the last set-up cycle, as on a real bus.
    if (!loop_started_) loop_to_bus_s_ = sim_->bus.now_s() + opt_.drive.loop_period_s - now_s;
    const double bus_s = now_s + loop_to_bus_s_;
    if (opt_.sim_silence_at_s >= 0.0 && !silence_set_) {
      sim_->bus.silence(opt_.drive.node_id, bus_s + opt_.sim_silence_at_s);
      silence_set_ = true;
    }
    sim_->bus.advance_to(bus_s);
  }
  loop_started_ = true;
  // The master keeps time on the bus's clock, as it did at start-up (its heartbeat timing).
  bus_now_s_ = sim_ ? sim_->bus.now_s() : socket_->now_s();
  master_->receive(bus_now_s_);
  supervise_power(bus_now_s_);
  const HwStatus st = status();
  // A loop does not write after a drive fault (the controller does not): the cycle's RPDO and
  // SYNC go now, so the drive keeps its SYNC and the master its supervision and controlword.
  transmit_pending_ = st != HwStatus::drive_fault;
  if (!transmit_pending_) master_->transmit();
  const DriveFeedback& f = master_->feedback();
  out.motor_counts = std::llround(f.position_counts * scale_.motor_counts_per_drive_count);
  out.linear_counts =
      std::llround(f.second_encoder_counts * scale_.linear_counts_per_encoder_count);
  out.load_force_n = std::numeric_limits<double>::quiet_NaN();  // no load cell on this path
  return st;
}

HwStatus Cia402Hardware::write_motor_angle(double motor_angle_cmd_rad) noexcept {
  const double counts = motor_angle_cmd_rad * scale_.drive_counts_per_rad;
  // The drive's target is 32 bits: a command beyond it is a fault, not a wrapped position.
  if (!(std::abs(counts) < 2147483647.0)) return HwStatus::drive_fault;
  master_->set_target_counts(static_cast<std::int32_t>(std::lround(counts)));
  if (transmit_pending_) {
    transmit_pending_ = false;
    master_->transmit();
  }
  return command_status();
}

SimulatedCia402Drive* Cia402Hardware::simulated_drive() { return sim_ ? &sim_->drive : nullptr; }

std::string Cia402Hardware::describe() const {
  const int load_percent = static_cast<int>(std::lround(100.0 * bus_load_fraction(opt_.drive)));
  return "CiA 402 drive, node " + std::to_string(opt_.drive.node_id) + " on " +
         (sim_ ? std::string("the simulated bus") : opt_.can) + ": " +
         describe_identity(master_->identity()) + "; the cycle takes " +
         std::to_string(load_percent) + " % of the bus at " +
         std::to_string(opt_.drive.bitrate_bit_s) + " bit/s";
}

}  // namespace maglead::canopen
