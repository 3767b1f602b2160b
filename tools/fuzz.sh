#!/usr/bin/env bash
# Fuzzing: builds the libFuzzer targets of tests/fuzz with the preset fuzz (clang++, ASan/UBSan,
# MAGLEAD_FUZZ=ON, in build-fuzz) and runs each from its seed corpus for a bounded time
# (MAGLEAD_FUZZ_SECONDS in all, default 90, split by the shares below; as many targets at once as
# there are cores). Exits non-zero on a crash, a sanitizer
# report, a hang (-timeout) or a failed oracle; the input that did it is in build-fuzz/crashes/
# (replay: build-fuzz/bin/TARGET FILE). Arguments, if any, name the targets to run (default: all).
set -euo pipefail
cd "$(dirname "$0")/.."
total_s=${MAGLEAD_FUZZ_SECONDS:-90}
# target:corpus:share (tests/fuzz/corpus/CORPUS holds the seeds): the one list of fuzz targets
# (ModbusCore::handle; the TCP and RTU request framers; the recording reader; the TOML readers of
# actuator/calibration/network.toml and the model file).
# The third field is the target's share of the time (in 90ths): the framers are small and saturate
# in seconds; the recording reader runs ~50 inputs/s under ASan here (its 1 MiB read buffer is
# fresh pages every input), the TOML readers a few hundred.
targets=(fuzz_modbus_core:core:20 fuzz_tcp_framer:tcp:5 fuzz_rtu_framer:rtu:8
  fuzz_recording:recording:22 fuzz_config:config:35)
if (($# > 0)); then
  chosen=()
  for want in "$@"; do
    for t in "${targets[@]}"; do [[ ${t%%:*} == "$want" ]] && chosen+=("$t"); done
  done
  ((${#chosen[@]} == $#)) || { echo "fuzz: unknown target among: $*" >&2; exit 2; }
  targets=("${chosen[@]}")
fi
cmake --preset fuzz >/dev/null  # clang++, MAGLEAD_FUZZ=ON, in build-fuzz/
cmake --build --preset fuzz -j "${MAGLEAD_FUZZ_JOBS:-$(nproc)}" --target "${targets[@]%%:*}"
shares=0
for t in "${targets[@]}"; do shares=$((shares + ${t##*:})); done

# One target for its share of the time; its output in build-fuzz/NAME.log, a line here.
fuzz_one() {
  local name corpus share per_s start_ms ms dict=()
  IFS=: read -r name corpus share <<<"$1"
  per_s=$((total_s * share / shares))
  ((per_s > 0)) || per_s=1
  # New inputs go to build-fuzz/corpus (kept between runs); the seeds in the tree stay as they are.
  mkdir -p "build-fuzz/corpus/$corpus" build-fuzz/crashes
  echo "fuzz: $name for ${per_s} s"
  # tests/fuzz/corpus/CORPUS.dict: tokens of the format (keys, sections), if it has one
  [[ -f tests/fuzz/corpus/$corpus.dict ]] && dict=("-dict=tests/fuzz/corpus/$corpus.dict")
  start_ms=$((${EPOCHREALTIME/./} / 1000))
  if ! ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
      "build-fuzz/bin/$name" -max_total_time="$per_s" -timeout=10 -print_final_stats=1 "${dict[@]}" \
      -artifact_prefix="build-fuzz/crashes/$name-" "build-fuzz/corpus/$corpus" \
      "tests/fuzz/corpus/$corpus" >"build-fuzz/$name.log" 2>&1; then
    ms=$((${EPOCHREALTIME/./} / 1000 - start_ms))
    tail -n 40 "build-fuzz/$name.log" >&2
    echo "fuzz: $name FAILED after $((ms / 1000)).$((ms % 1000 / 100)) s (input in build-fuzz/crashes/, log build-fuzz/$name.log)" >&2
    return 1
  fi
  grep -E '^stat::number_of_executed_units' "build-fuzz/$name.log" | sed "s/^/fuzz: $name /" || true
}

# Each fuzzer is one process on one core: MAGLEAD_FUZZ_JOBS (default: the cores) run side by
# side, each target still getting its share of the seconds, so the wall time is total_s / jobs.
jobs_max=${MAGLEAD_FUZZ_JOBS:-$(nproc)}
failed=0
running=0
for t in "${targets[@]}"; do
  if ((running >= jobs_max)); then
    wait -n || failed=1
    running=$((running - 1))
  fi
  fuzz_one "$t" &
  running=$((running + 1))
done
while ((running > 0)); do
  wait -n || failed=1
  running=$((running - 1))
done
((failed == 0)) || exit 1
echo "fuzz: no crash, no oracle failure"
