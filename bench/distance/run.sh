#!/usr/bin/env bash
# Distance transforms vs peers on synthetic.network rods and plates (256³ and 512³):
#   Euclidean DT vs scipy.ndimage.distance_transform_edt (same mask via .npy, same border convention,
#   results compared), chamfer (3,4,5) vs a memcpy of its output bytes, plus feature transform and
#   chamfer b(p) timings. Prints one markdown section.
#   bench/distance/run.sh BUILD_DIR [SIZES]   (SIZES default "256 512"; scipy takes ~45 s at 512³)
set -euo pipefail
build=${1:-build}
sizes=${2:-"256 512"}
threads=${SKEL_BENCH_THREADS:-2}
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
cmake --build "$build" --target bench_distance >/dev/null
bin="$build/bench/distance/bench_distance"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

get() { sed -n "s/^$1=//p" "$2"; }

echo "## Distance transforms"
echo
echo "Masks: \`synthetic.network\` (module defaults, size n³). Our runs use $threads threads (chamfer is"
echo "sequential). EDT: both sides use the same border convention (voxels outside the array are object,"
echo "as in SciPy); max |ours - scipy| is checked at 256³. Ratio = peer time / our time. Peak RSS is the"
echo "peak of the whole process (input mask included)."
echo
echo "| volume | object | EDT ours (s) | EDT CPU s | voxels/s | peak MiB | scipy EDT (s) | peak MiB | ratio | max abs diff | feature transform (s) | chamfer (s) | memcpy warm (s) | memcpy new (s) | chamfer / memcpy warm | chamfer / memcpy new | chamfer b(p) (s) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for n in $sizes; do
  for shape in rods plates; do
    d="$work/$n-$shape"
    mkdir -p "$d"
    "$bin" "$n" "$shape" "$d" generate >"$d/gen.txt"
    for m in edt ft chamfer memcpy memcpy_fresh chamfer_bp; do
      "$bin" "$n" "$shape" "$d" "$m" "$threads" >"$d/$m.txt"
    done
    "$py" - "$d" "$n" >"$d/scipy.txt" <<'EOF'
import resource, sys, time
import numpy as np
from scipy import ndimage
d, n = sys.argv[1], int(sys.argv[2])
m = np.load(d + "/mask.npy")
t0 = time.perf_counter()
e = ndimage.distance_transform_edt(m != 0)
t = time.perf_counter() - t0
print("time=%.4f" % t)
print("peak_rss_mib=%.0f" % (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0))
if n <= 256:
    ours = np.load(d + "/edt.npy")
    print("maxdiff=%.3g" % float(np.max(np.abs(ours.astype(np.float64) - e))))
else:
    print("maxdiff=n/a")
EOF
    obj=$(get object_fraction "$d/gen.txt")
    te=$(get time "$d/edt.txt"); ce=$(get cpu "$d/edt.txt"); re=$(get peak_rss_mib "$d/edt.txt")
    ts=$(get time "$d/scipy.txt"); rs=$(get peak_rss_mib "$d/scipy.txt"); md=$(get maxdiff "$d/scipy.txt")
    tf=$(get time "$d/ft.txt"); tc=$(get time "$d/chamfer.txt"); tm=$(get time "$d/memcpy.txt"); tn=$(get time "$d/memcpy_fresh.txt")
    tb=$(get time "$d/chamfer_bp.txt")
    awk -v n="$n" -v s="$shape" -v obj="$obj" -v te="$te" -v ce="$ce" -v re="$re" -v ts="$ts" -v rs="$rs" -v md="$md" \
        -v tf="$tf" -v tc="$tc" -v tm="$tm" -v tn="$tn" -v tb="$tb" 'BEGIN {
      v = n * n * n
      printf "| %s %d³ | %.1f%% | %.3f | %.3f | %.3g | %d | %.2f | %d | %.1f× | %s | %.3f | %.4f | %.4f | %.4f | %.1f× | %.1f× | %.3f |\n",
        s, n, 100 * obj, te, ce, v / te, re, ts, rs, ts / te, md, tf, tc, tm, tn, tc / tm, tc / tn, tb }'
  done
done
echo
echo "EDT: separable exact lower envelopes (x rows and y on 16-column blocks plane by plane, z on 64-column blocks with the square root fused, only runs of"
echo "non-zero values); chamfer: SSE4.1 uint16 raster scans skipping background blocks. memcpy copies"
echo "the chamfer output's bytes (2 per voxel): \"warm\" between two touched buffers, \"new\" into a freshly"
echo "allocated buffer (page faults included, as for any function returning a new volume; same huge-page"
echo "advice as our outputs). Machine: $(nproc) cores,"
echo "$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)."
