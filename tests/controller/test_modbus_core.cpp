// Modbus request handling at the PDU level: every function code, every exception case, control
// ownership, and that a refused request changes nothing.
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <limits>
#include <string_view>
#include <vector>

#include "maglead/modbus/modbus_core.hpp"
#include "maglead/modbus/modbus_rtu.hpp"
#include "maglead/plant/simulated_actuator.hpp"

using namespace maglead;
using namespace maglead::controller;
using namespace maglead::modbus;
namespace reg = maglead::registers;

namespace {

using Bytes = std::vector<std::uint8_t>;

struct CoreRig {
  SimulatedActuator plant{paper_like_plant(), 3, 0.02};
  ControllerConfig cfg;
  Controller ctl{cfg, plant};
  ModbusCore core;
  double t_s = 0.0;
  explicit CoreRig(bool read_only = false) : core(ctl, {read_only, "test"}) { run(5); }
  explicit CoreRig(const ControllerConfig& c) : cfg(c), core(ctl, {false, "test"}) { run(5); }
  void run(int cycles) {
    for (int i = 0; i < cycles; ++i) ctl.step(t_s += 1e-3);
  }
  Bytes req(const Bytes& pdu, std::uint16_t client = 1) {
    std::uint8_t out[ModbusCore::kMaxPdu];
    const std::size_t n =
        core.handle(ClientInfo{client, 0x7F000001, false}, pdu.data(), pdu.size(), out);
    return Bytes(out, out + n);
  }
};

Bytes u16(std::uint16_t v) {
  return {static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)};
}
Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}
Bytes rd(std::uint8_t fc, std::uint16_t start, std::uint16_t count) {
  return cat({{fc}, u16(start), u16(count)});
}
Bytes write_regs(std::uint16_t start, const std::vector<std::uint16_t>& words) {
  Bytes p = cat({{16},
                 u16(start),
                 u16(static_cast<std::uint16_t>(words.size())),
                 {static_cast<std::uint8_t>(2 * words.size())}});
  for (auto w : words) p = cat({p, u16(w)});
  return p;
}
Bytes write_one(std::uint16_t addr, std::uint16_t value) {
  return cat({{6}, u16(addr), u16(value)});
}
std::uint16_t word_at(const Bytes& resp, std::size_t i) {
  return static_cast<std::uint16_t>((resp[2 + 2 * i] << 8) | resp[3 + 2 * i]);
}
Bytes exception(std::uint8_t fc, Exception e) {
  return {static_cast<std::uint8_t>(fc | 0x80), static_cast<std::uint8_t>(e)};
}
std::uint16_t addr(const char* name) { return reg::find(name)->address; }
std::vector<std::uint16_t> f32_words(float v) {
  const auto u = std::bit_cast<std::uint32_t>(v);
  return {static_cast<std::uint16_t>(u >> 16), static_cast<std::uint16_t>(u)};
}
std::vector<std::uint16_t> i32_words(std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  return {static_cast<std::uint16_t>(u >> 16), static_cast<std::uint16_t>(u)};
}

}  // namespace

TEST(ModbusCore, ReadsIdentityAndWordOrderProbes) {
  CoreRig r;
  const Bytes resp = r.req(rd(4, 0, 8));
  ASSERT_EQ(resp.size(), 2u + 16u);
  EXPECT_EQ(resp[1], 16);
  EXPECT_EQ(word_at(resp, 0), reg::kDeviceType);
  EXPECT_EQ(word_at(resp, 3), 1000);
  EXPECT_EQ(word_at(resp, 4), 0x1234);
  EXPECT_EQ(word_at(resp, 5), 0x5678);
  EXPECT_EQ(word_at(resp, 6), 0x449A);
  EXPECT_EQ(word_at(resp, 7), 0x522B);
  Bytes fc3 = r.req(rd(3, 0, 8));  // function 3 reads input registers too
  fc3[0] = 4;
  EXPECT_EQ(fc3, resp);
}

TEST(ModbusCore, AddressExceptions) {
  CoreRig r;
  const auto ill = Exception::illegal_data_address;
  EXPECT_EQ(r.req(rd(3, 200, 1)), exception(3, ill));   // outside the mapped ranges
  EXPECT_EQ(r.req(rd(3, 150, 10)), exception(3, ill));  // partly outside
  EXPECT_EQ(r.req(rd(3, 21, 2)), exception(3, ill));    // starts in the middle of nut_pos_um
  EXPECT_EQ(r.req(rd(3, 20, 1)), exception(3, ill));    // ends in the middle
  EXPECT_EQ(r.req(rd(4, 1000, 1)), exception(4, ill));  // FC4 does not read holding registers
  EXPECT_EQ(r.req(rd(3, 65535, 2)), exception(3, ill));
  EXPECT_EQ(r.req(rd(1, 5, 1)), exception(1, ill));   // no such coil
  EXPECT_EQ(r.req(rd(2, 10, 8)), exception(2, ill));  // partly beyond the status bits
  EXPECT_EQ(r.req(write_one(addr("status_word"), 1)), exception(6, ill));        // read-only
  EXPECT_EQ(r.req(write_one(addr("force_setpoint_mn"), 1)), exception(6, ill));  // half of an i32
  EXPECT_EQ(r.req(write_regs(addr("force_setpoint_mn") + 1, {0, 0})), exception(16, ill));
}

