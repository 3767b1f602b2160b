// libFuzzer target: ModbusCore::handle on a controller with the simulated plant.
//
// Input: a sequence of records [flags][len][len bytes of request PDU]; a short last record is
// cut to what is there. flags & 3 chooses the client (0: TCP client 1, 1: TCP client 2,
// 2: RTU, 3: RTU broadcast); flags & 4 closes that client first (owner loss). After each
// request the loop runs one cycle, so posted commands are taken and the queue never stays full.
//
// Oracles (a failure prints the reason and aborts, which libFuzzer reports as a crash):
//  - the reply is a well-formed PDU: nothing for a broadcast or an empty request; otherwise
//    either the function code with the function's reply shape, or function | 0x80 with one
//    exception code among 01 02 03 04 06 0B (and 01 for an unknown function);
//  - the client-writable image (holding registers 1000…1019, coils 0…4) read back after every
//    request lies inside the register table's documented [min, max], the control word inside
//    its mask, and the coils agree with the control word;
//  - a refused request (an exception) leaves the image as it was; a write of one register
//    (function 6) that was accepted reads back as written.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "maglead/modbus/modbus_core.hpp"
#include "maglead/plant/simulated_actuator.hpp"

using namespace maglead;
using namespace maglead::controller;
using namespace maglead::modbus;
namespace reg = maglead::registers;

