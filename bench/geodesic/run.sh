#!/usr/bin/env bash
# Geodesic boundary distance benchmark; prints a markdown section. BIG=1 adds 512³.
# SIZES=1024 (comma-separated sizes) and SHAPES=plates (plates, mixed, rods, spheres) pick other runs;
# sizes of 512³ and more need several GiB (mask 1 B, importance 4 B, surface 1 B per voxel, about
# 10-16 B per object voxel of working memory, the EDT yardstick 4 B per voxel): on a shared machine run
# them under `flock /work/bigmem.lock`.
set -euo pipefail
build=${1:-build}
cmake --build "$build" --target bench_geodesic >/dev/null
sizes=${SIZES:-$([ -n "${BIG:-}" ] && echo big || echo small)}
"$build/bench/geodesic/bench_geodesic" 2 "$sizes" 20,40,80 "${SHAPES:-plates,mixed}"