// Finding 8: PLCs poll in blocks; reserved addresses inside the documented ranges read as 0.
TEST(ModbusCore, BlockReadsAcrossReservedAddressesWork) {
  CoreRig r;
  const Bytes a = r.req(rd(4, 0, 16));
  ASSERT_EQ(a.size(), 2u + 32u);
  EXPECT_EQ(word_at(a, 8), 0);  // reserved 8 and 9
  EXPECT_EQ(word_at(a, 9), 0);
  EXPECT_EQ(word_at(a, 13), static_cast<std::uint16_t>(reg::DriveState::ready));
  const Bytes b = r.req(rd(3, 40, 72));  // 40..111 crosses the reserved addresses of 56..99
  ASSERT_EQ(b.size(), 2u + 144u);
  for (std::uint16_t addr = 56; addr < 100; ++addr) {
    if (!reg::at(reg::Table::input_register, addr)) {
      EXPECT_EQ(word_at(b, addr - 40u), 0) << addr;
    }
  }
  EXPECT_EQ(word_at(b, 100 - 40), word_at(r.req(rd(4, 100, 2)), 0));  // nut_pos_m_f32, high word
  // Every poll block of the generated docs is one working request.
  for (const auto& blk : reg::poll_blocks()) {
    const Bytes resp =
        r.req(rd(blk.table == reg::Table::input_register ? 4 : 3, blk.first, blk.count));
    EXPECT_EQ(resp.size(), 2u + 2u * blk.count) << blk.first;
  }
  // Reserved addresses are not writable, and a read may not split a 32-bit value at a block edge.
  EXPECT_EQ(r.req(write_one(68, 1)), exception(6, Exception::illegal_data_address));
  EXPECT_EQ(r.req(rd(4, 0, 21)), exception(4, Exception::illegal_data_address));
}

TEST(ModbusCore, QuantityAndFunctionExceptions) {
  CoreRig r;
  EXPECT_EQ(r.req(rd(3, 10, 0)), exception(3, Exception::illegal_data_value));
  EXPECT_EQ(r.req(rd(3, 10, 126)), exception(3, Exception::illegal_data_value));
  EXPECT_EQ(r.req({3, 0, 10}), exception(3, Exception::illegal_data_value));  // truncated
  EXPECT_EQ(r.req({0x41, 0, 0}), exception(0x41, Exception::illegal_function));
  EXPECT_EQ(r.req({20, 0}), exception(20, Exception::illegal_function));
  Bytes bad = write_regs(addr("force_setpoint_n_f32"), f32_words(1.0f));
  bad[5] = 3;  // byte count disagrees with the quantity
  EXPECT_EQ(r.req(bad), exception(16, Exception::illegal_data_value));
}

TEST(ModbusCore, OutOfRangeWritesChangeNothing) {
  CoreRig r;
  const std::uint16_t pos = addr("position_setpoint_um");
  const Bytes before = r.req(rd(3, 1000, 20));
  // Each refusal's reason is readable (a PLC that missed the 03 learns why nothing changed).
  const auto refusal = [&] { return word_at(r.req(rd(4, addr("write_refusal_reason"), 1)), 0); };
  EXPECT_EQ(r.req(write_regs(pos, i32_words(41000))), exception(16, Exception::illegal_data_value));
  EXPECT_EQ(refusal(), static_cast<std::uint16_t>(reg::Refusal::out_of_range));  // 0 .. 40 mm
  const double limit = r.ctl.safe_force_limit_n(1.0);
  EXPECT_EQ(
      r.req(write_regs(addr("force_setpoint_n_f32"), f32_words(static_cast<float>(limit + 1.0)))),
      exception(16, Exception::illegal_data_value));
  EXPECT_EQ(refusal(), static_cast<std::uint16_t>(reg::Refusal::force_beyond_safe_limit));
  EXPECT_EQ(r.req(write_regs(addr("force_setpoint_n_f32"), f32_words(150.0f))),
            exception(16, Exception::illegal_data_value));
  EXPECT_EQ(refusal(), static_cast<std::uint16_t>(reg::Refusal::out_of_range));
  EXPECT_EQ(r.req(write_one(addr("control_word"), 0x12)),  // execute with stop
            exception(6, Exception::illegal_data_value));
  EXPECT_EQ(refusal(), static_cast<std::uint16_t>(reg::Refusal::bad_control_word));
  EXPECT_EQ(r.req(write_regs(addr("force_setpoint_n_f32"), f32_words(std::nanf("")))),
            exception(16, Exception::illegal_data_value));
  // A multi-register write with one bad value writes none of them.
  auto words = i32_words(25000);
  for (auto w : i32_words(0)) words.push_back(w);  // velocity limit 0: out of range
  EXPECT_EQ(r.req(write_regs(pos, words)), exception(16, Exception::illegal_data_value));
  EXPECT_EQ(r.req(write_one(addr("mode_command"), 4)), exception(6, Exception::illegal_data_value));
  EXPECT_EQ(r.req(rd(3, 1000, 20)), before);
}

