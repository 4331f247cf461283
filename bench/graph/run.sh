#!/usr/bin/env bash
# Graph benchmark: skeleton_to_graph + network_statistics vs a SciPy pixel-graph peer; prints markdown.
# Usage: bench/graph/run.sh BUILD_DIR [n]   (default n = 512)
set -euo pipefail
build=${1:-build}
n=${2:-512}
here=$(cd "$(dirname "$0")" && pwd)
cmake --build "$build" --target bench_graph >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "## Graph: skeleton → SpatialGraph (dual cubes) + network statistics"
echo
echo "Synthetic skeleton: random 26-connected segments (8–64 voxels) in an ${n}³ grid."
echo
echo "| grid | threads | skeleton voxels | nodes | edges | branch points | skeleton_to_graph s | Mvoxel/s | statistics s | peak RSS MiB |"
echo "|---|---|---|---|---|---|---|---|---|---|"
rows=$("$build/bench/graph/bench_graph" "$work" "$n")
echo "$rows"
read -r pt prss pj pb pe < <(/usr/bin/python3 "$here/scipy_peer.py" "$work/skeleton.npy")
ours=$(echo "$rows" | awk -F'|' 'NR==2 {gsub(/ /,"",$8); print $8}')
echo
echo "| peer (same volume) | time s | peak RSS MiB | junction clusters | branches | end points | ratio = peer / ours (2 threads) |"
echo "|---|---|---|---|---|---|---|"
ratio=$(/usr/bin/python3 -c "print(f'{$pt/$ours:.2f}')")
echo "| SciPy pixel graph (convolve + label) | $pt | $prss | $pj | $pb | $pe | $ratio |"
echo
echo "The peer only counts (neighbour counts, labels, pixel-graph length); ours builds the full graph with polylines and classifies every voxel's manifold type."
