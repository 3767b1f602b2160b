// maglead serve: run the 1 kHz controller on an actuator (the simulated one, or a CiA 402 drive
// over CANopen) and serve it over Modbus TCP and/or RTU until interrupted (or for --duration).
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <memory>
#include <optional>
#include <thread>

#include "cli_common.hpp"
#include "maglead/analysis/results.hpp"
#include "maglead/modbus/network_config.hpp"
#include "maglead/registers/registers.hpp"
#include "maglead/runtime/service.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::cli {
namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int signal_number) { g_stop = signal_number; }

struct ServeOptions {
  std::string config = default_config_dir(), network, calibration, duration, model;
  std::vector<std::string> sim_effects;
  std::string bind, allow_csv, rtu_device, rtu_parity;
  int port = -1, unit = -1, max_connections = -1, rtu_baud = -1, rtu_unit = -1, rtu_stop_bits = -1,
      rtu_data_bits = -1;
  double frame_timeout_s = -1, idle_timeout_s = -1, watchdog_ms = -1;
  std::vector<std::string> allow;
  bool read_only = false, no_tcp = false, rs485 = false, no_twin = false;
  std::uint64_t seed = 1;
  double spring_n_per_m = 2000.0, spring_anchor_m = 0.02, start_pos_m = 0.02;
  std::string backend = "simulated", can, sim_can_silence_at;  // can: empty unless given
  double sim_can_drop = 0.0;
  std::string can_or_sim() const { return can.empty() ? "sim" : can; }
};

void add_network_options(CLI::App* cmd, ServeOptions& o) {
  auto* g = cmd->add_option_group("Modbus TCP (defaults from network.toml)");
  g->add_option("--bind", o.bind, "Bind address (default 127.0.0.1)");
  g->add_option("--port", o.port, "TCP port (default 1502; 0 = any free port, printed)")
      ->check(CLI::Range(0, 65535));
  g->add_option("--unit", o.unit, "Unit id answered over TCP (default 1; 255 is answered too)")
      ->check(CLI::Range(0, 255));
  g->add_option("--max-connections", o.max_connections,
                "Connection cap (default 32; at the cap the longest idle one is closed)")
      ->check(CLI::Range(1, 1024));
  g->add_option("--frame-timeout", o.frame_timeout_s,
                "Seconds a started request may take (default 1.0; 500ms also reads)")
      ->transform(quantity_in({"s", "s", 1.0, "--frame-timeout 0.5 or 500ms"}))
      ->check(CLI::Range(0.001, 3600.0));
  g->add_option("--idle-timeout", o.idle_timeout_s,
                "Close idle connections after this many seconds (default 60; 0 never)")
      ->transform(quantity_in({"s", "s", 1.0, "--idle-timeout 60"}))
      ->check(CLI::Range(0.0, 1e7));
  g->add_option("--allow", o.allow, "Allowed client IPv4 address or a.b.c.d/len (repeatable)");
  g->add_flag("--no-tcp", o.no_tcp, "Do not serve TCP");
  auto* r = cmd->add_option_group("Modbus RTU (defaults from network.toml)");
  r->add_option("--rtu-device", o.rtu_device, "Serial device; enables RTU");
  r->add_option("--rtu-baud", o.rtu_baud, "Baud rate (default 19200)")
      ->check(CLI::Range(50, 4000000));
  r->add_option("--rtu-parity", o.rtu_parity, "Parity N, E or O (default E)")
      ->check(CLI::IsMember({"N", "E", "O"}));
  r->add_option("--rtu-data-bits", o.rtu_data_bits, "Data bits (default 8)")
      ->check(CLI::Range(7, 8));
  r->add_option("--rtu-stop-bits", o.rtu_stop_bits, "Stop bits (default 1)")
      ->check(CLI::Range(1, 2));
  r->add_option("--rtu-unit", o.rtu_unit, "RTU unit id (default 1)")->check(CLI::Range(1, 247));
  r->add_flag("--rtu-rs485", o.rs485, "Switch the line to RS-485 mode");
}

