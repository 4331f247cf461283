#!/usr/bin/env bash
# Executor overhead benchmark; prints a markdown section.
set -euo pipefail
build=${1:-build}
cmake --build "$build" --target bench_engine >/dev/null
"$build/bench/engine/bench_engine"
