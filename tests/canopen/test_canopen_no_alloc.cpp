// The CANopen cycle allocates nothing: the master's cycle and the virtual bus with the simulated
// drive, over enable, a moving target, 1 % lost frames, a late TPDO, an EMCY fault and its
// reset; and the controller's cycle on the backend "cia402" through its power requests (enable,
// quick stop, a drive fault and the controller's reset, enable again). Every global operator new
// and delete is replaced in this binary (counting_new.cpp; its own executable: the replacement is
// process-wide).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <new>

#include "counting_new.hpp"
#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/controller/controller.hpp"
#include "rig.hpp"

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
  {
    const test_support::AllocationCount probe_count;
    // A call of operator new, not a new-expression: the compiler may elide the latter.
    void* volatile probe = ::operator new(sizeof(int));
    ::operator delete(probe);
    ASSERT_EQ(probe_count.count(), 1U);
  }

  bool alarm_said = false;
  const test_support::AllocationCount counted;
  for (int k = 0; k < 3000; ++k) {
    alarm_said |= rig.master.fault() == MasterFault::drive_fault &&
                  std::strcmp(rig.master.alarm_text(), "sensor (encoder) error") == 0;
    if (k == 1500) rig.master.request(DriveRequest::fault_reset);
    if (k == 1600) rig.master.request(DriveRequest::enabled);
    rig.master.set_target_counts(start_counts +
                                 static_cast<std::int32_t>(500 * std::sin(k * 1e-3)));
    rig.cycles(1);
  }
  EXPECT_EQ(counted.count(), 0U);
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
  const test_support::AllocationCount counted;
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
  EXPECT_EQ(counted.count(), 0U);
  EXPECT_GT(cycles_in_fault, 0U);
  EXPECT_EQ(ctl.snapshot().drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_EQ(hw.master().feedback().state, DriveState::operation_enabled);
}

}  // namespace
}  // namespace maglead::canopen
