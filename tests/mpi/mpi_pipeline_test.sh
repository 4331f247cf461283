#!/usr/bin/env bash
# skelflow-mpi against skelflow (issue 17), run by ctest when MPI is found:
#   mpi_pipeline_test.sh same    SKELFLOW SKELFLOW_MPI MPIEXEC "MPI_FLAGS" WORKDIR
#     the outputs of -np 1, 2 and 3 are the bytes of one skelflow process with the same budget and
#     blocks (odd block sizes, objects crossing block corners); no scratch or temporary is left; the
#     report lists every rank.
#   mpi_pipeline_test.sh fail    ...
#     a rank that fails (SKELFLOW_TEST_FAIL_RANK) ends the run on every rank with its error printed by
#     rank 0, exit status 1, and no output file.
set -euo pipefail
mode=$1 skelflow=$2 skelflow_mpi=$3 mpiexec=$4 mpiflags=$5 work=$6
if [ "$(id -u)" = 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
# Small runs on a shared machine: one thread per rank, no MPI progress spinning contest.
export OMPI_MCA_mpi_yield_when_idle=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
rm -rf "$work"
mkdir -p "$work"
cat > "$work/p.yaml" <<'YAML'
skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: rods, size: [37, 29, 23], period: 12, radius: 3, noise: 0.1}}
  denoise: {module: segmentation.median, inputs: {image: phantom.image}}
  smooth: {module: segmentation.gaussian, inputs: {image: denoise.image}, params: {sigma: [1.0, 1.5, 0.7]}}
  seg: {module: segmentation.threshold, inputs: {image: smooth.image}, params: {method: otsu}}
  parts: {module: segmentation.connected_components, inputs: {mask: seg.mask}, params: {connectivity: 26}}
  edt: {module: distance.euclidean, inputs: {mask: seg.mask}}
  dist: {module: distance.chamfer, inputs: {mask: seg.mask}}
  save_smooth: {module: io.write_volume, inputs: {volume: smooth.image}, params: {path: out/smooth.h5}}
  save_mask: {module: io.write_volume, inputs: {volume: seg.mask}, params: {path: out/mask.h5}}
  save_labels: {module: io.write_volume, inputs: {volume: parts.labels}, params: {path: out/labels.h5}}
  save_table: {module: io.write_table, inputs: {table: parts.table}, params: {path: out/components.csv}}
  save_edt: {module: io.write_volume, inputs: {volume: edt.distance}, params: {path: out/edt.h5}}
  save_dist: {module: io.write_volume, inputs: {volume: dist.distance}, params: {path: out/dist.h5}}
execution: {memory_budget: 1MiB, block: [13, 11, 9]}
YAML
outputs="out/components.csv out/dist.h5 out/edt.h5 out/labels.h5 out/mask.h5 out/smooth.h5"
listing() { (cd "$1" && find . -mindepth 1 | sort | tr '\n' ' '); }

# The same stages on a volume streamed from a file (io.read_volume block-wise, distributed too).
cat > "$work/read.yaml" <<'YAML'
skelflow: 1
nodes:
  read: {module: io.read_volume, params: {path: ref/out/smooth.h5}}
  seg: {module: segmentation.threshold, inputs: {image: read.volume}, params: {low: 0.3}}
  parts: {module: segmentation.connected_components, inputs: {mask: seg.mask}, params: {connectivity: 6}}
  edt: {module: distance.euclidean, inputs: {mask: seg.mask}}
  save_labels: {module: io.write_volume, inputs: {volume: parts.labels}, params: {path: out/labels.h5}}
  save_table: {module: io.write_table, inputs: {table: parts.table}, params: {path: out/components.csv}}
  save_edt: {module: io.write_volume, inputs: {volume: edt.distance}, params: {path: out/edt.h5}}
execution: {memory_budget: 1MiB, block: [16, 7, 10]}
YAML
read_outputs="out/components.csv out/edt.h5 out/labels.h5"

