#!/usr/bin/env bash
# The test command: set up, check the tree, check the format and run clang-tidy, build, run every
# test; then again under ASan/UBSan, the tests that start threads (label threads) under
# ThreadSanitizer, and the fuzz targets (clang, libFuzzer) for 90 s in all. Every build is a
# preset of CMakePresets.json (release, asan-ubsan, tsan, fuzz); the preset says what is built
# and which tests run. MAGLEAD_LINT=0 skips the format check and clang-tidy,
# MAGLEAD_SKIP_SANITIZERS=1 the sanitizer and fuzz passes (both for local runs; CI runs all).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/check_tree.sh
if [ "${MAGLEAD_LINT:-1}" != 0 ]; then
  bash tools/format.sh --check
fi
bash tools/build.sh release
if [ "${MAGLEAD_LINT:-1}" != 0 ]; then
  bash tools/tidy.sh  # needs build/compile_commands.json
fi
ctest --preset release
if [ "${MAGLEAD_SKIP_SANITIZERS:-0}" != 1 ]; then
  bash tools/build.sh asan-ubsan
  ctest --preset asan-ubsan
  bash tools/build.sh tsan  # only the threaded tests' executables: the build preset lists them
  ctest --preset tsan
  bash tools/fuzz.sh
fi
