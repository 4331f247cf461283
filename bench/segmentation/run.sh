#!/usr/bin/env bash
# Segmentation filters vs SciPy / scikit-image on synthetic.network rods and plates (256³ and 512³),
# every operation on the identical data (.npy) in the same run, each side in its own process:
#   connected components (26) vs scipy.ndimage.label (3×3×3 structure; component counts compared),
#   Gaussian sigma 2 of the mask as float32 vs scipy.ndimage.gaussian_filter (truncate 3.5, mode
#   nearest, float32; max |diff| at 256³), median radius 1 of a noisy uint8 image vs
#   scipy.ndimage.median_filter(size=3, mode='nearest'), dilation with the radius-3 ball vs
#   scipy.ndimage.binary_dilation with the same ball (differing voxels at 256³), Otsu threshold +
#   mask of a noisy float32 image vs skimage.filters.threshold_otsu + (image > t).
# Prints one markdown section.
#   bench/segmentation/run.sh BUILD_DIR [SIZES]   (SIZES default "256 512"; the peers take ~3 min at 512³)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
sizes=${2:-"256 512"}
threads=${SKEL_BENCH_THREADS:-2}
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
cmake --build "$build" --target bench_segmentation >/dev/null
bin="$build/bench/segmentation/bench_segmentation"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

get() { sed -n "s/^$1=//p" "$2"; }

ops="cc gaussian median dilate otsu"
rows=""
for n in $sizes; do
  for shape in rods plates; do
    d="$work/$n-$shape"
    mkdir -p "$d"
    "$bin" "$n" "$shape" "$d" generate "$threads" >"$d/gen.txt"
    obj=$(get object_fraction "$d/gen.txt")
    for op in $ops; do
      "$bin" "$n" "$shape" "$d" "$op" "$threads" >"$d/$op.ours.txt"
      "$py" "$here/scipy_peer.py" "$d" "$n" "$op" >"$d/$op.peer.txt"
      to=$(get time "$d/$op.ours.txt"); ro=$(get peak_rss_mib "$d/$op.ours.txt")
      tp=$(get time "$d/$op.peer.txt"); rp=$(get peak_rss_mib "$d/$op.peer.txt")
      case $op in
        cc) name="connected components (26)"; check="components $(get count "$d/$op.ours.txt") / $(get count "$d/$op.peer.txt")" ;;
        gaussian) name="Gaussian σ=2 (float32)"; md=$(get maxdiff "$d/$op.peer.txt"); check="max abs diff ${md:-n/a}" ;;
        median) name="median r=1 (uint8)"; df=$(get differ "$d/$op.peer.txt"); check="differing voxels ${df:-n/a}" ;;
        dilate) name="dilate ball r=3"; df=$(get differ "$d/$op.peer.txt"); check="differing voxels ${df:-n/a}" ;;
        otsu) name="Otsu threshold + mask (float32)"
              check="t $(get threshold "$d/$op.ours.txt") / $(get threshold "$d/$op.peer.txt"), object $(get object "$d/$op.ours.txt") / $(get object "$d/$op.peer.txt")" ;;
      esac
      rows+=$(awk -v n="$n" -v s="$shape" -v obj="$obj" -v name="$name" -v to="$to" -v ro="$ro" -v tp="$tp" -v rp="$rp" -v check="$check" 'BEGIN {
        v = n * n * n
        printf "| %s %d³ | %.1f%% | %s | %.3f | %.3g | %d | %.3f | %.3g | %d | %.1f× | %s |", s, n, 100 * obj, name, to, v / to, ro, tp, v / tp, rp, tp / to, check }')$'\n'
    done
  done
done

echo "## Segmentation filters"
echo
echo "Inputs: \`synthetic.network\` (make_network, shape rods | plates, module defaults, seed 1, size n³)."
echo "The mask is the operand of connected components, Gaussian (as float32) and dilation; median and Otsu"
echo "run on noisy grey images of the same object (uint8: object 128..223, background 0..95; float32: object"
echo "0.6..1.0, background 0..0.4; per-voxel uniform noise). Both sides read the identical .npy files; each"
echo "operation runs in its own process (peak RSS = that process's peak, input included). Ours: $threads threads,"
echo "best of 3 runs (256³) or 2 (512³); peers (single-threaded SciPy / scikit-image): one run. Ratio = peer"
echo "time / our time. Check column: ours / peer (components: counts; Gaussian: max |ours − scipy| at 256³;"
echo "median, dilation: voxels that differ at 256³; Otsu: threshold and object voxel count)."
echo
echo "| volume | object | operation | ours (s) | voxels/s | peak MiB | peer (s) | voxels/s | peak MiB | ratio | check (ours / peer) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
printf "%s" "$rows"
echo
echo "Peers: \`scipy.ndimage.label(m, structure=ones((3,3,3)))\`, \`gaussian_filter(f, 2, truncate=3.5,"
echo "mode='nearest', output=float32)\`, \`median_filter(a, size=3, mode='nearest')\`, \`binary_dilation(m,"
echo "structure=ball(3))\` (border value 0, as ours: outside the array contributes nothing), and"
echo "\`skimage.filters.threshold_otsu(f)\` then \`f > t\` (ours: \`otsu_threshold\` then \`threshold(f, t⁺, ∞)\`;"
echo "both use 256 histogram bins between min and max; skimage returns a bin centre, ours a bin edge)."
echo "Ours: union-find connected components with table and size-ordered labels; separable Gaussian;"
echo "vectorised forgetful-selection median; dilation by an exact separable squared EDT."
echo "Machine: $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)."
