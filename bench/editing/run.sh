#!/usr/bin/env bash
# Editing benchmark: GraphEditor operations + undo on ~10⁶ segments, journal cost, replay by
# position, and the GUI edit mode's picking; prints one markdown section.
# Usage: bench/editing/run.sh BUILD_DIR [n = 70 (3·n³ edges)] [reps = 100]
set -euo pipefail
build=${1:-build}
n=${2:-70}
reps=${3:-100}
cmake --build "$build" --target bench_editing >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "## Editing: undoable graph operations, journal and picking (issue 10, thesis §6.1)"
echo
echo "Goal: each operation and its undo < 50 ms, picking < 100 ms on a 10⁶-segment graph. No peer:"
echo "no library offers exact-undo editing of spatial graphs; the table states absolute times."
echo
"$build/bench/editing/bench_editing" "$work" "$n" "$reps"
echo
echo "Journal: every op appends one YAML line and calls fsync (file in \`mktemp -d\`); the difference of"
echo "the two op columns is the journal cost. Picking is gui/graph_pick (as in skelflow-gui's edit mode)."
