#!/usr/bin/env bash
# Out-of-core execution (issue 16) vs in memory, in the same run: a synthetic vessel mask of n³
# (default 512) read from HDF5 -> chamfer, exact Euclidean DT, connected components, once in memory
# and once with --memory-budget (default 256MiB; the block-wise stages keep their volumes in scratch
# files). Peak RSS of each process (/usr/bin/time -v), wall time and time per stage (the run
# report). The results are not written (io.write_volume runs in memory and would load them); the
# tests (tests/pipelines/out_of_core_test.cpp) check that the out-of-core results are the same bytes.
#   bench/out_of_core/run.sh BUILD_DIR [SIZE] [BUDGET]
set -euo pipefail
build=${1:-build}
n=${2:-512}
budget=${3:-256MiB}
threads=${SKEL_BENCH_THREADS:-2}
cmake --build "$build" --target skelflow >/dev/null
bin="$build/cli/skelflow"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cat >"$work/make.yaml" <<YAML
skelflow: 1
nodes:
  vessels: {module: synthetic.vessel_tree, params: {size: [$n, $n, $n], seed: 1}}
  save: {module: io.write_volume, inputs: {volume: vessels.mask}, params: {path: mask.h5}}
YAML
cat >"$work/bench.yaml" <<YAML
skelflow: 1
nodes:
  read: {module: io.read_volume, params: {path: mask.h5}}
  chamfer: {module: distance.chamfer, inputs: {mask: read.volume}}
  edt: {module: distance.euclidean, inputs: {mask: read.volume}}
  components: {module: segmentation.connected_components, inputs: {mask: read.volume}}
YAML
"$bin" run "$work/make.yaml" --quiet --threads "$threads"

# run LABEL ARGS...: prints "LABEL|wall s|peak MiB|per-stage seconds"
run() {
  local label=$1
  shift
  /usr/bin/time -v "$bin" run "$work/bench.yaml" --quiet --threads "$threads" --report "$work/$label.json" "$@" \
    2>"$work/$label.time" >/dev/null
  local rss wall stages
  rss=$(awk -F: '/Maximum resident set size/ {printf "%.0f", $2 / 1024}' "$work/$label.time")
  wall=$(sed -n 's/^  "seconds": \([0-9.e+-]*\),$/\1/p' "$work/$label.json")
  stages=$(/usr/bin/python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
print(", ".join("%s %.2f" % (n["id"], n["seconds"]) for n in r["nodes"]))' "$work/$label.json")
  echo "| $label | $(printf '%.2f' "$wall") | $rss | $stages |"
}

echo "## Out-of-core execution"
echo
echo "Mask: \`synthetic.vessel_tree\` $n³ (seed 1, uint8, $((n * n * n / 1048576)) MiB), read from HDF5, then chamfer"
echo "(uint16 out), exact Euclidean DT (float32 out) and connected components (uint32 labels + uint8 mask),"
echo "$threads threads. In memory vs \`--memory-budget $budget\` (blocks and slabs from the budget; scratch"
echo "files next to the pipeline). Peak RSS of the whole process (the mask read in memory included:"
echo "io.read_volume is not block-wise yet)."
echo
echo "| run | wall s | peak RSS MiB | seconds per stage |"
echo "|---|---|---|---|"
run in-memory
run "budget-$budget" --memory-budget "$budget"
# The 2 GiB TIFF stack of issue 19 (about 15 min and 6.5 GB of temporary disk): on request.
if [ "${SKEL_BENCH_TIFF_STREAM:-0}" = 1 ]; then
  echo
  bash "$(dirname "$0")/tiff_stream.sh" "$build"
fi
