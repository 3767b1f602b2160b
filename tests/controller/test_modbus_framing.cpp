// The TCP and RTU request framers (modbus/framing.hpp): whole frames, prefixes that need more
// bytes, and every error with its reason. The servers only move bytes through these.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "maglead/modbus/framing.hpp"

using namespace maglead::modbus;

namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes mbap(std::uint16_t tid, std::uint16_t protocol, std::uint16_t length, std::uint8_t unit) {
  return {static_cast<std::uint8_t>(tid >> 8),
          static_cast<std::uint8_t>(tid),
          static_cast<std::uint8_t>(protocol >> 8),
          static_cast<std::uint8_t>(protocol),
          static_cast<std::uint8_t>(length >> 8),
          static_cast<std::uint8_t>(length),
          unit};
}

// Appends the CRC, low byte first, as sent on the line.
Bytes with_crc(Bytes b) {
  const std::uint16_t crc = modbus_crc16(b.data(), b.size());
  b.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  b.push_back(static_cast<std::uint8_t>(crc >> 8));
  return b;
}

}  // namespace

TEST(TcpFramer, FramesOneRequestAndLeavesTheNext) {
  Bytes b = mbap(0x1234, 0, 6, 1);
  for (const int x : {3, 0, 0, 0, 8}) b.push_back(static_cast<std::uint8_t>(x));
  const Bytes next = mbap(0x1235, 0, 6, 1);
  b.insert(b.end(), next.begin(), next.end());
  const TcpFrame f = frame_tcp(b.data(), b.size());
  ASSERT_EQ(f.status, FrameStatus::frame);
  EXPECT_EQ(f.size, 12u);
  EXPECT_EQ(f.transaction_id, 0x1234);
  EXPECT_EQ(f.unit_id, 1);
  EXPECT_EQ(f.pdu, b.data() + 7);
  EXPECT_EQ(f.pdu_size, 5u);
  // The second request is only a header: more is needed.
  EXPECT_EQ(frame_tcp(b.data() + f.size, b.size() - f.size).status, FrameStatus::need_more);
}

TEST(TcpFramer, EveryPrefixOfARequestNeedsMore) {
  Bytes b = mbap(1, 0, 6, 1);
  for (const int x : {3, 0, 0, 0, 8}) b.push_back(static_cast<std::uint8_t>(x));
  for (std::size_t n = 0; n < b.size(); ++n)
    EXPECT_EQ(frame_tcp(b.data(), n).status, FrameStatus::need_more) << n << " bytes";
}

TEST(TcpFramer, RefusesAWrongProtocolOrLengthWithAReason) {
  const Bytes protocol = mbap(1, 1, 6, 1);
  const TcpFrame p = frame_tcp(protocol.data(), protocol.size());
  EXPECT_EQ(p.status, FrameStatus::error);
  EXPECT_NE(p.reason.find("protocol"), std::string_view::npos);
  for (const int length : {0, 1, 255, 0xFFFF}) {
    const Bytes b = mbap(1, 0, static_cast<std::uint16_t>(length), 1);
    const TcpFrame f = frame_tcp(b.data(), b.size());
    EXPECT_EQ(f.status, FrameStatus::error) << length;
    EXPECT_NE(f.reason.find("length"), std::string_view::npos);
  }
  // The longest legal frame: a 253-byte PDU.
  Bytes longest = mbap(1, 0, 254, 1);
  longest.resize(6 + 254, 0x10);
  EXPECT_EQ(frame_tcp(longest.data(), longest.size()).size, kMaxTcpAdu);
}

TEST(RtuFramer, FramesByFunctionLength) {
  const Bytes read = with_crc({1, 3, 0, 0, 0, 8});
  Bytes b = read;
  b.push_back(0x01);  // the next frame's first byte
  const RtuFrame f = frame_rtu(b.data(), b.size(), false);
  ASSERT_EQ(f.status, FrameStatus::frame);
  EXPECT_EQ(f.size, 8u);
  EXPECT_EQ(f.unit_id, 1);
  EXPECT_EQ(f.pdu, b.data() + 1);
  EXPECT_EQ(f.pdu_size, 5u);
  // Write multiple: its byte count decides the length (9 + 4).
  const Bytes write = with_crc({1, 16, 0x03, 0xEE, 0, 2, 4, 1, 2, 3, 4});
  EXPECT_EQ(frame_rtu(write.data(), write.size(), false).size, 13u);
  for (std::size_t n = 0; n < write.size(); ++n)
    EXPECT_EQ(frame_rtu(write.data(), n, false).status, FrameStatus::need_more) << n;
}

