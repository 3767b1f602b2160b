#pragma once
// What the operator commands (poll, watch, set, enable, disable, reset, record) share on the
// command line: the connection options and one-line error reporting with distinct exit codes.
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cli_common.hpp"
#include "maglead/operator/client.hpp"

namespace maglead::cli {

struct ConnectionOptions {
  op::Endpoint ep;
  std::string parity = "E";
};

inline std::shared_ptr<ConnectionOptions> add_connection_options(CLI::App* cmd) {
  auto c = std::make_shared<ConnectionOptions>();
  auto* g = cmd->add_option_group("Connection", "Modbus TCP (default) or RTU (--serial)");
  g->add_option("--host", c->ep.host, "Controller host (TCP)")->capture_default_str();
  g->add_option("--port", c->ep.port, "TCP port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  g->add_option("--unit", c->ep.unit, "Unit id")->check(CLI::Range(0, 255))->capture_default_str();
  g->add_option("--serial", c->ep.serial, "Serial device: Modbus RTU instead of TCP");
  g->add_option("--baud", c->ep.baud, "RTU baud rate")
      ->check(CLI::Range(50, 4000000))
      ->capture_default_str();
  g->add_option("--parity", c->parity, "RTU parity N, E or O")
      ->check(CLI::IsMember({"N", "E", "O"}))
      ->capture_default_str();
  g->add_option("--stop-bits", c->ep.stop_bits, "RTU stop bits")
      ->check(CLI::Range(1, 2))
      ->capture_default_str();
  g->add_option("--timeout", c->ep.timeout_s, "Reply timeout per request [s]")
      ->check(CLI::Range(0.01, 60.0))
      ->capture_default_str();
  return c;
}

inline op::Endpoint endpoint_of(const ConnectionOptions& c) {
  op::Endpoint ep = c.ep;
  ep.parity = c.parity.empty() ? 'E' : c.parity[0];
  return ep;
}

/// Runs an operator command: a ClientError becomes one line on stderr and its exit code
/// (2 refused before sending, 3 communication, 4 refused by the controller).
template <class Fn>
void run_operator(const char* command, Fn&& fn) {
  // A dropped TCP connection must be an error message, never a SIGPIPE.
  std::signal(SIGPIPE, SIG_IGN);
  try {
    fn();
  } catch (const op::ClientError& e) {
    std::fprintf(stderr, "%s\n",
                 error_text("maglead " + std::string(command) + ": " + e.what()).c_str());
    throw CLI::RuntimeError(e.exit_code());
  }
}

/// The limits the controller enforces, from the same files it reads.
inline op::Limits load_limits(const std::string& config_dir, const std::string& calibration_path) {
  op::Limits l;
  l.actuator = load_actuator_or_default(config_dir);
  const std::string actuator_path = config_file(config_dir, "actuator.toml");
  if (std::filesystem::exists(actuator_path)) l.actuator_source = actuator_path;
  const std::string path =
      calibration_path.empty() ? config_file(config_dir, "calibration.toml") : calibration_path;
  l.calibration = load_calibration(path);
  l.calibration_source = path;
  return l;
}

}  // namespace maglead::cli
