#!/usr/bin/env bash
# skelflow-mpi (issue 17): one skelflow process vs mpirun -np 1/2/4 skelflow-mpi in the same run, on
# the vessel phantom of bench/out_of_core/vessel_budget.sh (synthetic.vessel_tree, 64 roots, root
# radius 9, min radius 2.5, length scale 2, noise 0.1, seed 1, rescaled to uint8) of n³ (default
# 1024) read from HDF5 -> Gaussian (sigma 0.7) -> Otsu threshold -> components (26, min_fraction
# 0.05) -> exact Euclidean DT, under a memory budget per rank (default 1GiB): the stages skelflow-mpi
# distributes. Per run: wall and CPU seconds (/usr/bin/time, CPU of all ranks), peak RSS of the
# largest rank, seconds per stage (rank 0's report); per rank (the report's `ranks`): time in its
# blocks, of which reading and writing the shared scratch volumes, idle share (time in collectives /
# wall), bytes exchanged, bytes read + written; and whether the component table (counts and sizes)
# is the bytes of one process's. Then the inputs of the cost model (bench/RESULTS.md, "skelflow-mpi"):
# compute seconds per block voxel, I/O bandwidth per rank, seconds per collective.
#   bench/mpi/run.sh BUILD_DIR [SIZE] [BUDGET] [WORK_DIR]
# SKEL_BENCH_PIPELINE=skeleton: the stages distributed since (session 8) instead: read -> Gaussian ->
# Otsu -> fill_cavities -> exact Euclidean DT -> block-wise thinning (DOHT, priority the DT) ->
# skeleton_to_graph; same: the graph file (and the fill's mask) equal one process's.
# SKEL_BENCH_NPS: the rank counts (default "1 2 4").
# Memory: the phantom generator holds about 5 bytes per voxel (5 GiB at 1024³), each rank about its
# budget plus ~300 MiB: run it under `flock /work/bigmem.lock` on shared machines. Disk: about 16
# bytes per voxel at the peak (input, scratch volumes) in WORK_DIR (default: a new folder under the
# build dir, removed at the end). Ranks beyond the cores share them (--oversubscribe): on a 2-core
# machine -np 4 measures overhead, not speed-up.
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
n=${2:-1024}
budget=${3:-1GiB}
threads=${SKEL_BENCH_THREADS:-1}
# Per-block journals (--resume) are kept by one process but not in distributed loops: off for all.
read -r -a run_args <<<"${SKEL_BENCH_RUN_ARGS:---no-block-resume}"
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
cmake --build "$build" --target skelflow skelflow-mpi >/dev/null
bin="$build/cli/skelflow"
mpibin="$build/cli/skelflow-mpi"
if [ "$(id -u)" = 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
# Waiting ranks yield their core (more ranks than cores), no single-copy mechanism in containers.
export OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_MCA_mpi_yield_when_idle=1
work=${4:-$build/mpi_bench_work}
mkdir -p "$work"
work=$(cd "$work" && pwd)
trap 'rm -rf "$work"' EXIT

cat >"$work/make.yaml" <<YAML
skelflow: 1
nodes:
  phantom: {module: synthetic.vessel_tree, params: {size: [$n, $n, $n], seed: 1, roots: 64, root_radius: 9, min_radius: 2.5, length_scale: 2, noise: 0.1}}
  image8: {module: volume.convert, inputs: {input: phantom.image}, params: {dtype: uint8, mode: rescale}}
  save: {module: io.write_volume, inputs: {volume: image8.output}, params: {path: image.h5}}
YAML
cat >"$work/bench.yaml" <<'YAML'
skelflow: 1
nodes:
  read: {module: io.read_volume, params: {path: image.h5}}
  smooth: {module: segmentation.gaussian, inputs: {image: read.volume}, params: {sigma: [0.7, 0.7, 0.7]}}
  seg: {module: segmentation.threshold, inputs: {image: smooth.image}, params: {method: otsu}}
  largest: {module: segmentation.connected_components, inputs: {mask: seg.mask}, params: {connectivity: 26, min_fraction: 0.05}}
  distance: {module: distance.euclidean, inputs: {mask: largest.mask}}
  save_table: {module: io.write_table, inputs: {table: largest.table}, params: {path: components.csv}}
YAML
pipeline=${SKEL_BENCH_PIPELINE:-components}
compare=components.csv
if [ "$pipeline" = skeleton ]; then
  cat >"$work/bench.yaml" <<'YAML'
skelflow: 1
nodes:
  read: {module: io.read_volume, params: {path: image.h5}}
  smooth: {module: segmentation.gaussian, inputs: {image: read.volume}, params: {sigma: [0.7, 0.7, 0.7]}}
  seg: {module: segmentation.threshold, inputs: {image: smooth.image}, params: {method: otsu}}
  fill: {module: segmentation.fill_cavities, inputs: {mask: seg.mask}}
  distance: {module: distance.euclidean, inputs: {mask: fill.mask}}
  thin: {module: thinning.doht, inputs: {mask: fill.mask, priority: distance.distance}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: thin.skeleton, distance: distance.distance}}
  save_graph: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: graph.vtp}}
  save_thin: {module: io.write_table, inputs: {table: thin.table}, params: {path: thinning.csv}}