// A round value sent low word first decodes to a subnormal float32 (10.0 N as 0, 16672: 2.3e-41
// N), inside the register's range; staged, an execute would hold 0 N and report it reached.
TEST(ModbusCore, ASubnormalFloatSetpointIsRefusedAsTheWrongWordOrder) {
  CoreRig r;
  const std::uint16_t force = addr("force_setpoint_n_f32");
  ASSERT_EQ(r.req(write_regs(force, f32_words(5.0f))).size(), 5u);
  const Bytes before = r.req(rd(3, 1000, 20));
  const auto refusal = [&] { return word_at(r.req(rd(4, addr("write_refusal_reason"), 1)), 0); };
  const auto swapped = [](float v) {
    const auto w = f32_words(v);
    return std::vector<std::uint16_t>{w[1], w[0]};
  };
  ASSERT_EQ(swapped(10.0f), (std::vector<std::uint16_t>{0, 16672}));
  EXPECT_EQ(r.req(write_regs(force, swapped(10.0f))), exception(16, Exception::illegal_data_value));
  EXPECT_EQ(refusal(), static_cast<std::uint16_t>(reg::Refusal::word_order));
  EXPECT_EQ(r.req(write_regs(addr("position_setpoint_m_f32"), swapped(0.03125f))),
            exception(16, Exception::illegal_data_value));
  EXPECT_EQ(refusal(), static_cast<std::uint16_t>(reg::Refusal::word_order));
  EXPECT_EQ(r.req(rd(3, 1000, 20)), before);
  // Zero and the smallest normal float32 are values, not a word-order mistake.
  EXPECT_EQ(r.req(write_regs(force, f32_words(0.0f))).size(), 5u);
  EXPECT_EQ(r.req(write_regs(force, f32_words(std::numeric_limits<float>::min()))).size(), 5u);
}

// A PLC reads the limits the drive runs with (not the shipped defaults) and a setpoint just
// inside them is taken, just outside refused: the block says what the write check does.
TEST(ModbusCore, TheLimitsBlockReadsTheConfigurationTheWriteCheckUses) {
  ControllerConfig c;
  c.actuator.stroke_min_m = 0.005, c.actuator.stroke_max_m = 0.030;
  c.actuator.safe_force_fraction = 0.5;
  c.force_stroke_margin_m = 2e-3, c.force_speed_limit_m_s = 0.05;
  CoreRig r(c);
  const Bytes b = r.req(rd(4, addr("force_limit_push_n_f32"), 14));
  ASSERT_EQ(b.size(), 2u + 28u);
  const auto f32 = [&](const char* name) {
    const std::size_t i = addr(name) - addr("force_limit_push_n_f32");
    return static_cast<double>(std::bit_cast<float>(
        static_cast<std::uint32_t>((word_at(b, i) << 16) | word_at(b, i + 1))));
  };
  const double push = f32("force_limit_push_n_f32"), pull = f32("force_limit_pull_n_f32");
  EXPECT_NEAR(push, 0.5 * c.calibration.peak_push_n, 1e-4);
  EXPECT_NEAR(pull, 0.5 * c.calibration.peak_pull_n, 1e-4);
  EXPECT_NEAR(f32("stroke_min_m_f32"), 0.005, 1e-9);
  EXPECT_NEAR(f32("stroke_max_m_f32"), 0.030, 1e-9);
  EXPECT_NEAR(f32("force_window_min_m_f32"), 0.007, 1e-9);
  EXPECT_NEAR(f32("force_window_max_m_f32"), 0.028, 1e-9);
  EXPECT_NEAR(f32("force_speed_limit_m_s_f32"), 0.05, 1e-9);
  const std::uint16_t force = addr("force_setpoint_n_f32");
  for (const double limit : {push, pull}) {
    const double inward = limit > 0 ? -0.01 : 0.01;
    EXPECT_EQ(r.req(write_regs(force, f32_words(static_cast<float>(limit - inward)))),
              exception(16, Exception::illegal_data_value));
    EXPECT_EQ(r.req(write_regs(force, f32_words(static_cast<float>(limit + inward)))).size(), 5u);
  }
  const std::uint16_t pos = addr("position_setpoint_m_f32");
  EXPECT_EQ(r.req(write_regs(pos, f32_words(0.0049f))),
            exception(16, Exception::illegal_data_value));
  EXPECT_EQ(word_at(r.req(rd(4, addr("write_refusal_reason"), 1)), 0),
            static_cast<std::uint16_t>(reg::Refusal::position_outside_stroke));
  EXPECT_EQ(r.req(write_regs(pos, f32_words(0.0051f))).size(), 5u);
}

