// libFuzzer target: the Modbus TCP request framer (frame_tcp) on a byte stream that arrives in
// pieces, framed the way TcpServer does (frames taken from the front while there are any).
//
// Input: [chunk][stream…]: the stream arrives `chunk % 16 + 1` bytes at a time.
// Oracles (checked against the MBAP rules, not against the framer's code):
//  - a frame: protocol id 0, length field L in 2..254, size 6 + L within the bytes there, unit
//    and PDU where the header says, transaction id as sent; the same frame from exactly its own
//    bytes, and "need more" from any shorter prefix;
//  - "need more": fewer than 7 bytes, or a valid header whose frame is not all there;
//  - an error: a non-empty reason, and the header really breaks a rule; it ends the stream.
#include <cstring>
#include <vector>

#include "fuzz_common.hpp"
#include "maglead/modbus/framing.hpp"

using namespace maglead::modbus;

namespace {

constexpr std::string_view kTarget = "fuzz_tcp_framer";

std::uint16_t be16(const std::uint8_t* p) { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }

void check(bool cond, std::string_view what) {
  if (!cond) maglead::fuzz::oracle_failed(kTarget, what);
}

void check_frame(const std::uint8_t* buf, std::size_t n, const TcpFrame& f) {
  check(n >= kMbapSize && be16(buf + 2) == 0, "a frame without protocol id 0");
  const std::size_t length = be16(buf + 4);
  check(length >= 2 && length <= 254, "a frame with a length field outside 2..254");
  check(f.size == 6 + length && f.size <= n, "frame size is not 6 + the length field");
  check(f.transaction_id == be16(buf) && f.unit_id == buf[6], "transaction or unit id wrong");
  check(f.pdu == buf + kMbapSize && f.pdu_size == length - 1, "PDU not where the header says");
  const TcpFrame alone = frame_tcp(buf, f.size);
  check(alone.status == FrameStatus::frame && alone.size == f.size,
        "not the same frame from its own bytes");
  check(frame_tcp(buf, f.size - 1).status == FrameStatus::need_more,
        "a frame's prefix is not 'need more'");
}

void check_need_more(const std::uint8_t* buf, std::size_t n) {
  if (n < kMbapSize) return;
  const std::size_t length = be16(buf + 4);
  check(be16(buf + 2) == 0 && length >= 2 && length <= 254 && n < 6 + length,
        "'need more' for a broken header or a complete frame");
}

void check_error(const std::uint8_t* buf, std::size_t n, const TcpFrame& f) {
  check(!f.reason.empty(), "an error without a reason");
  check(n >= kMbapSize, "an error before the header is complete");
  const std::size_t length = be16(buf + 4);
  check(be16(buf + 2) != 0 || length < 2 || length > 254, "an error for a valid header");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::size_t chunk = data[0] % 16 + 1;
  const std::uint8_t* stream = data + 1;
  const std::size_t total = size - 1;
  std::vector<std::uint8_t> in;  // what the server holds: what arrived, minus frames taken
  for (std::size_t sent = 0; sent < total;) {
    const std::size_t k = std::min(chunk, total - sent);
    in.insert(in.end(), stream + sent, stream + sent + k);
    sent += k;
    for (;;) {
      const TcpFrame f = frame_tcp(in.data(), in.size());
      if (f.status == FrameStatus::need_more) {
        check_need_more(in.data(), in.size());
        break;
      }
      if (f.status == FrameStatus::error) {
        check_error(in.data(), in.size(), f);
        return 0;  // the server closes the connection
      }
      check_frame(in.data(), in.size(), f);
      in.erase(in.begin(), in.begin() + static_cast<std::ptrdiff_t>(f.size));
    }
  }
  return 0;
}
