#include "maglead/settings/settings.hpp"

#include <arpa/inet.h>

#include <cstdio>
#include <initializer_list>
#include <optional>
#include <stdexcept>
#include <string_view>

#include "maglead/physics/toml_config.hpp"

namespace maglead::modbus {

using controller::FaultReaction;
using controller::parse_realtime_policy;
namespace {

/// A number as a person writes it: 99999, 0.001, 1e+07 (never 99999.000000).
std::string as_written(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

struct Reader {
  const std::string& path;
  const toml::table& root;

  /// FILE:LINE:COLUMN: key: why, at the node (or the file's start).
  [[noreturn]] void fail(const toml::node* at, const std::string& key,
                         const std::string& why) const {
    config::fail(path, at, key + ": " + why);
  }
  const toml::table* section(const char* name,
                             std::initializer_list<std::string_view> known) const {
    const toml::table* t = config::section(path, root, name);
    if (t) config::check_keys(path, *t, std::string("[") + name + "]", known);
    return t;
  }
  template <class T>
  void get(const toml::table* t, const char* sec, const char* key, T& out, double lo,
           double hi) const {
    if (!t) return;
    const auto* node = t->get(key);
    if (!node) return;
    const std::string name = std::string(sec) + "." + key;
    if constexpr (std::is_same_v<T, bool>) {
      const auto v = node->value<bool>();
      if (!v) fail(node, name, "must be true or false");
      out = *v;
    } else if constexpr (std::is_same_v<T, std::string>) {
      const auto v = node->value<std::string>();
      if (!v) fail(node, name, "must be a string");
      out = *v;
    } else {
      const auto v = node->value<double>();
      if (!v) fail(node, name, "must be a number");
      if (!(*v >= lo && *v <= hi))
        fail(node, name,
             as_written(*v) + " is outside " + as_written(lo) + " .. " + as_written(hi));
      if constexpr (std::is_integral_v<T>) {
        if (*v != static_cast<double>(static_cast<long long>(*v)))
          fail(node, name, "must be a whole number");
      }
      out = static_cast<T>(*v);
    }
  }
};

}  // namespace

std::optional<FaultReaction> parse_fault_reaction(std::string_view text) {
  if (text == "mode_default") return FaultReaction::mode_default;
  if (text == "release") return FaultReaction::release;
  if (text == "hold") return FaultReaction::hold;
  if (text == "disable") return FaultReaction::disable;
  return std::nullopt;
}

namespace {

/// [fault_reaction] and [runtime]: the reaction to each alarm and the realtime policy.
void read_reactions_and_runtime(const Reader& r, NetworkConfig& c) {
  const auto* fr = r.section("fault_reaction", {"watchdog", "owner_lost", "sensor_fault",
                                                "step_out", "release_rate_n_per_s"});
  for (auto [key, field] : {std::pair{"watchdog", &c.reactions.watchdog},
                            std::pair{"owner_lost", &c.reactions.owner_lost},
                            std::pair{"sensor_fault", &c.reactions.sensor_fault},
                            std::pair{"step_out", &c.reactions.step_out}}) {
    std::string v;
    r.get(fr, "fault_reaction", key, v, 0, 0);
    if (v.empty()) continue;
    const auto parsed = parse_fault_reaction(v);
    if (!parsed)
      r.fail(fr ? fr->get(key) : nullptr, std::string("fault_reaction.") + key,
             "\"" + v + "\" is not one of mode_default, release, hold, disable");
    *field = *parsed;
  }
  r.get(fr, "fault_reaction", "release_rate_n_per_s", c.reactions.release_rate_n_per_s, 1e-3, 1e6);
  const auto* rt = r.section("runtime", {"realtime"});
  std::string realtime;
  r.get(rt, "runtime", "realtime", realtime, 0, 0);
  if (!realtime.empty() && !parse_realtime_policy(realtime, c.realtime))
    r.fail(rt ? rt->get("realtime") : nullptr, "runtime.realtime",
           "\"" + realtime + "\" is not one of off, try, require");
}

}  // namespace

NetworkConfig load_network_config(const std::string& path) {
  const toml::table root = config::parse_file(path);
  for (const auto& [k, v] : root)
    if (k.str() != "tcp" && k.str() != "rtu" && k.str() != "server" &&
        k.str() != "fault_reaction" && k.str() != "runtime")
      config::fail(
          path, &v,
          std::string(k.str()) + ": unknown section (tcp, rtu, server, fault_reaction, runtime)");
  Reader r{path, root};
  NetworkConfig c;
  const auto* tcp =
      r.section("tcp", {"enabled", "bind_address", "port", "unit_id", "max_connections",
                        "frame_timeout_s", "idle_timeout_s", "allow"});
  r.get(tcp, "tcp", "enabled", c.tcp_enabled, 0, 1);
  r.get(tcp, "tcp", "bind_address", c.tcp.bind_address, 0, 0);
  if (in_addr a{}; inet_pton(AF_INET, c.tcp.bind_address.c_str(), &a) != 1)
    r.fail(tcp ? tcp->get("bind_address") : nullptr, "tcp.bind_address",
           "'" + c.tcp.bind_address + "' is not an IPv4 address (e.g. \"127.0.0.1\", \"0.0.0.0\")");
  r.get(tcp, "tcp", "port", c.tcp.port, 0, 65535);
  r.get(tcp, "tcp", "unit_id", c.tcp.unit_id, 0, 255);
  r.get(tcp, "tcp", "max_connections", c.tcp.max_connections, 1, 1024);
  r.get(tcp, "tcp", "frame_timeout_s", c.tcp.frame_timeout_s, 0.001, 3600);
  r.get(tcp, "tcp", "idle_timeout_s", c.tcp.idle_timeout_s, 0, 1e7);
  if (tcp) {
    if (const auto* node = tcp->get("allow")) {
      const auto* arr = node->as_array();
      if (!arr) r.fail(node, "tcp.allow", "must be an array of strings");
      for (const auto& e : *arr) {
        const auto s = e.value<std::string>();
        if (!s) r.fail(&e, "tcp.allow", "must be an array of strings");
        try {
          parse_ipv4_cidr(*s);
        } catch (const std::exception& ex) {
          r.fail(&e, "tcp.allow", ex.what());
        }
        c.tcp.allow.push_back(*s);
      }
    }
  }
  const auto* rtu =
      r.section("rtu", {"device", "baud", "parity", "data_bits", "stop_bits", "unit_id", "rs485"});
  r.get(rtu, "rtu", "device", c.rtu.device, 0, 0);
  r.get(rtu, "rtu", "baud", c.rtu.baud, 50, 4000000);
  std::string parity(1, c.rtu.parity);
  r.get(rtu, "rtu", "parity", parity, 0, 0);
  if (parity != "N" && parity != "E" && parity != "O")
    r.fail(rtu ? rtu->get("parity") : nullptr, "rtu.parity", "must be \"N\", \"E\" or \"O\"");
  c.rtu.parity = parity[0];
  r.get(rtu, "rtu", "data_bits", c.rtu.data_bits, 7, 8);
  r.get(rtu, "rtu", "stop_bits", c.rtu.stop_bits, 1, 2);
  r.get(rtu, "rtu", "unit_id", c.rtu.unit_id, 1, 247);
  r.get(rtu, "rtu", "rs485", c.rtu.rs485, 0, 1);
  const auto* server = r.section("server", {"read_only", "watchdog_ms"});
  r.get(server, "server", "read_only", c.read_only, 0, 1);
  double wd_ms = 0;
  r.get(server, "server", "watchdog_ms", wd_ms, 0, 60000);
  c.watchdog_s = wd_ms * 1e-3;
  read_reactions_and_runtime(r, c);
  return c;
}

}  // namespace maglead::modbus
