// The maglead command's operator new: large blocks (whole recording columns and the analysis's
// filtered signals, tens of MB each) are asked to be backed by transparent huge pages, once an
// offline command turns it on (large_blocks.hpp).
//
// Why: analysing an hour at 1 kHz touches about 1 GB of freshly allocated memory; in 4 KiB pages
// that is ~150 k page faults, a fifth of the run (`maglead bench analyze`, perf). With huge
// pages it is a few hundred. glibc does the same with GLIBC_TUNABLES=glibc.malloc.hugetlb=1, but
// tunables are read only at start-up, so the command does it itself, for large blocks only.
// Where the kernel has THP off (`never`) madvise fails or does nothing and the block is plain
// memory: only the speed differs, never a value. Small blocks (the controller's, the
// parser's) are untouched. Replaces only the plain forms: libstdc++'s array, nothrow and sized
// forms call these, and free() releases both. A sanitizer brings its own operator new in every
// form (its nothrow new would meet our delete: ASan's alloc-dealloc-mismatch), so sanitized
// builds keep theirs and give no advice.
#include "large_blocks.hpp"

#include <atomic>

namespace {
std::atomic<bool> advise_large_blocks{false};
}  // namespace

void maglead::cli::advise_large_blocks_to_huge_pages() {
  advise_large_blocks.store(true, std::memory_order_relaxed);
}

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
bool maglead::cli::huge_page_advice_built() { return false; }
#else
#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace {

constexpr std::size_t kLargeBlockBytes = std::size_t{4} << 20;  // two 2 MiB huge pages
constexpr std::uintptr_t kPageBytes = 4096;                     // madvise wants page alignment

void advise_huge_pages(void* block, std::size_t bytes) {
  const auto begin = reinterpret_cast<std::uintptr_t>(block);
  const std::uintptr_t lead = (kPageBytes - begin % kPageBytes) % kPageBytes;  // to a page start
  const std::uintptr_t last = (begin + bytes) & ~(kPageBytes - 1);
  if (last > begin + lead)  // advice only: a failure leaves ordinary pages
    (void)madvise(static_cast<char*>(block) + lead, last - (begin + lead), MADV_HUGEPAGE);
}

}  // namespace

bool maglead::cli::huge_page_advice_built() { return true; }

void* operator new(std::size_t bytes) {
  void* p = std::malloc(bytes == 0 ? 1 : bytes);
  if (p == nullptr) throw std::bad_alloc();
  if (bytes >= kLargeBlockBytes && advise_large_blocks.load(std::memory_order_relaxed))
    advise_huge_pages(p, bytes);
  return p;
}

void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t /*bytes*/) noexcept { std::free(p); }
#endif
