#pragma once
// A scratch directory of this test process: CTest runs test cases of several binaries at once,
// so shared names in the system temp directory would race.
#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

inline std::string test_tmp_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const std::string name =
      info ? std::string(info->test_suite_name()) + "." + info->name() : "global";
  const auto dir = std::filesystem::path(testing::TempDir()) /
                   ("maglead-" + std::to_string(getpid()) + "-" + name);
  std::filesystem::create_directories(dir);
  return dir.string();
}
