#!/usr/bin/env bash
# Python overhead: thinning.doht called from Python on a NumPy volume vs the same node run by the CLI.
#   bench/python/run.sh BUILD_DIR     (prints a markdown section; bench/run.sh python keeps it)
# SKEL_BENCH_PY_SIZE (default 512) and SKEL_BENCH_PY_REPEAT (default 3) change the grid and repeats.
set -euo pipefail
build=${1:?usage: run.sh BUILD_DIR}
here=$(cd "$(dirname "$0")" && pwd)
exec "${SKEL_BENCH_PYTHON:-/usr/bin/python3}" "$here/doht_overhead.py" --build "$build" \
  --size "${SKEL_BENCH_PY_SIZE:-512}" --repeat "${SKEL_BENCH_PY_REPEAT:-3}" --threads "$(nproc)"