void add_sim_options(CLI::App* cmd, ServeOptions& o) {
  auto* s = cmd->add_option_group("Simulated actuator");
  s->add_option("--sim-seed", o.seed, "Random seed of the simulated plant")->capture_default_str();
  s->add_option("--sim-spring", o.spring_n_per_m, "Load: spring rate to a wall [N/m], 0 = free nut")
      ->transform(quantity_in({"N/m", "", 1.0, "--sim-spring 2000"}))
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  s->add_option("--sim-spring-anchor", o.spring_anchor_m,
                "Load: spring free length position [m; 20mm also reads]")
      ->transform(quantity_in({"m", "m", 1.0, "--sim-spring-anchor 0.02 or 20mm"}))
      ->capture_default_str();
  s->add_option("--sim-start", o.start_pos_m, "Nut position at start [m; 20mm also reads]")
      ->transform(quantity_in({"m", "m", 1.0, "--sim-start 0.02 or 20mm"}))
      ->capture_default_str();
  const std::string effects_help = plant_effects_help(
      "Where the simulated plant differs from the model, NAME=VALUE as simulate --effect "
      "(repeatable):");
  s->add_option("--sim-effect", o.sim_effects, effects_help);
}

void add_backend_options(CLI::App* cmd, ServeOptions& o) {
  auto* b = cmd->add_option_group("Hardware backend");
  b->add_option("--backend", o.backend,
                "simulated: the simulated actuator; cia402: a CiA 402 servo drive over CANopen "
                "(see --can)")
      ->check(CLI::IsMember(runtime::backend_names()))
      ->capture_default_str();
  b->add_option("--can", o.can,
                "cia402: the SocketCAN interface of the drive (e.g. can0), or sim: the simulated "
                "CiA 402 drive in-process around the simulated actuator (default: sim)")
      ->check(CLI::Validator(
          [](const std::string& name) {
            return name.empty() ? std::string("an interface name (e.g. can0) or sim, not empty")
                                : std::string();
          },
          "INTERFACE"));
  b->add_option("--sim-can-drop", o.sim_can_drop,
                "cia402 --can sim: fraction of CAN frames lost on the simulated bus (start-up "
                "tries each SDO sdo_attempts times, 3 in drive.toml: from about 5 % loss it may "
                "fail; raise sdo_attempts there)")
      ->check(CLI::Range(0.0, 0.5))
      ->capture_default_str();
  b->add_option("--sim-can-silence-at", o.sim_can_silence_at,
                "cia402 --can sim: the simulated drive falls silent this long after start (e.g. "
                "10s)");
}

/// The cia402 backend's settings: CONFIG/drive.toml where there is one, over a drive that counts
/// as the actuator's encoders do; the loop's period always.
void set_cia402(const ServeOptions& o, const ActuatorParams& actuator,
                canopen::Cia402BackendOptions& c) {
  // --can sim without the backend would run the plain simulated actuator, not the CANopen path.
  if (o.backend != "cia402" &&
      (!o.can.empty() || o.sim_can_drop > 0.0 || !o.sim_can_silence_at.empty()))
    throw CLI::ValidationError(
        "--can", "applies to --backend cia402 only: type --backend cia402 --can " + o.can_or_sim());
  if (o.can_or_sim() != "sim" && (o.sim_can_drop > 0.0 || !o.sim_can_silence_at.empty()))
    throw CLI::ValidationError(
        o.sim_can_drop > 0.0 ? "--sim-can-drop" : "--sim-can-silence-at",
        "applies to --can sim only (the simulated drive), not --can " + o.can_or_sim());
  c.can = o.can_or_sim();
  c.sim_drop_fraction = o.sim_can_drop;
  c.sim_seed = o.seed;
  if (!o.sim_can_silence_at.empty())
    c.sim_silence_at_s = parse_duration_s(o.sim_can_silence_at, "--sim-can-silence-at");
  c.drive.loop_period_s = 1.0 / actuator.sample_rate_hz;
  c.drive.counts_per_motor_turn = actuator.motor_counts_per_rev;
  c.drive.gear_ratio = actuator.gear_ratio;
  c.drive.second_encoder_m_per_count = actuator.linear_count_m;
  const std::string drive_toml = config_file(o.config, "drive.toml");
  if (o.backend == "cia402" && std::filesystem::exists(drive_toml))
    c.drive = canopen::load_drive_config(drive_toml, c.drive);
}

