#include "maglead/runtime/service.hpp"

#include <pthread.h>
#include <sched.h>

#include <map>
#include <mutex>
#include <stdexcept>

#include "maglead/modbus/modbus_core.hpp"
#include "maglead/modbus/modbus_rtu.hpp"
#include "maglead/modbus/modbus_tcp.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::runtime {
namespace {

std::unique_ptr<SimulatedActuator> make_simulated_actuator(const ActuatorParams& actuator,
                                                           const BackendOptions& options) {
  const SimulatedOptions& o = options.simulated;
  if (!(o.start_pos_m >= actuator.stroke_min_m && o.start_pos_m <= actuator.stroke_max_m))
    throw std::invalid_argument(
        "simulated actuator: the start position must lie within the stroke");
  if (!(o.spring_n_per_m >= 0.0))
    throw std::invalid_argument("simulated actuator: the spring rate must not be negative [N/m]");
  PlantParams plant = paper_like_plant();
  plant.actuator = actuator;
  plant.effects = o.effects;
  auto sim = std::make_unique<SimulatedActuator>(plant, o.seed, o.start_pos_m);
  if (o.spring_n_per_m > 0) {
    LoadSetting load;
    load.kind = LoadSetting::Kind::spring_to_wall;
    load.stiffness_n_per_m = o.spring_n_per_m;
    load.damping_n_s_per_m = 5.0;
    load.anchor_pos_m = o.spring_anchor_m;
    sim->set_load(load);
  }
  return sim;
}

std::unique_ptr<ActuatorHardware> make_simulated(const ActuatorParams& actuator,
                                                 const BackendOptions& options) {
  return make_simulated_actuator(actuator, options);
}

/// A CiA 402 drive over CANopen; with --can sim the simulated actuator inside a simulated drive.
std::unique_ptr<ActuatorHardware> make_cia402(const ActuatorParams& actuator,
                                              const BackendOptions& options) {
  std::unique_ptr<SimulatedActuator> plant;
  if (options.cia402.can == "sim") plant = make_simulated_actuator(actuator, options);
  return std::make_unique<canopen::Cia402Hardware>(actuator, options.cia402, std::move(plant));
}

struct Registry {
  std::mutex mutex;
  std::map<std::string, BackendFactory> factories{{"simulated", make_simulated},
                                                  {"cia402", make_cia402}};
};
Registry& registry() {
  static Registry r;
  return r;
}

/// The last core this process may run on, where LoopRunner pins by default; -1 if unknown.
int last_allowed_cpu() {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) return -1;
  for (int c = CPU_SETSIZE - 1; c >= 0; --c)
    if (CPU_ISSET(c, &allowed)) return c;
  return -1;
}

/// Keeps the calling thread (and the threads it starts meanwhile) off one core; restores on exit.
class OffCore {
 public:
  explicit OffCore(int cpu) {
    if (cpu < 0 || pthread_getaffinity_np(pthread_self(), sizeof saved_, &saved_) != 0) return;
    cpu_set_t others = saved_;
    CPU_CLR(cpu, &others);
    active_ = CPU_COUNT(&others) > 0 &&
              pthread_setaffinity_np(pthread_self(), sizeof others, &others) == 0;
  }
  ~OffCore() {
    if (active_) pthread_setaffinity_np(pthread_self(), sizeof saved_, &saved_);
  }
  OffCore(const OffCore&) = delete;
  OffCore& operator=(const OffCore&) = delete;

 private:
  cpu_set_t saved_{};
  bool active_ = false;
};

}  // namespace

void register_backend(const std::string& name, BackendFactory factory) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  if (!r.factories.emplace(name, std::move(factory)).second)
    throw std::invalid_argument("hardware backend \"" + name + "\" is registered already");
}

std::vector<std::string> backend_names() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  std::vector<std::string> names;
  for (const auto& [name, factory] : r.factories) names.push_back(name);
  return names;
}

