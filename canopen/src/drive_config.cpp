#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "maglead/canopen/master.hpp"

namespace maglead::canopen {
namespace {

// Above this share the cycle's frames leave too little room for SDO, EMCY and the
// retransmissions after bus errors, and a late TPDO becomes the rule.
constexpr double max_bus_load = 0.7;
constexpr std::array<std::uint32_t, 8> cia_bitrates{10'000,  20'000,  50'000,  125'000,
                                                    250'000, 500'000, 800'000, 1'000'000};

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("[drive] " + what);
}

}  // namespace

bool interpolation_period_code(double period_s, std::uint8_t& value, std::int8_t& exponent) {
  // 0x60C2: period = value · 10^exponent s with value an 8-bit unsigned integer; the largest
  // exponent that is exact, so that 1 ms reads as 1 · 10^-3 s, as drives document it.
  for (int e = 0; e >= -6; --e) {
    const double v = period_s / std::pow(10.0, e);
    if (v <= 255.0 && std::abs(v - std::round(v)) < 1e-9 * v + 1e-9 && std::round(v) >= 1.0) {
      value = static_cast<std::uint8_t>(std::lround(v));
      exponent = static_cast<std::int8_t>(e);
      return true;
    }
  }
  return false;
}

double bus_load_fraction(const DriveConfig& config) {
  const double cycle_bits =
      frame_bits_worst(0) + frame_bits_worst(rpdo1_map().total_bits() / 8) +
      frame_bits_worst(tpdo1_map().total_bits() / 8) +
      frame_bits_worst(tpdo2_map(config).total_bits() / 8) +
      frame_bits_worst(1) * config.loop_period_s / config.heartbeat_producer_s;
  return cycle_bits / (static_cast<double>(config.bitrate_bit_s) * config.loop_period_s);
}

void check_drive_config(const DriveConfig& c) {
  require(c.node_id >= 1 && c.node_id <= 127, "node_id must lie in 1..127");
  require(
      std::find(cia_bitrates.begin(), cia_bitrates.end(), c.bitrate_bit_s) != cia_bitrates.end(),
      "bitrate_bit_s must be a CiA 301 bit rate (10000 ... 1000000)");
  std::uint8_t value = 0;
  std::int8_t exponent = 0;
  require(c.loop_period_s > 0.0 && interpolation_period_code(c.loop_period_s, value, exponent),
          "the loop period must be n·10^k s with n in 1..255 (0x60C2)");
  const double producer_ms = c.heartbeat_producer_s * 1e3;
  require(producer_ms >= 1.0 && producer_ms <= 65535.0 &&
              std::abs(producer_ms - std::round(producer_ms)) < 1e-9,
          "heartbeat_producer_s must be a whole number of ms in 0.001..65.535 s");
  // One heartbeat may come late without a fault; a second missing one is a silent drive.
  require(c.heartbeat_timeout_s >= 1.5 * c.heartbeat_producer_s,
          "heartbeat_timeout_s must be at least 1.5 times heartbeat_producer_s");
  require(c.counts_per_motor_turn > 0.0 && c.gear_ratio > 0.0 && c.second_encoder_m_per_count > 0.0,
          "counts_per_motor_turn, gear_ratio and second_encoder_m_per_count must be positive");
  require(c.sdo_timeout_s > 0.0 && c.sdo_attempts >= 1 && c.max_missed_cycles >= 1 &&
              c.boot_timeout_s > 0.0,
          "sdo_timeout_s and boot_timeout_s must be positive, sdo_attempts and "
          "max_missed_cycles at least 1");
  const double load = bus_load_fraction(c);
  if (load > max_bus_load) {
    std::array<char, 160> text{};
    std::snprintf(text.data(), text.size(),
                  "the cycle's frames take %.0f %% of the bus at %u bit/s (at most %.0f %%): "
                  "raise the bit rate or the loop period",
                  100.0 * load, c.bitrate_bit_s, 100.0 * max_bus_load);
    require(false, text.data());
  }
}

PdoMap rpdo1_map() {
  PdoMap m;
  m.entries[0] = {0x6040, 0, 16};  // controlword
  m.entries[1] = {0x607A, 0, 32};  // target position
  m.count = 2;
  return m;
}

PdoMap tpdo1_map() {
  PdoMap m;
  m.entries[0] = {0x6041, 0, 16};  // statusword
  m.entries[1] = {0x6064, 0, 32};  // position actual value
  m.entries[2] = {0x603F, 0, 16};  // error code
  m.count = 3;
  return m;
}

PdoMap tpdo2_map(const DriveConfig& config) {
  PdoMap m;
  m.entries[0] = {config.second_encoder_index, config.second_encoder_sub, 32};
  m.count = 1;
  return m;
}

}  // namespace maglead::canopen
