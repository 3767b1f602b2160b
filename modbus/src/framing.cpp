#include "maglead/modbus/framing.hpp"

namespace maglead::modbus {
namespace {

std::uint16_t be16(const std::uint8_t* p) { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }

/// Total length of the RTU request in buf (address, PDU, CRC), 0 if not known yet, -1 when the
/// function has no length rule (then the line's silence ends the frame).
long rtu_expected_length(const std::uint8_t* buf, std::size_t n) {
  if (n < 2) return 0;
  switch (buf[1]) {
    case 1:
    case 2:
    case 3:
    case 4:
    case 5:
    case 6:
    case 8:
      return 8;
    case 15:
    case 16:
      return n < 7 ? 0 : 9 + buf[6];
    case 23:
      return n < 11 ? 0 : 13 + buf[10];
    case 43:
      return 7;
    default:
      return -1;
  }
}

RtuFrame rtu_error(std::string_view reason) {
  RtuFrame f;
  f.status = FrameStatus::error;
  f.reason = reason;
  return f;
}

}  // namespace

TcpFrame frame_tcp(const std::uint8_t* buf, std::size_t n) {
  TcpFrame f;
  if (n < kMbapSize) return f;
  const std::uint16_t length = be16(buf + 4);
  // A wrong protocol id or length means nobody can know where the next frame starts.
  if (be16(buf + 2) != 0) {
    f.status = FrameStatus::error;
    f.reason = "MBAP protocol id is not 0";
    return f;
  }
  if (length < 2 || length > kMaxMbapLength) {
    f.status = FrameStatus::error;
    f.reason = "MBAP length field outside 2..254";
    return f;
  }
  if (n < 6u + length) return f;
  f.status = FrameStatus::frame;
  f.size = 6u + length;
  f.transaction_id = be16(buf);
  f.unit_id = buf[6];
  f.pdu = buf + kMbapSize;
  f.pdu_size = length - 1u;
  return f;
}

RtuFrame frame_rtu(const std::uint8_t* buf, std::size_t n, bool silent) {
  if (n == 0) return {};
  const long want = rtu_expected_length(buf, n);
  std::size_t size = 0;
  // Too long first, then cut short: an over-long frame and a cut-short one are told apart.
  if (want > static_cast<long>(kMaxRtuAdu) || n > kMaxRtuAdu)
    return rtu_error("RTU frame longer than 256 bytes");
  if (want > 0 && n >= static_cast<std::size_t>(want)) {
    size = static_cast<std::size_t>(want);
  } else if (want < 0 && silent) {
    size = n;  // a function without a length rule: the silence ends it
  } else if (silent) {
    return rtu_error("RTU frame cut short by the line's silence");
  } else {
    return {};
  }
  if (size < 4) return rtu_error("RTU frame shorter than address, function and CRC");
  if (modbus_crc16(buf, size - 2) != (buf[size - 2] | (buf[size - 1] << 8)))
    return rtu_error("RTU frame CRC mismatch");
  RtuFrame f;
  f.status = FrameStatus::frame;
  f.size = size;
  f.unit_id = buf[0];
  f.pdu = buf + 1;
  f.pdu_size = size - 3;
  return f;
}

std::size_t rtu_resync_offset(const std::uint8_t* buf, std::size_t n, bool silent) {
  for (std::size_t k = 1; k + 4 <= n; ++k)
    if (frame_rtu(buf + k, n - k, silent).status == FrameStatus::frame) return k;
  return n;
}

std::uint16_t modbus_crc16(const std::uint8_t* data, std::size_t len) {
  std::uint16_t crc = 0xFFFF;
  for (std::size_t i = 0; i < len; ++i) {
    crc ^= data[i];
    for (int b = 0; b < 8; ++b)
      crc = (crc & 1) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001)
                      : static_cast<std::uint16_t>(crc >> 1);
  }
  return crc;
}

}  // namespace maglead::modbus
