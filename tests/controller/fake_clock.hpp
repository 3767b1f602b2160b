#pragma once
// A LoopClock for tests: time moves only when the loop sleeps (to the deadline it asks for),
// plus lateness injected on chosen wake-ups. No real time passes, so nothing here is timed.
#include <cstdint>
#include <map>
#include <vector>

#include "maglead/controller/loop_runner.hpp"

namespace maglead::testing {

class FakeLoopClock final : public controller::LoopClock {
 public:
  std::int64_t now_ns() noexcept override { return t_ns_; }
  void sleep_until(std::int64_t deadline_ns) noexcept override {
    if (deadlines_.size() < deadlines_.capacity()) deadlines_.push_back(deadline_ns);
    if (deadline_ns > t_ns_) t_ns_ = deadline_ns;
    const auto it = late_.find(sleeps_++);
    if (it != late_.end()) t_ns_ += it->second;
  }
  /// The wake-up after the n-th sleep (0-based, i.e. the start of cycle n + 2) comes late_ns late.
  void wake_late(std::uint64_t nth_sleep, std::int64_t late_ns) { late_[nth_sleep] = late_ns; }
  /// Deadlines the loop slept to, in order (up to `capacity` kept, reserved before the loop runs).
  const std::vector<std::int64_t>& deadlines() const { return deadlines_; }
  explicit FakeLoopClock(std::size_t capacity = 1 << 16, std::int64_t t0_ns = 5'000'000'000)
      : t_ns_(t0_ns) {
    deadlines_.reserve(capacity);
  }

 private:
  std::int64_t t_ns_;
  std::uint64_t sleeps_ = 0;
  std::map<std::uint64_t, std::int64_t> late_;
  std::vector<std::int64_t> deadlines_;
};

}  // namespace maglead::testing
