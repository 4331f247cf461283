#!/usr/bin/env bash
# Skeleton mesh vs iso-surface benchmark; prints a markdown section. BIG=1 adds 256³.
set -euo pipefail
build=${1:-build}
cmake --build "$build" --target bench_mesh >/dev/null
"$build/bench/mesh/bench_mesh" 2 ${BIG:+big}