/// network.toml (when there is one), then the options that override it.
modbus::NetworkConfig network_config(const ServeOptions& o) {
  const std::string net_path =
      o.network.empty() ? config_file(o.config, "network.toml") : o.network;
  modbus::NetworkConfig net;
  if (!o.network.empty() || std::filesystem::exists(net_path))
    net = modbus::load_network_config(net_path);
  if (!o.bind.empty()) net.tcp.bind_address = o.bind;
  if (o.port >= 0) net.tcp.port = o.port;
  if (o.unit >= 0) net.tcp.unit_id = static_cast<std::uint8_t>(o.unit);
  if (o.max_connections > 0) net.tcp.max_connections = o.max_connections;
  if (o.frame_timeout_s > 0) net.tcp.frame_timeout_s = o.frame_timeout_s;
  if (o.idle_timeout_s >= 0) net.tcp.idle_timeout_s = o.idle_timeout_s;
  if (!o.allow.empty()) net.tcp.allow = o.allow;
  if (o.no_tcp) net.tcp_enabled = false;
  if (!o.rtu_device.empty()) net.rtu.device = o.rtu_device;
  if (o.rtu_baud > 0) net.rtu.baud = o.rtu_baud;
  if (!o.rtu_parity.empty()) net.rtu.parity = o.rtu_parity[0];
  if (o.rtu_data_bits > 0) net.rtu.data_bits = o.rtu_data_bits;
  if (o.rtu_stop_bits > 0) net.rtu.stop_bits = o.rtu_stop_bits;
  if (o.rtu_unit > 0) net.rtu.unit_id = static_cast<std::uint8_t>(o.rtu_unit);
  if (o.rs485) net.rtu.rs485 = true;
  if (o.read_only) net.read_only = true;
  if (o.watchdog_ms >= 0) net.watchdog_s = o.watchdog_ms * 1e-3;
  if (!net.tcp_enabled && net.rtu.device.empty())
    throw CLI::ValidationError("serve", "nothing to serve: TCP is off and no RTU device is given");
  return net;
}

/// What the service runs: the configuration folder, the model file and the simulated plant.
/// `model_used` gets the model file served (empty: none, the actuator's friction).
runtime::ServiceConfig service_config(const ServeOptions& o, const modbus::NetworkConfig& net,
                                      std::string& model_used) {
  runtime::ServiceConfig sc;
  auto& cfg = sc.controller;
  cfg = controller_config_of(o.config, o.calibration, o.model, &model_used);
  cfg.watchdog_s = net.watchdog_s;
  cfg.reactions = net.reactions;
  if (!(o.start_pos_m >= cfg.actuator.stroke_min_m && o.start_pos_m <= cfg.actuator.stroke_max_m)) {
    // The range with its units, and where it is set: "0.0404 m" alone does not say how far out.
    char b[200];
    std::snprintf(b, sizeof b, "%g m (%g mm) must lie within the stroke %g .. %g m (%g .. %g mm",
                  o.start_pos_m, o.start_pos_m * 1e3, cfg.actuator.stroke_min_m,
                  cfg.actuator.stroke_max_m, cfg.actuator.stroke_min_m * 1e3,
                  cfg.actuator.stroke_max_m * 1e3);
    throw CLI::ValidationError("--sim-start", b + std::string(", stroke_min_m / stroke_max_m in ") +
                                                  config_file(o.config, "actuator.toml") + ")");
  }
  sc.backend.simulated = {o.seed, o.spring_n_per_m, o.spring_anchor_m, o.start_pos_m, {}};
  apply_plant_effects("--sim-effect", o.sim_effects, sc.backend.simulated.effects);
  sc.backend.name = o.backend;
  set_cia402(o, cfg.actuator, sc.backend.cia402);
  sc.twin = !o.no_twin;
  sc.twin_config = twin::load_monitor_config(o.config);
  if (!model_used.empty()) sc.twin_config.model = twin::load_twin_model(model_used);
  sc.network = net;
  return sc;
}

/// The coupling terms the model adds to the calibration, only those it states.
std::string coupling_text(const CouplingModel& c) {
  std::vector<std::string> terms;
  char buf[96];
  if (c.gain != 1.0) {
    std::snprintf(buf, sizeof buf, "coupling %.3f x calibration", c.gain);
    terms.emplace_back(buf);
  }
  if (c.angle_ripple != 0.0) {
    std::snprintf(buf, sizeof buf, "%.1f %% ripple per screw turn", 100.0 * c.angle_ripple);
    terms.emplace_back(buf);
  }
  if (c.end_zone_m > 0 && c.end_max_reduction > 0) {
    std::snprintf(buf, sizeof buf, "%.0f %% weaker within %.1f mm of the ends",
                  100.0 * c.end_max_reduction, 1e3 * c.end_zone_m);
    terms.emplace_back(buf);
  }
  std::string out = terms.empty() ? "coupling as calibrated" : terms.front();
  for (std::size_t i = 1; i < terms.size(); ++i) out += ", " + terms[i];
  return out;
}

