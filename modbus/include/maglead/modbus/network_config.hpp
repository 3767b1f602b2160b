#pragma once
// config/network.toml: the Modbus server's options (every one is also on the command line).
#include <optional>
#include <string>
#include <string_view>

#include "maglead/controller/controller.hpp"
#include "maglead/controller/loop_runner.hpp"
#include "maglead/modbus/modbus_rtu.hpp"
#include "maglead/modbus/modbus_tcp.hpp"

namespace maglead::modbus {

struct NetworkConfig {
  bool tcp_enabled = true;
  TcpOptions tcp;
  RtuOptions rtu;  // rtu.device empty: no RTU
  bool read_only = false;
  double watchdog_s = 0.0;
  controller::FaultReactions reactions;  // [fault_reaction]
  controller::RealtimePolicy realtime =
      controller::RealtimePolicy::attempt;  // [runtime] realtime: "off" | "try" | "require"
};

/// Reads [tcp], [rtu], [server], [fault_reaction] and [runtime]; absent keys keep their defaults.
/// Throws std::runtime_error naming the file and key on a malformed value or an unknown key.
NetworkConfig load_network_config(const std::string& path);
/// "mode_default", "release", "hold" or "disable"; nothing otherwise.
std::optional<controller::FaultReaction> parse_fault_reaction(std::string_view text);

}  // namespace maglead::modbus
