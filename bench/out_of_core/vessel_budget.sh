#!/usr/bin/env bash
# The whole vessel pipeline under a memory budget (issue 16, thesis Table 5.2): a synthetic vessel
# image (uint8, ~3.5 % vessel) read from HDF5 -> Gaussian -> Otsu threshold -> large components ->
# exact Euclidean DT -> smooth DOHT -> dual-cube graph -> prune -> statistics -> .am + summary.csv.
# Runs it in memory and with --memory-budget in the same run (the in-memory run is skipped with
# SKEL_BENCH_SKIP_IN_MEMORY=1, for volumes that do not fit), and prints one markdown section: wall
# time and peak RSS of each process (/usr/bin/time -v), seconds per stage (run report), peak scratch
# disk, and the recovered network of both runs against the phantom's ground truth.
#   bench/out_of_core/vessel_budget.sh BUILD_DIR NX NY NZ [BUDGET] [WORK_DIR]
# NX NY NZ: the volume; when NX or NY is more than 1280 the phantom is made at NX/2 x NY/2 x NZ and
# mirrored 2 x 2 in x and y (the phantom generator holds 5 bytes per voxel in memory); mirroring
# keeps every vessel continuous across the seams. BUDGET default 2GiB. SKEL_BENCH_RUN_ARGS: extra
# flags of the budget run (e.g. --no-block-resume). WORK_DIR (default: a new
# folder under the build dir) needs about 12 bytes per voxel of free disk at the peak (input,
# scratch volumes), and is removed at the end.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(cd "${1:?build dir}" && pwd)
nx=${2:?nx}
ny=${3:?ny}
nz=${4:?nz}
budget=${5:-2GiB}
threads=${SKEL_BENCH_THREADS:-2}
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
cmake --build "$build" --target skelflow >/dev/null
bin="$build/cli/skelflow"
work=${6:-$build/vessel_budget_work}
mkdir -p "$work"
work=$(cd "$work" && pwd)
trap 'rm -rf "$work"' EXIT

px=$nx
py_=$ny
mirror=0
if [ "$nx" -gt 1280 ] || [ "$ny" -gt 1280 ]; then
  px=$((nx / 2))
  py_=$((ny / 2))
  mirror=1
fi
# Ground truth: the vessel bench's dense network (64 roots, thick roots, long segments).
cat >"$work/make.yaml" <<YAML
skelflow: 1
nodes:
  phantom: {module: synthetic.vessel_tree, params: {size: [$px, $py_, $nz], seed: 1, roots: 64, root_radius: 9, min_radius: 2.5, length_scale: 2, noise: 0.1}}
  image8: {module: volume.convert, inputs: {input: phantom.image}, params: {dtype: uint8, mode: rescale}}
  save: {module: io.write_volume, inputs: {volume: image8.output}, params: {path: image.h5}}
  truth_stats: {module: analysis.network_statistics, inputs: {graph: phantom.truth}}
  save_truth: {module: io.write_table, inputs: {table: truth_stats.summary}, params: {path: truth_summary.csv}}
YAML
cat >"$work/bench.yaml" <<'YAML'
skelflow: 1
nodes:
  read: {module: io.read_volume, params: {path: image.h5}}
  smooth: {module: segmentation.gaussian, inputs: {image: read.volume}, params: {sigma: [0.7, 0.7, 0.7]}}
  seg: {module: segmentation.threshold, inputs: {image: smooth.image}, params: {method: otsu}}
  largest: {module: segmentation.connected_components, inputs: {mask: seg.mask}, params: {connectivity: 26, min_fraction: 0.05}}
  distance: {module: distance.euclidean, inputs: {mask: largest.mask}}
  skeleton: {module: thinning.doht, inputs: {mask: largest.mask, priority: distance.distance}, params: {variant: smooth, end_point_length: 2}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: skeleton.skeleton, distance: distance.distance}, params: {smooth_passes: 0}}
  pruned: {module: graph.prune, inputs: {graph: graph.graph}, params: {min_length: 4.0, radius_factor: 2.0}}
  stats: {module: analysis.network_statistics, inputs: {graph: pruned.graph}}
  save_am: {module: io.write_graph, inputs: {graph: pruned.graph}, params: {path: network.am}}
  save_summary: {module: io.write_table, inputs: {table: stats.summary}, params: {path: summary.csv}}
YAML
t0=$(date +%s)
"$bin" run "$work/make.yaml" --quiet --threads "$threads"
if [ $mirror = 1 ]; then
  mv "$work/image.h5" "$work/half.h5"
  "$py" - "$work/half.h5" "$work/image.h5" "$nx" "$ny" <<'PY'
import sys, h5py, numpy as np
src, dst, nx, ny = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
with h5py.File(src, "r") as f:
    d = f["volume"]
    nz, hy, hx = d.shape
    with h5py.File(dst, "w") as g:
        o = g.create_dataset("volume", shape=(nz, ny, nx), dtype=d.dtype, chunks=d.chunks, compression="gzip",
                             compression_opts=1, shuffle=False)
        for k, v in d.attrs.items():
            o.attrs[k] = v
        step = d.chunks[0]
        for z in range(0, nz, step):  # slab by slab: a 2 x 2 mirrored tiling in x and y
            s = d[z:z + step]
            full = np.empty((s.shape[0], ny, nx), dtype=s.dtype)
            full[:, :hy, :hx] = s
            full[:, :hy, hx:] = s[:, :, ::-1][:, :, :nx - hx]
            full[:, hy:, :] = full[:, :hy, :][:, ::-1, :][:, :ny - hy, :]
            o[z:z + step] = full
