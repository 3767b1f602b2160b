#pragma once
// The digital twin off the loop's critical path. The loop thread's step() pushes the cycle's
// sample into an SPSC queue and returns the latest published results without waiting; a twin
// thread (lower priority than the loop, off its core when pinning is possible) runs
// twin::TwinMonitor on every sample in order and publishes through a seqlock, each result
// tagged with the cycle it belongs to. A full queue, or results older than max_lag_cycles,
// raise `lagging` (status bit twin_lagging): the loop is never late because of the twin.
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "maglead/controller/detail/seqlock.hpp"
#include "maglead/controller/ports/twin_hook.hpp"

namespace maglead::twin {
class TwinMonitor;
struct TwinMonitorConfig;
}  // namespace maglead::twin

namespace maglead::runtime {

struct TwinRunnerOptions {
  // Results may trail the loop by this many cycles before `lagging` is raised. 5 ms keeps the
  // step-out warning (50 ms look-ahead) at least 40 ms ahead of a slip while not lagging.
  std::uint64_t max_lag_cycles = 5;
};

/// Where the twin thread runs (start()). avoid_cpu: the loop's core (-1: none to avoid).
struct TwinPlacement {
  int avoid_cpu = -1;
  int fifo_priority = 0;  // > 0: ask for SCHED_FIFO at this priority (below the loop's)
};

/// What the loop side saw (loop thread writes, any thread reads).
struct TwinRunnerStats {
  std::uint64_t dropped = 0;         // samples not queued (queue full)
  std::uint64_t lagging_cycles = 0;  // cycles that reported lagging
  std::uint64_t max_lag_cycles = 0;  // largest distance between a cycle and its latest result
};

class TwinRunner final : public controller::TwinHook {
 public:
  /// Builds the monitor (allocates; before the loop starts). Throws on a bad model.
  TwinRunner(const twin::TwinMonitorConfig& config, TwinRunnerOptions options = {});
  ~TwinRunner() override;
  TwinRunner(const TwinRunner&) = delete;
  TwinRunner& operator=(const TwinRunner&) = delete;

  /// Starts the twin thread. Throws std::runtime_error if it cannot start. `refused()` then
  /// names what of `placement` was not granted ("" = all of it).
  void start(const TwinPlacement& placement = {});
  void stop();
  const std::string& refused() const { return refused_; }

  /// Loop thread: queue the sample (never waits), return the latest results.
  void step(const controller::TwinSample& in, controller::TwinReport& out) noexcept override;
  void resync(double t_s, double screw_angle_rad, double nut_pos_m) noexcept override;
  void clear_warnings() noexcept override;

  /// Twin side: run the monitor on everything queued; returns how many messages. The thread
  /// calls it; a test without start() calls it to be deterministic.
  std::size_t drain() noexcept;

  TwinRunnerStats stats() const noexcept;

 private:
  enum class Kind : std::uint8_t { sample, resync, clear };
  struct Message {
    Kind kind = Kind::sample;
    controller::TwinSample sample;
  };
  void run();
  void place(const TwinPlacement& placement);
  void process(const Message& m) noexcept;
  void push_control(const Message& m) noexcept;

  std::unique_ptr<twin::TwinMonitor> monitor_;
  TwinRunnerOptions options_;
  // 256 cycles of slack: a twin thread held up for a quarter of a second loses nothing.
  controller::detail::SpscQueue<Message, 256> queue_;
  controller::detail::SeqLock<controller::TwinReport> results_;
  // Loop thread only: a resync / clear that did not fit the queue, pushed again before the next
  // sample (a resync supersedes a clear: it clears the drift history too).
  Message pending_control_{};
  bool has_pending_control_ = false;
  // Loop thread only: the latest results it read. The loop never waits for the twin's seqlock
  // writer: caught mid-write, it keeps these (one cycle older) instead.
  controller::TwinReport latest_{};
  // Twin thread only.
  bool reset_ok_ = true;  // false once a re-sync failed: the twin then reports itself unhealthy
  // Loop thread writes, others read.
  std::atomic<std::uint64_t> dropped_{0}, lagging_cycles_{0}, max_lag_{0};
  std::thread thread_;
  std::atomic<bool> running_{false}, placed_{false};
  std::string refused_;  // written by the twin thread before placed_, read after it
};

}  // namespace maglead::runtime