std::unique_ptr<ActuatorHardware> make_hardware(const ActuatorParams& actuator,
                                                const BackendOptions& options) {
  BackendFactory factory;
  {
    Registry& r = registry();
    const std::lock_guard lock(r.mutex);
    const auto it = r.factories.find(options.name);
    if (it != r.factories.end()) factory = it->second;
  }
  if (!factory) {
    std::string known;
    for (const auto& n : backend_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown hardware backend \"" + options.name +
                                "\" (registered: " + known + ")");
  }
  return factory(actuator, options);
}

struct Service::Servers {
  std::unique_ptr<modbus::ModbusCore> core;
  std::unique_ptr<modbus::TcpServer> tcp;
  std::unique_ptr<modbus::RtuServer> rtu;
};

Service::Service(const ServiceConfig& config)
    : cfg_(config), servers_(std::make_unique<Servers>()) {
  hardware_ = make_hardware(cfg_.controller.actuator, cfg_.backend);
  controller_ = std::make_unique<controller::Controller>(cfg_.controller, *hardware_);
  if (cfg_.twin) {
    twin::TwinMonitorConfig tc = cfg_.twin_config;
    tc.actuator = cfg_.controller.actuator;  // the twin sees the same actuator and calibration
    tc.calibration = cfg_.controller.calibration;
    tc.stop_force_sd_n = cfg_.controller.observer_model_uncertainty_n;
    tc.integrator.max_step_s = 1.0 / cfg_.controller.actuator.sample_rate_hz;
    twin_ = std::make_unique<TwinRunner>(tc, cfg_.twin_options);
    controller_->attach_twin(twin_.get());
  }
  if (cfg_.serve_modbus) {
    const auto& net = cfg_.network;
    servers_->core = std::make_unique<modbus::ModbusCore>(
        *controller_, modbus::ServerOptions{net.read_only, cfg_.model_name.empty()
                                                               ? cfg_.backend.name + " actuator"
                                                               : cfg_.model_name});
    if (net.tcp_enabled)
      servers_->tcp = std::make_unique<modbus::TcpServer>(*servers_->core, net.tcp);
    if (!net.rtu.device.empty())
      servers_->rtu = std::make_unique<modbus::RtuServer>(*servers_->core, net.rtu);
  }
  loop_ = std::make_unique<controller::LoopRunner>(*controller_);
}

Service::~Service() { stop(); }

void Service::start() {
  if (started_) return;
  const auto policy = cfg_.network.realtime;
  loop_cpu_ = policy == controller::RealtimePolicy::off ? -1 : last_allowed_cpu();
  loop_->set_realtime(policy, loop_cpu_);
  // The twin first, so the loop's first samples find it running.
  if (twin_)
    twin_->start(
        {loop_cpu_, policy == controller::RealtimePolicy::off ? 0 : cfg_.twin_fifo_priority});
  try {
    loop_->start();
  } catch (...) {
    if (twin_) twin_->stop();
    throw;
  }
  started_ = true;
  // The network threads inherit this thread's affinity: keep them off the loop's core.
  const OffCore off(loop_->realtime_grant().pinned ? loop_cpu_ : -1);
  if (servers_->tcp) servers_->tcp->start();
  if (servers_->rtu) servers_->rtu->start();
}

void Service::stop() {
  if (!started_) return;
  started_ = false;
  if (servers_->tcp) servers_->tcp->stop();
  if (servers_->rtu) servers_->rtu->stop();
  loop_->stop();
  if (twin_) twin_->stop();
}

int Service::tcp_port() const { return servers_->tcp ? servers_->tcp->port() : -1; }

std::string Service::hardware_description() const {
  const auto* drive = dynamic_cast<const canopen::Cia402Hardware*>(hardware_.get());
  return drive != nullptr ? drive->describe() : std::string();
}

std::string Service::refused() const {
  std::string r = loop_->realtime_grant().refused;
  if (twin_ && !twin_->refused().empty()) r += (r.empty() ? "" : ", ") + twin_->refused();
  return r;
}

}  // namespace maglead::runtime
