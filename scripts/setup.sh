#!/usr/bin/env bash
# Installs the Debian packages Skelflow needs (only those missing), then configures and builds.
# Idempotent: a second run installs nothing and rebuilds only what changed.
#   scripts/setup.sh [demo|test] [--no-build] [--build-dir DIR] [--build-type TYPE]
#     (no command)  install + configure + build everything
#     demo          install + build the CLI + run the vessel pipeline (pipelines/vessel_network.yaml); results go to out/demo/
#     test          install + build everything + run the whole test suite (ctest); CI (.ci/run) then
#                   runs scripts/ci_sanitize.sh --inputs: the tests of what reads users' pipelines
#                   and files again under ASan + UBSan in build-asan/
# clang and libclang-rt-14-dev (libFuzzer) are for the fuzz targets: scripts/fuzz.sh, fuzz/README.md.
# libasan8 (gcc's AddressSanitizer runtime; build-essential pulls it in) is also needed at run time by
# skelflow-hdf5-probe, the HDF5 structure probe's helper (modules/io/hdf5_probe.hpp).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build_dir="$here/build"
build_type=RelWithDebInfo
do_build=1
command=build
while [ $# -gt 0 ]; do
  case "$1" in
    demo|test|build) command=$1 ;;
    --no-build) do_build=0 ;;
    --build-dir) build_dir=$2; shift ;;
    --build-type) build_type=$2; shift ;;
    *) echo "setup.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift
done

packages=(
  build-essential cmake ninja-build pkg-config git ccache libasan8
  qtbase5-dev libqt5opengl5-dev libvtk9-dev libvtk9-qt-dev libx11-dev
  libhdf5-dev zlib1g-dev libyaml-cpp-dev libgtest-dev libgmock-dev libbenchmark-dev
  libeigen3-dev libtbb-dev libnanoflann-dev libexpat1-dev libtiff-dev
  libopenmpi-dev libhdf5-openmpi-dev
  xvfb xauth
  clang libclang-rt-14-dev
  python3-scipy python3-skimage python3-h5py python3-numpy python3-vtk9 python3-tifffile
  python3-dev pybind11-dev python3-pytest python3-networkx python3-pandas
  python3-nibabel python3-zarr libblosc-dev libzstd-dev nlohmann-json3-dev
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd=sudo
  export DEBIAN_FRONTEND=noninteractive
  $sudo_cmd apt-get update -qq
  $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "setup: all packages present"
fi

[ $do_build = 1 ] || exit 0
jobs=$(nproc)
# The Python module (build/python/skelflow, `import skelflow` with PYTHONPATH=build/python) is built
# against Debian's python3, where numpy, networkx and pytest are installed.
# The test command builds with line tables only (-g1) and compiles the test programs' own sources at
# -O1 (SKEL_DEBUG_INFO, SKEL_TEST_OPT_LEVEL in CMakeLists.txt): the libraries under test keep -O3, and
# a cold build takes ~40 % less time. The other commands leave these settings as the tree has them
# (full debug information and the build type's level in a new tree).
test_flags=()
[ "$command" = test ] && test_flags=(-DSKEL_DEBUG_INFO=lines -DSKEL_TEST_OPT_LEVEL=1)
cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE="$build_type" -DPython3_EXECUTABLE=/usr/bin/python3 "${test_flags[@]}"
case "$command" in
  demo)
    cmake --build "$build_dir" -j "$jobs" --target skelflow
    out="$here/out/demo"
    "$build_dir/cli/skelflow" run "$here/pipelines/vessel_network.yaml" --output-dir "$out" --report "$out/run.json"
    echo
    echo "demo: results are in $out (run report: $out/run.json)"
    echo "demo: vessel graph $out/vessels/network.am and network.vtp (open in Amira / ParaView),"
    echo "demo: ground truth $out/vessels/truth.am, per-segment table $out/vessels/segments.csv, summary:"
    cat "$out/vessels/summary.csv" || true
    echo "demo: inspect a file with: $build_dir/cli/skelflow info <file>"
    ;;
  test)
    cmake --build "$build_dir" -j "$jobs"
    ctest --test-dir "$build_dir" -j "$jobs" --output-on-failure --timeout 900
    ;;
  build)
    cmake --build "$build_dir" -j "$jobs"
    ;;
esac
