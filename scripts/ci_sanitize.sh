#!/usr/bin/env bash
# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer, GUI and benchmarks off, in its
# own build dir (build-asan/).
#   scripts/ci_sanitize.sh [--inputs] [--build-dir DIR]
#     (default)  every test (the whole suite: 750 tests)
#     --inputs   only the tests labelled `inputs` (CMake target skel_input_tests): what reads users'
#                files — tests/modules/io, the golden error messages of tests/errors (malformed
#                pipelines and files through the real `skelflow`) and fuzz_corpus_<target> (every
#                seed of fuzz/corpus/ through its fuzz target, so the corpus is a sanitizer
#                regression suite without clang). `.ci/run` runs this mode by default.
# With SKEL_CI_FUZZ_SECONDS=N (default 0: off, it needs a second, clang build of the readers) each
# libFuzzer target also fuzzes for N s.
# Time (docs/reliability.md "Time"), measured cold on the idle 2-core VM on 2026-12-07: the whole
# suite 1 508 s of build and 844 s of tests (25 + 14 min, 6.6 GB); --inputs 879 s and 138 s
# (15 + 2 min, 3.8 GB).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build_dir="$here/build-asan"
mode=all
while [ $# -gt 0 ]; do
  case "$1" in
    --inputs) mode=inputs ;;
    --build-dir) build_dir=$2; shift ;;
    *) echo "ci_sanitize.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift
done
jobs=$(nproc)
start=$(date +%s)
# -O1 -g1 (Debug type with its flags replaced): ASan's usual level. With ASan + UBSan one file took
# 8 s of CPU at -O1 -g1 against 30 s at the tree's -O3 -g (5.7 s without sanitizers).
cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1 -DNDEBUG" \
  -DSKEL_SANITIZE=ON -DSKEL_BUILD_GUI=OFF -DSKEL_BUILD_BENCH=OFF >/dev/null
ctest_filter=()
if [ $mode = inputs ]; then
  cmake --build "$build_dir" -j "$jobs" --target skel_input_tests
  ctest_filter=(-L '^inputs$')
else
  cmake --build "$build_dir" -j "$jobs"
fi
built=$(date +%s)
# halt_on_error: a UBSan report fails its test (gcc's default is to print and go on).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:check_initialization_order=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$here/fuzz/lsan.supp}  # leaks inside libhdf5 only; render_test and Mpi.* run without the leak check (tests/CMakeLists.txt)
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# The HDF5 probe's helper (build-asan/cli/skelflow-hdf5-probe) is built with the same sanitizers; its
# worker does not take these settings but its own (modules/io/hdf5_probe.cpp: no leak check, no
# symbolizing), since a sanitizer report there is the verdict on a user's file, not a test failure.
ctest --test-dir "$build_dir" -j "$jobs" --output-on-failure --timeout 2400 "${ctest_filter[@]}"
tested=$(date +%s)
echo "sanitizers ($mode): build $((built - start)) s, tests $((tested - built)) s"
seconds=${SKEL_CI_FUZZ_SECONDS:-0}
if [ "$seconds" -gt 0 ]; then
  if command -v clang++ >/dev/null; then
    "$here/scripts/fuzz.sh" all "$seconds"
  else
    echo "sanitizers: SKEL_CI_FUZZ_SECONDS=$seconds but no clang++: libFuzzer runs skipped"
  fi
fi