// A PLC that clamps a setpoint to the limits it read writes back their float32 words, or the
// integer mirror of a staged limit: both are accepted (within half an integer register's unit)
// and staged as the limit itself; a unit beyond is refused.
TEST(ModbusCore, TheLimitsAsReadAreAcceptedBack) {
  CoreRig r;
  const auto words_at = [&](const char* name) {
    const Bytes b = r.req(rd(4, addr(name), 2));
    return std::vector<std::uint16_t>{word_at(b, 0), word_at(b, 1)};
  };
  const std::uint16_t force_f32 = addr("force_setpoint_n_f32"),
                      force_mn = addr("force_setpoint_mn");
  for (const char* name : {"force_limit_push_n_f32", "force_limit_pull_n_f32"}) {
    EXPECT_EQ(r.req(write_regs(force_f32, words_at(name))).size(), 5u) << name;
    const double limit = r.ctl.safe_force_limit_n(
        std::string_view(name).find("push") != std::string_view::npos ? 1.0 : -1.0);
    const Bytes staged = r.req(rd(3, force_f32, 2));
    EXPECT_EQ(std::bit_cast<float>(
                  static_cast<std::uint32_t>((word_at(staged, 0) << 16) | word_at(staged, 1))),
              static_cast<float>(limit))
        << name;
    const Bytes mirror = r.req(rd(3, force_mn, 2));
    EXPECT_EQ(r.req(write_regs(force_mn, {word_at(mirror, 0), word_at(mirror, 1)})).size(), 5u);
    const auto beyond = static_cast<std::int32_t>(std::lround(limit * 1e3 + (limit > 0 ? 1 : -1)));
    EXPECT_EQ(r.req(write_regs(force_mn, i32_words(beyond))),
              exception(16, Exception::illegal_data_value));
  }
  const std::uint16_t pos_f32 = addr("position_setpoint_m_f32");
  for (const char* name : {"stroke_min_m_f32", "stroke_max_m_f32"})
    EXPECT_EQ(r.req(write_regs(pos_f32, words_at(name))).size(), 5u) << name;
}

TEST(ModbusCore, BadControlWordCombinationsAreRefused) {
  CoreRig r;
  const std::uint16_t cw = addr("control_word");
  EXPECT_EQ(r.req(write_one(cw, 1u << 5)),
            exception(6, Exception::illegal_data_value));  // reserved bit
  EXPECT_EQ(r.req(write_one(cw, (1u << reg::kExecute) | (1u << reg::kStop))),
            exception(6, Exception::illegal_data_value));
  EXPECT_EQ(r.req(write_one(cw, (1u << reg::kExecute) | (1u << reg::kFaultReset))),
            exception(6, Exception::illegal_data_value));
  EXPECT_EQ(word_at(r.req(rd(3, cw, 1)), 0), 0);
}

TEST(ModbusCore, WritesReadBackAndBothScalingsShareOneValue) {
  CoreRig r;
  EXPECT_EQ(r.req(write_regs(addr("force_setpoint_mn"), i32_words(-12500))).size(), 5u);
  const Bytes f = r.req(rd(3, addr("force_setpoint_n_f32"), 2));
  const float v =
      std::bit_cast<float>(static_cast<std::uint32_t>((word_at(f, 0) << 16) | word_at(f, 1)));
  EXPECT_FLOAT_EQ(v, -12.5f);
}

// A float32 just past a limit, within its rounding slack, is taken as the limit: its integer
// mirror reads inside its documented range, and the block written back as read is taken.
TEST(ModbusCore, AFloatWithinItsSlackPastALimitIsStoredAsTheLimit) {
  CoreRig r;
  const auto& acc = *std::find_if(reg::table().begin(), reg::table().end(),
                                  [](const auto& x) { return x.name == "accel_limit_m_s2_f32"; });
  // 0.8 ppm past: inside the float32 slack (1 ppm), 4 units of the integer mirror (1 µm/s²).
  const auto past = static_cast<float>(acc.max * (1.0 + 0.8e-6));
  ASSERT_EQ(r.req(write_regs(addr("accel_limit_m_s2_f32"), f32_words(past))).size(), 5u);
  const Bytes block_read = r.req(rd(3, 1000, 20));
  std::vector<std::uint16_t> block;
  for (std::size_t i = 0; i < 20; ++i) block.push_back(word_at(block_read, i));
  EXPECT_EQ(r.req(write_regs(1000, block)).size(), 5u);
}

