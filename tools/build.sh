#!/usr/bin/env bash
# Configures and builds maglead with a preset of CMakePresets.json (default: release, in build/):
# `tools/build.sh asan-ubsan`. A build preset that names targets builds only those.
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-release}
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)"