/// The model file's terms, as the corrected model states them: "offset (offset_n 2.004 N);
/// left out: viscous_friction". Empty for a model without terms.
std::string model_terms_text(const twin::TwinModel& m) {
  std::string on, off;
  for (const auto& t : m.terms) {
    if (!t.enabled) {
      off += (off.empty() ? "" : ", ") + t.id;
      continue;
    }
    analysis::Parameters values;  // written as analyze writes a finding's
    for (const auto& [name, value] : t.parameters) values.push_back({name, value, false});
    const std::string params = analysis::summary_text(values, {});
    on += (on.empty() ? "" : "; ") + t.id + (params.empty() ? "" : " (" + params + ")");
  }
  if (on.empty() && off.empty()) return "";
  return "model terms: " + (on.empty() ? std::string("none enabled") : on) +
         (off.empty() ? "" : "; disabled in the file: " + off);
}

/// The configuration files serve reads, as the user would name them: those of the folder that
/// exist, and the files given by option instead.
std::string files_read(const ServeOptions& o) {
  std::string out;
  const auto add = [&](const std::string& name, const std::string& given) {
    const std::string path = given.empty() ? config_file(o.config, name) : given;
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return;
    out += (out.empty() ? "" : ", ") + (given.empty() ? name : given);
  };
  add("actuator.toml", "");
  add("calibration.toml", o.calibration);
  add("network.toml", o.network);
  add("model.toml", o.model);
  if (o.backend == "cia402") add("drive.toml", "");
  return out.empty() ? "no files: built-in defaults" : "read " + out;
}

/// One line of serve's own, "maglead serve: …", wrapped at spaces under its text on a terminal
/// (80 columns and up stay readable); into a pipe or a log each line stays whole.
template <typename... Args>
void say(const char* format, Args... args) {
  constexpr std::string_view kPrefix = "maglead serve: ";
  char text[512];
  std::snprintf(text, sizeof text, format, args...);
  std::printf("%s\n",
              wrapped(std::string(kPrefix) + text, kPrefix.size(), terminal_columns()).c_str());
  std::fflush(stdout);
}

void print_banner(const ServeOptions& o, const runtime::ServiceConfig& sc,
                  const std::string& model_used, runtime::Service& service) {
  const auto& cfg = sc.controller;
  const auto& net = sc.network;
  if (!service.refused().empty())
    say("realtime \"try\": not granted: %s", service.refused().c_str());
  const std::string drive = service.hardware_description();
  const bool real_drive = o.backend == "cia402" && o.can_or_sim() != "sim";
  const std::string load =
      real_drive ? "the load it drives"
      : o.spring_n_per_m > 0
          ? "spring " + std::to_string(static_cast<int>(o.spring_n_per_m)) + " N/m"
          : "free nut";
  if (!drive.empty()) say("%s", drive.c_str());
  say("control loop %.0f Hz on the %s (%s), %s, %s", cfg.actuator.sample_rate_hz,
      o.backend == "cia402"
          ? (real_drive ? "CiA 402 drive" : "simulated actuator through a simulated CiA 402 drive")
          : "simulated actuator",
      load.c_str(), service.loop().realtime() ? "SCHED_FIFO" : "normal scheduling",
      service.twin() ? "digital twin running on its own thread" : "no twin");
  say("configuration from %s (%s)",
      std::filesystem::absolute(o.config).lexically_normal().string().c_str(),
      files_read(o).c_str());
  char offset[48] = "";
  if (cfg.friction.offset_n != 0.0)
    std::snprintf(offset, sizeof offset, ", offset %.3f N", cfg.friction.offset_n);
  say("model from %s: F_c %.2f/%.2f N, break-away %.2f/%.2f N (+p/-p)%s, %s%s",
      model_used.empty() ? "[actuator]" : model_used.c_str(), cfg.friction.coulomb_pos_n,
      cfg.friction.coulomb_neg_n, cfg.friction.breakaway_pos_n, cfg.friction.breakaway_neg_n,
      offset, coupling_text(cfg.coupling).c_str(),
      o.sim_effects.empty() ? "" : "; the simulated plant differs (--sim-effect)");
  if (const auto terms = model_terms_text(sc.twin_config.model); !terms.empty())
    say("%s", terms.c_str());
  const auto& rm = cfg.reference_move;
  say("reference move (mode_command 3): %.1f .. %.1f mm at %.1f and %.1f mm/s, "
      "%.2f m/s^2 ([reference_move])",
      rm.window_min_m * 1e3, rm.window_max_m * 1e3, rm.slow_m_s * 1e3, rm.fast_m_s * 1e3,
      rm.accel_m_s2);
  if (service.tcp_port() >= 0)
    say("Modbus TCP on %s:%d, unit %d%s", net.tcp.bind_address.c_str(), service.tcp_port(),
        net.tcp.unit_id, net.read_only ? ", read-only" : "");
  if (!net.rtu.device.empty())
    say("Modbus RTU on %s, %d %d%c%d, unit %d%s", net.rtu.device.c_str(), net.rtu.baud,
        net.rtu.data_bits, net.rtu.parity, net.rtu.stop_bits, net.rtu.unit_id,
        net.read_only ? ", read-only" : "");
  std::fflush(stdout);
}

