// LoopRunner on a fake clock: absolute deadlines, lateness and overruns, skipping ahead after
// a stall, the period log, and the loop on its own thread read by others while it runs
// (label `threads`: these also run under ThreadSanitizer). Nothing here waits on real time.
#include <gtest/gtest.h>

#include <thread>

#include "fake_clock.hpp"
#include "fake_hardware.hpp"
#include "maglead/controller/controller.hpp"
#include "maglead/controller/loop_runner.hpp"

using namespace maglead;
using namespace maglead::controller;
using maglead::testing::FakeLoopClock;
using maglead::testing::FaultInjectingHardware;
namespace reg = maglead::registers;

namespace {

constexpr std::int64_t kPeriod = 1'000'000;  // 1 kHz
constexpr std::int64_t kT0 = 5'000'000'000;  // FakeLoopClock's start

struct RunnerRig {
  SimulatedActuator plant{paper_like_plant(), 9, 0.02};
  FaultInjectingHardware hw{plant};
  ControllerConfig cfg;
  Controller ctl{cfg, hw};
  FakeLoopClock clock;
  LoopRunner loop{ctl, clock, 4096};
};

}  // namespace

TEST(LoopRunner, SleepsToAbsoluteDeadlinesAndStepsOnScheduledTime) {
  RunnerRig rig;
  rig.clock.wake_late(2, kPeriod * 4 / 10);  // cycle 4 starts 0.4 periods late
  rig.loop.run_cycles(10);
  const auto& d = rig.clock.deadlines();
  ASSERT_EQ(d.size(), 10u);
  for (std::size_t k = 0; k < d.size(); ++k)
    EXPECT_EQ(d[k], kT0 + static_cast<std::int64_t>(k + 1) * kPeriod) << k;
  const Snapshot s = rig.ctl.snapshot();
  EXPECT_EQ(s.cycle, 10u);
  EXPECT_NEAR(s.t_s, 9e-3, 1e-12);  // the controller's time is the schedule, not the wake-up
  EXPECT_NEAR(s.late_max_s, 0.4e-3, 1e-12);
  EXPECT_EQ(s.overrun_count, 0u);  // late, but within its period
}

TEST(LoopRunner, AStartMoreThanAPeriodLateIsAnOverrunAndShiftsNothing) {
  RunnerRig rig;
  rig.clock.wake_late(4, kPeriod * 3 / 2);  // cycle 6 starts 1.5 periods late
  rig.loop.run_cycles(20);
  const Snapshot s = rig.ctl.snapshot();
  EXPECT_EQ(s.overrun_count, 1u);
  EXPECT_NEAR(s.late_max_s, 1.5e-3, 1e-12);
  const auto& d = rig.clock.deadlines();
  for (std::size_t k = 0; k < d.size(); ++k)
    EXPECT_EQ(d[k], kT0 + static_cast<std::int64_t>(k + 1) * kPeriod) << k;
  EXPECT_EQ(rig.loop.stats().skips, 0u);
}

TEST(LoopRunner, AfterAStallItSkipsAheadInsteadOfBursting) {
  RunnerRig rig;
  rig.clock.wake_late(4, 100 * kPeriod);  // suspended for 100 periods
  rig.loop.run_cycles(20);
  EXPECT_EQ(rig.loop.stats().skips, 1u);
  const auto& d = rig.clock.deadlines();
  // Cycle 6 started 100 periods late; its successor is due one period after it ended, and
  // every later one a period after that: no burst of 100 catch-up cycles.
  const std::int64_t resumed = kT0 + 5 * kPeriod + 100 * kPeriod;
  EXPECT_EQ(d[5], resumed + kPeriod);
  for (std::size_t k = 6; k < d.size(); ++k) EXPECT_EQ(d[k] - d[k - 1], kPeriod) << k;
  EXPECT_EQ(rig.ctl.snapshot().overrun_count, 1u);
}

TEST(LoopRunner, PeriodLogHoldsTheMeasuredPeriods) {
  RunnerRig rig;
  rig.loop.run_cycles(3);
  rig.loop.begin_period_log();
  rig.clock.wake_late(5, kPeriod / 4);
  rig.loop.run_cycles(5);
  const auto log = rig.loop.end_period_log();
  ASSERT_EQ(log.size(), 5u);
  // Sleep 5 woke cycle 7 a quarter period late: that period is 1.25 ms, the next 0.75 ms.
  const double expect[] = {1e-3, 1e-3, 1e-3, 1.25e-3, 0.75e-3};
  for (std::size_t i = 0; i < 5; ++i) EXPECT_NEAR(log[i], expect[i], 1e-9) << i;
}

