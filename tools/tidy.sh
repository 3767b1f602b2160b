#!/usr/bin/env bash
# clang-tidy-14 with the root .clang-tidy over the project's sources, from the compile commands of
# build-tidy/: the release preset configured (not built) without unity batches, so every source
# is its own entry (the release build compiles the command line's files in batches). Every
# finding is an error. The fuzz targets need clang's -fsanitize=fuzzer and are not checked.
#   tools/tidy.sh              every source of the project (2 jobs, or MAGLEAD_TIDY_JOBS)
#   tools/tidy.sh --since REV  the sources changed since REV; a changed header brings in every
#                              source of its top-level module (a quick check before a push)
#   tools/tidy.sh REGEX...     only the files whose path matches one of the regexes
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
cmake --preset release -B build-tidy -DMAGLEAD_UNITY_TOOLS=OFF >/dev/null
if [ "${1:-}" = --since ]; then
  filters=()
  while read -r f; do
    case $f in
      tests/fuzz/*) ;;
      *.cpp) filters+=("^$root/$f\$") ;;
      *.hpp) filters+=("^$root/${f%%/*}/") ;;
    esac
  done < <(git diff --name-only "${2:?--since needs a revision}" -- '*.cpp' '*.hpp')
  if ((${#filters[@]} == 0)); then
    echo "tidy: no C++ source changed since $2"
    exit 0
  fi
elif (($#)); then
  filters=("$@")
else
  # Every source of the project, a module added later too; not build trees (generated sources),
  # not tests/fuzz.
  filters=("^$root/(?!build)(?!tests/fuzz/)")
fi
start=$(date +%s)
# -w: the compiler's own warnings are the build's business (gcc's flags, -Werror); tidy checks only.
if ! run-clang-tidy -clang-tidy-binary "$(command -v clang-tidy-14)" -p build-tidy \
    -j "${MAGLEAD_TIDY_JOBS:-2}" -quiet -extra-arg=-w "${filters[@]}" >build-tidy/tidy.log 2>&1; then
  sed 's/\x1b\[[0-9;]*m//g' build-tidy/tidy.log | grep -E '(warning|error):' | sed "s|^$root/||" |
    sort -u >&2 || cat build-tidy/tidy.log >&2
  echo "tidy: FAILED after $(($(date +%s) - start)) s (full log: build-tidy/tidy.log)" >&2
  exit 1
fi
echo "tidy: clean ($(($(date +%s) - start)) s)"
