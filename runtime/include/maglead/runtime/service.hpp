#pragma once
// The composition of `maglead serve`: which hardware backend, the digital twin on its thread or
// none, the Modbus transports, and the realtime settings of the loop and the threads beside it.
// The CLI parses options and configuration files into a ServiceConfig and calls this.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/controller/controller.hpp"
#include "maglead/controller/loop_runner.hpp"
#include "maglead/controller/ports/hardware.hpp"
#include "maglead/modbus/network_config.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/runtime/twin_runner.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::runtime {

/// The simulated actuator's load and start (backend "simulated").
struct SimulatedOptions {
  std::uint64_t seed = 1;
  double spring_n_per_m = 2000.0;  // spring to a wall, 0: free nut
  double spring_anchor_m = 0.02;   // the spring's free-length position
  double start_pos_m = 0.02;       // nut position at start
  PlantEffects effects;            // where the plant differs from the model (--sim-effect)
};

struct BackendOptions {
  std::string name = "simulated";
  SimulatedOptions simulated;  // also the plant inside the simulated drive of cia402 --can sim
  canopen::Cia402BackendOptions cia402;
};

/// Builds the hardware port for an actuator. Throws std::invalid_argument on bad options.
using BackendFactory = std::function<std::unique_ptr<ActuatorHardware>(
    const ActuatorParams& actuator, const BackendOptions& options)>;
/// A real drive registers its factory here (before the service is built). Throws if the name is
/// taken.
void register_backend(const std::string& name, BackendFactory factory);
/// The registered names ("simulated" is built in).
std::vector<std::string> backend_names();
/// Throws std::invalid_argument naming the registered backends if `options.name` is unknown.
std::unique_ptr<ActuatorHardware> make_hardware(const ActuatorParams& actuator,
                                                const BackendOptions& options);

struct ServiceConfig {
  controller::ControllerConfig controller;
  BackendOptions backend;
  bool twin = true;
  // The twin's monitor (settings::load_monitor_config, or built in code); the service gives it
  // the controller's actuator and calibration. Its model is the one the controller is served.
  twin::TwinMonitorConfig twin_config;
  TwinRunnerOptions twin_options;
  // The twin thread's SCHED_FIFO priority when realtime is not "off": below the loop's (50),
  // above every SCHED_OTHER thread (network, clients), so a busy network cannot starve the
  // step-out warning. 0: SCHED_OTHER.
  int twin_fifo_priority = 20;
  modbus::NetworkConfig network;  // transports, read-only, watchdog, [runtime] realtime
  bool serve_modbus = true;       // false: no transports (benchmarks add their own clients)
  std::string model_name;         // FC43 model name; "" = the backend's name
};

class Service {
 public:
  /// Builds backend, controller, twin and servers (binds the TCP port). Throws on set-up errors.
  explicit Service(const ServiceConfig& config);
  ~Service();
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  /// Starts the twin thread, the loop and the transports. Throws std::runtime_error when
  /// realtime = "require" is not granted or a thread cannot start.
  void start();
  void stop();

  controller::Controller& controller() { return *controller_; }
  controller::LoopRunner& loop() { return *loop_; }
  const TwinRunner* twin() const { return twin_.get(); }
  /// -1 without TCP.
  int tcp_port() const;
  /// What the backend says of itself at start (a drive's identity and bus load); "" if nothing.
  std::string hardware_description() const;
  /// What of the realtime settings was not granted, loop and twin ("" = everything asked for).
  std::string refused() const;
  /// The core the loop is pinned to (-1: not pinned).
  int loop_cpu() const { return loop_cpu_; }

 private:
  struct Servers;
  ServiceConfig cfg_;
  std::unique_ptr<ActuatorHardware> hardware_;
  std::unique_ptr<controller::Controller> controller_;
  std::unique_ptr<TwinRunner> twin_;
  std::unique_ptr<Servers> servers_;
  std::unique_ptr<controller::LoopRunner> loop_;
  int loop_cpu_ = -1;
  bool started_ = false;
};

}  // namespace maglead::runtime
