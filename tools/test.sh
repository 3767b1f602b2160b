#!/usr/bin/env bash
# The test command: set up, check the tree, build, run every test; then again under ASan/UBSan.
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
fi
