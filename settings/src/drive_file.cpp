#include <array>
#include <cstdio>
#include <string>
#include <type_traits>

#include "maglead/physics/toml_config.hpp"
#include "maglead/settings/settings.hpp"

namespace maglead::canopen {
namespace {

/// A number as a person writes it: 300, 0.001, 1e+09 (never 300.000000).
std::string as_written(double v) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.10g", v);
  return text.data();
}

/// t[key] into `out` when present: a number within lo .. hi (whole where T is an integer),
/// else an error at the value naming drive.KEY.
template <class T>
void read(const std::string& path, const toml::table& t, const char* key, T& out, double lo,
          double hi) {
  const toml::node* node = t.get(key);
  if (node == nullptr) return;
  const auto v = node->value<double>();
  const std::string name = std::string("drive.") + key;
  if (!v) config::fail(path, node, name + ": must be a number");
  if (!(*v >= lo && *v <= hi))
    config::fail(
        path, node,
        name + ": " + as_written(*v) + " is outside " + as_written(lo) + " .. " + as_written(hi));
  if (std::is_integral_v<T> && *v != static_cast<double>(static_cast<long long>(*v)))
    config::fail(path, node, name + ": must be a whole number");
  out = static_cast<T>(*v);
}

}  // namespace

DriveConfig load_drive_config(const std::string& path, DriveConfig base) {
  const toml::table root = config::parse_file(path);
  config::check_keys(path, root, "drive.toml:", {"drive"});
  const toml::table* t = config::section(path, root, "drive", true);
  config::check_keys(path, *t, "[drive]",
                     {"node_id", "bitrate_bit_s", "counts_per_motor_turn", "second_encoder_index",
                      "second_encoder_sub", "second_encoder_m_per_count", "heartbeat_producer_s",
                      "heartbeat_timeout_s", "sdo_timeout_s", "sdo_attempts"});
  read(path, *t, "node_id", base.node_id, 1, 127);
  read(path, *t, "bitrate_bit_s", base.bitrate_bit_s, 10'000, 1'000'000);
  read(path, *t, "counts_per_motor_turn", base.counts_per_motor_turn, 1, 1e9);
  read(path, *t, "second_encoder_index", base.second_encoder_index, 0x1000, 0xFFFF);
  read(path, *t, "second_encoder_sub", base.second_encoder_sub, 0, 255);
  read(path, *t, "second_encoder_m_per_count", base.second_encoder_m_per_count, 1e-9, 1e-2);
  read(path, *t, "heartbeat_producer_s", base.heartbeat_producer_s, 0.001, 65.535);
  read(path, *t, "heartbeat_timeout_s", base.heartbeat_timeout_s, 0.0015, 600);
  read(path, *t, "sdo_timeout_s", base.sdo_timeout_s, 0.001, 10);
  read(path, *t, "sdo_attempts", base.sdo_attempts, 1, 100);
  // What needs more than one key (a CiA bit rate, the bus load, heartbeat against timeout).
  try {
    check_drive_config(base);
  } catch (const std::invalid_argument& e) {
    config::fail(path, t, e.what());
  }
  return base;
}

}  // namespace maglead::canopen
