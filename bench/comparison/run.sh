#!/usr/bin/env bash
# Comparison benchmark: comparison.skeleton_distance on an n³ skeleton pair (seeded EDT and k-d tree,
# vs SciPy's distance_transform_edt and cKDTree on the same .npy files) and comparison.graph_match
# on an m³-node lattice graph (~3·m³ edges) against a copy with k edges deleted and j added.
# Prints one markdown section.
# Usage: bench/comparison/run.sh BUILD_DIR [n] [m]   (defaults n = 512, m = 33: 104544 edges)
#   or set SKEL_BENCH_CMP_N / SKEL_BENCH_CMP_M; quick smoke run: bench/comparison/run.sh build 64 8
set -euo pipefail
build=${1:-build}
n=${2:-${SKEL_BENCH_CMP_N:-512}}
m=${3:-${SKEL_BENCH_CMP_M:-33}}
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
here=$(cd "$(dirname "$0")" && pwd)
cmake --build "$build" --target bench_comparison >/dev/null
bin="$build/bench/comparison/bench_comparison"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin" make_skeletons "$work" "$n"
edges=$((3 * m * m * (m - 1)))
k=$((edges / 100))
j=$((edges / 200))
echo "## Comparison: skeleton distance and graph matching"
echo
echo "Skeleton distance: reference = random 26-connected segments (8–64 voxels, n²/12 of them) in an ${n}³ grid;"
echo "other = the same segments shifted by one voxel in x with 10 % of them left out. Distance of every"
echo "reference voxel to the other skeleton; changed = distance > 2. Times exclude reading the .npy files;"
echo "peak RSS is per process (each line is its own process) and includes the two input volumes."
echo
echo "| method | grid | threads | reference points | time s | Mvoxel/s | mean distance | changed | peak RSS MiB |"
echo "|---|---|---|---|---|---|---|---|---|"
declare -A ours
for t in 1 2; do
  row=$("$bin" distance "$work" transform $t)
  echo "$row"
  ours[transform$t]=$(echo "$row" | awk -F'|' '{gsub(/ /,"",$6); print $6}')
done
row=$("$bin" distance "$work" kdtree 2)
echo "$row"
ours[kdtree2]=$(echo "$row" | awk -F'|' '{gsub(/ /,"",$6); print $6}')
read -r et erss epts emean ech < <("$py" "$here/scipy_peer.py" "$work" edt 1)
read -r kt krss kpts kmean kch < <("$py" "$here/scipy_peer.py" "$work" kdtree 2)
echo "| SciPy distance_transform_edt(~other) (peer) | ${n}³ | 1 | $epts | $et | $("$py" -c "print(f'{$n**3/$et/1e6:.1f}')") | $emean | $ech | $erss |"
echo "| SciPy cKDTree.query (peer) | ${n}³ | 2 | $kpts | $kt | $("$py" -c "print(f'{$n**3/$kt/1e6:.1f}')") | $kmean | $kch | $krss |"
echo
echo "Ratios peer / ours: EDT (1 thread) $("$py" -c "print(f'{$et/${ours[transform1]}:.2f}')"), EDT vs ours on 2 threads $("$py" -c "print(f'{$et/${ours[transform2]}:.2f}')"), k-d tree (2 threads) $("$py" -c "print(f'{$kt/${ours[kdtree2]}:.2f}')")."
echo "SciPy's EDT computes the full float64 distance map (8 B/voxel) plus its int32 feature work arrays; ours is a"
echo "float32 seeded EDT read at the skeleton voxels. Mean and changed count must agree across all lines."
echo
echo "Graph matching: ${m}³ lattice nodes 10 µm apart, edges to the +x/+y/+z neighbours with three jittered"
echo "interior points; the copy has k = 1 % of the edges deleted and j = 0.5 % added (bent face diagonals, half"
echo "to a new node). node_tolerance 2, edge_tolerance 1.5, sample_spacing 0.5, overlap 0.8. \"exact\" = the"
echo "reported false negatives / positives equal k / j."
echo
echo "| nodes | edges | k deleted | j added | threads | samples | edge FN | edge FP | exact | time s | peak RSS MiB |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for t in 1 2; do
  "$bin" match "$m" "$k" "$j" $t
done
echo
echo "No peer: no packaged library matches spatial graphs with polylines (NetMets is a stand-alone C++/CUDA tool)."
