#pragma once
// CiA 301 on the master's side: COB-IDs of the predefined connection set, NMT commands,
// heartbeat states, EMCY decoding with texts, and PDO packing by a mapping. Pure functions and
// plain data, so the cycle can use them without allocating.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "maglead/canopen/can_bus.hpp"

namespace maglead::canopen {

// Function codes of the predefined connection set (CiA 301 §7.3.3), plus the node id.
inline constexpr std::uint32_t cob_nmt = 0x000;
inline constexpr std::uint32_t cob_sync = 0x080;
inline constexpr std::uint32_t cob_emcy = 0x080;
inline constexpr std::uint32_t cob_tpdo1 = 0x180;
inline constexpr std::uint32_t cob_rpdo1 = 0x200;
inline constexpr std::uint32_t cob_tpdo2 = 0x280;
inline constexpr std::uint32_t cob_sdo_tx = 0x580;  // server -> client
inline constexpr std::uint32_t cob_sdo_rx = 0x600;  // client -> server
inline constexpr std::uint32_t cob_heartbeat = 0x700;

enum class NmtCommand : std::uint8_t {
  start = 0x01,
  stop = 0x02,
  enter_pre_operational = 0x80,
  reset_node = 0x81,
  reset_communication = 0x82,
};
CanFrame nmt_frame(NmtCommand command, std::uint8_t node_id) noexcept;
CanFrame sync_frame() noexcept;

/// The NMT state a heartbeat reports (its one data byte).
enum class NmtState : std::uint8_t {
  boot_up = 0x00,
  stopped = 0x04,
  operational = 0x05,
  pre_operational = 0x7F,
  unknown = 0xFF,
};
NmtState nmt_state_of(std::uint8_t heartbeat_byte) noexcept;
const char* nmt_state_text(NmtState state) noexcept;

/// One emergency message (CiA 301 §7.2.7): error code, error register, manufacturer bytes.
struct Emergency {
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
};
Emergency decode_emergency(const CanFrame& frame) noexcept;
/// The CiA 301 / CiA 402 meaning of an error code: the exact code where listed, else its class.
const char* emergency_text(std::uint16_t error_code) noexcept;

/// One mapped object of a PDO: what a mapping entry 0x1600/0x1A00 sub n holds.
struct PdoEntry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bits = 0;  // 8, 16 or 32
  /// The mapping entry's value: index << 16 | sub << 8 | bits.
  constexpr std::uint32_t mapping_value() const {
    return static_cast<std::uint32_t>(index) << 16 | static_cast<std::uint32_t>(sub) << 8 | bits;
  }
};

/// A PDO's mapping: up to 4 objects, at most 64 bits.
struct PdoMap {
  std::array<PdoEntry, 4> entries{};
  std::size_t count = 0;
  int total_bits() const noexcept;
};

/// Packs values (each the object's raw value, two's complement for signed objects) in mapping
/// order, little-endian as CiA 301 lays a PDO out. Returns false when `values` does not match.
bool pack_pdo(const PdoMap& map, std::span<const std::uint32_t> values, CanFrame& out) noexcept;
/// Unpacks a PDO by its mapping; false when the frame is shorter than the mapping.
bool unpack_pdo(const PdoMap& map, const CanFrame& frame, std::span<std::uint32_t> values) noexcept;

/// Little-endian helpers for the 1..4-byte fields of SDO and PDO frames.
std::uint32_t get_le(const std::uint8_t* bytes, std::size_t n) noexcept;
void put_le(std::uint8_t* bytes, std::size_t n, std::uint32_t value) noexcept;

}  // namespace maglead::canopen
