#pragma once
// Runs Controller::step at the sample rate, on its own thread or on the caller's, on absolute
// deadlines of a LoopClock (a late cycle does not shift the ones after it), acts on the
// CycleStatus each step returns, and logs cycle periods on request for jitter statistics.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "maglead/controller/controller.hpp"

namespace maglead::controller {

/// The loop's time: a monotonic clock in nanoseconds and a sleep to an absolute deadline of it.
/// Service uses steady_loop_clock(); tests inject a fake that advances on sleep_until.
class LoopClock {
 public:
  virtual ~LoopClock() = default;
  virtual std::int64_t now_ns() noexcept = 0;
  /// Returns at or after `deadline_ns` (at once if it has passed). Must not allocate.
  virtual void sleep_until(std::int64_t deadline_ns) noexcept = 0;
};

/// std::chrono::steady_clock, slept on with clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME),
/// the clock steady_clock reads on Linux. Stateless; one instance serves every runner.
LoopClock& steady_loop_clock() noexcept;

/// `[runtime] realtime` in config/network.toml: what the loop thread asks of Linux.
/// off: nothing; attempt ("try"): SCHED_FIFO, the thread pinned to one core, mlockall, and
/// whatever is refused is reported; require: the loop does not start without all three.
enum class RealtimePolicy : std::uint8_t { off, attempt, require };
/// "off", "try" or "require"; false otherwise.
bool parse_realtime_policy(const std::string& text, RealtimePolicy& out);

/// What the loop thread got (after start()).
struct RealtimeGrant {
  bool fifo = false;    // SCHED_FIFO
  bool pinned = false;  // bound to cpu
  bool locked = false;  // mlockall(MCL_CURRENT | MCL_FUTURE)
  int cpu = -1;
  std::string refused;  // what was asked and not granted, with the reason ("" = nothing)
};

/// What the runner saw (any thread may read; updated once per cycle).
struct LoopStats {
  std::uint64_t cycles = 0;
  std::uint64_t hardware_error_cycles = 0;       // step() returned CycleStatus::hardware_error
  std::uint64_t first_hardware_error_cycle = 0;  // 1-based cycle number, 0 = none yet
  std::uint64_t skips = 0;  // times the loop was so far behind that it skipped periods
};

class LoopRunner {
 public:
  /// period_log_capacity: how many periods one log can hold (allocated here, not in the loop).
  explicit LoopRunner(Controller& controller, LoopClock& clock = steady_loop_clock(),
                      std::size_t period_log_capacity = 1 << 18);
  ~LoopRunner();
  LoopRunner(const LoopRunner&) = delete;
  LoopRunner& operator=(const LoopRunner&) = delete;

  /// Before start(). Default off. cpu < 0: the last core this process may run on.
  void set_realtime(RealtimePolicy policy, int cpu = -1) {
    policy_ = policy;
    cpu_ = cpu;
  }
  /// Starts the loop thread once it has applied the realtime policy. Throws std::runtime_error
  /// if the thread cannot start, or (policy require) naming what was refused.
  void start();
  void stop();
  bool realtime() const { return realtime_.load(); }              // SCHED_FIFO granted
  const RealtimeGrant& realtime_grant() const { return grant_; }  // after start()

  /// Runs `cycles` cycles on the calling thread (not while started), on the same deadlines
  /// as the thread would; time continues from the previous run.
  void run_cycles(std::uint64_t cycles);

  /// What a failed hardware access does: Controller::step has already latched the fault
  /// (sensor_fault or drive_fault, alarm 5 / 6) and runs its reaction; the runner counts the
  /// cycle and keeps running, so the network still reads the fault and a client can reset it.
  LoopStats stats() const noexcept;

  /// Start logging cycle periods and lateness from the next cycle; end_period_log() returns the
  /// periods [s], end_cycle_log() both.
  struct CycleLog {
    std::vector<double> periods_s;  // start to start
    std::vector<double> late_s;     // start after its deadline
  };
  void begin_period_log();
  std::vector<double> end_period_log() { return end_cycle_log().periods_s; }
  CycleLog end_cycle_log();

 private:
  void run();
  void apply_realtime();
  void cycle() noexcept;
  Controller& controller_;
  LoopClock& clock_;
  std::int64_t period_ns_;
  std::thread thread_;
  std::atomic<bool> running_{false}, realtime_{false};
  RealtimePolicy policy_ = RealtimePolicy::off;
  int cpu_ = -1;
  RealtimeGrant grant_;  // written by the loop thread before it sets set_up_
  std::atomic<bool> set_up_{false};
  // Loop state (the thread that runs cycles).
  bool timed_ = false, logged_one_ = false;
  std::int64_t t0_ = 0, next_ = 0, last_start_ = 0;
  // Stats, written by the loop only.
  std::atomic<std::uint64_t> cycles_{0}, hw_errors_{0}, first_hw_error_{0}, skips_{0};
  // Period and lateness log: the loop appends while logging_; log_count_ publishes the entries.
  std::vector<float> log_, late_log_;
  std::atomic<bool> logging_{false};
  std::atomic<std::size_t> log_count_{0};
};

}  // namespace maglead::controller
