#!/usr/bin/env bash
# The test command: set up, check the tree, build, run every test; then again under ASan/UBSan,
# the tests that start threads (label threads) under ThreadSanitizer, and the fuzz targets (clang,
# libFuzzer) for 60 s in all.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/check_tree.sh
bash tools/build.sh build
(cd build && ctest --output-on-failure -j 2)
if [ "${MAGLEAD_SKIP_SANITIZERS:-0}" != 1 ]; then
  bash tools/build.sh build-asan -DMAGLEAD_SANITIZE=ON
  (cd build-asan && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    ctest --output-on-failure -j 2 -LE no_sanitizer)
  # Only the threaded tests' executables are built: the rest has no threads to check.
  cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMAGLEAD_WERROR=ON -DMAGLEAD_TSAN=ON >/dev/null
  cmake --build build-tsan -j "$(nproc)" --target test_loop_runner test_threads test_twin_runner
  (cd build-tsan && TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" \
    ctest --output-on-failure -j 2 -L threads)
  bash tools/fuzz.sh
fi
