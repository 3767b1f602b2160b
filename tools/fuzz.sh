#!/usr/bin/env bash
# Fuzzing: builds the libFuzzer targets of tests/fuzz with the preset fuzz (clang++, ASan/UBSan,
# MAGLEAD_FUZZ=ON, in build-fuzz) and runs each from its seed corpus for a bounded time
# (MAGLEAD_FUZZ_SECONDS in all, default 60). Exits non-zero on a crash, a sanitizer report or a failed oracle; the input that
# did it is in build-fuzz/crashes/ (replay: build-fuzz/bin/TARGET FILE).
set -euo pipefail
cd "$(dirname "$0")/.."
total_s=${MAGLEAD_FUZZ_SECONDS:-60}
# target:corpus (tests/fuzz/corpus/CORPUS holds the seeds): the one list of fuzz targets
targets=(fuzz_modbus_core:core)
cmake --preset fuzz >/dev/null  # clang++, MAGLEAD_FUZZ=ON, in build-fuzz/
cmake --build --preset fuzz -j "${MAGLEAD_FUZZ_JOBS:-$(nproc)}" --target "${targets[@]%%:*}"
per_s=$((total_s / ${#targets[@]}))
((per_s > 0)) || per_s=1
for t in "${targets[@]}"; do
  name=${t%%:*} corpus=${t#*:}
  # New inputs go to build-fuzz/corpus (kept between runs); the seeds in the tree stay as they are.
  mkdir -p "build-fuzz/corpus/$corpus" build-fuzz/crashes
  echo "fuzz: $name for ${per_s} s"
  if ! ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
      "build-fuzz/bin/$name" -max_total_time="$per_s" -timeout=10 -print_final_stats=1 \
      -artifact_prefix="build-fuzz/crashes/$name-" "build-fuzz/corpus/$corpus" "tests/fuzz/corpus/$corpus"; then
    echo "fuzz: $name FAILED (input in build-fuzz/crashes/)" >&2
    exit 1
  fi
done
echo "fuzz: no crash, no oracle failure"
