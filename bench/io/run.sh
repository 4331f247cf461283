#!/usr/bin/env bash
# HDF5 I/O: our io::write_volume / read_volume / read_box (automatic ~1 MiB chunks, deflate 0 and 1)
# vs h5py (contiguous, chunks=True, chunks=True + gzip 1) on the same 512³ uint8 and float32 arrays,
# in the same run. Files go to a temporary directory that is deleted at the end. Prints one markdown
# section.
#   bench/io/run.sh BUILD_DIR [SIZE] [BLOCK]   (SIZE default 512, BLOCK default 64)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
n=${2:-512}
block=${3:-64}
py=${SKEL_BENCH_PYTHON:-/usr/bin/python3}
cmake --build "$build" --target bench_io >/dev/null
bin="$build/bench/io/bench_io"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

get() { sed -n "s/^$1=//p" "$2"; }

"$bin" "$n" "$work" generate
rows=""
cmp=""
helper=""
row() {  # dtype writer layout chunks write read blocks bytes peak identical
  rows+=$(awk -v n="$n" -v dt="$1" -v who="$2" -v lay="$3" -v ch="$4" -v tw="$5" -v tr="$6" -v tb="$7" -v fb="$8" -v pk="$9" -v same="${10}" 'BEGIN {
    bytes = n * n * n * (dt == "uint8" ? 1 : 4)
    printf "| %s | %s | %s | %s | %.3f | %.0f | %.3f | %.0f | %.3f | %.0f | %.1f | %.2f | %s | %s |", dt, who, lay, ch, tw, bytes / tw / 1e6, tr, bytes / tr / 1e6, tb, bytes / tb / 1e6, fb / 1048576, bytes / fb, pk, same }')$'\n'
}
for dt in uint8 float32; do
  shuf=""
  if [ "$dt" = float32 ]; then shuf=" + shuffle"; fi
  for level in 0 1; do
    "$bin" "$n" "$work" run "$dt" "$level" "$block" >"$work/ours_${dt}_$level.txt"
  done
  "$py" "$here/h5py_peer.py" "$work" "$dt" "$block" >"$work/h5py_$dt.txt"
  for level in 0 1; do
    f="$work/ours_${dt}_$level.txt"
    lay="auto ~1 MiB chunks"
    if [ "$level" = 1 ]; then lay="auto ~1 MiB chunks, deflate 1$shuf"; fi
    row "$dt" "ours" "$lay" "$(get chunks "$f")" "$(get write "$f")" "$(get read "$f")" "$(get blocks "$f")" \
        "$(get file_bytes "$f")" "$(get peak_rss_mib "$f")" "$(get identical "$f"); h5py reads it: $(get "h5py_reads_ours_$level" "$work/h5py_$dt.txt")"
  done
  for level in 0 1; do
    f="$work/ours_${dt}_$level.txt"
    lay="auto ~1 MiB chunks"
    if [ "$level" = 1 ]; then lay="auto ~1 MiB chunks, deflate 1$shuf"; fi
    helper+=$(awk -v dt="$dt" -v lay="$lay" -v r="$(get read "$f")" -v ri="$(get read_inprocess "$f")" -v b="$(get blocks "$f")" \
      -v bi="$(get blocks_inprocess "$f")" -v c="$(get read_cpu "$f")" -v ci="$(get read_inprocess_cpu "$f")" \
      -v h="$(get reads_in_helper "$f")" -v same="$(get identical_inprocess "$f")" 'BEGIN {
      printf "| %s | %s | %s | %.3f | %.3f | %.2f | %.3f | %.3f | %.3f | %.3f | %.2f | %s |", dt, lay, h, r, ri, r / ri, c, ci, b, bi, b / bi, same }')$'\n'
  done
  f="$work/ours_${dt}_1.txt"
  cmp+=$(awk -v dt="$dt" -v r="$(get read "$f")" -v r5="$(get read_h5dread "$f")" -v c="$(get read_cpu "$f")" \
    -v c5="$(get read_h5dread_cpu "$f")" -v b="$(get blocks "$f")" -v b5="$(get blocks_h5dread "$f")" \
    -v same="$(get identical_h5dread "$f")" 'BEGIN {
    printf "| %s | %.3f | %.3f | %.2f | %.3f | %.3f | %.3f | %.3f | %s |", dt, r, r5, r5 / r, c, c5, b, b5, same }')$'\n'
  p="$work/h5py_$dt.txt"
  for lay in contiguous auto_chunks auto_chunks_gzip1; do
    case $lay in
      contiguous) text="contiguous" ;;
      auto_chunks) text="chunks=True" ;;
      auto_chunks_gzip1) text="chunks=True, gzip 1$shuf" ;;
    esac
    row "$dt" "h5py" "$text" "$(get "$lay.chunks" "$p")" "$(get "$lay.write" "$p")" "$(get "$lay.read" "$p")" "$(get "$lay.blocks" "$p")" \
        "$(get "$lay.file_bytes" "$p")" "$(get peak_rss_mib "$p")" "$(get "$lay.identical" "$p")"
  done
  rm -f "$work"/*.h5
done

echo "## HDF5 I/O"
echo
echo "Volumes: \`synthetic.network\` rods ${n}³ (seed 1, noise 0.1): uint8 = its 0/1 mask, float32 = its"
echo "smoothed grey image with noise ($(awk -v n="$n" 'BEGIN { printf "%.0f", n*n*n/1048576 }') MiB and $(awk -v n="$n" 'BEGIN { printf "%.0f", 4*n*n*n/1048576 }') MiB). Both sides write the identical arrays (.npy),"
echo "best of 2 runs each; write = until the file is closed (no fsync; our write goes to a temporary sibling"
echo "and is renamed into place), read = whole dataset into memory right after writing (page cache warm:"
echo "this measures HDF5 + filters, not the disk), blocks = every ${block}³ box read by its own call"
echo "(ours: \`io::read_box\`, which opens the file each call; h5py: slicing one open dataset). MB/s ="
echo "uncompressed bytes / time / 10⁶. Chunks are (x, y, z). Peak MiB: ours per (dtype, level) process,"
echo "h5py one process per dtype (all its layouts). Identical: the read-back array equals the written one."
echo "Our compressed writes shuffle + deflate the chunks on all $(nproc) hardware threads and store them with"
echo "H5Dwrite_chunk (io::WriteOptions::threads = 0); h5py compresses in HDF5's single-threaded filter pipeline."
echo
echo "| dtype | writer | layout | chunks | write (s) | write MB/s | read (s) | read MB/s | ${block}³ blocks (s) | blocks MB/s | file MiB | compression ratio | peak MiB | identical |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
printf "%s" "$rows"
echo
echo "Deflated reads (level 1): our chunk decoding (\`io/hdf5_chunks.hpp\`, chunks inflated on all $(nproc) threads) against"
echo "libhdf5's filter pipeline in H5Dread (\`SKEL_HDF5_OWN_CHUNKS=0\`), same process and file, best of 2; CPU = one"
echo "read, all threads of the process."
echo
echo "| dtype | read ours (s) | read H5Dread (s) | H5Dread / ours | CPU ours (s) | CPU H5Dread (s) | ${block}³ blocks ours (s) | ${block}³ blocks H5Dread (s) | identical |"
echo "|---|---|---|---|---|---|---|---|---|"
printf "%s" "$cmp"
echo
echo "Reads in the helper program (the default since issue 22: the file is opened and decoded by"
echo "\`skelflow-hdf5-probe\`, the voxels come back through shared memory) against the same reads in the"
echo "reader's own process (\`SKEL_HDF5_PROBE=0\`), same process and file, best of 2; CPU = one whole read, the"
echo "reader's process only (the helper's CPU is not in it)."
echo
echo "| dtype | layout | in helper | read (s) | read in-process (s) | read ratio | CPU (s) | CPU in-process (s) | ${block}³ blocks (s) | ${block}³ blocks in-process (s) | blocks ratio | identical |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
printf "%s" "$helper"
echo
echo "HDF5 $(/usr/bin/python3 -c 'import h5py; print(h5py.version.hdf5_version, "(h5py", h5py.__version__ + ")")' 2>/dev/null || echo "?"); ours links the system HDF5"
echo "$(dpkg-query -W -f='${Version}' libhdf5-dev 2>/dev/null || echo "?"). Machine: $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1); temp dir on"
echo "$(df -P "${TMPDIR:-/tmp}" | awk 'NR == 2 { print $1 }')."
