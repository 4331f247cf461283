#!/usr/bin/env bash
# skelflow-mpi against skelflow (issue 17), run by ctest when MPI is found:
#   mpi_pipeline_test.sh same    SKELFLOW SKELFLOW_MPI MPIEXEC "MPI_FLAGS" WORKDIR
#     skelflow links no MPI library (ldd);
#     the outputs of -np 1, 2 and 3 are the bytes of one skelflow process with the same budget and
#     blocks (odd block sizes, objects crossing block corners); no scratch or temporary is left; the
#     report lists every rank.
#   mpi_pipeline_test.sh resume  ...
#     with -np 1, 2 and 3: the job is killed (SIGKILL to mpirun and every rank) in the middle of the
#     distributed thinning and in the middle of illumination_z (not distributed: every rank journals
#     its blocks), each time resumed with `mpirun -np N ... --resume`; the outputs are the bytes of
#     one uninterrupted skelflow process, the resumed runs loaded the finished stages and illum's
#     finished blocks, and nothing is left. Resuming with another number of ranks is refused.
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
  thin: {module: thinning.doht, inputs: {mask: seg.mask, priority: edt.distance}}
  save_skel: {module: io.write_volume, inputs: {volume: thin.skeleton}, params: {path: out/skeleton.h5}}
  save_thin: {module: io.write_table, inputs: {table: thin.table}, params: {path: out/thinning.csv}}
  fill: {module: segmentation.fill_cavities, inputs: {mask: seg.mask}}
  save_fill: {module: io.write_volume, inputs: {volume: fill.mask}, params: {path: out/filled.h5}}
  illum: {module: segmentation.illumination_z, inputs: {image: phantom.image}}
  save_illum: {module: io.write_volume, inputs: {volume: illum.image}, params: {path: out/illum.h5}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: thin.skeleton, distance: edt.distance}, params: {with_manifold: true}}
  save_graph: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: out/graph.vtp}}
  save_manifold: {module: io.write_volume, inputs: {volume: graph.manifold}, params: {path: out/manifold.h5}}
execution: {memory_budget: 1MiB, block: [13, 11, 9]}
YAML
outputs="out/components.csv out/dist.h5 out/edt.h5 out/filled.h5 out/graph.vtp out/illum.h5 out/labels.h5 out/manifold.h5 out/mask.h5 out/skeleton.h5 out/smooth.h5 out/thinning.csv"
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

# Thinning, fill and the graph on more blocks than the halo reaches across (blocks 16³, halo ~6:
# only neighbouring sub-blocks overlap), so that the thinning's wavefronts hold several blocks.
cat > "$work/thin.yaml" <<'YAML'
skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: rods, size: [96, 80, 48], period: 16, radius: 4, noise: 0.05, seed: 3}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}, params: {method: otsu}}
  fill: {module: segmentation.fill_cavities, inputs: {mask: seg.mask}}
  edt: {module: distance.euclidean, inputs: {mask: fill.mask}}
  thin: {module: thinning.doht, inputs: {mask: fill.mask, priority: edt.distance}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: thin.skeleton, distance: edt.distance}}
  save_skel: {module: io.write_volume, inputs: {volume: thin.skeleton}, params: {path: out/skeleton.h5}}
  save_thin: {module: io.write_table, inputs: {table: thin.table}, params: {path: out/thinning.csv}}
  save_graph: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: out/graph.vtp}}
execution: {memory_budget: 4MiB, block: [16, 16, 16]}
YAML
thin_outputs="out/graph.vtp out/skeleton.h5 out/thinning.csv"

