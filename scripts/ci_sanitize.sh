#!/usr/bin/env bash
# Second CI step (its own CI job; .ci/run calls it after `scripts/setup.sh test` when
# SKEL_CI_SANITIZE=1): the whole test suite under
# AddressSanitizer + UndefinedBehaviorSanitizer, GUI and benchmarks off, in its own build dir. The
# suite includes fuzz_corpus_<target>: every seed of fuzz/corpus/ through its fuzz target (so the
# fuzz corpus is a sanitizer regression suite without clang). With SKEL_CI_FUZZ_SECONDS=N (default
# 0: off, it needs a second, clang build of the readers) each libFuzzer target also fuzzes for N s.
# Measured cold (ccache off, 2026-11-24, docs/reliability.md "Time"): the build is 2 054 s of CPU
# (~17 min on an idle 2-core machine, 16 GB on disk) plus the ctest (~4-5 min idle, 379 s of CPU): a second CI job
# of ~20-25 minutes, well inside the 90-minute limit. Not part of .ci/run by default (see there).
#   scripts/ci_sanitize.sh [--build-dir DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build_dir="$here/build-asan"
[ "${1:-}" = --build-dir ] && build_dir=$2
jobs=$(nproc)
start=$(date +%s)
# -O1 -g1 (Debug type with its flags replaced): ASan's usual level. With ASan + UBSan one file took
# 8 s of CPU at -O1 -g1 against 30 s at the tree's -O3 -g (5.7 s without sanitizers).
cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1 -DNDEBUG" \
  -DSKEL_SANITIZE=ON -DSKEL_BUILD_GUI=OFF -DSKEL_BUILD_BENCH=OFF >/dev/null
cmake --build "$build_dir" -j "$jobs"
built=$(date +%s)
# halt_on_error: a UBSan report fails its test (gcc's default is to print and go on).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:check_initialization_order=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$here/fuzz/lsan.supp}  # leaks inside libhdf5 only; render_test and Mpi.* run without the leak check (tests/CMakeLists.txt)
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# The HDF5 probe's helper (build-asan/cli/skelflow-hdf5-probe) is built with the same sanitizers; its
# worker does not take these settings but its own (modules/io/hdf5_probe.cpp: no leak check, no
# symbolizing), since a sanitizer report there is the verdict on a user's file, not a test failure.
ctest --test-dir "$build_dir" -j "$jobs" --output-on-failure --timeout 2400
tested=$(date +%s)
echo "sanitizers: build $((built - start)) s, tests $((tested - built)) s"
seconds=${SKEL_CI_FUZZ_SECONDS:-0}
if [ "$seconds" -gt 0 ]; then
  if command -v clang++ >/dev/null; then
    "$here/scripts/fuzz.sh" all "$seconds"
  else
    echo "sanitizers: SKEL_CI_FUZZ_SECONDS=$seconds but no clang++: libFuzzer runs skipped"
  fi
fi