// The lateness beside each period (what `maglead bench modbus` reports per case).
TEST(LoopRunner, CycleLogHoldsEachCyclesLateness) {
  RunnerRig rig;
  rig.loop.run_cycles(3);
  rig.loop.begin_period_log();
  rig.clock.wake_late(5, kPeriod / 4);
  rig.clock.wake_late(6, kPeriod * 3 / 2);
  rig.loop.run_cycles(5);
  const auto log = rig.loop.end_cycle_log();
  ASSERT_EQ(log.late_s.size(), 5u);
  ASSERT_EQ(log.periods_s.size(), 5u);
  // Cycles 7 and 8 woke a quarter and one and a half periods late; the others on time.
  const double expect[] = {0.0, 0.0, 0.0, 0.25e-3, 1.5e-3};
  for (std::size_t i = 0; i < 5; ++i) EXPECT_NEAR(log.late_s[i], expect[i], 1e-9) << i;
  EXPECT_EQ(rig.ctl.snapshot().overrun_count, 1u);
}

TEST(LoopRunner, RunCyclesIsRefusedWhileTheThreadRuns) {
  RunnerRig rig;
  rig.loop.start();
  EXPECT_THROW(rig.loop.run_cycles(1), std::logic_error);
  rig.loop.stop();
  EXPECT_NO_THROW(rig.loop.run_cycles(1));
}

// The loop on its own thread while this thread posts commands and reads snapshots and stats,
// as the network thread does: every snapshot whole (t_s matches its cycle), commands applied.
TEST(LoopRunner, OnItsThreadTradesCommandsAndSnapshotsWithAnotherThread) {
  RunnerRig rig;
  rig.loop.start();
  CommandImage image = rig.ctl.initial_image();
  image.control_word = 1u << reg::kEnable;
  bool posted = false;
  std::uint64_t last_cycle = 0, posted_at = 0;
  int torn = 0, backwards = 0;
  // Post once the loop is past cycle 100, then read on for 2000 cycles more.
  while (!posted || rig.loop.stats().cycles < posted_at + 2000) {
    const Snapshot s = rig.ctl.snapshot();
    if (s.cycle > 0 && std::llround(s.t_s * 1e3) != static_cast<long long>(s.cycle) - 1) ++torn;
    if (s.cycle < last_cycle) ++backwards;
    last_cycle = s.cycle;
    if (!posted && s.cycle > 100) {
      posted = rig.ctl.post(Command{image, true});
      posted_at = s.cycle;
    }
    std::this_thread::yield();
  }
  rig.loop.stop();
  const LoopStats st = rig.loop.stats();
  const Snapshot s = rig.ctl.snapshot();
  EXPECT_EQ(torn, 0);
  EXPECT_EQ(backwards, 0);
  EXPECT_EQ(s.cycle, st.cycles);
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_EQ(st.hardware_error_cycles, 0u);
  // The clock is only touched by the loop thread; joined now, its record is ours to read.
  const auto& d = rig.clock.deadlines();
  for (std::size_t k = 1; k < d.size(); ++k) ASSERT_EQ(d[k] - d[k - 1], kPeriod) << k;
}

// [runtime] realtime. What is granted depends on the machine's privileges, so these assert
// what holds either way: "off" asks for nothing; "try" starts and reports exactly what it did
// not get; "require" either gets all three or does not start, naming what was refused.
TEST(LoopRunner, RealtimeOffAsksForNothing) {
  RunnerRig rig;
  rig.loop.set_realtime(RealtimePolicy::off);
  rig.loop.start();
  rig.loop.stop();
  const RealtimeGrant& g = rig.loop.realtime_grant();
  EXPECT_FALSE(g.fifo || g.pinned || g.locked);
  EXPECT_TRUE(g.refused.empty());
  EXPECT_FALSE(rig.loop.realtime());
}

TEST(LoopRunner, RealtimeTryStartsAndReportsWhatItDidNotGet) {
  RunnerRig rig;
  rig.loop.set_realtime(RealtimePolicy::attempt);
  rig.loop.start();
  while (rig.loop.stats().cycles < 10) std::this_thread::yield();
  rig.loop.stop();
  const RealtimeGrant& g = rig.loop.realtime_grant();
  EXPECT_EQ(g.refused.find("SCHED_FIFO") == std::string::npos, g.fifo) << g.refused;
  EXPECT_EQ(g.refused.find("pinning") == std::string::npos, g.pinned) << g.refused;
  EXPECT_EQ(g.refused.find("memory lock") == std::string::npos, g.locked) << g.refused;
  EXPECT_EQ(rig.loop.realtime(), g.fifo);
  EXPECT_TRUE(!g.pinned || g.cpu >= 0);
}

TEST(LoopRunner, RealtimeRequireStartsOnlyWithEverything) {
  RunnerRig rig;
  rig.loop.set_realtime(RealtimePolicy::require);
  try {
    rig.loop.start();
    const RealtimeGrant& g = rig.loop.realtime_grant();
    EXPECT_TRUE(g.fifo && g.pinned && g.locked);
    rig.loop.stop();
  } catch (const std::runtime_error& e) {
    const RealtimeGrant& g = rig.loop.realtime_grant();
    EXPECT_FALSE(g.refused.empty());
    EXPECT_NE(std::string(e.what()).find(g.refused), std::string::npos) << e.what();
    EXPECT_EQ(rig.loop.stats().cycles, 0u) << "the loop did not run";
  }
}
