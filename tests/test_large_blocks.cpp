// The maglead command's operator new (tools/src/large_blocks.cpp): large blocks are advised to
// transparent huge pages (the mapping's VmFlags show "hg"), and every block still works.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "large_blocks.hpp"

namespace {

/// The VmFlags of the mapping holding `address`, from /proc/self/smaps ("" if none is found).
std::string vm_flags_at(const void* address) {
  const auto a = reinterpret_cast<std::uintptr_t>(address);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    const auto dash = line.find('-');
    const auto space = line.find(' ');
    if (dash != std::string::npos && space != std::string::npos && dash < space &&
        line.find(':') > space) {  // a mapping's first line: "start-end perms ..."
      const auto start = std::stoull(line.substr(0, dash), nullptr, 16);
      const auto end = std::stoull(line.substr(dash + 1, space - dash - 1), nullptr, 16);
      inside = start <= a && a < end;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      return line.substr(8);
    }
  }
  return "";
}

bool has_flag(const std::string& flags, const std::string& flag) {
  std::istringstream words(flags);
  std::string w;
  while (words >> w)
    if (w == flag) return true;
  return false;
}

// Off until a command turns it on (the controller's never do), then on for every large block.
TEST(LargeBlocks, LargeVectorIsAdvisedToHugePagesOnceTurnedOn) {
  if (!std::filesystem::exists("/sys/kernel/mm/transparent_hugepage/enabled"))
    GTEST_SKIP() << "kernel without transparent huge pages";
  if (!maglead::cli::huge_page_advice_built()) GTEST_SKIP() << "a sanitizer's operator new";
  const auto flags_of_a_column = [] {
    std::vector<double> column(std::size_t{4} << 20);  // 32 MiB, a recording column's size
    return vm_flags_at(column.data() + column.size() / 2);
  };
  const std::string before = flags_of_a_column();
  ASSERT_FALSE(before.empty()) << "no mapping found in /proc/self/smaps";
  EXPECT_FALSE(has_flag(before, "hg")) << "VmFlags:" << before;
  maglead::cli::advise_large_blocks_to_huge_pages();
  const std::string after = flags_of_a_column();
  EXPECT_TRUE(has_flag(after, "hg")) << "VmFlags:" << after;
}

TEST(LargeBlocks, BlocksOfEverySizeHoldTheirValues) {
  for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{1000}, std::size_t{1} << 20}) {
    std::vector<double> v(n);
    std::iota(v.begin(), v.end(), 0.0);
    const auto* array = new double[n + 1];  // the array form goes through the same operator new
    delete[] array;
    EXPECT_EQ(std::accumulate(v.begin(), v.end(), 0.0),
              0.5 * static_cast<double>(n) * (static_cast<double>(n) - 1.0));
  }
}

}  // namespace
