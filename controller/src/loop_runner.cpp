#include "maglead/controller/loop_runner.hpp"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cmath>
#include <stdexcept>

namespace maglead::controller {
namespace {

std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

LoopRunner::LoopRunner(Controller& controller, std::size_t period_log_capacity)
    : controller_(controller), log_(period_log_capacity) {}

LoopRunner::~LoopRunner() { stop(); }

void LoopRunner::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void LoopRunner::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

void LoopRunner::begin_period_log() {
  logging_.store(false);
  log_count_.store(0);
  logging_.store(true);
}

std::vector<double> LoopRunner::end_period_log() {
  logging_.store(false);
  // Let a cycle that saw logging_ still true finish its write.
  timespec ts{0, 3'000'000};
  nanosleep(&ts, nullptr);
  const std::size_t n = std::min(log_count_.load(std::memory_order_acquire), log_.size());
  return std::vector<double>(log_.begin(), log_.begin() + static_cast<std::ptrdiff_t>(n));
}

void LoopRunner::run() {
  // Real-time priority when the system grants it; the loop is correct without, just noisier.
  sched_param sp{};
  sp.sched_priority = 50;
  realtime_.store(pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0);

  const double rate = controller_.config().actuator.sample_rate_hz;
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / rate));
  const std::int64_t t0 = now_ns();
  std::int64_t next = t0, last_start = t0;
  bool first = true;
  while (running_.load(std::memory_order_relaxed)) {
    const std::int64_t start = now_ns();
    const std::int64_t late = start - next;
    controller_.step(static_cast<double>(next - t0) * 1e-9, static_cast<double>(late) * 1e-9);
    if (!first && logging_.load(std::memory_order_relaxed)) {
      const std::size_t i = log_count_.load(std::memory_order_relaxed);
      if (i < log_.size()) {
        log_[i] = static_cast<float>(static_cast<double>(start - last_start) * 1e-9);
        log_count_.store(i + 1, std::memory_order_release);
      }
    }
    first = false;
    last_start = start;
    next += period_ns;
    // More than a few periods behind (suspended, debugger): skip ahead instead of bursting.
    if (now_ns() - next > 5 * period_ns) next = now_ns() + period_ns;
    timespec ts{static_cast<time_t>(next / 1'000'000'000), static_cast<long>(next % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
}

}  // namespace maglead::controller