// The commands block read and written back whole (FC16 at HR 1000, 20 registers) carries both
// copies of each setpoint: one copy changed alone used to lose to the float32 one silently.
TEST(ModbusCore, AWriteWhoseTwoCopiesOfASetpointDisagreeIsRefused) {
  CoreRig r;
  ASSERT_EQ(r.req(write_regs(addr("force_setpoint_n_f32"), f32_words(5.0f))).size(), 5u);
  const Bytes before = r.req(rd(3, 1000, 20));
  std::vector<std::uint16_t> block;
  for (std::size_t i = 0; i < 20; ++i) block.push_back(word_at(before, i));
  const auto set = [&](std::vector<std::uint16_t> b, const char* name,
                       const std::vector<std::uint16_t>& w) {
    const std::size_t i = addr(name) - 1000u;
    b[i] = w[0], b[i + 1] = w[1];
    return b;
  };
  EXPECT_EQ(r.req(write_regs(1000, block)).size(), 5u);  // as read: the copies agree
  const auto one_copy = set(block, "force_setpoint_mn", i32_words(20000));
  EXPECT_EQ(r.req(write_regs(1000, one_copy)), exception(16, Exception::illegal_data_value));
  EXPECT_EQ(word_at(r.req(rd(4, addr("write_refusal_reason"), 1)), 0),
            static_cast<std::uint16_t>(reg::Refusal::copies_disagree));
  EXPECT_EQ(r.req(rd(3, 1000, 20)), before);
  const auto pos_copy = set(block, "position_setpoint_m_f32", f32_words(0.03f));
  EXPECT_EQ(r.req(write_regs(1000, pos_copy)), exception(16, Exception::illegal_data_value));
  // Within half the integer's unit (0.5 mN) the two agree; both changed is taken.
  EXPECT_EQ(
      r.req(write_regs(1000, set(one_copy, "force_setpoint_n_f32", f32_words(20.0004f)))).size(),
      5u);
  EXPECT_EQ(word_at(r.req(rd(3, addr("force_setpoint_mn"), 2)), 1), 20000);
}

TEST(ModbusCore, AnEnableEdgeClaimsControlOthersAreRefusedWith04) {
  CoreRig r;
  const std::uint16_t cw = addr("control_word");
  ASSERT_EQ(r.req(write_one(cw, 1), 7).size(), 5u);  // client 7 enables
  EXPECT_EQ(r.core.owner(), 7);
  // Finding 9: a refusal that retrying cannot fix is 04, with the reason readable; 06 stays
  // for "busy, try again" (a full command queue).
  EXPECT_EQ(r.req(write_one(addr("mode_command"), 1), 8),
            exception(6, Exception::server_device_failure));
  EXPECT_EQ(r.req(cat({{5}, u16(0), u16(0)}), 8), exception(5, Exception::server_device_failure));
  EXPECT_EQ(word_at(r.req(rd(4, addr("write_refusal_reason"), 1), 8), 0),
            static_cast<std::uint16_t>(reg::Refusal::not_owner));
  EXPECT_EQ(r.req(rd(3, addr("control_owner"), 1), 8)[3], 7);  // others may read who owns
  r.run(3);
  const Bytes st = r.req(rd(2, 0, 14), 8);
  EXPECT_TRUE(st[2] & (1u << reg::kEnabled));
  EXPECT_TRUE(st[3] & (1u << (reg::kOwned - 8)));
  // The owner releases by clearing enable; the next one claims with its own edge.
  ASSERT_EQ(r.req(write_one(cw, 0), 7).size(), 5u);
  EXPECT_EQ(r.core.owner(), 0);
  ASSERT_EQ(r.req(write_one(cw, 1), 9).size(), 5u);
  EXPECT_EQ(r.core.owner(), 9);
  ASSERT_EQ(r.req(write_one(cw, 0), 9).size(), 5u);
  EXPECT_EQ(r.core.owner(), 0);
}

