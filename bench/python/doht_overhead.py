"""What calling thinning.doht from Python costs over the CLI's node time.

One mask and its distance map (synthetic.network: a jittered lattice of rods of radius 3 every 24
voxels, N^3 voxels, dense enough that thinning works on every part of the grid) are made once and
written to HDF5. Then, alternating, R times each:
  - CLI:    `skelflow run` of read mask -> read distance -> thinning.doht, with --report; the time
            is the doht node's `seconds` (its run() alone).
  - Python: skelflow.modules.thinning.doht(mask, distance) on the NumPy arrays; the time is the
            whole call (building the one-node pipeline, validation, wrapping the arrays without
            copies, the run, the output array), and the node's own `seconds` from
            skelflow.last_report() for the same call.
overhead = call - node (same call, so machine noise cancels); ratio = call / CLI node (medians).
Prints a markdown section.
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    a = ap.parse_args()
    build = pathlib.Path(a.build).resolve()
    sys.path.insert(0, str(build / "python"))
    import skelflow

    cli = build / "cli" / "skelflow"
    n, t = a.size, a.threads
    with tempfile.TemporaryDirectory(prefix="skel_pybench_") as tmp:
        tmp = pathlib.Path(tmp)
        made = skelflow.run(_phantom_pipeline(skelflow, n), threads=t, output_dir=tmp,
                            outputs=["phantom.mask", "distance.distance"])
        mask, dist = made["phantom.mask"], made["distance.distance"]
        del made
        pipeline = tmp / "doht.yaml"
        pipeline.write_text(
            "skelflow: 1\nnodes:\n"
            "  mask: {module: io.read_volume, params: {path: mask.h5}}\n"
            "  dist: {module: io.read_volume, params: {path: dist.h5}}\n"
            "  doht: {module: thinning.doht, inputs: {mask: mask.volume, priority: dist.volume}}\n")
        cli_node, py_call, py_node = [], [], []
        skeleton_voxels = None
        for _ in range(a.repeat):
            report = tmp / "run.json"
            r = subprocess.run([str(cli), "run", str(pipeline), "--quiet", "--threads", str(t), "--report", str(report)],
                               capture_output=True, text=True)
            if r.returncode != 0:
                sys.exit("skelflow run failed: " + r.stderr)
            cli_node.append(_node_seconds(json.loads(report.read_text()), "doht"))
            t0 = time.perf_counter()
            out = skelflow.modules.thinning.doht(mask, dist, threads=t)
            py_call.append(time.perf_counter() - t0)
            py_node.append(_node_seconds(skelflow.last_report(), "doht"))
            skeleton_voxels = int(np.count_nonzero(out.skeleton))
            del out
    med = statistics.median
    overhead = [c - nd for c, nd in zip(py_call, py_node)]
    print("## Python: thinning.doht from NumPy vs the CLI node\n")
    print(f"synthetic.network rods (radius 3, period 24) {n}³: mask uint8 and float32 distance as NumPy arrays "
          "(no copies), "
          f"{t} threads, {a.repeat} alternating runs each, medians. CLI node = the doht node's run() in "
          "`skelflow run --report`; Python call = the whole `skelflow.modules.thinning.doht(mask, distance)` "
          "call; overhead = call − the node's own time in that call (skelflow.last_report()), which no "
          "difference between processes affects (the CLI runs in a fresh process, whose first touches of "
          "memory cost page faults that a warm Python process may not pay).\n")
    print("| grid | threads | skeleton voxels | CLI node s | Python call s | Python node s | overhead s | overhead % | call / CLI node |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| {n}³ | {t} | {skeleton_voxels} | {med(cli_node):.3f} | {med(py_call):.3f} | {med(py_node):.3f} | "
          f"{med(overhead):.4f} | {100 * med(overhead) / med(py_node):.2f} | {med(py_call) / med(cli_node):.3f} |")
    print()
    print("All runs (s): CLI node " + ", ".join(f"{x:.3f}" for x in cli_node) + "; Python call " +
          ", ".join(f"{x:.3f}" for x in py_call) + "; Python node " + ", ".join(f"{x:.3f}" for x in py_node) + ".")


def _phantom_pipeline(skelflow, n):
    p = skelflow.Pipeline()
    p.add_node("phantom", "synthetic.network", shape="rods", size=[n, n, n], seed=1, radius=3.0, period=24.0)
    p.add_node("distance", "distance.euclidean")
    p.add_node("save_mask", "io.write_volume", path="mask.h5")
    p.add_node("save_dist", "io.write_volume", path="dist.h5")
    p.connect("phantom.mask", "distance.mask")
    p.connect("phantom.mask", "save_mask.volume")
    p.connect("distance.distance", "save_dist.volume")
    return p


def _node_seconds(report, node):
    for rec in report["nodes"]:
        if rec["id"] == node:
            return float(rec["seconds"])
    raise KeyError(node)


if __name__ == "__main__":
    main()