TEST(RtuFramer, SilenceEndsAFunctionWithoutLengthRuleAndCutsShortTheOthers) {
  const Bytes unknown = with_crc({1, 0x41, 7, 7, 7});
  EXPECT_EQ(frame_rtu(unknown.data(), unknown.size(), false).status, FrameStatus::need_more);
  const RtuFrame f = frame_rtu(unknown.data(), unknown.size(), true);
  ASSERT_EQ(f.status, FrameStatus::frame);
  EXPECT_EQ(f.size, unknown.size());
  const Bytes cut = {1, 3, 0, 0};
  const RtuFrame c = frame_rtu(cut.data(), cut.size(), true);
  EXPECT_EQ(c.status, FrameStatus::error);
  EXPECT_NE(c.reason.find("cut short"), std::string_view::npos);
}

TEST(RtuFramer, RefusesABadCrcAndAnOversizedFrameWithAReason) {
  Bytes bad = with_crc({1, 3, 0, 0, 0, 8});
  bad.back() ^= 1;
  const RtuFrame c = frame_rtu(bad.data(), bad.size(), false);
  EXPECT_EQ(c.status, FrameStatus::error);
  EXPECT_NE(c.reason.find("CRC"), std::string_view::npos);
  // A write whose byte count makes it longer than 256 bytes (13 + 250).
  Bytes big = {1, 23, 0, 0, 0, 1, 0, 0, 0, 125, 250};
  const RtuFrame o = frame_rtu(big.data(), big.size(), false);
  EXPECT_EQ(o.status, FrameStatus::error);
  EXPECT_NE(o.reason.find("longer"), std::string_view::npos);
  // A function without a length rule: 256 bytes ended by the silence are a frame, 257 bytes are
  // too long even before the silence.
  Bytes longest = {1, 0x41};
  longest.resize(254, 0x55);
  longest = with_crc(longest);
  EXPECT_EQ(frame_rtu(longest.data(), longest.size(), true).size, kMaxRtuAdu);
  longest.push_back(0);
  EXPECT_EQ(frame_rtu(longest.data(), longest.size(), false).status, FrameStatus::error);
  const Bytes tiny = {1, 0x41};
  EXPECT_EQ(frame_rtu(tiny.data(), tiny.size(), true).status, FrameStatus::error);
}

// A reader not scheduled during the silence gets a cut-short frame and the next request in one
// read (the RTU integration test's 5 + 8 bytes under a loaded sanitizer run): the request after
// the refused start is found by its CRC; a lone broken frame leaves nothing to serve.
TEST(RtuFramer, FindsTheWholeRequestAfterACutShortOneReadTogether) {
  const Bytes good = with_crc({3, 4, 0, 0, 0, 1});
  Bytes both(good.begin(), good.begin() + 5);
  both.insert(both.end(), good.begin(), good.end());
  ASSERT_EQ(frame_rtu(both.data(), both.size(), false).status, FrameStatus::error);
  const std::size_t k = rtu_resync_offset(both.data(), both.size(), false);
  ASSERT_EQ(k, 5u);
  const RtuFrame f = frame_rtu(both.data() + k, both.size() - k, false);
  ASSERT_EQ(f.status, FrameStatus::frame);
  EXPECT_EQ(f.size, good.size());
  Bytes bad = good;
  bad.back() ^= 1;
  EXPECT_EQ(rtu_resync_offset(bad.data(), bad.size(), true), bad.size());
  const Bytes cut(good.begin(), good.begin() + 5);
  EXPECT_EQ(rtu_resync_offset(cut.data(), cut.size(), true), cut.size());
}
