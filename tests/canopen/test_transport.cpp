// The CAN transports: the virtual bus's delivery, clock and fault injection; SocketCAN's
// refusal without an interface and its reading of error frames; the bus-load arithmetic.
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>

#include <stdexcept>
#include <string>

#include "maglead/canopen/socketcan_bus.hpp"
#include "maglead/canopen/virtual_bus.hpp"

namespace maglead::canopen {
namespace {

CanFrame frame(std::uint32_t id, std::uint8_t first_byte = 0) {
  CanFrame f;
  f.id = id;
  f.len = 1;
  f.data[0] = first_byte;
  return f;
}

TEST(VirtualBus, DeliversToEveryOtherPortAfterItsLatencyNotToTheSender) {
  VirtualBusOptions o;
  o.latency_s = 200e-6;
  o.tick_s = 50e-6;
  VirtualCanBus bus(o);
  VirtualCanPort& a = bus.attach(0);
  VirtualCanPort& b = bus.attach(1);
  VirtualCanPort& c = bus.attach(2);
  ASSERT_EQ(a.send(frame(0x123, 42)), CanStatus::ok);
  CanFrame got;
  EXPECT_EQ(b.receive(got, bus.now_s()), CanStatus::timeout);  // not yet on the wire's far end
  const double sent_s = bus.now_s();
  ASSERT_EQ(b.receive(got, sent_s + 1e-3), CanStatus::ok);
  EXPECT_EQ(got.id, 0x123U);
  EXPECT_EQ(got.data[0], 42);
  // Delivered at the first tick at or after the latency, not before and not a tick later.
  EXPECT_GE(bus.now_s() - sent_s, o.latency_s - 1e-9);
  EXPECT_LE(bus.now_s() - sent_s, o.latency_s + o.tick_s + 1e-9);
  EXPECT_EQ(c.receive(got, bus.now_s()), CanStatus::ok);
  EXPECT_EQ(a.receive(got, bus.now_s()), CanStatus::timeout);
}

TEST(VirtualBus, ReceiveWaitsUntilItsDeadlineAndNoLonger) {
  VirtualCanBus bus;
  VirtualCanPort& a = bus.attach(0);
  CanFrame got;
  EXPECT_EQ(a.receive(got, 2e-3), CanStatus::timeout);
  EXPECT_GE(bus.now_s(), 2e-3 - 1e-9);
  EXPECT_LT(bus.now_s(), 2e-3 + 50e-6 + 1e-9);
  // A deadline already past only looks: time does not move.
  const double before_s = bus.now_s();
  EXPECT_EQ(a.receive(got, 0.0), CanStatus::timeout);
  EXPECT_EQ(bus.now_s(), before_s);
}

int dropped_of(std::uint64_t seed, int frames) {
  VirtualBusOptions o;
  o.drop_fraction = 0.01;
  o.seed = seed;
  o.queue_frames = 4;
  VirtualCanBus bus(o);
  VirtualCanPort& a = bus.attach(0);
  bus.attach(1);
  for (int i = 0; i < frames; ++i) a.send(frame(0x200));
  EXPECT_EQ(bus.dropped() + bus.carried(), static_cast<std::uint64_t>(frames));
  return static_cast<int>(bus.dropped());
}

TEST(VirtualBus, DropsItsFractionReproduciblyFromTheSeed) {
  constexpr int frames = 20000;
  const int dropped = dropped_of(3, frames);
  // Binomial(20000, 0.01): mean 200, standard deviation 14; five of them either side.
  EXPECT_GT(dropped, 200 - 5 * 14);
  EXPECT_LT(dropped, 200 + 5 * 14);
  EXPECT_EQ(dropped_of(3, frames), dropped);
  EXPECT_NE(dropped_of(4, frames), dropped);  // another seed, another sequence
}

TEST(VirtualBus, ASilencedNodeReachesNobodyFromItsTime) {
  VirtualCanBus bus;
  VirtualCanPort& master = bus.attach(0);
  VirtualCanPort& drive = bus.attach(5);
  bus.silence(5, 1e-3);
  drive.send(frame(0x185));
  bus.advance_to(1.2e-3);
  drive.send(frame(0x185));
  master.send(frame(0x205));  // the others still speak
  CanFrame got;
  ASSERT_EQ(master.receive(got, 2e-3), CanStatus::ok);
  EXPECT_EQ(master.receive(got, 3e-3), CanStatus::timeout);
  EXPECT_EQ(bus.silenced(), 1U);
  EXPECT_EQ(drive.receive(got, 3e-3), CanStatus::ok);
  EXPECT_EQ(got.id, 0x205U);
}

TEST(VirtualBus, AFullQueueLosesFramesAndCountsThem) {
  VirtualBusOptions o;
  o.queue_frames = 3;
  VirtualCanBus bus(o);
  VirtualCanPort& a = bus.attach(0);
  VirtualCanPort& b = bus.attach(1);
  for (std::uint8_t i = 0; i < 5; ++i) a.send(frame(0x100, i));
  EXPECT_EQ(b.overflows(), 2U);
  CanFrame got;
  for (std::uint8_t i = 0; i < 3; ++i) {
    ASSERT_EQ(b.receive(got, 1e-3), CanStatus::ok);
    EXPECT_EQ(got.data[0], i);  // the oldest kept, in order
  }
}

TEST(VirtualBus, RefusesSettingsWithoutMeaning) {
  VirtualBusOptions o;
  o.drop_fraction = 1.0;
  EXPECT_THROW(VirtualCanBus{o}, std::invalid_argument);
  o.drop_fraction = 0.0;
  o.tick_s = 0.0;
  EXPECT_THROW(VirtualCanBus{o}, std::invalid_argument);
}

TEST(SocketCan, AMissingInterfaceIsRefusedByNameWithHowToBringOneUp) {
  try {
    SocketCanBus bus("mlnocan7");
    FAIL() << "opened a CAN interface that does not exist";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("\"mlnocan7\" does not exist"), std::string::npos) << what;
    EXPECT_NE(what.find("ip link set mlnocan7 up type can bitrate 1000000"), std::string::npos)
        << what;
  }
  // The hint brings the interface up at the drive's bit rate (drive.toml), not a fixed one.
  try {
    SocketCanBus bus("mlnocan7", 500'000);
    FAIL() << "opened a CAN interface that does not exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("up type can bitrate 500000"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(SocketCanBus(""), std::runtime_error);
  // A name the kernel cannot hold says how long one may be.
  try {
    SocketCanBus bus("an-interface-name-too-long");
    FAIL() << "took a name longer than the kernel's";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("1 to 15 characters"), std::string::npos) << e.what();
  }
}

TEST(SocketCan, ErrorFramesAreReportedAndBusOffTellsItself) {
  EXPECT_EQ(classify_error_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF), CanStatus::bus_off);
  EXPECT_EQ(classify_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL), CanStatus::error_frame);
  EXPECT_EQ(classify_error_frame(CAN_ERR_FLAG | CAN_ERR_PROT | CAN_ERR_BUSERROR),
            CanStatus::error_frame);
}