/// A drive fault's cause (IR 68) and the drive's own error code (IR 69) when it gave one.
void say_drive_fault_cause(const controller::Snapshot& s) {
  const auto codes = registers::codes_of("drive_fault_cause");
  const auto it = std::find_if(codes.begin(), codes.end(), [&](const registers::Code& c) {
    return c.value == s.drive_fault_cause;
  });
  if (it == codes.end()) return;
  char code[48] = "";
  if (s.drive_error_code != 0)
    std::snprintf(code, sizeof code, "; drive_error_code 0x%04X", s.drive_error_code);
  say("  cause at %.2f s: drive_fault_cause %u %.*s (%.*s)%s", s.t_s,
      static_cast<unsigned>(s.drive_fault_cause), static_cast<int>(it->name.size()),
      it->name.data(), static_cast<int>(it->description.size()), it->description.data(), code);
}

/// A fault latched or cleared since the last look, said once: the terminal running serve is
/// where an operator looks first when a command is refused.
struct AlarmSeen {
  std::uint16_t alarm = 0, cause = 0;
  bool returned = false;
};

void say_alarm_change(const controller::Snapshot& s, AlarmSeen& seen) {
  // A reset whose fault came back at once leaves the alarm as it was: said on its own.
  const bool returned =
      s.reject_reason == static_cast<std::uint16_t>(registers::Reject::fault_returned) &&
      ((s.command_status >> registers::kRejected) & 1u) != 0;
  if (returned && !seen.returned)
    say("fault reset rejected at %.2f s: the fault came back at once (alarm_code %u); its cause "
        "persists",
        s.t_s, static_cast<unsigned>(s.alarm_code));
  seen.returned = returned;
  const std::uint16_t alarm = s.alarm_code;
  // A drive fault's cause can sharpen after the latch (its PDOs time out before its heartbeat).
  if (alarm == seen.alarm && alarm != 0 && s.drive_fault_cause != seen.cause)
    say_drive_fault_cause(s);
  seen.cause = s.drive_fault_cause;
  if (alarm == seen.alarm) return;
  const auto codes = registers::alarm_codes();
  const auto it = std::find_if(codes.begin(), codes.end(),
                               [&](const registers::Code& c) { return c.value == alarm; });
  if (alarm == 0)
    say("fault cleared at %.2f s (alarm_code 0)", s.t_s);
  else if (it != codes.end())
    say("fault latched at %.2f s: alarm_code %u %.*s (%.*s)", s.t_s, static_cast<unsigned>(alarm),
        static_cast<int>(it->name.size()), it->name.data(),
        static_cast<int>(it->description.size()), it->description.data());
  else
    say("fault latched at %.2f s: alarm_code %u", s.t_s, static_cast<unsigned>(alarm));
  if (s.drive_fault_cause != 0) say_drive_fault_cause(s);
  seen.alarm = alarm;
}

