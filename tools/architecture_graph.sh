#!/usr/bin/env bash
# Draws the module graph of docs/architecture.md from CMake's own dependency graph
# (`cmake --graphviz`): the project's libraries and the maglead program, without tests, external
# libraries and interface helpers. Writes docs/architecture.svg; needs graphviz (`dot`).
#   tools/architecture_graph.sh [BUILD_DIR]   (default build/, configured with the release preset)
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-build}
mkdir -p "$dir/graphviz"
# CMake reads these options from the build directory.
cat >"$dir/CMakeGraphVizOptions.cmake" <<'OPTS'
set(GRAPHVIZ_GRAPH_NAME "maglead")
set(GRAPHVIZ_EXTERNAL_LIBS FALSE)
set(GRAPHVIZ_INTERFACE_LIBS FALSE)
set(GRAPHVIZ_GENERATE_PER_TARGET FALSE)
set(GRAPHVIZ_GENERATE_DEPENDERS FALSE)
set(GRAPHVIZ_IGNORE_TARGETS "^test_" "^fuzz_" "^maglead_warnings$" "^maglead_opencv$")
OPTS
if [ "$dir" = build ]; then
  cmake --preset release --graphviz="$dir/graphviz/maglead.dot" >/dev/null
else
  cmake -S . -B "$dir" --graphviz="$dir/graphviz/maglead.dot" >/dev/null
fi
# Module names without the maglead_ prefix; libraries as boxes, the program in bold; no legend.
sed -e 's/"maglead_\([a-z0-9_]*\)"/"\1"/' \
    -e 's/shape = egg/shape = box, style = bold/; s/shape = octagon/shape = box/' \
    -e 's/^digraph "maglead" {/digraph "maglead" {\n  node [fontname = "sans-serif"];/' \
    -e '/^subgraph clusterLegend {/,/^}/d' \
    "$dir/graphviz/maglead.dot" >"$dir/graphviz/maglead_clean.dot"
dot -Tsvg "$dir/graphviz/maglead_clean.dot" -o docs/architecture.svg
echo "wrote docs/architecture.svg"
