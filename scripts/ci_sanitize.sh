#!/usr/bin/env bash
# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer, GUI and benchmarks off, in its
# own build dir (build-asan/).
#   scripts/ci_sanitize.sh [--inputs] [--opt LEVEL] [--build-dir DIR]
#     (default)  every test (the whole suite: 750 tests), compiled at -O1
#     --inputs   only the tests labelled `inputs` (CMake target skel_input_tests): what reads users'
#                pipelines and files — tests/modules/io, the golden error messages of tests/errors
#                (malformed pipelines and files through the real `skelflow`), tests/framework (the
#                pipeline loader, parameters, staged outputs, journals), tests/cli (the command line
#                end to end, kill and resume) and fuzz_corpus_<target> (every seed of fuzz/corpus/
#                through its fuzz target, so the corpus is a sanitizer regression suite without
#                clang). `.ci/run` runs this mode by default. Compiled at -O0: half the build time
#                of -O1 (below), and these tests run no faster at -O1.
#     --opt LEVEL  the optimisation level (0, 1, 2, g) instead of the mode's own. The build dir keeps
#                one level: another one recompiles it.
# With SKEL_CI_FUZZ_SECONDS=N (default 0: off, it needs a second, clang build of the readers) each
# libFuzzer target also fuzzes for N s.
# Time (docs/reliability.md "Time"), measured cold on the idle 2-core VM on 2026-12-07: the whole
# suite at -O1 1 508 s of build and 844 s of tests (25 + 14 min, 6.6 GB); --inputs at -O1 868-879 s
# and 138-142 s (15 + 2 min, 3.7 GB), at -O0 443 s and 113 s (7.4 + 1.9 min, 2.6 GB); with
# tests/framework and tests/cli in the subset (362 tests, session 24) 548 s and 211 s (2.8 GB).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build_dir="$here/build-asan"
mode=all
opt=
while [ $# -gt 0 ]; do
  case "$1" in
    --inputs) mode=inputs ;;
    --opt)
      opt=$2; shift
      case "$opt" in 0|1|2|g) ;; *) echo "ci_sanitize.sh: --opt must be 0, 1, 2 or g, not '$opt'" >&2; exit 2 ;; esac ;;
    --build-dir) build_dir=$2; shift ;;
    *) echo "ci_sanitize.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift
done
jobs=$(nproc)
start=$(date +%s)
# -O1 -g1 or -O0 -g1 (Debug type with its flags replaced; -g1: file:line in the reports). -O1 is
# ASan's usual level, which the whole suite's compute-heavy tests need. With ASan + UBSan at -O1 some
# files compile very slowly (modules/io/volume_tiff.cpp: 77 s, against 18 s at -O0 and 24 s at the
# normal tree's -O3 -g1), so the inputs subset, whose tests are file reading and small pipelines,
# builds at -O0: it finds what -O1 finds (no access is optimised away) and its tests took 113 s there
# against 142 s at -O1.
if [ -z "$opt" ]; then
  opt=1
  [ $mode = inputs ] && opt=0
fi
cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O$opt -g1 -DNDEBUG" \
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
echo "sanitizers ($mode, -O$opt): build $((built - start)) s, tests $((tested - built)) s"
seconds=${SKEL_CI_FUZZ_SECONDS:-0}
if [ "$seconds" -gt 0 ]; then
  if command -v clang++ >/dev/null; then
    "$here/scripts/fuzz.sh" all "$seconds"
  else
    echo "sanitizers: SKEL_CI_FUZZ_SECONDS=$seconds but no clang++: libFuzzer runs skipped"
  fi
fi
