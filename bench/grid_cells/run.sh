#!/usr/bin/env bash
# Grid cell vs voxel thinning benchmark; prints a markdown section. Sizes default to 128 and 256.
set -euo pipefail
build=${1:-build}
cmake --build "$build" --target bench_grid_cells >/dev/null
"$build/bench/grid_cells/bench_grid_cells" 2 128 256
