#!/usr/bin/env bash
# clang-tidy-14 with the root .clang-tidy over the project's sources, from the compile commands of
# build-tidy/ (the release preset configured, not built). Every finding is an error. The fuzz
# targets need clang's -fsanitize=fuzzer and are not checked.
#   tools/tidy.sh              every product source (what tools/test.sh and CI run; 2 jobs, or
#                              MAGLEAD_TIDY_JOBS). The command line's files are read in their
#                              unity batches, as the release build compiles them: clang-tidy 14
#                              matches its checks in every header, and each file alone spends
#                              ~14 s in CLI11's. Not tests/: their findings are checked by --all
#                              and --since.
#   tools/tidy.sh --all        the same and every test source
#   tools/tidy.sh --since REV  the sources changed since REV, tests too, one file at a time; a
#                              changed header brings in every source of its top-level module (a
#                              quick check before a push)
#   tools/tidy.sh REGEX...     only the files whose path matches one of the regexes, one at a time
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
unity=OFF
case ${1:-} in
  --since)
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
    ;;
  "" | --all)
    # Every source, a module added later too; not build trees (generated sources) but the
    # command line's unity batches, not tests/fuzz.
    unity=ON
    tools_batches="^$root/build-tidy/tools/CMakeFiles/maglead\\.dir/Unity/"
    if [ "${1:-}" = --all ]; then
      filters=("^$root/(?!build)(?!tests/fuzz/)" "$tools_batches")
    else
      filters=("^$root/(?!build)(?!tests/)" "$tools_batches")
    fi
    ;;
  *) filters=("$@") ;;
esac
cmake --preset release -B build-tidy -DMAGLEAD_UNITY_TOOLS=$unity >/dev/null
if [ $unity = ON ]; then
  # A unity batch includes .cpp files on purpose; every other check applies as in the root file.
  printf 'InheritParentConfig: true\nChecks: -bugprone-suspicious-include\n' \
    >build-tidy/tools/CMakeFiles/maglead.dir/Unity/.clang-tidy
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
