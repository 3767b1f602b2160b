#include "maglead/controller/loop_runner.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <stdexcept>

namespace maglead::controller {
namespace {

class SteadyLoopClock final : public LoopClock {
 public:
  std::int64_t now_ns() noexcept override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
  void sleep_until(std::int64_t deadline_ns) noexcept override {
    // libstdc++'s steady_clock is CLOCK_MONOTONIC; an absolute sleep on it does not drift.
    const timespec ts{static_cast<time_t>(deadline_ns / 1'000'000'000),
                      static_cast<long>(deadline_ns % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
};

}  // namespace

bool parse_realtime_policy(const std::string& text, RealtimePolicy& out) {
  if (text == "off")
    out = RealtimePolicy::off;
  else if (text == "try")
    out = RealtimePolicy::attempt;
  else if (text == "require")
    out = RealtimePolicy::require;
  else
    return false;
  return true;
}

LoopClock& steady_loop_clock() noexcept {
  static SteadyLoopClock clock;
  return clock;
}

LoopRunner::LoopRunner(Controller& controller, LoopClock& clock, std::size_t period_log_capacity)
    : controller_(controller),
      clock_(clock),
      period_ns_(static_cast<std::int64_t>(
          std::llround(1e9 / controller.config().actuator.sample_rate_hz))),
      log_(period_log_capacity),
      late_log_(period_log_capacity) {}

LoopRunner::~LoopRunner() { stop(); }

void LoopRunner::start() {
  if (running_.exchange(true)) return;
  set_up_.store(false);
  try {
    thread_ = std::thread([this] {
      apply_realtime();
      const bool go = policy_ != RealtimePolicy::require || grant_.refused.empty();
      if (!go) running_.store(false);
      set_up_.store(true);
      set_up_.notify_one();
      if (go) run();
    });
  } catch (const std::system_error& e) {
    running_.store(false);
    throw std::runtime_error(std::string("control loop: cannot start its thread: ") + e.what());
  }
  set_up_.wait(false);
  if (!running_.load()) {
    thread_.join();
    throw std::runtime_error("control loop: realtime = \"require\" and not granted: " +
                             grant_.refused);
  }
}

void LoopRunner::apply_realtime() {
  grant_ = RealtimeGrant{};
  if (policy_ == RealtimePolicy::off) return;
  std::string refused;
  const auto refuse = [&](const char* what, int err) {
    if (!refused.empty()) refused += ", ";
    refused += std::string(what) + " (" + std::strerror(err) + ")";
  };
  // Pinned to one core: by default the last one this process may use.
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  int cpu = cpu_;
  if (cpu < 0 && sched_getaffinity(0, sizeof allowed, &allowed) == 0)
    for (int c = CPU_SETSIZE - 1; c >= 0 && cpu < 0; --c)
      if (CPU_ISSET(c, &allowed)) cpu = c;
  if (cpu >= 0 && cpu < CPU_SETSIZE) {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu, &one);
    const int err = pthread_setaffinity_np(pthread_self(), sizeof one, &one);
    grant_.pinned = err == 0;
    grant_.cpu = cpu;
    if (err != 0) refuse("pinning to a core", err);
  } else {
    refuse("pinning to a core", EINVAL);
  }
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  // A sanitizer's shadow memory is terabytes of address space: never lock it.
  refused += std::string(refused.empty() ? "" : ", ") + "memory lock (not under a sanitizer)";
#else
  grant_.locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
  if (!grant_.locked) refuse("memory lock", errno);
#endif
  sched_param sp{};
  sp.sched_priority = 50;
  const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  grant_.fifo = err == 0;
  if (err != 0) refuse("SCHED_FIFO", err);
  realtime_.store(grant_.fifo);
  grant_.refused = refused;
}

void LoopRunner::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

void LoopRunner::run_cycles(std::uint64_t cycles) {
  if (running_.load()) throw std::logic_error("LoopRunner::run_cycles while the loop thread runs");
  for (std::uint64_t i = 0; i < cycles; ++i) cycle();
}

LoopStats LoopRunner::stats() const noexcept {
  LoopStats s;
  s.cycles = cycles_.load(std::memory_order_acquire);
  s.hardware_error_cycles = hw_errors_.load(std::memory_order_relaxed);
  s.first_hardware_error_cycle = first_hw_error_.load(std::memory_order_relaxed);
  s.skips = skips_.load(std::memory_order_relaxed);
  return s;
}

void LoopRunner::begin_period_log() {
  logging_.store(false);
  log_count_.store(0);
  logging_.store(true);
}

LoopRunner::CycleLog LoopRunner::end_cycle_log() {
  logging_.store(false);
  // Let a cycle that saw logging_ still true finish its write.
  timespec ts{0, 3'000'000};
  nanosleep(&ts, nullptr);
  const auto n = static_cast<std::ptrdiff_t>(
      std::min(log_count_.load(std::memory_order_acquire), log_.size()));
  return {std::vector<double>(log_.begin(), log_.begin() + n),
          std::vector<double>(late_log_.begin(), late_log_.begin() + n)};
}

void LoopRunner::cycle() noexcept {
  if (!timed_) {
    t0_ = next_ = last_start_ = clock_.now_ns();
    timed_ = true;
  }
  const std::int64_t start = clock_.now_ns();
  const std::int64_t late = start - next_;
  const CycleStatus status =
      controller_.step(static_cast<double>(next_ - t0_) * 1e-9, static_cast<double>(late) * 1e-9);
  const std::uint64_t n = cycles_.load(std::memory_order_relaxed) + 1;
  if (status != CycleStatus::ok) {
    // The controller has latched sensor_fault or drive_fault and runs the reaction; count it.
    if (first_hw_error_.load(std::memory_order_relaxed) == 0)
      first_hw_error_.store(n, std::memory_order_relaxed);
    hw_errors_.store(hw_errors_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  }
  if (logged_one_ && logging_.load(std::memory_order_relaxed)) {
    const std::size_t i = log_count_.load(std::memory_order_relaxed);
    if (i < log_.size()) {
      log_[i] = static_cast<float>(static_cast<double>(start - last_start_) * 1e-9);
      late_log_[i] = static_cast<float>(static_cast<double>(late) * 1e-9);
      log_count_.store(i + 1, std::memory_order_release);
    }
  }
  logged_one_ = true;
  last_start_ = start;
  cycles_.store(n, std::memory_order_release);
  next_ += period_ns_;
  // More than a few periods behind (suspended, debugger): skip ahead instead of bursting.
  const std::int64_t now = clock_.now_ns();
  if (now - next_ > 5 * period_ns_) {
    next_ = now + period_ns_;
    skips_.store(skips_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  }
  clock_.sleep_until(next_);
}

void LoopRunner::run() {
  // The loop is correct without real-time scheduling, just noisier (apply_realtime).
  while (running_.load(std::memory_order_relaxed)) cycle();
}

}  // namespace maglead::controller
