#!/usr/bin/env bash
# Regenerates the report screenshots in docs/ (report_1280x800.png, report_390x844.png): runs the
# report's browser test on a simulated drifting actuator and keeps what headless chromium saw.
# Usage: tools/screenshots.sh [BUILD_DIR]   (default build/; run tools/build.sh or cmake first)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 "$root/tests/operator/report_browser.py" "$build/bin/maglead" "$root/config" "$work" \
  --screenshots "$root/docs"
