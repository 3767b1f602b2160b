#include "maglead/canopen/protocol.hpp"

namespace maglead::canopen {

std::uint32_t get_le(const std::uint8_t* bytes, std::size_t n) noexcept {
  std::uint32_t value = 0;
  for (std::size_t i = 0; i < n; ++i) value |= static_cast<std::uint32_t>(bytes[i]) << (8 * i);
  return value;
}

void put_le(std::uint8_t* bytes, std::size_t n, std::uint32_t value) noexcept {
  for (std::size_t i = 0; i < n; ++i) bytes[i] = static_cast<std::uint8_t>(value >> (8 * i));
}

CanFrame nmt_frame(NmtCommand command, std::uint8_t node_id) noexcept {
  CanFrame f;
  f.id = cob_nmt;
  f.len = 2;
  f.data[0] = static_cast<std::uint8_t>(command);
  f.data[1] = node_id;
  return f;
}

CanFrame sync_frame() noexcept {
  CanFrame f;
  f.id = cob_sync;
  return f;
}

NmtState nmt_state_of(std::uint8_t heartbeat_byte) noexcept {
  switch (heartbeat_byte & 0x7F) {  // bit 7 is the node-guarding toggle, not the state
    case 0x00:
      return NmtState::boot_up;
    case 0x04:
      return NmtState::stopped;
    case 0x05:
      return NmtState::operational;
    case 0x7F:
      return NmtState::pre_operational;
    default:
      return NmtState::unknown;
  }
}

const char* nmt_state_text(NmtState state) noexcept {
  switch (state) {
    case NmtState::boot_up:
      return "boot-up";
    case NmtState::stopped:
      return "stopped";
    case NmtState::operational:
      return "operational";
    case NmtState::pre_operational:
      return "pre-operational";
    case NmtState::unknown:
      break;
  }
  return "unknown NMT state";
}

Emergency decode_emergency(const CanFrame& frame) noexcept {
  Emergency e;
  e.error_code = static_cast<std::uint16_t>(get_le(frame.data.data(), 2));
  e.error_register = frame.data[2];
  for (std::size_t i = 0; i < e.manufacturer.size(); ++i) e.manufacturer[i] = frame.data[3 + i];
  return e;
}

namespace {

struct CodeText {
  std::uint16_t code;
  const char* text;
};

// Exact codes of CiA 301 (communication) and CiA 402 (drives) a servo drive reports most.
constexpr std::array<CodeText, 16> exact_codes{{
    {0x0000, "error reset or no error"},
    {0x2310, "continuous over-current"},
    {0x3210, "DC link over-voltage"},
    {0x3220, "DC link under-voltage"},
    {0x4210, "excess temperature of the device"},
    {0x5113, "supply voltage low"},
    {0x7121, "motor blocked"},
    {0x7300, "sensor (encoder) error"},
    {0x7305, "incremental sensor 1 fault"},
    {0x7306, "incremental sensor 2 fault"},
    {0x8110, "CAN overrun (objects lost)"},
    {0x8120, "CAN in error passive mode"},
    {0x8130, "life guard or heartbeat error"},
    {0x8140, "recovered from bus-off"},
    {0x8611, "following error"},
    {0x8612, "reference limit"},
}};

// Classes by the code's high byte (CiA 301 table 21), for a code not listed exactly.
constexpr std::array<CodeText, 12> code_classes{{
    {0x10, "generic error"},
    {0x20, "current"},
    {0x30, "voltage"},
    {0x40, "temperature"},
    {0x50, "device hardware"},
    {0x60, "device software"},
    {0x70, "additional modules"},
    {0x80, "monitoring"},
    {0x81, "communication"},
    {0x86, "control (position or velocity)"},
    {0x90, "external error"},
    {0xFF, "device specific"},
}};

}  // namespace

const char* emergency_text(std::uint16_t error_code) noexcept {
  for (const auto& c : exact_codes)
    if (c.code == error_code) return c.text;
  const auto high = static_cast<std::uint16_t>(error_code >> 8);
  // The most specific class first: 0x81xx before 0x80xx, then the class of the high nibble.
  for (const auto& c : code_classes)
    if (c.code == high) return c.text;
  for (const auto& c : code_classes)
    if (c.code == (high & 0xF0)) return c.text;
  return "unknown error code";
}

int PdoMap::total_bits() const noexcept {
  int bits = 0;
  for (std::size_t i = 0; i < count; ++i) bits += entries[i].bits;
  return bits;
}

bool pack_pdo(const PdoMap& map, std::span<const std::uint32_t> values, CanFrame& out) noexcept {
  if (values.size() != map.count || map.total_bits() > 64) return false;
  std::size_t at = 0;
  for (std::size_t i = 0; i < map.count; ++i) {
    const std::size_t n = map.entries[i].bits / 8U;
    put_le(out.data.data() + at, n, values[i]);
    at += n;
  }
  out.len = static_cast<std::uint8_t>(at);
  return true;
}

bool unpack_pdo(const PdoMap& map, const CanFrame& frame,
                std::span<std::uint32_t> values) noexcept {
  if (values.size() != map.count || map.total_bits() > 8 * frame.len) return false;
  std::size_t at = 0;
  for (std::size_t i = 0; i < map.count; ++i) {
    const std::size_t n = map.entries[i].bits / 8U;
    values[i] = get_le(frame.data.data() + at, n);
    at += n;
  }
  return true;
}

const char* can_status_text(CanStatus status) noexcept {
  switch (status) {
    case CanStatus::ok:
      return "ok";
    case CanStatus::timeout:
      return "no frame before the deadline";
    case CanStatus::tx_busy:
      return "transmit queue full";
    case CanStatus::error_frame:
      return "CAN error frame";
    case CanStatus::bus_off:
      return "CAN controller bus-off";
    case CanStatus::io_error:
      return "CAN socket error";
  }
  return "unknown CAN status";
}

}  // namespace maglead::canopen