// Finding 1: when the owner's connection closes, the drive faults with alarm owner_lost and
// runs its reaction; the next client does not become owner by writing, and its setpoint does
// not act, until it clears the fault and claims with an enable edge.
TEST(ModbusCore, OwnerLossFaultsTheDriveAndANewOwnerMustClaim) {
  CoreRig r;
  const std::uint16_t cw = addr("control_word");
  const std::uint16_t force = addr("force_setpoint_n_f32");
  ASSERT_EQ(r.req(write_regs(force, f32_words(5.0f)), 7).size(), 5u);
  ASSERT_EQ(r.req(write_one(addr("mode_command"), 2), 7).size(), 5u);
  ASSERT_EQ(r.req(write_one(cw, 1), 7).size(), 5u);
  r.run(3);
  ASSERT_EQ(r.req(write_one(cw, 1 | 16), 7).size(), 5u);  // execute: force mode
  r.run(3);
  ASSERT_EQ(r.ctl.snapshot().active_mode, static_cast<std::uint16_t>(reg::Mode::force));

  r.core.client_closed(7);
  r.run(2);
  auto s = r.ctl.snapshot();
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  EXPECT_EQ(s.alarm_code, static_cast<std::uint16_t>(reg::Alarm::owner_lost));
  EXPECT_NE(s.fault_reaction, static_cast<std::uint16_t>(reg::Reaction::none));
  EXPECT_EQ(r.core.owner(), 0);
  EXPECT_EQ(word_at(r.req(rd(3, cw, 1), 8), 0), 0);  // the levels were cleared

  // Client 8 writes a new setpoint with enable and execute at once: no owner, no effect.
  ASSERT_EQ(r.req(write_regs(force, f32_words(9.0f)), 8).size(), 5u);
  ASSERT_EQ(r.req(write_one(cw, 1 | 16), 8).size(), 5u);
  r.run(3);
  s = r.ctl.snapshot();
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::fault));
  EXPECT_EQ(s.active_force_setpoint_n, 0.0);
  // The documented take-over: fault reset, then an enable edge, then execute.
  ASSERT_EQ(r.req(write_one(cw, 4), 8).size(),
            5u);  // fault_reset (enable low: this releases the claim)
  r.run(3);
  EXPECT_EQ(r.ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  EXPECT_EQ(r.core.owner(), 0);
  ASSERT_EQ(r.req(write_one(cw, 1), 8).size(), 5u);
  EXPECT_EQ(r.core.owner(), 8);
  r.run(3);
  EXPECT_EQ(r.ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  // A closed connection that was not the owner changes nothing.
  r.core.client_closed(7);
  r.run(2);
  EXPECT_EQ(r.ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
}

TEST(ModbusCore, CoilsAreControlWordBits) {
  CoreRig r;
  EXPECT_EQ(r.req(cat({{5}, u16(reg::kEnable), u16(0xFF00)})).size(), 5u);
  EXPECT_EQ(word_at(r.req(rd(3, addr("control_word"), 1)), 0), 1);
  EXPECT_EQ(r.req(rd(1, 0, 5)), (Bytes{1, 1, 0x01}));
  EXPECT_EQ(r.req(cat({{5}, u16(0), u16(0x1234)})), exception(5, Exception::illegal_data_value));
  // FC15: enable and stop together.
  EXPECT_EQ(r.req(cat({{15}, u16(0), u16(2), {1}, {0x03}})).size(), 5u);
  EXPECT_EQ(word_at(r.req(rd(3, addr("control_word"), 1)), 0), 3);
}

TEST(ModbusCore, ReadOnlyServerRefusesEveryWrite) {
  CoreRig r(true);
  EXPECT_EQ(r.req(write_one(addr("mode_command"), 1)), exception(6, Exception::illegal_function));
  EXPECT_EQ(r.req(cat({{5}, u16(0), u16(0xFF00)})), exception(5, Exception::illegal_function));
  EXPECT_EQ(r.req(rd(4, 10, 1)).size(), 4u);
}

TEST(ModbusCore, ReadWriteMultipleWritesThenReadsAndValidatesBoth) {
  CoreRig r;
  const std::uint16_t cw = addr("control_word");
  // Write enable, read control word + mode back in the same request.
  Bytes fc23 = cat({{23}, u16(cw), u16(2), u16(cw), u16(1), {2}, u16(1)});
  const Bytes resp = r.req(fc23);
  ASSERT_EQ(resp.size(), 6u);
  EXPECT_EQ(word_at(resp, 0), 1);
  // A bad read range refuses the whole request: the write does not happen.
  Bytes bad = cat({{23}, u16(21), u16(2), u16(addr("mode_command")), u16(1), {2}, u16(2)});
  EXPECT_EQ(r.req(bad), exception(23, Exception::illegal_data_address));
  EXPECT_EQ(word_at(r.req(rd(3, addr("mode_command"), 1)), 0), 0);
  // Status and control in one exchange: status block plus command block.
  const Bytes both = r.req(cat({{23}, u16(10), u16(44), u16(cw), u16(1), {2}, u16(1)}));
  EXPECT_EQ(both[1], 88);
}

TEST(ModbusCore, DiagnosticsEchoAndCounters) {
  CoreRig r;
  const Bytes echo = {8, 0, 0, 0xAB, 0xCD};
  EXPECT_EQ(r.req(echo), echo);
  r.req(rd(3, 200, 1));  // one exception
  const Bytes exc = r.req({8, 0, 0x0D, 0, 0});
  EXPECT_EQ(exc, (Bytes{8, 0, 0x0D, 0, 1}));
  const Bytes msgs = r.req({8, 0, 0x0E, 0, 0});
  EXPECT_EQ(msgs[4], 4);  // echo, read, the exception query, this one
  EXPECT_EQ(r.req({8, 0, 0x0A, 0, 0}), (Bytes{8, 0, 0x0A, 0, 0}));
  EXPECT_EQ(r.req({8, 0, 0x0B, 0, 0}), (Bytes{8, 0, 0x0B, 0, 1}));
  EXPECT_EQ(r.req({8, 0, 0x04, 0, 0}),
            exception(8, Exception::illegal_function));  // listen-only: unsupported
}

TEST(ModbusCore, DeviceIdentification) {
  CoreRig r;
  const Bytes basic = r.req({43, 14, 1, 0});
  ASSERT_GT(basic.size(), 7u);
  EXPECT_EQ(basic[6], 3);  // vendor, product code, revision
  EXPECT_EQ(basic[7], 0);
  EXPECT_EQ(std::string(basic.begin() + 9, basic.begin() + 9 + basic[8]), "maglead project");
  const Bytes one = r.req({43, 14, 4, 5});
  EXPECT_EQ(one[6], 1);
  EXPECT_EQ(std::string(one.begin() + 9, one.end()), "test");
  EXPECT_EQ(r.req({43, 14, 4, 0x80}), exception(43, Exception::illegal_data_address));
  EXPECT_EQ(r.req({43, 14, 9, 0}), exception(43, Exception::illegal_data_value));
  EXPECT_EQ(r.req({43, 13, 1, 0}), exception(43, Exception::illegal_function));
}

TEST(ModbusCore, FullCommandQueueAnswersBusyAndChangesNothing) {
  CoreRig r;
  const std::uint16_t mode = addr("heartbeat");
  int busy_at = -1;
  for (int i = 0; i < 2000 && busy_at < 0; ++i) {  // the loop is not stepping: the queue fills
    const Bytes resp = r.req(write_one(mode, static_cast<std::uint16_t>(i + 1)));
    if (resp == exception(6, Exception::server_busy)) busy_at = i;
  }
  ASSERT_GT(busy_at, 0);
  EXPECT_EQ(word_at(r.req(rd(3, mode, 1)), 0), busy_at);  // the refused value was not taken
  r.run(100);
  EXPECT_EQ(r.req(write_one(mode, 7)).size(), 5u);
}

TEST(ModbusCore, BroadcastSetpointWritesActWithoutReply) {
  CoreRig r;
  const Bytes pdu = write_regs(addr("force_setpoint_n_f32"), f32_words(4.0f));
  std::uint8_t out[ModbusCore::kMaxPdu];
  EXPECT_EQ(r.core.handle(ClientInfo{ModbusCore::kRtuClient, 0, true}, pdu.data(), pdu.size(), out),
            0u);
  EXPECT_EQ(r.req(rd(3, addr("force_setpoint_n_f32"), 2)), (cat({{3, 4}, u16(0x4080), u16(0)})));
}

// Finding 7: a broadcast may not change the drive's state (enable, mode, fault reset, …).
TEST(ModbusCore, BroadcastStateChangesAreRefused) {
  CoreRig r;
  std::uint8_t out[ModbusCore::kMaxPdu];
  const ClientInfo bc{ModbusCore::kRtuClient, 0, true};
  for (const Bytes& pdu :
       {cat({{5}, u16(reg::kEnable), u16(0xFF00)}), write_one(addr("control_word"), 1),
        write_one(addr("mode_command"), 2), cat({{15}, u16(0), u16(3), {1}, {0x05}}),
        write_regs(addr("control_word"), {1, 2})}) {
    EXPECT_EQ(r.core.handle(bc, pdu.data(), pdu.size(), out), 0u);  // nothing is answered
    EXPECT_EQ(out[0] & 0x80, 0x80);
    EXPECT_EQ(out[1], static_cast<std::uint8_t>(Exception::server_device_failure));
  }
  r.run(3);
  EXPECT_EQ(r.ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::ready));
  EXPECT_EQ(word_at(r.req(rd(3, addr("control_word"), 2)), 0), 0);
  EXPECT_EQ(word_at(r.req(rd(3, addr("control_word"), 2)), 1), 0);
  EXPECT_EQ(word_at(r.req(rd(4, addr("write_refusal_reason"), 1)), 0),
            static_cast<std::uint16_t>(reg::Refusal::broadcast_state_change));
  // The same write addressed to the unit acts.
  EXPECT_EQ(r.req(write_one(addr("control_word"), 1), ModbusCore::kRtuClient).size(), 5u);
  r.run(3);
  EXPECT_EQ(r.ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
}

// A PLC that enables and executes position mode without writing a target: the staged target is
// where the nut is (30 mm here), read back as such, and the nut stays (it moved to mid-stroke,
// 20 mm, before). A target written is the one taken, even one equal to what was staged.
TEST(ModbusCore, AnExecuteWithoutATargetHoldsTheNutWhereItStarted) {
  SimulatedActuator plant{paper_like_plant(), 3, 0.03};
  ControllerConfig cfg;
  Controller ctl{cfg, plant};
  ModbusCore core(ctl, {false, "test"});
  double t_s = 0.0;
  const auto run = [&](int cycles) {
    for (int i = 0; i < cycles; ++i) ctl.step(t_s += 1e-3);
  };
  const auto req = [&](const Bytes& pdu) {
    std::uint8_t out[ModbusCore::kMaxPdu];
    const std::size_t n =
        core.handle(ClientInfo{1, 0x7F000001, false}, pdu.data(), pdu.size(), out);
    return Bytes(out, out + n);
  };
  run(5);
  const double start_m = ctl.snapshot().nut_pos_m;
  const Bytes target = req(rd(3, addr("position_setpoint_um"), 2));
  const auto raw = static_cast<std::int32_t>((word_at(target, 0) << 16) | word_at(target, 1));
  EXPECT_NEAR(raw * 1e-6, start_m, 1e-6);
  const std::uint16_t cw = addr("control_word");
  ASSERT_EQ(req(write_one(cw, 1)).size(), 5u);
  ASSERT_EQ(req(write_one(addr("mode_command"), 1)).size(), 5u);
  ASSERT_EQ(req(write_one(cw, 1u | (1u << reg::kExecute))).size(), 5u);
  run(2000);
  EXPECT_NEAR(ctl.snapshot().nut_pos_m, start_m, 0.2e-3);
  // A target written is taken, and the nut's position never replaces it.
  ASSERT_EQ(req(write_regs(addr("position_setpoint_um"), i32_words(25000))).size(), 5u);
  run(5);
  const Bytes kept = req(rd(3, addr("position_setpoint_um"), 2));
  EXPECT_EQ(static_cast<std::int32_t>((word_at(kept, 0) << 16) | word_at(kept, 1)), 25000);
  ASSERT_EQ(req(write_one(cw, 1)).size(), 5u);
  ASSERT_EQ(req(write_one(cw, 1u | (1u << reg::kExecute))).size(), 5u);
  run(3000);
  EXPECT_NEAR(ctl.snapshot().nut_pos_m, 0.025, 0.2e-3);
}

TEST(ModbusCore, RegistersCarryTheLoopsValues) {
  CoreRig r;
  r.run(20);
  const auto snap = r.ctl.snapshot();
  const Bytes resp = r.req(rd(4, 20, 2));
  const auto raw = static_cast<std::int32_t>((word_at(resp, 0) << 16) | word_at(resp, 1));
  EXPECT_NEAR(raw * 1e-6, snap.nut_pos_m, 1e-6);
  const Bytes st = r.req(rd(4, 13, 1));
  EXPECT_EQ(word_at(st, 0), static_cast<std::uint16_t>(reg::DriveState::ready));
}

TEST(ModbusRtu, SilenceTimesFollowTheSerialLineSpec) {
  // 11-bit characters (8E1): 3.5 characters at 9600 Bd are 4.01 ms, at 19200 Bd 2.005 ms.
  EXPECT_NEAR(rtu_timing(9600, 11).t3_5_s, 3.5 * 11 / 9600.0, 1e-12);
  EXPECT_NEAR(rtu_timing(9600, 11).t1_5_s, 1.5 * 11 / 9600.0, 1e-12);
  EXPECT_NEAR(rtu_timing(19200, 11).t3_5_s, 2.005e-3, 1e-6);
  EXPECT_NEAR(rtu_timing(19200, 10).t3_5_s, 1.823e-3, 1e-6);  // 8N1
  // Above 19200 Bd, fixed values.
  EXPECT_EQ(rtu_timing(38400, 11).t3_5_s, 1.75e-3);
  EXPECT_EQ(rtu_timing(115200, 11).t1_5_s, 750e-6);
}

TEST(ModbusRtu, Crc16MatchesTheSpecExample) {
  // Modbus over serial line spec, example: 02 07 → CRC 0x1241 (sent 41 12).
  const std::uint8_t frame[] = {0x02, 0x07};
  EXPECT_EQ(modbus_crc16(frame, 2), 0x1241);
}
