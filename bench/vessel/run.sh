#!/usr/bin/env bash
# The whole vessel pipeline (pipelines/vessel_network.yaml, unchanged) on a SIZE³ phantom: wall time
# and peak RSS per stage from the run report, and the recovered network against the phantom's ground
# truth. Prints one markdown section.
#   bench/vessel/run.sh BUILD_DIR [SIZE]     (SIZE default 512)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=${1:-build}
n=${2:-512}
threads=${SKEL_BENCH_THREADS:-2}
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
cmake --build "$build" --target skelflow >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The shipped pipeline plus statistics of the ground-truth graph, for the comparison below.
cp "$root/pipelines/vessel_network.yaml" "$work/p.yaml"
cat >>"$work/p.yaml" <<'YAML'
  truth_stats: {module: analysis.network_statistics, inputs: {graph: phantom.truth}}
  save_truth_summary: {module: io.write_table, inputs: {table: truth_stats.summary}, params: {path: vessels/truth_summary.csv}}
YAML
# A denser network than the small default: 64 roots, thicker root vessels, longer segments.
params=(--set "phantom.size=[$n,$n,$n]" --set phantom.roots=64 --set phantom.root_radius=9
        --set phantom.min_radius=2.5 --set phantom.length_scale=2)
load0=$(cut -d' ' -f1 /proc/loadavg)
"$build/cli/skelflow" run "$work/p.yaml" "${params[@]}" --threads "$threads" --output-dir "$work/out" \
  --report "$work/run.json" >"$work/log.txt" 2>&1
"$py" - "$work" "$n" "$threads" "${params[*]}" "$load0" <<'PY'
import csv, json, sys
work, n, threads, params, load0 = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
r = json.load(open(work + "/run.json"))
print("## Vessel pipeline (whole, %d³)" % n)
print()
print("`pipelines/vessel_network.yaml` run by `skelflow run` with `%s`, %s threads." % (params, threads))
print("Per stage: wall time, the process's peak RSS when the stage ended (a high-water mark: it includes")
print("every earlier stage) and its RSS then (what stays alive), from the run report;")
print("floor: the stage's physical floor, one read of its volume inputs and one write of its volume output")
print("at this machine's memory bandwidth measured in the same run (a NumPy copy of 1 GiB, best of 3:")
print("bytes read + written per second), and the ratio time / floor.")
print()
import numpy as np, time
a = np.ones(1 << 28, dtype=np.float32); b = np.empty_like(a)
best = min((lambda t0: (np.copyto(b, a), time.perf_counter() - t0)[1])(time.perf_counter()) for _ in range(3))
bw = 2.0 * a.nbytes / best  # bytes moved per second (read + write)
del a, b
# Bytes per voxel read + written by each volume stage (inputs read once, output written once).
# io.write_volume: the mask read, the gzip'd HDF5 file written (~0.1 byte per voxel: counted as 0).
floor_bytes = {"segmentation.gaussian": 4 + 4, "segmentation.threshold": 4 + 1,
               "segmentation.connected_components": 1 + 1, "io.write_volume": 1,
               "distance.euclidean": 1 + 4, "thinning.doht": 1 + 4 + 1}
voxels = float(n) ** 3
print("| stage | module | time (s) | CPU (s) | peak RSS (MiB) | RSS after (MiB) | floor (s) | time / floor |")
print("|---|---|---|---|---|---|---|---|")
processing = 0.0
processing_cpu = 0.0
phantom_peak = 0.0
for node in r["nodes"]:
    fb = floor_bytes.get(node["module"])
    fl = "%.3f | %.1f×" % (fb * voxels / bw, node["seconds"] / (fb * voxels / bw)) if fb else " | "
    print("| %s | %s | %.3f | %.2f | %.0f | %.0f | %s |" % (node["id"], node["module"], node["seconds"],
          node.get("cpu_seconds", 0.0), node["peak_rss_mib"], node.get("rss_mib", 0.0), fl))
    if node["module"] != "synthetic.vessel_tree":
        processing += node["seconds"]
        processing_cpu += node.get("cpu_seconds", 0.0)
    else:
        phantom_peak = node["peak_rss_mib"]
print("| **total** | | **%.2f** | | **%.0f** | | | |" % (r["seconds"], r["peak_rss_mib"]))
print()
bpv = lambda mib: mib * 1048576.0 / voxels
print("Processing (every stage but the phantom; stages that overlap are counted each): %.1f s wall, %.1f s CPU"
      " (cpu_seconds: the process's CPU time while a stage ran); load average %s at the start, %s at the end; peak RSS %.2f bytes per voxel (%.0f MiB; the phantom"
      " stage alone reached %.2f); memory bandwidth %.1f GB/s." % (processing, processing_cpu, load0, open("/proc/loadavg").read().split()[0], bpv(r["peak_rss_mib"]), r["peak_rss_mib"],
                                                                bpv(phantom_peak), bw / 1e9))
print()
def row(path):
    with open(path) as f:
        return next(csv.DictReader(f))
rec = row(work + "/out/vessels/summary.csv")
tru = row(work + "/out/vessels/truth_summary.csv")
length = [k for k in rec if k.startswith("total_length")][0]
print("| | ground truth | recovered | difference |")
print("|---|---|---|---|")
for key in ["branch_points", "end_points", "loops", length]:
    a, b = float(tru[key]), float(rec[key])
    print("| %s | %.1f | %.1f | %+.1f%% |" % (key, a, b, 100.0 * (b - a) / a if a else 0.0))
print()
import os
cpu = [l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")][0]
print("Machine: %d cores, %s." % (os.cpu_count(), cpu))
PY
