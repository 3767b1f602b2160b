// The CANopen cycle allocates nothing: the master's cycle and the virtual bus with the simulated
// drive, over enable, a moving target, 1 % lost frames, a late TPDO, an EMCY fault and its
// reset; and the controller's cycle on the backend "cia402" through its power requests (enable,
// quick stop, a drive fault and the controller's reset, enable again). Every global operator new
// and delete is replaced in this binary (its own executable: the replacement is process-wide); the
// news count while armed. All of them, with malloc and free, so that a sanitizer's allocator (which
// brings its own) sees each block paired.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <new>

#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/controller/controller.hpp"
#include "rig.hpp"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<std::uint64_t> g_news{0};
}  // namespace

// GCC sees free() on what it takes for a new-expression's pointer in the replacements below
// (they are that allocator): not a mismatch here.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace {
void* counted(std::size_t bytes, std::size_t align = 0) {
  if (g_counting.load(std::memory_order_relaxed)) g_news.fetch_add(1, std::memory_order_relaxed);
  if (bytes == 0) bytes = 1;
  return align > alignof(std::max_align_t)
             ? std::aligned_alloc(align, (bytes + align - 1) / align * align)
             : std::malloc(bytes);
}
void* counted_or_throw(std::size_t bytes, std::size_t align = 0) {
  if (void* p = counted(bytes, align)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t n) { return counted_or_throw(n); }
void* operator new[](std::size_t n) { return counted_or_throw(n); }
void* operator new(std::size_t n, std::align_val_t a) {
  return counted_or_throw(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return counted_or_throw(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return counted(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return counted(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

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

TEST(CanopenNoAlloc, TheControllersPowerRequestsThroughTheBackendAllocateNothing) {
  namespace reg = maglead::registers;
  const auto bit = [](int b) { return static_cast<std::uint16_t>(1U << b); };
  Cia402BackendOptions o;
  o.sim_drop_fraction = 0.01;
  Cia402Hardware hw(paper_like_plant().actuator, o,
                    std::make_unique<SimulatedActuator>(paper_like_plant(), 3, 0.02));
  controller::ControllerConfig c;
  c.actuator = paper_like_plant().actuator;
  controller::Controller ctl(c, hw);
  controller::CommandImage image = ctl.initial_image();
  // The control words posted at these cycles: enable, stop, release, (a drive fault at 400),
  // enable low and reset, enable again.
  struct Post {
    int cycle;
    std::uint16_t control_word;
  };
  const Post posts[] = {{10, bit(reg::kEnable)},
                        {100, static_cast<std::uint16_t>(bit(reg::kEnable) | bit(reg::kStop))},
                        {200, bit(reg::kEnable)},
                        {500, 0},
                        {501, bit(reg::kFaultReset)},
                        {600, 0},
                        {601, bit(reg::kEnable)}};
  std::uint64_t cycles_in_fault = 0;
  g_news = 0;
  g_counting = true;
  for (int k = 0; k < 800; ++k) {
    for (const Post& p : posts) {
      if (p.cycle != k) continue;
      image.control_word = p.control_word;
      (void)ctl.post(controller::Command{image, false});
    }
    if (k == 400) hw.simulated_drive()->inject_fault(0x2310, 0.0);  // at once: over-current
    ctl.step(k * 1e-3);
    cycles_in_fault +=
        ctl.snapshot().drive_state == static_cast<std::uint16_t>(reg::DriveState::fault);
  }
  g_counting = false;
  EXPECT_EQ(g_news.load(), 0U);
  EXPECT_GT(cycles_in_fault, 0U);
  EXPECT_EQ(ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_EQ(hw.master().feedback().state, DriveState::operation_enabled);
}

}  // namespace
}  // namespace maglead::canopen
