#pragma once
// Single-writer seqlock over a trivially copyable value, stored as atomic words so that a
// reader racing the writer is well defined; readers retry until they see one whole version.
// The writer never waits, so the loop cannot be held up by a reader.
#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace maglead::controller::detail {

template <class T>
class SeqLock {
  static_assert(std::is_trivially_copyable_v<T>);
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

 public:
  void store(const T& value) noexcept {
    std::uint64_t buf[kWords] = {};
    std::memcpy(buf, &value, sizeof(T));
    const auto s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_relaxed);
    seq_.store(s + 2, std::memory_order_release);
  }

  /// One attempt, never waits: false (out untouched) while the writer is storing or if it
  /// stored meanwhile. For a reader that must not wait on its writer (the loop reading the
  /// twin's results).
  bool try_load(T& out) const noexcept {
    std::uint64_t buf[kWords];
    const auto s0 = seq_.load(std::memory_order_acquire);
    if (s0 & 1) return false;
    for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (seq_.load(std::memory_order_relaxed) != s0) return false;
    std::memcpy(&out, buf, sizeof(T));
    return true;
  }

  T load() const noexcept {
    std::uint64_t buf[kWords];
    for (;;) {
      const auto s0 = seq_.load(std::memory_order_acquire);
      if (s0 & 1) continue;
      for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s0) break;
    }
    T out;
    std::memcpy(&out, buf, sizeof(T));
    return out;
  }

 private:
  std::atomic<std::uint64_t> seq_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

/// Bounded single-producer single-consumer ring. Producers on several threads must serialise
/// among themselves (the Modbus core does, under its own mutex, which the loop never takes).
template <class T, std::size_t N>
class SpscQueue {
  static_assert((N & (N - 1)) == 0 && std::is_trivially_copyable_v<T>);

 public:
  bool push(const T& v) noexcept {
    const auto head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == N) return false;
    slots_[head & (N - 1)] = v;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  bool pop(T& v) noexcept {
    const auto tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    v = slots_[tail & (N - 1)];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

 private:
  std::array<T, N> slots_{};
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
};

}  // namespace maglead::controller::detail