namespace {

constexpr std::uint16_t kImageFirst = 1000,
                        kImageCount = 20;     // control_word … accel_limit_m_s2_f32
constexpr std::uint16_t kInspector = 0xFFFE;  // reads only: never owns control

[[noreturn]] void fail(const char* what, const std::uint8_t* pdu, std::size_t len) {
  std::fprintf(stderr, "fuzz_modbus_core oracle failed: %s; request:", what);
  for (std::size_t i = 0; i < len; ++i) std::fprintf(stderr, " %02x", pdu[i]);
  std::fprintf(stderr, "\n");
  std::abort();
}
#define ORACLE(cond, what)             \
  do {                                 \
    if (!(cond)) fail(what, pdu, len); \
  } while (0)

std::uint16_t be16(const std::uint8_t* p) { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }

// Fitted once: the same parameters for every input.
const PlantParams& plant_params() {
  static const PlantParams params = paper_like_plant();
  return params;
}

struct Rig {
  SimulatedActuator plant{plant_params(), 3, 0.02};
  ControllerConfig cfg;
  Controller ctl{cfg, plant};
  ModbusCore core{ctl, {false, "fuzz"}};
  double t_s = 0.0;
  Rig() {
    for (int i = 0; i < 5; ++i) step();
  }
  void step() { ctl.step(t_s += 1e-3); }
};

struct Image {
  std::uint8_t words[2 * kImageCount];
  std::uint8_t coils;
  bool operator==(const Image& o) const { return std::memcmp(this, &o, sizeof o) == 0; }
};

// Reads the writable image through the core and checks it against the documented ranges.
Image read_image(Rig& rig, const std::uint8_t* pdu, std::size_t len) {
  const ClientInfo inspector{kInspector, 0, false};
  std::uint8_t out[ModbusCore::kMaxPdu];
  const std::uint8_t rd_regs[] = {3, kImageFirst >> 8, kImageFirst & 0xFF, 0, kImageCount};
  ORACLE(rig.core.handle(inspector, rd_regs, sizeof rd_regs, out) == 2 + 2u * kImageCount &&
             out[0] == 3,
         "the image's holding registers cannot be read");
  Image img{};
  std::memcpy(img.words, out + 2, sizeof img.words);
  const std::uint8_t rd_coils[] = {1, 0, 0, 0, 5};
  ORACLE(
      rig.core.handle(inspector, rd_coils, sizeof rd_coils, out) == 3 && out[0] == 1 && out[1] == 1,
      "the coils cannot be read");
  img.coils = out[2];

  for (std::uint16_t a = kImageFirst; a < kImageFirst + kImageCount;) {
    int word = 0;
    const reg::Register* r = reg::at(reg::Table::holding_register, a, &word);
    ORACLE(r && word == 0 && r->access == reg::Access::read_write,
           "the image block is not the table's");
    std::uint16_t w[2] = {0, 0};
    const int n = reg::word_count(r->type);
    for (int k = 0; k < n; ++k) w[k] = be16(img.words + 2 * (a - kImageFirst + k));
    if (!reg::in_range(*r, reg::decode(*r, w))) {
      std::fprintf(stderr, "register %.*s = %g outside [%g, %g]\n",
                   static_cast<int>(r->name.size()), r->name.data(), reg::decode(*r, w), r->min,
                   r->max);
      fail("the writable image left its documented range", pdu, len);
    }
    a = static_cast<std::uint16_t>(a + n);
  }
  const std::uint16_t control_word = be16(img.words);
  ORACLE((control_word & ~reg::kControlWordMask) == 0, "control word outside its mask");
  ORACLE(img.coils == control_word, "coils disagree with the control word");
  return img;
}

bool known_exception(std::uint8_t code) {
  return code == 0x01 || code == 0x02 || code == 0x03 || code == 0x04 || code == 0x06 ||
         code == 0x0B;
}

bool implemented(std::uint8_t fc) {
  return fc == 1 || fc == 2 || fc == 3 || fc == 4 || fc == 5 || fc == 6 || fc == 8 || fc == 15 ||
         fc == 16 || fc == 23 || fc == 43;
}

// The reply shape of a normal (non-exception) response to `pdu`.
void check_reply(const std::uint8_t* pdu, std::size_t len, const std::uint8_t* out, std::size_t n) {
  const std::uint8_t fc = pdu[0];
  switch (fc) {
    case 1:
    case 2: {
      ORACLE(len == 5, "read bits answered a malformed request");
      const std::uint16_t count = be16(pdu + 3);
      ORACLE(out[1] == (count + 7) / 8 && n == 2u + out[1], "read bits: byte count");
      return;
    }
    case 3:
    case 4:
      ORACLE(len == 5, "read registers answered a malformed request");
      ORACLE(out[1] == 2 * be16(pdu + 3) && n == 2u + out[1], "read registers: byte count");
      return;
    case 5:
    case 6:
      ORACLE(len == 5 && n == 5 && std::memcmp(out, pdu, 5) == 0, "write single: not an echo");
      return;
    case 15:
    case 16:
      ORACLE(n == 5 && std::memcmp(out, pdu, 5) == 0, "write multiple: not start and count");
      return;
    case 23:
      ORACLE(len >= 10 && out[1] == 2 * be16(pdu + 3) && n == 2u + out[1],
             "read/write registers: byte count");
      return;
    case 8:
      ORACLE(len >= 3, "diagnostics answered a malformed request");
      if (be16(pdu + 1) == 0)
        ORACLE(n == len && std::memcmp(out, pdu, len) == 0, "diagnostics 0: not an echo");
      else
        ORACLE(len == 5 && n == 5 && std::memcmp(out, pdu, 3) == 0, "diagnostics: reply shape");
      return;
    case 43: {
      ORACLE(len == 4 && n >= 7 && out[1] == 0x0E && out[2] == pdu[2] && out[3] == 0x82 &&
                 out[4] == 0 && out[5] == 0,
             "device identification: header");
      std::size_t p = 7;
      for (int i = 0; i < out[6]; ++i) {
        ORACLE(p + 2 <= n && out[p + 1] <= 64, "device identification: object header");
        p += 2u + out[p + 1];
      }
      ORACLE(p == n, "device identification: objects do not fill the reply");
      return;
    }
    default:
      fail("a function the server does not implement was answered normally", pdu, len);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // A fresh controller per input: a crash reproduces from its input alone.
  const auto rig = std::make_unique<Rig>();
  (void)read_image(*rig, data, 0);  // the initial image is in range too
  std::size_t i = 0;
  for (int records = 0; i + 2 <= size && records < 16; ++records) {
    const std::uint8_t flags = data[i];
    const std::size_t len = std::min<std::size_t>(data[i + 1], size - i - 2);
    const std::uint8_t* pdu = data + i + 2;
    i += 2 + len;

    const std::uint16_t ids[] = {1, 2, ModbusCore::kRtuClient, ModbusCore::kRtuClient};
    const ClientInfo client{ids[flags & 3], (flags & 3) < 2 ? 0x7F000001u + (flags & 1u) : 0u,
                            (flags & 3) == 3};
    if (flags & 4) rig->core.client_closed(client.id);

    const Image before = read_image(*rig, pdu, len);
    // Sized exactly: a reply longer than kMaxPdu is an overflow that ASan reports.
    const auto out = std::make_unique<std::uint8_t[]>(ModbusCore::kMaxPdu);
    const std::size_t n = rig->core.handle(client, pdu, len, out.get());
    ORACLE(n <= ModbusCore::kMaxPdu, "reply longer than a PDU");
    if (len == 0 || client.broadcast) {
      ORACLE(n == 0, "answered a broadcast or an empty request");
    } else {
      const std::uint8_t fc = pdu[0];
      ORACLE(n >= 2, "reply shorter than two bytes");
      if (fc & 0x80)
        ORACLE(n == 2 && out[0] == fc && out[1] == 0x01,
               "a function code >= 0x80 not refused with 01");
      if (out[0] == static_cast<std::uint8_t>(fc | 0x80)) {
        ORACLE(n == 2, "exception reply longer than two bytes");
        ORACLE(known_exception(out[1]), "exception code outside 01 02 03 04 06 0B");
        if (!implemented(fc)) ORACLE(out[1] == 0x01, "an unknown function not refused with 01");
        const Image after = read_image(*rig, pdu, len);
        ORACLE(after == before, "a refused request changed the image");
      } else {
        ORACLE(out[0] == fc, "reply does not echo the function code");
        check_reply(pdu, len, out.get(), n);
        const Image after = read_image(*rig, pdu, len);
        if (fc == 6) {
          const std::uint16_t a = be16(pdu + 1);
          ORACLE(a >= kImageFirst && a < kImageFirst + kImageCount,
                 "function 6 accepted outside the image");
          ORACLE(std::memcmp(after.words + 2 * (a - kImageFirst), pdu + 3, 2) == 0,
                 "function 6 accepted but does not read back as written");
        }
      }
    }
    rig->step();
    (void)read_image(*rig, pdu, len);  // also after a broadcast, which is not answered
  }
  return 0;
}
