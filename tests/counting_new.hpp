#pragma once
// Allocation counting for the no-allocation tests: counting_new.cpp replaces every global operator
// new and delete of the executable it is linked into (process-wide, so each such test is an
// executable of its own). The replacements use malloc and free, so that a sanitizer's allocator
// (which brings its own new and delete) sees each block paired.
#include <cstddef>
#include <cstdint>

namespace maglead::test_support {

/// Counts the allocations of every thread made while it lives.
class AllocationCount {
 public:
  AllocationCount();
  ~AllocationCount();
  AllocationCount(const AllocationCount&) = delete;
  AllocationCount& operator=(const AllocationCount&) = delete;
  /// Allocations since construction.
  std::uint64_t count() const;
  /// Bytes asked by the first allocation counted (0: none yet).
  std::size_t first_size_bytes() const;

 private:
  std::uint64_t start_;
};

}  // namespace maglead::test_support