YAML
  compare=graph.vtp
fi
read -r -a nps <<<"${SKEL_BENCH_NPS:-1 2 4}"
t0=$(date +%s)
"$bin" run "$work/make.yaml" --quiet --threads 2
t1=$(date +%s)

# run LABEL COMMAND...: one run; its row goes to $work/rows.md.
run() {
  local label=$1
  shift
  mkdir -p "$work/$label"
  local rc=0
  /usr/bin/time -f "%e %U %S %M" -o "$work/$label.time" "$@" run "$work/bench.yaml" --quiet --threads "$threads" \
    --memory-budget "$budget" --output-dir "$work/$label" --scratch "$work/$label/scratch" \
    --report "$work/$label.json" "${run_args[@]}" >/dev/null 2>"$work/$label.err" || rc=$?
  local same=no
  if [ "$label" = serial ]; then
    same=-
  elif cmp -s "$work/serial/$compare" "$work/$label/$compare"; then
    same=yes
  fi
  "$py" - "$work" "$label" "$rc" "$same" >>"$work/rows.md" <<'PY'
import json, sys
work, label, rc, same = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
wall, user, sys_, rss = open(f"{work}/{label}.time").read().split()[-4:]
try:
    r = json.load(open(f"{work}/{label}.json"))
    stages = ", ".join("%s %.1f" % (n["id"], n["seconds"]) for n in r["nodes"] if n["seconds"] >= 0.05)
    ranks = "; ".join(
        "r%d: blocks %.1f s (I/O %.1f s), idle %.0f %%, %s B exchanged, %.0f MiB I/O"
        % (k["rank"], k["seconds_blocks"], k["seconds_io"], 100 * k["idle_share"], k["bytes_sent"] + k["bytes_received"],
           (k["bytes_read"] + k["bytes_written"]) / 2**20) for k in r.get("ranks", []))
except Exception:
    stages, ranks = "(no report)", ""
if rc != 0:
    stages = "FAILED rc %d: %s" % (rc, open(f"{work}/{label}.err").read().strip()[:300])
print("| %s | %.1f | %.1f | %.0f | %s | %s | %s |" % (label, float(wall), float(user) + float(sys_), int(rss) / 1024, same,
                                                      stages, ranks or "-"))
PY
}

run serial "$bin"
for np in "${nps[@]}"; do
  run "np$np" mpirun --oversubscribe --bind-to none -np "$np" "$mpibin"
done

echo "## skelflow-mpi at ${n}³"
echo
echo "\`bench/mpi/run.sh\`: the vessel phantom of vessel_budget.sh at ${n}³ (uint8, made in $((t1 - t0)) s, not"
if [ "$pipeline" = skeleton ]; then
  echo "timed) read from HDF5 -> Gaussian (sigma 0.7) -> Otsu -> fill_cavities -> exact Euclidean DT -> thinning"
  echo "(DOHT, block-wise) -> skeleton_to_graph, \`--memory-budget $budget ${run_args[*]}\` per rank, $threads thread(s) per rank, $(nproc) cores shared with other"
else
  echo "timed) read from HDF5 -> Gaussian (sigma 0.7) -> Otsu -> components (26, min_fraction 0.05) -> exact"
  echo "Euclidean DT, \`--memory-budget $budget ${run_args[*]}\` per rank, $threads thread(s) per rank, $(nproc) cores shared with other"
fi
echo "users of the machine (load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)). CPU: all ranks; RSS: the"
echo "largest rank. same: $compare equals one process's (cmp)."
echo
echo "| run | wall s | CPU s | peak RSS MiB | same | seconds per stage (rank 0) | per rank |"
echo "|---|---|---|---|---|---|---|"
cat "$work/rows.md"
echo
# Cost model inputs from the distributed runs: compute seconds per voxel of the distributed stages'
# blocks (block time minus I/O time, summed over ranks, per voxel pass), I/O bandwidth per rank,
# seconds per collective (waiting included: an upper bound of the exchange cost).
"$py" - "$work" "$n" <<'PY'
import json, sys
work, n = sys.argv[1], int(sys.argv[2])
print("| run | compute s (all ranks) | I/O s (all ranks) | I/O GiB | I/O MiB/s per rank | collectives per rank | waiting s per collective |")
print("|---|---|---|---|---|---|---|")
for np in (1, 2, 3, 4, 8):
    try:
        r = json.load(open(f"{work}/np{np}.json"))
    except Exception:
        continue
    ks = r.get("ranks", [])
    comp = sum(k["seconds_blocks"] - k["seconds_io"] for k in ks)
    io = sum(k["seconds_io"] for k in ks)
    b = sum(k["bytes_read"] + k["bytes_written"] for k in ks)
    coll = max(k["collectives"] for k in ks)
    wait = sum(k["seconds_waiting"] for k in ks) / max(1, len(ks))
    print("| -np %d | %.1f | %.1f | %.2f | %.0f | %d | %.4f |" % (np, comp, io, b / 2**30, (b / 2**20) / io if io > 0 else 0,
                                                              coll, wait / coll if coll else 0))
PY
