#!/usr/bin/env bash
# Fails when a tracked file names a path outside the repository: the development-only
# `../shared` folder (or its spec/, data/, reference/ subfolders) that a clone does not have.
# The repository must be complete on its own: data it needs is under data/, conventions and
# formats under docs/. Prints every offending line as file:line:text.
set -euo pipefail
cd "$(dirname "$0")/.."
pattern='\.\./shared|(^|[^[:alnum:]_./-])shared/(spec|data|reference)/'
self=tools/check_tree.sh
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  hits=$(git grep -n -I -E "$pattern" -- . ":(exclude)$self" || true)
else  # an exported tree without .git: check every file but build output
  hits=$(grep -rn -I -E "$pattern" --exclude-dir='build*' --exclude-dir=out . |
         grep -v "^\./$self:" || true)
fi
if [ -n "$hits" ]; then
  echo "check_tree: these lines name a path outside the repository (../shared is not in a clone):" >&2
  echo "$hits" >&2
  exit 1
fi
echo "check_tree: no tracked file names ../shared"