case "$mode" in
same)
  "$skelflow" run "$work/p.yaml" --output-dir "$work/ref" --quiet
  "$skelflow" run "$work/read.yaml" --output-dir "$work/read_ref" --quiet
  for np in 1 2 3; do
    dir="$work/np$np"
    # shellcheck disable=SC2086
    "$mpiexec" $mpiflags -np "$np" "$skelflow_mpi" run "$work/p.yaml" --output-dir "$dir" --quiet --report "$work/report$np.json"
    for f in $outputs; do
      cmp "$work/ref/$f" "$dir/$f" || { echo "FAIL: -np $np: $f differs from one process"; exit 1; }
    done
    want="./out $(for f in $outputs; do printf './%s ' "$f"; done)"
    got=$(listing "$dir")
    [ "$got" = "$want" ] || { echo "FAIL: -np $np left: $got (expected: $want)"; exit 1; }
    ranks=$(grep -c '"rank": ' "$work/report$np.json" || true)
    [ "$ranks" = "$np" ] || { echo "FAIL: -np $np: the report lists $ranks ranks"; cat "$work/report$np.json"; exit 1; }
    grep -q '"idle_share": ' "$work/report$np.json" || { echo "FAIL: no idle share in the report"; exit 1; }
    grep -q '"seconds_io": ' "$work/report$np.json" || { echo "FAIL: no I/O time in the report"; exit 1; }
    # shellcheck disable=SC2086
    "$mpiexec" $mpiflags -np "$np" "$skelflow_mpi" run "$work/read.yaml" --output-dir "$work/read$np" --quiet
    for f in $read_outputs; do
      cmp "$work/read_ref/$f" "$work/read$np/$f" || { echo "FAIL: -np $np, read.yaml: $f differs from one process"; exit 1; }
    done
  done
  # Every rank computed blocks of the distributed stages.
  for r in 0 1 2; do
    grep "\"rank\": $r," "$work/report3.json" | grep -qv '"blocks": 0,' || { echo "FAIL: rank $r computed no block"; cat "$work/report3.json"; exit 1; }
    grep "\"rank\": $r," "$work/report3.json" | grep -qv '"bytes_written": 0}' || { echo "FAIL: rank $r wrote nothing to the shared volumes"; cat "$work/report3.json"; exit 1; }
  done
  # Nothing left beside the pipeline: no scratch file, no temporary.
  extra=$(cd "$work" && find . -maxdepth 1 -mindepth 1 -name '.*' | tr '\n' ' ')
  [ -z "$extra" ] || { echo "FAIL: left in the pipeline folder: $extra"; exit 1; }
  echo "OK: -np 1, 2, 3 give the bytes of one process"
  ;;
fail)
  set +e
  # shellcheck disable=SC2086
  SKELFLOW_TEST_FAIL_RANK=1 "$mpiexec" $mpiflags -np 3 "$skelflow_mpi" run "$work/p.yaml" \
    --output-dir "$work/failed" --quiet --report "$work/failed.json" > "$work/out.txt" 2>&1
  rc=$?
  set -e
  cat "$work/out.txt"
  [ "$rc" != 0 ] || { echo "FAIL: a failed rank ended with status 0"; exit 1; }
  grep -q "rank 1: .*failure injected on rank 1" "$work/out.txt" || { echo "FAIL: rank 0 did not name rank 1's error"; exit 1; }
  grep -q "p.yaml:[0-9]*:[0-9]*: node '" "$work/out.txt" || { echo "FAIL: the error names no node"; exit 1; }
  [ "$(grep -c 'failure injected' "$work/out.txt")" = 1 ] || { echo "FAIL: the error was printed more than once"; exit 1; }
  if [ -d "$work/failed" ]; then
    left=$(listing "$work/failed")
    [ -z "$left" ] || [ "$left" = "./out " ] || { echo "FAIL: a failed run left: $left"; exit 1; }
  fi
  extra=$(cd "$work" && find . -maxdepth 1 -mindepth 1 -name '.*' | tr '\n' ' ')
  [ -z "$extra" ] || { echo "FAIL: a failed run left in the pipeline folder: $extra"; exit 1; }
  grep -q '"ok": false' "$work/failed.json" || { echo "FAIL: the report does not say the run failed"; exit 1; }
  echo "OK: a failed rank ends the run with its error on rank 0 and no output"
  ;;
*) echo "unknown mode $mode"; exit 2 ;;
esac
