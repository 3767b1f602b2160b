#!/usr/bin/env bash
# clang-format-14 with the root .clang-format over the tracked C++ files (*.cpp, *.hpp).
#   tools/format.sh --check   lists the files that differ and fails (CI, tools/test.sh)
#   tools/format.sh [FILE...] formats the named files in place (default: every tracked file)
set -euo pipefail
cd "$(dirname "$0")/.."
fmt=${CLANG_FORMAT:-clang-format-14}
if [ "${1:-}" = --check ]; then
  mapfile -t files < <(git ls-files '*.cpp' '*.hpp')
  bad=()
  for f in "${files[@]}"; do
    "$fmt" --dry-run -Werror "$f" >/dev/null 2>&1 || bad+=("$f")
  done
  if ((${#bad[@]})); then
    echo "format: ${#bad[@]} of ${#files[@]} files differ from .clang-format (fix: tools/format.sh FILE...):" >&2
    printf '  %s\n' "${bad[@]}" >&2
    exit 1
  fi
  echo "format: ${#files[@]} files as .clang-format says"
  exit 0
fi
if (($#)); then files=("$@"); else mapfile -t files < <(git ls-files '*.cpp' '*.hpp'); fi
"$fmt" -i "${files[@]}"
