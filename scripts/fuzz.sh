#!/usr/bin/env bash
# Runs the libFuzzer targets of fuzz/ (built with clang in build-fuzz/, see fuzz/README.md).
#   scripts/fuzz.sh TARGET|all SECONDS [RUNS]
#                                          fuzz each target for SECONDS, or until RUNS inputs have run
#                                          when RUNS is given and reached first (new inputs go to
#                                          build-fuzz/corpus/<target>/, the seeds in fuzz/corpus/ stay)
#   scripts/fuzz.sh regress                every seed of fuzz/corpus/ once through its target (CI)
# Targets: pipeline hdf5 tiff graph_amira graph_swc graph_graphml graph_vtp graph_csv landmarks transform journal
#          volume_nrrd volume_metaimage volume_nifti volume_vti volume_amira
# A crash, sanitizer report, leak, timeout (10 s per input) or allocation over 1 GB stops a target; its
# input is saved as fuzz/crashes/<target>/crash-<sha1> (or leak-, timeout-, oom-) and the script fails.
# A huge malloc returns NULL as glibc would (allocator_may_return_null): libhdf5 then reports an error,
# while our operator new throws std::bad_alloc, which the targets do not catch (a finding).
# Prints one line per target: executions, new corpus entries, findings.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build_dir=${SKEL_FUZZ_BUILD_DIR:-$here/build-fuzz}
all_targets=(pipeline hdf5 tiff graph_amira graph_swc graph_graphml graph_vtp graph_csv landmarks transform journal
             volume_nrrd volume_metaimage volume_nifti volume_vti volume_amira)

usage() { sed -n '2,11p' "$0" >&2; exit 2; }
[ $# -ge 1 ] || usage
mode=fuzz
case "$1" in
  regress) mode=regress; targets=("${all_targets[@]}") ;;
  all) targets=("${all_targets[@]}") ;;
  *) targets=("$1") ;;
esac
seconds=${2:-}
max_runs=${3:-0}
if [ $mode = fuzz ] && ! [[ "$seconds" =~ ^[0-9]+$ && "$max_runs" =~ ^[0-9]+$ ]]; then usage; fi
for t in "${targets[@]}"; do
  [[ " ${all_targets[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target '$t' (expected one of: ${all_targets[*]})" >&2; exit 2; }
done
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ not found (scripts/setup.sh installs it)" >&2; exit 2; }

if [ ! -f "$build_dir/build.ninja" ]; then
  CC=clang CXX=clang++ cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DSKEL_FUZZ=ON -DSKEL_BUILD_TESTS=OFF -DSKEL_BUILD_GUI=OFF -DSKEL_BUILD_BENCH=OFF >/dev/null
fi
ninja -C "$build_dir" -j "$(nproc)" $(printf 'fuzz_%s ' "${targets[@]}") >/dev/null

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$here/fuzz/lsan.supp}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
failed=0
for t in "${targets[@]}"; do
  exe="$build_dir/fuzz/fuzz_$t"
  seeds="$here/fuzz/corpus/$t"
  crashes="$here/fuzz/crashes/$t"
  log="$build_dir/fuzz-$t.log"
  mkdir -p "$crashes"
  common=(-rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=10 "-artifact_prefix=$crashes/")
  # hdf5: no leak check per input. libhdf5 1.10 leaks a few hundred bytes on many corrupt files
  # (suppressed, fuzz/lsan.supp), and each such input made libFuzzer run a full leak check (186
  # inputs/s). Skelflow's own leaks are covered by the other targets and the ASan + UBSan ctest.
  [ "$t" = hdf5 ] && common+=(-detect_leaks=0)
  # hdf5: some inputs keep libhdf5 busy until the probe's memory limit or timeout refuses them (up to
  # a second each); the fuzz runs (not the regression replay) schedule fast inputs more often.
  [ "$t" = hdf5 ] && [ $mode = fuzz ] && common+=(-entropic_scale_per_exec_time=1)
  if [ $mode = regress ]; then
    # Each seed once (libFuzzer runs the files given and exits).
    if "$exe" "${common[@]}" "$seeds"/* >"$log" 2>&1; then rc=0; else rc=$?; fi
    n=$(find "$seeds" -type f | wc -l)
    if [ $rc = 0 ]; then echo "fuzz $t: $n seeds, no finding"; else echo "fuzz $t: FAILED (rc $rc), see $log"; tail -30 "$log"; failed=1; fi
  else
    work="$build_dir/corpus/$t"
    mkdir -p "$work"
    before=$(find "$crashes" -type f | wc -l)
    # A finding stops libFuzzer: start it again (the finding is saved) until SECONDS have passed, so
    # that the execution count covers the whole time; at most 50 restarts.
    runs=0 restarts=0 rc=0 t0=$(date +%s)
    : >"$log"
    while :; do
      left=$(( seconds - ($(date +%s) - t0) ))
      [ $left -gt 0 ] || break
      limit=()
      if [ "$max_runs" -gt 0 ]; then
        [ $runs -lt "$max_runs" ] || break
        limit=(-runs=$(( max_runs - runs )))
      fi
      if "$exe" "${common[@]}" -max_total_time="$left" "${limit[@]}" -print_final_stats=1 "$work" "$seeds" >>"$log" 2>&1; then r=0; else r=$?; fi
      n=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
      sed -i 's/stat::number_of_executed_units/stat::counted_executed_units/' "$log"
      runs=$(( runs + ${n:-0} ))
      [ $r = 0 ] && break
      rc=$r restarts=$(( restarts + 1 ))
      [ $restarts -lt 50 ] || break
    done
    found=$(( $(find "$crashes" -type f | wc -l) - before ))
    echo "fuzz $t: $runs executions in $(( $(date +%s) - t0 )) s (limit ${seconds} s), corpus $(find "$work" -type f | wc -l) (+ $(find "$seeds" -type f | wc -l) seeds), findings $found (inputs saved in fuzz/crashes/$t/), restarts $restarts"
    if [ $rc != 0 ]; then grep -E 'ERROR|SUMMARY|what\(\)' "$log" | sort | uniq -c | head -20; failed=1; fi
  fi
done
exit $failed
