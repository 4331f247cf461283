#!/usr/bin/env bash
# Thinning benchmark vs scikit-image skeletonize_3d; prints a markdown section.
# Usage: bench/thinning/run.sh BUILD_DIR [sizes...]   (default sizes: 256 512)
set -euo pipefail
build=${1:-build}
shift || true
here=$(cd "$(dirname "$0")" && pwd)
cmake --build "$build" --target bench_thinning >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [ $# -eq 0 ]; then set -- 256 512; fi
"$build/bench/thinning/bench_thinning" "$here" "$work" "$@"