case "$mode" in
same)
  # The serial program needs no MPI at run time (only skelflow-mpi links it).
  if command -v ldd > /dev/null; then
    mpi_libs=$(ldd "$skelflow" | grep -E 'libmpi|openmpi|libhdf5_openmpi|libhdf5_mpich' || true)
    [ -z "$mpi_libs" ] || { echo "FAIL: skelflow links MPI: $mpi_libs"; exit 1; }
  fi
  "$skelflow" run "$work/p.yaml" --output-dir "$work/ref" --quiet
  "$skelflow" run "$work/read.yaml" --output-dir "$work/read_ref" --quiet
  "$skelflow" run "$work/thin.yaml" --output-dir "$work/thin_ref" --quiet
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
    # shellcheck disable=SC2086
    "$mpiexec" $mpiflags -np "$np" "$skelflow_mpi" run "$work/thin.yaml" --output-dir "$work/thin$np" --quiet --report "$work/thin$np.json"
    for f in $thin_outputs; do
      cmp "$work/thin_ref/$f" "$work/thin$np/$f" || { echo "FAIL: -np $np, thin.yaml: $f differs from one process"; exit 1; }
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
resume)
  "$skelflow" run "$work/p.yaml" --output-dir "$work/ref" --quiet
  # Every process of the job: mpirun leads its own session (setsid), the ranks are in it.
  job_pids() { ps -eo pid=,sid= | awk -v s="$1" '$2 == s { print $1 }'; }
  for np in 1 2 3; do
    dir="$work/np$np" scratch="$work/scratch$np"
    rm -rf "$dir" "$scratch"
    mkdir -p "$scratch"
    args=(run "$work/p.yaml" --output-dir "$dir" --scratch "$scratch")
    killed_thin=0 killed_illum=0 rc=1
    declare -A journal_size=()
    for round in 1 2 3 4 5 6; do
      # shellcheck disable=SC2086
      SKELFLOW_TEST_BLOCK_DELAY_MS=40 setsid "$mpiexec" $mpiflags -np "$np" "$skelflow_mpi" "${args[@]}" \
        > "$work/resume$np.$round.log" 2>&1 &
      job=$!
      killed=0
      while kill -0 "$job" 2>/dev/null; do
        # The run removes its resume folder when it ends, maybe while find lists it (find then fails
        # with "No such file or directory", which set -e made this test's failure once in CI).
        rd=$(find "$scratch" -maxdepth 1 -name '.skelflow-resume-p-*' 2>/dev/null | head -1 || true)
        if [ -n "$rd" ] && [ -f "$rd/manifest.txt" ]; then
          # Mid-thinning: its shared skeleton exists and the stage is not done.
          if [ $killed_thin = 0 ] && compgen -G "$rd/thin.skeleton*.h5" > /dev/null && ! grep -q '^done thin ' "$rd/manifest.txt"; then
            sleep 0.15
            killed_thin=1 killed=1
          fi
          # Mid-illumination: every rank's journal of illum has grown since it was first seen (a block committed).
          if [ $killed = 0 ] && [ $killed_illum = 0 ]; then
            grown=0
            for ((r = 0; r < np; r++)); do
              j="$rd/illum.blocks"
              [ "$np" = 1 ] || j="$rd/illum.r$r.blocks"
              [ -f "$j" ] || continue
              size=$(stat -c %s "$j")
              if [ -z "${journal_size[$r]:-}" ]; then journal_size[$r]=$size; elif [ "$size" -gt "${journal_size[$r]}" ]; then grown=$((grown + 1)); fi
            done
            [ $grown = "$np" ] && killed_illum=1 killed=1
          fi
          if [ $killed = 1 ]; then
            # shellcheck disable=SC2046
            kill -9 $(job_pids "$job") 2>/dev/null || true
            break
          fi
        fi
        sleep 0.02
      done
      set +e
      wait "$job"
      rc=$?
      set -e
      for _ in $(seq 50); do [ -z "$(job_pids "$job")" ] && break; sleep 0.1; done
      [ -z "$(job_pids "$job")" ] || { echo "FAIL: -np $np: processes of the killed job remain"; exit 1; }
      [ $killed = 1 ] || break
      [ $round = 1 ] && [ "$np" -gt 1 ] && {
        # Another number of ranks is refused, naming both; the kept state stays.
        set +e
        # shellcheck disable=SC2086
        "$mpiexec" $mpiflags -np $((np == 2 ? 3 : 2)) "$skelflow_mpi" "${args[@]}" --resume > "$work/wrong$np.log" 2>&1
        wrong=$?
        set -e
        [ $wrong != 0 ] || { echo "FAIL: -np $np: resuming with another number of ranks succeeded"; exit 1; }
        grep -q "that run had $np rank(s), this one has" "$work/wrong$np.log" ||
          { echo "FAIL: -np $np: no clear error for another number of ranks"; cat "$work/wrong$np.log"; exit 1; }
        [ -n "$(find "$scratch" -maxdepth 1 -name '.skelflow-resume-p-*')" ] || { echo "FAIL: the refused run removed the kept state"; exit 1; }
      }
      [ "${args[-1]}" = --resume ] || args+=(--resume)
    done
    [ "$rc" = 0 ] || { echo "FAIL: -np $np: the resumed run failed ($rc)"; cat "$work/resume$np".*.log; exit 1; }
    [ $killed_thin = 1 ] && [ $killed_illum = 1 ] || { echo "FAIL: -np $np: not killed in both stages (thin $killed_thin, illum $killed_illum)"; cat "$work/resume$np".*.log; exit 1; }
    grep -q "finished stage(s) loaded" "$work/resume$np".*.log || { echo "FAIL: -np $np: no stage was loaded"; cat "$work/resume$np".*.log; exit 1; }
    grep -q "resumed node 'illum' from [1-9]" "$work/resume$np".*.log || { echo "FAIL: -np $np: illum did not resume from its blocks"; cat "$work/resume$np".*.log; exit 1; }
    for f in $outputs; do
      cmp "$work/ref/$f" "$dir/$f" || { echo "FAIL: -np $np, killed and resumed: $f differs from one uninterrupted process"; exit 1; }
    done
    left=$(cd "$scratch" && find . -mindepth 1 | tr '\n' ' ')
    [ -z "$left" ] || { echo "FAIL: -np $np: left in the scratch folder: $left"; exit 1; }
    unset journal_size
  done
  echo "OK: -np 1, 2, 3 killed mid-stage and resumed give the bytes of one process"
  ;;
*) echo "unknown mode $mode"; exit 2 ;;
esac
