#!/usr/bin/env bash
# skelflow-mpi (issue 17): one skelflow process vs mpirun -np 1/2/4 skelflow-mpi in the same run, on
# a synthetic vessel mask of n³ (default 512) read from HDF5 -> Gaussian -> threshold -> connected
# components and exact Euclidean DT under a memory budget (default 256MiB). Wall time, time per
# stage and, per rank, time in blocks, idle share (time in collectives / wall) and bytes exchanged
# (the run report's `ranks`). Needs about 1.5 GiB of RAM per rank at 512³: run it under
# `flock /work/bigmem.lock` on shared machines. Ranks beyond the cores share them (--oversubscribe):
# on a 2-core machine -np 4 measures overhead, not speed-up.
#   bench/mpi/run.sh BUILD_DIR [SIZE] [BUDGET]
set -euo pipefail
build=${1:-build}
n=${2:-512}
budget=${3:-256MiB}
threads=${SKEL_BENCH_THREADS:-1}
cmake --build "$build" --target skelflow skelflow-mpi >/dev/null
bin="$build/cli/skelflow"
mpibin="$build/cli/skelflow-mpi"
if [ "$(id -u)" = 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
export OMPI_MCA_btl_vader_single_copy_mechanism=none
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
  smooth: {module: segmentation.gaussian, inputs: {image: read.volume}, params: {sigma: [1, 1, 1]}}
  seg: {module: segmentation.threshold, inputs: {image: smooth.image}, params: {low: 0.5}}
  components: {module: segmentation.connected_components, inputs: {mask: seg.mask}}
  edt: {module: distance.euclidean, inputs: {mask: seg.mask}}
YAML
"$bin" run "$work/make.yaml" --quiet --threads "$threads"

summary() {
  /usr/bin/python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
stages = ", ".join("%s %.1f" % (n["id"], n["seconds"]) for n in r["nodes"])
ranks = "; ".join("r%d: blocks %.1f s, idle %.0f %%, %d B" % (k["rank"], k["seconds_blocks"], 100 * k["idle_share"],
                  k["bytes_sent"] + k["bytes_received"]) for k in r.get("ranks", []))
print("| %s | %.2f | %s | %s |" % (sys.argv[2], r["seconds"], stages, ranks or "-"))' "$1" "$2"
}

echo "## skelflow-mpi"
echo
echo "Mask: \`synthetic.vessel_tree\` $n³ (seed 1), read from HDF5 -> Gaussian (sigma 1) -> threshold ->"
echo "connected components + exact Euclidean DT, \`--memory-budget $budget\`, $threads thread(s) per rank;"
echo "$(nproc) cores shared with other users of the machine."
echo
echo "| run | wall s | seconds per stage (rank 0) | per rank |"
echo "|---|---|---|---|"
"$bin" run "$work/bench.yaml" --quiet --threads "$threads" --memory-budget "$budget" --report "$work/serial.json" >/dev/null
summary "$work/serial.json" "skelflow (1 process)"
for np in 1 2 4; do
  mpirun --oversubscribe -np "$np" "$mpibin" run "$work/bench.yaml" --quiet --threads "$threads" \
    --memory-budget "$budget" --report "$work/np$np.json" >/dev/null
  summary "$work/np$np.json" "skelflow-mpi -np $np"
done
