#!/bin/sh
# Makes data/stitch_tiles/ for pipelines/stitch_tiles.yaml: the vessel phantom (88 x 88 x 32 voxels of
# 2 µm, noise 0.03) cut into 2 x 2 overlapping tiles of 56 x 56 x 32 voxels (24-voxel overlaps, as a
# microscope would take them), saved as 8-bit TIFF stacks, and a tile list with stage positions that
# are off by up to 5 µm (2.5 voxels) per axis, as stage positions are. The true tile origins are
# (0, 0, 0), (64, 0, 0), (0, 64, 0) and (64, 64, 0) µm.
# Usage: scripts/make_stitch_tiles.sh [path/to/skelflow]   (from the repository root)
set -eu
skelflow=${1:-build/cli/skelflow}
out=data/stitch_tiles
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cat > "$tmp/tiles.yaml" <<YAML
skelflow: 1
nodes:
  phantom: {module: synthetic.vessel_tree, params: {size: [88, 88, 32], seed: 5, roots: 4, noise: 0.03, spacing: [2, 2, 2]}}
  u8: {module: volume.convert, inputs: {input: phantom.image}, params: {dtype: uint8, mode: rescale}}
  t00: {module: volume.crop, inputs: {input: u8.output}, params: {begin: [0, 0, 0], size: [56, 56, 32]}}
  t10: {module: volume.crop, inputs: {input: u8.output}, params: {begin: [32, 0, 0], size: [56, 56, 32]}}
  t01: {module: volume.crop, inputs: {input: u8.output}, params: {begin: [0, 32, 0], size: [56, 56, 32]}}
  t11: {module: volume.crop, inputs: {input: u8.output}, params: {begin: [32, 32, 0], size: [56, 56, 32]}}
  s00: {module: io.write_volume, inputs: {volume: t00.output}, params: {path: $PWD/$out/tile_0_0.tif, compression: 6}}
  s10: {module: io.write_volume, inputs: {volume: t10.output}, params: {path: $PWD/$out/tile_1_0.tif, compression: 6}}
  s01: {module: io.write_volume, inputs: {volume: t01.output}, params: {path: $PWD/$out/tile_0_1.tif, compression: 6}}
  s11: {module: io.write_volume, inputs: {volume: t11.output}, params: {path: $PWD/$out/tile_1_1.tif, compression: 6}}
YAML
"$skelflow" run "$tmp/tiles.yaml" --quiet
cat > "$out/tiles.csv" <<CSV
file,x,y,z
# stage positions in µm (the tiles' unit); true positions: (0,0,0), (64,0,0), (0,64,0), (64,64,0)
tile_0_0.tif,1.5,-2.0,0.5
tile_1_0.tif,60.5,3.5,-1.0
tile_0_1.tif,-3.0,67.5,2.0
tile_1_1.tif,68.0,61.0,-4.5
CSV