// The kernel's filter on a shared bus: the drive's own frames pass, whole ids only (a frame of
// another node differs in the low bits), standard frames only, no remote requests.
TEST(SocketCan, TheReceiveFilterPassesTheDrivesFramesOnly) {
  const auto filters = drive_receive_filter(5);
  const auto passes = [&](std::uint32_t can_id) {
    for (const CanIdFilter& f : filters)
      if ((can_id & f.mask) == (f.id & f.mask)) return true;
    return false;
  };
  for (std::uint32_t id : {0x085U, 0x185U, 0x285U, 0x585U, 0x705U}) EXPECT_TRUE(passes(id)) << id;
  for (std::uint32_t id : {0x086U, 0x184U, 0x186U, 0x385U, 0x605U, 0x080U, 0x000U, 0x705U | 0x10U})
    EXPECT_FALSE(passes(id)) << id;
  EXPECT_FALSE(passes(0x185U | CAN_EFF_FLAG));
  EXPECT_FALSE(passes(0x185U | CAN_RTR_FLAG));
}

TEST(CanFrames, WorstCaseLengthsAreTheLiterature) {
  // Davis et al. 2007: 135 bits for 8 data bytes, 55 for none (stuff bits and IFS included).
  EXPECT_EQ(frame_bits_worst(8), 135);
  EXPECT_EQ(frame_bits_worst(0), 55);
}

}  // namespace
}  // namespace maglead::canopen
