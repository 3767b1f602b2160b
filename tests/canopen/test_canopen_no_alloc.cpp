// The CANopen cycle allocates nothing: the master's cycle and the virtual bus with the simulated
// drive, over enable, a moving target, 1 % lost frames, a late TPDO, an EMCY fault and its
// reset. The global operator new is replaced in this binary (its own executable: the
// replacement is process-wide) and counts while armed. libstdc++'s other forms (new[],
// nothrow) call this one, and its operator delete frees with free(), so one replacement is
// enough.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <new>

#include "rig.hpp"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<std::uint64_t> g_news{0};
}  // namespace

void* operator new(std::size_t bytes) {
  if (g_counting.load(std::memory_order_relaxed)) g_news.fetch_add(1, std::memory_order_relaxed);
  void* p = std::malloc(bytes == 0 ? 1 : bytes);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

namespace maglead::canopen {
namespace {

TEST(CanopenNoAlloc, TheCycleAllocatesNothingThroughFaultsAndTheirReset) {
  VirtualBusOptions o;
  o.drop_fraction = 0.01;
  o.seed = 5;
  testing::Rig rig(o);
  rig.enable();
  ASSERT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
  const std::int32_t start_counts = rig.master.feedback().position_counts;
  rig.drive.delay_tpdo(rig.bus.now_s() + 0.5, 1.5e-3);
  rig.drive.inject_fault(0x7300, rig.bus.now_s() + 1.0);
  // The probe: an allocation here must be counted, or the test proves nothing.
  g_counting = true;
  auto* probe = new int(1);
  g_counting = false;
  delete probe;
  ASSERT_EQ(g_news.exchange(0), 1U);

  bool alarm_said = false;
  g_counting = true;
  for (int k = 0; k < 3000; ++k) {
    alarm_said |= rig.master.fault() == MasterFault::drive_fault &&
                  std::strcmp(rig.master.alarm_text(), "sensor (encoder) error") == 0;
    if (k == 1500) rig.master.request(DriveRequest::fault_reset);
    if (k == 1600) rig.master.request(DriveRequest::enabled);
    rig.master.set_target_counts(start_counts +
                                 static_cast<std::int32_t>(500 * std::sin(k * 1e-3)));
    rig.cycles(1);
  }
  g_counting = false;
  EXPECT_EQ(g_news.load(), 0U);
  // It went through what it says it did. An EMCY lost with the other frames does not lose the
  // alarm: it comes from 0x603F in the TPDO as well.
  EXPECT_TRUE(alarm_said);
  EXPECT_EQ(rig.master.feedback().state, DriveState::operation_enabled);
  EXPECT_GT(rig.bus.dropped(), 0U);
}

}  // namespace
}  // namespace maglead::canopen
