#!/usr/bin/env bash
# ThreadSanitizer run of the executor and the threaded algorithms (docs/reliability.md, "TSan").
# Builds build-tsan/ (-fsanitize=thread, -O1 -g1; GUI, benchmarks and Python off) and runs the test
# programs below with halt_on_error=0, no suppressions. In this build skel::parallel_for runs its
# ranges on std::threads instead of TBB (framework/src/core.cpp, __SANITIZE_THREAD__): Debian's
# libtbb is not instrumented, so TSan could not see TBB's hand-off and would report every loop.
# Exits non-zero when a test fails or TSan reports anything.
#   scripts/tsan.sh [--build-dir DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build_dir="$here/build-tsan"
[ "${1:-}" = --build-dir ] && build_dir=$2
tests=(framework/framework_engine_test modules/distance/distance_test modules/segmentation/segmentation_test
       modules/segmentation/segmentation_threads_edges_test modules/thinning/thinning_doht_test
       modules/thinning/thinning_lee94_test modules/thinning/thinning_grid_cell_test
       modules/geodesic/geodesic_test modules/geodesic/geodesic_surface_test
       modules/io/io_test framework/framework_out_of_core_test modules/distance/distance_blocks_test
       modules/segmentation/segmentation_blocks_test pipelines/out_of_core_pipelines_test
       pipelines/out_of_core_io_test)
cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1" \
  -DSKEL_BUILD_GUI=OFF -DSKEL_BUILD_BENCH=OFF -DSKEL_BUILD_PYTHON=OFF \
  "-DCMAKE_CXX_FLAGS=-fsanitize=thread -fno-omit-frame-pointer" -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread \
  -DCMAKE_SHARED_LINKER_FLAGS=-fsanitize=thread >/dev/null
cmake --build "$build_dir" -j "$(nproc)" --target "${tests[@]##*/}" skelflow
status=0
for t in "${tests[@]}"; do
  log="$build_dir/${t##*/}.tsan.log"
  rc=0
  TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=0} "$build_dir/tests/$t" >"$log" 2>&1 || rc=$?
  reports=$(grep -c 'WARNING: ThreadSanitizer' "$log" || true)
  echo "tsan ${t##*/}: exit $rc, $reports reports ($log)"
  [ "$rc" = 0 ] && [ "$reports" = 0 ] || status=1
done
exit $status
