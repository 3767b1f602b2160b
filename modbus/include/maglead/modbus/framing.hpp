#pragma once
// Request framing of the two transports as plain functions (bytes in → a frame, "need more" or
// an error with its reason), so that the servers' loops only move bytes and the framers are
// unit-tested and fuzzed without a socket or a serial line (tests/fuzz).
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace maglead::modbus {

enum class FrameStatus {
  frame,      // a whole request is at the buffer's start
  need_more,  // a prefix of one: wait for more bytes (RTU: or for the line's silence)
  error,      // the bytes cannot start a request; `reason` says why
};

/// A Modbus TCP request (MBAP header + PDU) at the start of a buffer.
struct TcpFrame {
  FrameStatus status = FrameStatus::need_more;
  std::size_t size = 0;  // bytes of the whole ADU (frame only): 6 + the header's length field
  std::uint16_t transaction_id = 0;
  std::uint8_t unit_id = 0;
  const std::uint8_t* pdu = nullptr;  // into the buffer (frame only)
  std::size_t pdu_size = 0;           // the header's length field − 1 (the unit byte)
  std::string_view reason;            // error only; a static string
};

inline constexpr std::size_t kMbapSize = 7;           // transaction, protocol, length, unit
inline constexpr std::size_t kMaxTcpAdu = 260;        // MBAP + 253-byte PDU
inline constexpr std::size_t kMaxRtuAdu = 256;        // address + 253-byte PDU + CRC
inline constexpr std::uint16_t kMaxMbapLength = 254;  // unit + 253-byte PDU

/// Frames the first request of `n` bytes of a TCP stream. An error (protocol id not 0, length
/// field outside 2..254) means the stream's framing is lost: the connection must close.
TcpFrame frame_tcp(const std::uint8_t* buf, std::size_t n);

/// A Modbus RTU request (address + PDU + CRC) at the start of a buffer.
struct RtuFrame {
  FrameStatus status = FrameStatus::need_more;
  std::size_t size = 0;  // bytes of the whole ADU, CRC included (frame only)
  std::uint8_t unit_id = 0;
  const std::uint8_t* pdu = nullptr;  // into the buffer (frame only)
  std::size_t pdu_size = 0;           // size − 3
  std::string_view reason;            // error only; a static string
};

/// Frames the first request of `n` bytes received on a serial line. `silent`: the line has
/// been quiet for t3.5 since the last byte, which ends a frame whose function has no length
/// rule and makes a still incomplete one an error. After an error the server serves the next
/// whole request in the buffer (rtu_resync_offset), else discards it all (the next frame starts
/// after the next silence).
RtuFrame frame_rtu(const std::uint8_t* buf, std::size_t n, bool silent);

/// Where a whole, CRC-valid request starts after a buffer start frame_rtu refused; n when none
/// does. A reader that was not scheduled during a silence receives a cut-short frame and the
/// next request in one read (5 + 8 bytes): the silence it never saw cannot separate them, the
/// CRC can (a false match is a 1 in 65 536 chance per offset, as on a noisy line).
std::size_t rtu_resync_offset(const std::uint8_t* buf, std::size_t n, bool silent);

/// Modbus CRC-16 (poly 0xA001, init 0xFFFF) as sent on the line (low byte first).
std::uint16_t modbus_crc16(const std::uint8_t* data, std::size_t len);

}  // namespace maglead::modbus