/// Loop overruns said on serve's terminal: the first as it happens, with what it means, then
/// at most one summary per kOverrunSummary with the count since, so the start-up lines (where
/// it serves, what it runs) stay on the screen of a loaded machine.
class OverrunReport {
 public:
  void operator()(const controller::Snapshot& snap, std::chrono::steady_clock::time_point now) {
    constexpr std::chrono::seconds kOverrunSummary{30};  // a trend, not a stream
    if (snap.overrun_count == reported_) return;
    if (reported_ == 0) {
      say("loop overrun: a cycle started %.0f µs late. A late cycle runs with the period it "
          "measured (after a stall the missed ones are skipped, not bunched), so control stays "
          "consistent but reacts that much later: now and then is harmless; steady overruns mean "
          "the machine is too busy for the control loop (realtime in "
          "network.toml). Further ones are summed every %lld s.",
          snap.late_max_s * 1e6, static_cast<long long>(kOverrunSummary.count()));
    } else if (now - last_ >= kOverrunSummary) {
      say("%llu loop overrun(s) in the last %.0f s (%llu in all), the worst start since serve "
          "started %.0f µs late",
          static_cast<unsigned long long>(snap.overrun_count - reported_),
          std::chrono::duration<double>(now - last_).count(),
          static_cast<unsigned long long>(snap.overrun_count), snap.late_max_s * 1e6);
    } else {
      return;
    }
    reported_ = snap.overrun_count;
    last_ = now;
  }

 private:
  std::uint64_t reported_ = 0;
  std::chrono::steady_clock::time_point last_;
};

/// Until Ctrl-C (or SIGTERM), or for duration_s when it is positive; faults and loop overruns
/// are said as they happen (OverrunReport), not only at exit.
void wait_for_stop(double duration_s, runtime::Service& service) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  AlarmSeen alarm_seen;
  OverrunReport overruns;
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const auto now = Clock::now();
    const auto snap = service.controller().snapshot();
    say_alarm_change(snap, alarm_seen);
    overruns(snap, now);
    if (duration_s > 0 && std::chrono::duration<double>(now - t0).count() >= duration_s) break;
  }
}

void run_serve(const ServeOptions& o) {
  const modbus::NetworkConfig net = network_config(o);
  const double duration_s = o.duration.empty() ? 0.0 : parse_duration_s(o.duration, "--duration");
  std::string model_used;
  const runtime::ServiceConfig sc = service_config(o, net, model_used);
  runtime::Service service(sc);  // "require" makes start() throw
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  service.start();
  print_banner(o, sc, model_used, service);
  wait_for_stop(duration_s, service);
  if (g_stop) fresh_line_after_interrupt(g_stop);
  service.stop();
  const auto snap = service.controller().snapshot();
  say("stopped after %llu cycles, %llu overruns, the worst start %.0f µs late",
      static_cast<unsigned long long>(snap.cycle),
      static_cast<unsigned long long>(snap.overrun_count), snap.late_max_s * 1e6);
}

void add_serve(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "serve",
      "Run the controller on the simulated actuator or a CiA 402 drive and serve it over Modbus "
      "TCP/RTU");
  auto o = std::make_shared<ServeOptions>();
  add_config_option(cmd, o->config);
  cmd->add_option("--network", o->network, "Network configuration (default: CONFIG/network.toml)");
  cmd->add_option("--calibration", o->calibration,
                  "Force calibration (default: CONFIG/calibration.toml)");
  cmd->add_option("--model", o->model,
                  "Model file the controller compensates with and the twin runs (default: "
                  "CONFIG/model.toml), e.g. the model_corrected.toml maglead analyze wrote")
      ->check(CLI::ExistingFile);
  cmd->add_option("--duration", o->duration,
                  "Stop after this long (e.g. 30s); default: until Ctrl-C");
  add_network_options(cmd, *o);
  cmd->add_flag("--read-only", o->read_only, "Refuse every write (exception 01)");
  cmd->add_flag("--no-twin", o->no_twin, "Run without the digital twin (its registers read 0)");
  cmd->add_option("--watchdog", o->watchdog_ms,
                  "Communication watchdog at start [ms; 0.5s also reads], 0 = off (default: "
                  "network.toml's watchdog_ms, shipped 0); the register watchdog_ms (HR 1003), "
                  "which poll and set show in seconds as watchdog_s")
      ->transform(quantity_in({"ms", "s", 1e-3, "--watchdog 500 or 0.5s"}))
      ->check(
          number_in({0.0, 60000.0, "ms", "0 = off, at most a minute", "--watchdog 500 or 0.5s"}));
  add_sim_options(cmd, *o);
  add_backend_options(cmd, *o);
  cmd->callback([o] { run_serve(*o); });
}

MAGLEAD_COMMAND(70, add_serve);

}  // namespace
}  // namespace maglead::cli
