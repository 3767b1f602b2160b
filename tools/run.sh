#!/usr/bin/env bash
# The main job: set up, build, and run the controller on its simulated actuator.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/build.sh release
exec build/bin/maglead serve "$@"
