#!/usr/bin/env bash
# Geodesic boundary distance benchmark; prints a markdown section. BIG=1 adds 512³.
set -euo pipefail
build=${1:-build}
cmake --build "$build" --target bench_geodesic >/dev/null
"$build/bench/geodesic/bench_geodesic" 2 ${BIG:+big}
