#!/usr/bin/env bash
# Runs every benchmark family (bench/<family>/run.sh BUILD_DIR), each against its peers in the same
# run, and writes bench/RESULTS.md with the machine's description.
#   bench/run.sh [--build-dir DIR] [family...]
#   bench/run.sh --collect      only rewrite RESULTS.md from bench/results/*.md (no benchmark runs)
# Each family's run.sh prints a markdown section to stdout; it is also kept in
# bench/results/<family>.md so that a partial run keeps the other families' last results.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
build="$root/build"
families=()
collect_only=0
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build=$(cd "$2" && pwd); shift ;;
    --collect) collect_only=1 ;;
    *) families+=("$1") ;;
  esac
  shift
done
if [ ${#families[@]} -eq 0 ] && [ $collect_only = 0 ]; then
  for d in "$here"/*/; do
    [ -x "$d/run.sh" ] && families+=("$(basename "$d")")
  done
fi
mkdir -p "$here/results"
export SKEL_BENCH_PYTHON=/usr/bin/python3
for f in ${families[@]+"${families[@]}"}; do
  echo "== bench: $f" >&2
  tmp=$(mktemp)
  if bash "$here/$f/run.sh" "$build" >"$tmp"; then
    mv "$tmp" "$here/results/$f.md"
  else
    echo "bench $f failed" >&2
    rm -f "$tmp"
  fi
done

{
  echo "# Benchmark results"
  echo
  echo "Written by \`bench/run.sh\`. Each section compares Skelflow with a peer on the same data in the"
  echo "same run; the ratio is peer time / Skelflow time (> 1 means Skelflow is faster)."
  echo
  echo "## Machine"
  echo
  echo "- CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores"
  echo "- Memory: $(free -g | awk '/Mem:/ {print $2}') GiB"
  echo "- OS: $(. /etc/os-release && echo "$PRETTY_NAME"), $(uname -r)"
  echo "- Compiler: $(c++ --version | head -n1)"
  echo "- Python peers: $(/usr/bin/python3 -c 'import scipy, skimage, numpy; print("numpy", numpy.__version__, "scipy", scipy.__version__, "scikit-image", skimage.__version__)' 2>/dev/null || echo unavailable)"
  echo "- Date of this write: $(date -u +%Y-%m-%d)"
  echo
  for s in "$here"/results/*.md; do
    [ -f "$s" ] || continue
    cat "$s"
    echo
  done
} >"$here/RESULTS.md"
echo "wrote $here/RESULTS.md" >&2