PY
  rm "$work/half.h5"
fi
t1=$(date +%s)
image_mib=$(du -m "$work/image.h5" | cut -f1)

# run LABEL ARGS...: one process; its row goes to $work/rows.md, its summary.csv to $work/LABEL/.
run() {
  local label=$1
  shift
  mkdir -p "$work/$label/scratch"
  local peak_disk=0
  ( while sleep 2; do du -sm "$work/$label/scratch" 2>/dev/null | cut -f1; done ) >"$work/$label.disk" &
  local watcher=$!
  local rc=0
  /usr/bin/time -v "$bin" run "$work/bench.yaml" --quiet --threads "$threads" --output-dir "$work/$label" \
    --report "$work/$label.json" "$@" 2>"$work/$label.time" >/dev/null || rc=$?
  kill $watcher 2>/dev/null || true
  wait $watcher 2>/dev/null || true
  peak_disk=$(sort -n "$work/$label.disk" | tail -1)
  "$py" - "$work" "$label" "$rc" "${peak_disk:-0}" >>"$work/rows.md" <<'PY'
import json, re, sys
work, label, rc, disk = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
t = open(f"{work}/{label}.time").read()
rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1)) / 1024
wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", t).group(1)
parts = [float(p) for p in wall.split(":")]
secs = sum(p * 60 ** i for i, p in enumerate(reversed(parts)))
cpu = float(re.search(r"User time \(seconds\): (\S+)", t).group(1)) + float(re.search(r"System time \(seconds\): (\S+)", t).group(1))
try:
    r = json.load(open(f"{work}/{label}.json"))
    stages = ", ".join("%s %.1f" % (n["id"], n["seconds"]) for n in r["nodes"] if n["seconds"] >= 0.05)
except Exception:
    stages = "(no report)"
if rc != 0:
    stages = "FAILED rc %d: %s" % (rc, t.strip().splitlines()[0][:300] if t.strip() else "")
print("| %s | %.1f | %.0f | %.0f | %s | %s |" % (label, secs, cpu, rss, disk, stages))
PY
}

echo "## Vessel pipeline under a memory budget (${nx}x${ny}x${nz})"
echo
echo "\`bench/out_of_core/vessel_budget.sh\`: \`synthetic.vessel_tree\` (64 roots, root radius 9, min radius 2.5,"
echo "length scale 2, noise 0.1, seed 1) at ${px}x${py_}x${nz}$( [ $mirror = 1 ] && echo ", mirrored 2 x 2 in x and y to ${nx}x${ny}x${nz}"),"
echo "rescaled to uint8 and written to HDF5 (gzip, ${image_mib} MiB, made in $((t1 - t0)) s, not timed below), then"
echo "read -> Gaussian (sigma 0.7) -> Otsu -> components (26, min_fraction 0.05) -> EDT -> smooth DOHT"
echo "(end_point_length 2) -> skeleton_to_graph -> prune -> statistics -> .am + summary.csv, $threads threads."
echo "Per process: wall and CPU seconds and peak RSS (/usr/bin/time -v), peak size of the scratch folder"
echo "(sampled every 2 s), seconds per stage (run report; stages under 0.05 s left out)."
echo
echo "| run | wall s | CPU s | peak RSS MiB | peak scratch MiB | seconds per stage |"
echo "|---|---|---|---|---|---|"
if [ "${SKEL_BENCH_SKIP_IN_MEMORY:-0}" != 1 ]; then
  run in-memory
fi
# shellcheck disable=SC2086  # SKEL_BENCH_RUN_ARGS: extra flags of the budget run, e.g. --no-block-resume
run "budget-$budget" --memory-budget "$budget" --scratch "$work/budget-$budget/scratch" ${SKEL_BENCH_RUN_ARGS:-}
cat "$work/rows.md"
echo
"$py" - "$work" "$budget" <<'PY'
import csv, os, sys
work, budget = sys.argv[1], sys.argv[2]
def summary(p):
    if not os.path.exists(p):
        return None
    with open(p) as f:
        return next(csv.DictReader(f), None)
truth = summary(f"{work}/truth_summary.csv")
runs = [(l, summary(f"{work}/{l}/summary.csv")) for l in ("in-memory", "budget-" + budget)]
runs = [(l, s) for l, s in runs if s]
keys = ["branch_points", "end_points", "loops", "total_length"]
print("| | phantom (one tile) | " + " | ".join(l for l, _ in runs) + " |")
print("|---|---|" + "---|" * len(runs))
for k in keys:
    tk = next((key for key in (truth or {}) if key.startswith(k)), None)
    row = [k, ("%.1f" % float(truth[tk])) if tk else "-"]
    for _, s in runs:
        sk = next((key for key in s if key.startswith(k)), None)
        row.append(("%.1f" % float(s[sk])) if sk else "-")
    print("| " + " | ".join(row) + " |")
PY
