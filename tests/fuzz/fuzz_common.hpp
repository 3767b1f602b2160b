#pragma once
// Helpers shared by the libFuzzer targets of this directory: a failed oracle aborts with its
// reason (libFuzzer reports that as a crash and keeps the input), and the readers that take a
// path get the input written to a file of their own.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>
#include <string_view>

namespace maglead::fuzz {

[[noreturn]] inline void oracle_failed(std::string_view target, std::string_view what) {
  std::fprintf(stderr, "%.*s oracle failed: %.*s\n", static_cast<int>(target.size()), target.data(),
               static_cast<int>(what.size()), what.data());
  std::abort();
}

/// Writes the bytes to a file of this process (one per suffix, overwritten by each input):
/// libFuzzer runs inputs one after the other in one process. In memory (/dev/shm) where there is
/// one: a file on disk costs the fuzzer most of its inputs per second.
inline std::string write_input(const std::uint8_t* data, std::size_t size,
                               std::string_view suffix) {
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::is_directory("/dev/shm", ec)
                                        ? std::filesystem::path("/dev/shm")
                                        : std::filesystem::temp_directory_path();
  const std::string path =
      (dir / ("maglead-fuzz-" + std::to_string(getpid()) + std::string(suffix))).string();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || std::fwrite(data, 1, size, f) != size || std::fclose(f) != 0)
    oracle_failed("fuzz", "cannot write the input file " + path);
  return path;
}

/// A refusal must say why and name the file it refused (every reader's promise).
inline void check_refusal(std::string_view target, const std::exception& e,
                          const std::string& path) {
  const std::string_view what = e.what();
  if (what.substr(0, path.size()) != path || what.size() <= path.size() + 2)
    oracle_failed(target,
                  "refused without naming the file and a reason: '" + std::string(what) + "'");
}

}  // namespace maglead::fuzz
