#pragma once
// The Modbus server's options (config/network.toml, read by maglead/settings; every one is also
// on the command line).
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

}  // namespace maglead::modbus
