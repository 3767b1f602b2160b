// libFuzzer target: the Modbus RTU request framer (frame_rtu) on bytes that arrive in pieces,
// some followed by the line's t3.5 silence, framed the way RtuServer does (frames taken from the
// front; after an error the next whole request in the buffer is served, rtu_resync_offset, else
// everything received is discarded).
//
// Input: [chunk][silences][stream…]: the stream arrives `chunk % 16 + 1` bytes at a time; bit
// i % 8 of `silences` says whether the line falls silent after piece i.
// Oracles (against the serial-line rules and a CRC computed here by a table, not the framer's):
//  - a frame: 4..256 bytes within those received, CRC right, unit and PDU at their places, and
//    its size the function's length rule (1–6, 8: 8; 15, 16: 9 + byte count; 23: 13 + write
//    byte count; 43: 7) or, for a function without one, everything up to the silence;
//  - "need more": never after a silence, never with more than 256 bytes or a complete frame;
//  - an error: a non-empty reason, and no valid frame was there to take;
//  - the resync after it: the first later offset where a whole CRC-valid frame starts, none before.
#include <array>
#include <vector>

#include "fuzz_common.hpp"
#include "maglead/modbus/framing.hpp"

using namespace maglead::modbus;

namespace {

constexpr std::string_view kTarget = "fuzz_rtu_framer";

void check(bool cond, std::string_view what) {
  if (!cond) maglead::fuzz::oracle_failed(kTarget, what);
}

// CRC-16/MODBUS by the byte-wise table (reflected 0x8005), independent of modbus_crc16.
std::uint16_t reference_crc(const std::uint8_t* p, std::size_t n) {
  static const std::array<std::uint16_t, 256> table = [] {
    std::array<std::uint16_t, 256> t{};
    for (unsigned i = 0; i < 256; ++i) {
      unsigned c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? (c >> 1) ^ 0xA001u : c >> 1;
      t[i] = static_cast<std::uint16_t>(c);
    }
    return t;
  }();
  unsigned crc = 0xFFFF;
  for (std::size_t i = 0; i < n; ++i) crc = (crc >> 8) ^ table[(crc ^ p[i]) & 0xFFu];
  return static_cast<std::uint16_t>(crc);
}

bool crc_ok(const std::uint8_t* p, std::size_t size) {
  return size >= 4 && reference_crc(p, size - 2) == (p[size - 2] | (p[size - 1] << 8));
}

/// The request length the function's rule gives; 0: not known yet; -1: no rule.
long length_rule(const std::uint8_t* p, std::size_t n) {
  if (n < 2) return 0;
  const std::uint8_t fc = p[1];
  if (fc <= 6 && fc >= 1) return 8;
  if (fc == 8) return 8;
  if (fc == 15 || fc == 16) return n >= 7 ? 9 + p[6] : 0;
  if (fc == 23) return n >= 11 ? 13 + p[10] : 0;
  if (fc == 43) return 7;
  return -1;
}

void check_frame(const std::uint8_t* p, std::size_t n, bool silent, const RtuFrame& f) {
  check(f.size >= 4 && f.size <= n && f.size <= kMaxRtuAdu, "frame size outside 4..256");
  check(crc_ok(p, f.size), "a frame with a wrong CRC");
  check(f.unit_id == p[0] && f.pdu == p + 1 && f.pdu_size == f.size - 3, "unit or PDU misplaced");
  const long rule = length_rule(p, n);
  check(rule > 0 ? f.size == static_cast<std::size_t>(rule) : silent && f.size == n,
        "frame size is not the function's length rule, nor ended by the silence");
}

void check_need_more(const std::uint8_t* p, std::size_t n, bool silent) {
  check(!silent, "'need more' after the line's silence");
  check(n <= kMaxRtuAdu, "'need more' with more than 256 bytes");
  const long rule = length_rule(p, n);
  check(rule <= 0 || n < static_cast<std::size_t>(rule), "'need more' with a whole frame there");
}

void check_error(const std::uint8_t* p, std::size_t n, bool silent, const RtuFrame& f) {
  check(!f.reason.empty(), "an error without a reason");
  const long rule = length_rule(p, n);
  if (n > kMaxRtuAdu || rule > static_cast<long>(kMaxRtuAdu)) return;  // too long
  if (rule > 0 && n >= static_cast<std::size_t>(rule))
    check(!crc_ok(p, static_cast<std::size_t>(rule)), "a valid frame refused");
  else if (rule < 0 && silent)
    check(!crc_ok(p, n), "a valid frame ended by the silence refused");
  else
    check(silent, "an incomplete frame refused before the silence");
}

// The offset rtu_resync_offset gives: a valid frame starts there and at no offset before it.
void check_resync(const std::uint8_t* p, std::size_t n, bool silent, std::size_t k) {
  check(k >= 1 && k <= n, "resync offset outside the buffer");
  for (std::size_t j = 1; j < k; ++j) {
    const long rule = length_rule(p + j, n - j);
    const std::size_t size = rule > 0 ? static_cast<std::size_t>(rule) : n - j;
    const bool whole = rule > 0 ? size <= n - j : rule < 0 && silent;
    check(!(whole && size <= kMaxRtuAdu && n - j <= kMaxRtuAdu && crc_ok(p + j, size)),
          "resync skipped a whole valid frame");
  }
  if (k < n)
    check(frame_rtu(p + k, n - k, silent).status == FrameStatus::frame,
          "resync offset where no frame starts");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const std::size_t chunk = data[0] % 16 + 1;
  const std::uint8_t silences = data[1];
  std::vector<std::uint8_t> buf;  // what the server holds
  for (std::size_t sent = 2, piece = 0; sent < size; ++piece) {
    const std::size_t k = std::min(chunk, size - sent);
    buf.insert(buf.end(), data + sent, data + sent + k);
    sent += k;
    const bool silent = ((silences >> (piece % 8)) & 1u) != 0 || sent == size;
    while (!buf.empty()) {
      const RtuFrame f = frame_rtu(buf.data(), buf.size(), silent);
      if (f.status == FrameStatus::need_more) {
        check_need_more(buf.data(), buf.size(), silent);
        break;
      }
      if (f.status == FrameStatus::error) {
        check_error(buf.data(), buf.size(), silent, f);
        const std::size_t skip = rtu_resync_offset(buf.data(), buf.size(), silent);
        check_resync(buf.data(), buf.size(), silent, skip);
        if (skip == buf.size()) {
          buf.clear();  // the server discards everything received
          break;
        }
        buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(skip));
        continue;
      }
      check_frame(buf.data(), buf.size(), silent, f);
      buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(f.size));
    }
  }
  return 0;
}
