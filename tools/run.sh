#!/usr/bin/env bash
# The main job: set up, build, and run the controller on its simulated actuator.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/build.sh build
if build/bin/maglead serve --help >/dev/null 2>&1; then
  exec build/bin/maglead serve "$@"
fi
# Until the controller lands: a simulated hand-push run and its force-estimation result.
build/bin/maglead simulate --scenario hand-push --duration 30s --seed 1 --out build/hand-push.csv
exec build/bin/maglead estimate --recording build/hand-push.csv
