// The SDO client against the simulated drive's server (expedited, segmented, the server's
// aborts) and against scripted servers that misbehave (the client's own aborts).
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "maglead/canopen/protocol.hpp"
#include "maglead/canopen/sdo_client.hpp"
#include "maglead/canopen/simulated_drive.hpp"
#include "maglead/canopen/virtual_bus.hpp"

namespace maglead::canopen {
namespace {

constexpr double sdo_timeout_s = 0.05;

// The simulated drive booted and pre-operational, with an SDO client on node 0.
struct DriveOnBus {
  DriveOnBus() : actuator(paper_like_plant(), 7, 0.02), drive(bus, actuator), port(bus.attach(0)) {
    bus.advance_to(1e-3);
    CanFrame boot;
    while (port.receive(boot, bus.now_s()) == CanStatus::ok) {
    }
  }
  VirtualCanBus bus;
  SimulatedActuator actuator;
  SimulatedCia402Drive drive;
  VirtualCanPort& port;
  SdoClient sdo{port, 1, sdo_timeout_s};
};

std::vector<std::uint8_t> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

TEST(Sdo, ExpeditedDownloadAndUploadOfEachWidth) {
  DriveOnBus d;
  const std::vector<std::uint8_t> mode{8};
  ASSERT_TRUE(d.sdo.download(0x6060, 0, mode).ok());
  std::vector<std::uint8_t> got;
  ASSERT_TRUE(d.sdo.upload(0x6061, 0, got).ok());  // the mode display follows the mode
  EXPECT_EQ(got, mode);
  const std::vector<std::uint8_t> period_ms{0xE8, 0x03};  // 1000 ms, 16 bit
  ASSERT_TRUE(d.sdo.download(0x1017, 0, period_ms).ok());
  ASSERT_TRUE(d.sdo.upload(0x1017, 0, got).ok());
  EXPECT_EQ(got, period_ms);
  ASSERT_TRUE(d.sdo.upload(0x1018, 1, got).ok());
  EXPECT_EQ(got, (std::vector<std::uint8_t>{0xFB, 0, 0, 0}));
}

TEST(Sdo, SegmentedUploadOfTheDeviceName) {
  DriveOnBus d;
  std::vector<std::uint8_t> got;
  ASSERT_TRUE(d.sdo.upload(0x1008, 0, got).ok());
  EXPECT_EQ(std::string(got.begin(), got.end()), "maglead simulated CiA 402 drive");  // 5 segments
}

TEST(Sdo, SegmentedDownloadThenUploadReturnsTheSameBytes) {
  DriveOnBus d;
  for (const std::string text : {"", "seven!!", "a note longer than seven bytes, 41 of them"}) {
    ASSERT_TRUE(d.sdo.download(0x2001, 0, bytes_of(text)).ok()) << text;
    std::vector<std::uint8_t> got;
    ASSERT_TRUE(d.sdo.upload(0x2001, 0, got).ok());
    EXPECT_EQ(std::string(got.begin(), got.end()), text);
  }
}

struct ServerAbort {
  bool upload;
  std::uint16_t index;
  std::uint8_t sub;
  std::vector<std::uint8_t> data;
  std::uint32_t code;
  const char* text;
};

TEST(Sdo, EveryAbortOfTheServerArrivesWithItsCodeAndText) {
  const std::vector<ServerAbort> cases{
      {true, 0x1234, 0, {}, 0x06020000, "object does not exist in the object dictionary"},
      {true, 0x1018, 7, {}, 0x06090011, "sub-index does not exist"},
      {false, 0x6041, 0, {0, 0}, 0x06010002, "attempt to write a read only object"},
      {false, 0x6060, 0, {8, 0}, 0x06070012, "length of service parameter too high"},
      {false, 0x6040, 0, {6}, 0x06070013, "length of service parameter too low"},
      {false, 0x6060, 0, {42}, 0x06090030, "invalid value for parameter"},
      {false, 0x1A00, 1, {0x10, 0, 0x41, 0x60}, 0x08000022, "present device state"},
      {false, 0x607A, 0, std::vector<std::uint8_t>(9, 1), 0x06070010, "does not match"},
      {false, 0x2001, 0, std::vector<std::uint8_t>(65, 1), 0x06070012, "too high"},
  };
  for (const auto& c : cases) {
    DriveOnBus d;
    std::vector<std::uint8_t> got;
    const SdoResult r =
        c.upload ? d.sdo.upload(c.index, c.sub, got) : d.sdo.download(c.index, c.sub, c.data);
    EXPECT_EQ(r.status, SdoStatus::aborted_by_server) << std::hex << c.index;
    EXPECT_EQ(r.abort_code, c.code) << std::hex << c.index;
    const std::string said = describe_sdo(r, c.upload, c.index, c.sub);
    EXPECT_NE(said.find(c.text), std::string::npos) << said;
    EXPECT_NE(said.find("aborted by the drive"), std::string::npos) << said;
  }
}

TEST(Sdo, PdoMappingRulesOfTheServer) {
  DriveOnBus d;
  const auto u32 = [](std::uint32_t v) {
    return std::vector<std::uint8_t>{
        static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
        static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
  };
  ASSERT_TRUE(d.sdo.download(0x1400, 1, u32(0x80000201)).ok());  // RPDO1 invalid: mappable
  ASSERT_TRUE(d.sdo.download(0x1600, 1, u32(0x60410010)).ok());  // statusword into an RPDO
  EXPECT_EQ(d.sdo.download(0x1600, 0, std::vector<std::uint8_t>{1}).abort_code, 0x06040041U);
  ASSERT_TRUE(d.sdo.download(0x1800, 1, u32(0x80000181)).ok());
  for (std::uint8_t s = 1; s <= 3; ++s)
    ASSERT_TRUE(d.sdo.download(0x1A00, s, u32(0x60640020)).ok());  // 3 x 32 bits
  EXPECT_EQ(d.sdo.download(0x1A00, 0, std::vector<std::uint8_t>{3}).abort_code, 0x06040042U);
  EXPECT_EQ(d.sdo.download(0x1A00, 0, std::vector<std::uint8_t>{2}).abort_code, 0U);
}

// A server scripted by a function from the request to the answer (or none).
class ScriptedServer final : public VirtualDevice {
 public:
  using Script = std::function<bool(const CanFrame& request, CanFrame& answer)>;
  ScriptedServer(VirtualCanBus& bus, Script script)
      : port_(bus.attach(1)), script_(std::move(script)) {
    bus.add_device(*this);
  }
  void poll(double now_s) noexcept override {
    CanFrame f;
    while (port_.receive(f, now_s) == CanStatus::ok) {
      if (f.id != cob_sdo_rx + 1) continue;
      requests.push_back(f);
      CanFrame answer;
      answer.id = cob_sdo_tx + 1;
      answer.len = 8;
      if (script_(f, answer)) port_.send(answer);
    }
  }
  std::vector<CanFrame> requests;  // all the client sent, its aborts included

 private:
  VirtualCanPort& port_;
  Script script_;
};

// The server's answer to an initiate request: command byte, the request's index and sub, data.
void answer_as(const CanFrame& request, CanFrame& answer, std::uint8_t command,
               std::uint32_t data) {
  answer.data[0] = command;
  for (int i = 1; i <= 3; ++i)
    answer.data[static_cast<std::size_t>(i)] = request.data[static_cast<std::size_t>(i)];
  put_le(answer.data.data() + 4, 4, data);
}

struct ClientCase {
  const char* what;
  bool upload;
  ScriptedServer::Script script;
  SdoStatus status;
  std::uint32_t code;
};

TEST(Sdo, TheClientAbortsWhatDoesNotFitAndSaysWhy) {
  const std::vector<ClientCase> cases{
      {"no answer", true, [](const CanFrame&, CanFrame&) { return false; }, SdoStatus::timeout,
       0x05040000},
      {"a download's answer to an upload", true,
       [](const CanFrame& r, CanFrame& a) {
         answer_as(r, a, 0x60, 0);
         return true;
       },
       SdoStatus::protocol_error, 0x05040001},
      {"the wrong object", true,
       [](const CanFrame& r, CanFrame& a) {
         answer_as(r, a, 0x43, 0);
         a.data[1] ^= 1;
         return true;
       },
       SdoStatus::protocol_error, 0x05040001},
      {"an upload segment with the toggle bit set first", true,
       [](const CanFrame& r, CanFrame& a) {
         if ((r.data[0] & 0xE0) == 0x40)
           answer_as(r, a, 0x41, 14);  // segmented, 14 bytes
         else
           a.data[0] = 0x10;  // toggle 1 where 0 is due
         return true;
       },
       SdoStatus::toggle_error, 0x05030000},
      {"a download segment acknowledged with the wrong toggle", false,
       [](const CanFrame& r, CanFrame& a) {
         if ((r.data[0] & 0xE0) == 0x20)
           answer_as(r, a, 0x60, 0);
         else
           a.data[0] = 0x30;  // download segment answer, toggle 1 where 0 is due
         return true;
       },
       SdoStatus::toggle_error, 0x05030000},
      {"an upload longer than the client takes", true,
       [](const CanFrame& r, CanFrame& a) {
         answer_as(r, a, 0x41, 5000);
         return true;
       },
       SdoStatus::too_large, 0x05040005},
      {"segments that do not add up to the announced size", true,
       [](const CanFrame& r, CanFrame& a) {
         if ((r.data[0] & 0xE0) == 0x40)
           answer_as(r, a, 0x41, 14);
         else
           a.data[0] = 0x01;  // last segment, 7 bytes: 7 of 14
         return true;
       },
       SdoStatus::protocol_error, 0x08000000},
  };
  for (const auto& c : cases) {
    VirtualCanBus bus;
    ScriptedServer server(bus, c.script);
    VirtualCanPort& port = bus.attach(0);
    SdoClient sdo(port, 1, sdo_timeout_s);
    std::vector<std::uint8_t> got;
    const double start_s = bus.now_s();
    const SdoResult r = c.upload ? sdo.upload(0x2001, 0, got)
                                 : sdo.download(0x2001, 0, std::vector<std::uint8_t>(10, 7));
    EXPECT_EQ(r.status, c.status) << c.what;
    EXPECT_EQ(r.abort_code, c.code) << c.what;
    EXPECT_LE(bus.now_s() - start_s, 2 * sdo_timeout_s) << c.what;
    // The server heard the abort, with the same code and the object's index.
    bus.advance_to(bus.now_s() + 1e-3);
    ASSERT_FALSE(server.requests.empty()) << c.what;
    const CanFrame& last = server.requests.back();
    EXPECT_EQ(last.data[0], 0x80) << c.what;
    EXPECT_EQ(get_le(last.data.data() + 1, 2), 0x2001U) << c.what;
    EXPECT_EQ(get_le(last.data.data() + 4, 4), c.code) << c.what;
    EXPECT_NE(describe_sdo(r, c.upload, 0x2001, 0).find("aborted by the master"),
              std::string::npos);
  }
}

TEST(Sdo, ATimeoutTakesItsTimeAndNoMore) {
  VirtualCanBus bus;
  VirtualCanPort& port = bus.attach(0);
  SdoClient sdo(port, 9, sdo_timeout_s);
  std::vector<std::uint8_t> got;
  EXPECT_EQ(sdo.upload(0x1000, 0, got).status, SdoStatus::timeout);
  EXPECT_NEAR(bus.now_s(), sdo_timeout_s, 60e-6);  // within a tick of the bus
  EXPECT_EQ(std::string(sdo_abort_text(0x05040000)), "SDO protocol timed out");
  EXPECT_EQ(std::string(sdo_abort_text(0x12345678)), "unknown abort code");
}

}  // namespace
}  // namespace maglead::canopen
