#pragma once
// Runs Controller::step at the sample rate on its own thread, on absolute deadlines of
// CLOCK_MONOTONIC (a late cycle does not shift the ones after it), and logs cycle periods
// on request for jitter statistics.
#include <atomic>
#include <thread>
#include <vector>

#include "maglead/controller/controller.hpp"

namespace maglead::controller {

class LoopRunner {
 public:
  /// period_log_capacity: how many periods one log can hold (allocated here, not in the loop).
  explicit LoopRunner(Controller& controller, std::size_t period_log_capacity = 1 << 18);
  ~LoopRunner();
  LoopRunner(const LoopRunner&) = delete;
  LoopRunner& operator=(const LoopRunner&) = delete;

  void start();  // throws std::runtime_error if the thread cannot start
  void stop();
  bool realtime() const { return realtime_.load(); }  // SCHED_FIFO granted

  /// Start logging cycle periods from the next cycle; end_period_log() returns them [s].
  void begin_period_log();
  std::vector<double> end_period_log();

 private:
  void run();
  Controller& controller_;
  std::thread thread_;
  std::atomic<bool> running_{false}, realtime_{false};
  std::vector<float> log_;
  std::atomic<bool> logging_{false};
  std::atomic<std::size_t> log_count_{0};
};

}  // namespace maglead::controller
