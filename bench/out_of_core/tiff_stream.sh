#!/usr/bin/env bash
# Issue 19: a 2048 x 2048 x 512 uint8 TIFF stack (2 GiB, made by make_tiff_stack.py in a temporary
# folder and deleted afterwards) streams through the out-of-core vessel pipeline with
# --memory-budget 512MiB: io.read_volume (TIFF pages box by box into a scratch volume) -> median ->
# Otsu threshold -> io.write_volume (HDF5, compressed, band by band). In the same run, a stack that
# fits in memory (same width and height, SMALL_NZ slices) goes through the same pipeline in memory
# and with the budget, for the ratio. Wall time and peak RSS of each process (/usr/bin/time -v),
# seconds and peak RSS per stage (the run report).
#   bench/out_of_core/tiff_stream.sh BUILD_DIR [NX NY NZ] [BUDGET] [SMALL_NZ]
# Scratch and stack live in $SKEL_BENCH_TMP (default /tmp); the big run needs ~3x the stack on disk
# (stack, read volume, median; the read volume is removed when the median is done, then the mask).
set -euo pipefail
build=${1:-build}
nx=${2:-2048}
ny=${3:-2048}
nz=${4:-512}
budget=${5:-512MiB}
small=${6:-64}
threads=${SKEL_BENCH_THREADS:-2}
here=$(cd "$(dirname "$0")" && pwd)
bin="$build/cli/skelflow"
work=$(mktemp -d "${SKEL_BENCH_TMP:-/tmp}/skelflow-tiff-stream.XXXXXX")
trap 'rm -rf "$work"' EXIT

pipeline() {  # pipeline STACK OUT
  cat <<YAML
skelflow: 1
nodes:
  read: {module: io.read_volume, params: {path: $1}}
  denoise: {module: segmentation.median, inputs: {image: read.volume}}
  seg: {module: segmentation.threshold, inputs: {image: denoise.image}, params: {method: otsu}}
  save: {module: io.write_volume, inputs: {volume: seg.mask}, params: {path: $2}}
  save_table: {module: io.write_table, inputs: {table: seg.table}, params: {path: $2.csv}}
YAML
}

# run LABEL YAML ARGS...: prints a table row
run() {
  local label=$1 yaml=$2
  shift 2
  /usr/bin/time -v "$bin" run "$yaml" --quiet --threads "$threads" --report "$work/$label.json" "$@" \
    2>"$work/$label.time" >/dev/null
  local rss wall stages fraction
  rss=$(awk -F: '/Maximum resident set size/ {printf "%.0f", $2 / 1024}' "$work/$label.time")
  wall=$(awk '/Elapsed \(wall clock\)/ {n = split($NF, t, ":"); s = 0; for (i = 1; i <= n; ++i) s = s * 60 + t[i]; printf "%.1f", s}' "$work/$label.time")
  stages=$(/usr/bin/python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
print(", ".join("%s %.1f s / %.0f MiB" % (n["id"], n["seconds"], n.get("peak_rss_mib", 0)) for n in r["nodes"]))' "$work/$label.json")
  fraction=$(awk -F, 'NR == 2 {printf "%.4f", $3}' "$work/$label.h5.csv")
  echo "| $label | $wall | $rss | $fraction | $stages |"
}

t0=$(date +%s)
/usr/bin/python3 "$here/make_tiff_stack.py" "$work/big.tif" "$nx" "$ny" "$nz" >/dev/null
t1=$(date +%s)
/usr/bin/python3 "$here/make_tiff_stack.py" "$work/small.tif" "$nx" "$ny" "$small" >/dev/null
pipeline "$work/big.tif" "$work/big-budget.h5" >"$work/big-budget.yaml"
pipeline "$work/small.tif" "$work/small-in-memory.h5" >"$work/small-in-memory.yaml"
pipeline "$work/small.tif" "$work/small-budget.h5" >"$work/small-budget.yaml"

echo "Stacks: \`make_tiff_stack.py\` (tubes over noise, uint8, uncompressed, one strip per page): ${nx}x${ny}x${nz}"
echo "($((nx * ny * nz / 1048576)) MiB, written in $((t1 - t0)) s) and ${nx}x${ny}x${small} ($((nx * ny * small / 1048576)) MiB). $threads threads."
echo
echo "| run | wall s | peak RSS MiB | object fraction | per stage: seconds / process peak RSS when it ended |"
echo "|---|---|---|---|---|"
run small-in-memory "$work/small-in-memory.yaml"
run small-budget "$work/small-budget.yaml" --memory-budget "$budget" --scratch "$work"
rm -f "$work/small.tif"
run big-budget "$work/big-budget.yaml" --memory-budget "$budget" --scratch "$work"
if cmp -s "$work/small-in-memory.h5" "$work/small-budget.h5"; then echo; echo "The small mask files (in memory, budget) are the same bytes."; else echo; echo "WARNING: the small mask files differ"; fi
