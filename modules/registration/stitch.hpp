#pragma once
// Stitching of overlapping tiles (thesis §6.1, the confocal vessel mosaics): tiles with roughly
// known stage positions are aligned pairwise by normalised cross-correlation (NCC) in their overlaps,
// their positions refined globally by least squares over all pairs, and merged by linear blending
// into one volume, in memory or block by block onto disk.
//
// Positions are in voxels of the common frame (the tiles share spacing, unit and voxel type): the
// position of a tile is where its voxel (0, 0, 0) lies. Tiles are read through a box reader, so only
// the overlaps (alignment) and the boxes a merge block touches (merging) are ever in memory.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "skel/interrupter.hpp"
#include "skel/out_of_core.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::registration {

// One line of a tile list: `file,x,y,z` (see parse_tile_list).
struct TileListEntry {
  std::string name;            // the file as written in the list
  std::filesystem::path file;  // resolved against the list's folder
  Vec3 position{0, 0, 0};      // as written (physical units or voxels)
  int64_t line = 0;            // 1-based line in the list, for messages
};

// Parses a tile list (CSV): one tile per line `file,x,y,z` (file relative to the list's folder, or
// absolute; x, y, z the stage position of the tile's voxel (0,0,0)); an optional header line whose
// second field is not a number (e.g. `file,x,y,z`), blank lines and lines starting with '#' are
// skipped; fields may be quoted ("a,b.tif") and surrounded by spaces. Throws InputError
// "LIST:LINE: ..." for a wrong field count, a field that is no finite number, an empty file name, or
// a list without tiles.
std::vector<TileListEntry> parse_tile_list(const std::string& text, const std::filesystem::path& list_path);

struct StitchTile {
  std::string name;    // how messages and tables name the tile (the file, as the user wrote it)
  std::string where;   // "tiles.csv:3" (list and line) for messages; may be empty
  Grid grid;           // dims, spacing, unit; origin and direction are ignored
  std::string type_id; // volume.u8, volume.u16, ...
  Vec3 position{0, 0, 0};  // nominal position of voxel (0,0,0), in voxels of the common frame
  // Reads the box [begin, begin + size) (tile voxels) as a Volume<T> of type_id.
  std::function<DataPtr(const Dims& begin, const Dims& size)> read_box;
};

struct StitchOptions {
  int64_t search_radius = 10;     // voxels searched around the nominal offset of each pair, per axis
  double min_correlation = 0.5;   // pairs whose NCC peak is lower are dropped (reported)
  int64_t min_overlap = 8;        // voxels of nominal overlap along every axis that make a pair
  int64_t fixed_tile = 0;         // tile that keeps its nominal position in the global fit
  int threads = 0;
  Interrupter interrupter{};
};

enum class PairStatus { used, low_correlation };

struct StitchPair {
  int64_t a = 0, b = 0;             // tile indices, a < b
  Vec3 nominal{0, 0, 0};            // nominal offset b − a (voxels)
  Vec3 measured{0, 0, 0};           // offset b − a at the NCC peak, sub-voxel (voxels)
  double correlation = 0.0;         // NCC at the integer peak
  int64_t overlap_voxels = 0;       // voxels compared at the peak
  PairStatus status = PairStatus::used;
  Vec3 residual{0, 0, 0};           // (P_b − P_a) − measured after the global fit (used pairs)
};

// Pairwise measurement of one pair (exposed for tests): NCC search within ±search_radius of the
// rounded nominal offset: every offset with the overlap sampled every 1, 2 or 4 voxels (at least
// 4096 voxels compared), the 8 best at full resolution, hill climbing over the 26 neighbours, and a
// parabola through the peak and its two neighbours along each axis for the sub-voxel part (clamped
// to ±0.5).
StitchPair measure_pair(const StitchTile& a, const StitchTile& b, int64_t ia, int64_t ib, const StitchOptions& options);

// Global least squares: positions P minimising Σ w (P_b − P_a − measured)² over the used pairs
// (w = correlation), tile `fixed` (and in every other connected group of tiles, its first tile) kept
// at `nominal`; tiles without a used pair keep their nominal position. Fills the residuals of the
// used pairs. Returns one position per tile.
std::vector<Vec3> solve_positions(const std::vector<Vec3>& nominal, std::vector<StitchPair>& pairs, int64_t fixed);

struct StitchLayout {
  std::vector<Vec3> nominal;    // nominal positions (voxels)
  std::vector<Vec3> positions;  // refined positions (voxels, sub-voxel)
  std::vector<Dims> placed;     // where each tile's voxel (0,0,0) lands in the merged volume
  std::vector<StitchPair> pairs;
  std::vector<int64_t> unconnected;  // tiles without any used pair (kept at nominal positions)
  Grid grid;                    // merged grid: spacing and unit of the tiles, origin = min position · spacing
  std::string type_id;
};

// Checks the tiles (same voxel type, spacing and unit; every tile overlapping another by
// min_overlap voxels along every axis), measures every overlapping pair (progress "pair k/n",
// cancellation between pairs), drops pairs below min_correlation, fits the positions globally and
// lays out the merged grid (positions relative to the fixed tile rounded to whole voxels). Throws
// InputError naming the tile
// (its `where` and name) for mixed types/spacing/units or a tile that overlaps no other.
StitchLayout align_tiles(const std::vector<StitchTile>& tiles, const StitchOptions& options);

// Merges the tiles at layout.placed by linear blending: each tile voxel weighs
// Π_axes min(i + 1, n − i) (falling linearly towards the tile's borders), the merged voxel is the
// weighted mean (rounded for integer types), 0 where no tile lies. Works block by block (`block`
// voxels, reading only the tile boxes a block touches) and hands each finished block to `sink`
// (voxel (0,0,0) of the block at `begin`). Progress "merge k/n blocks", cancellation between blocks.
using MergeSink = std::function<void(const DataObject& block, const Dims& begin)>;
void merge_tiles(const std::vector<StitchTile>& tiles, const StitchLayout& layout, const Dims& block,
                 const MergeSink& sink, const StitchOptions& options);
// In memory: the whole merged volume (type layout.type_id), merged in z-slabs.
DataPtr merge_tiles_in_memory(const std::vector<StitchTile>& tiles, const StitchLayout& layout,
                              const StitchOptions& options);
// Onto disk: every block written into `out` (grid and type of the layout).
void merge_tiles_into(const std::vector<StitchTile>& tiles, const StitchLayout& layout, ChunkedVolume& out,
                      const Dims& block, const StitchOptions& options);

// Table of tiles: tile, file, nominal_x/y/z and x/y/z (physical, `unit`), placed_x/y/z (voxel of the
// merged volume), pairs (used pairs of the tile).
Table tile_table(const std::vector<StitchTile>& tiles, const StitchLayout& layout);
// Table of pairs: tile_a, tile_b, file_a, file_b, overlap_voxels, correlation, dx/dy/dz (measured
// offset b − a, physical), residual (physical length of the residual), status (used, low_correlation).
Table pair_table(const std::vector<StitchTile>& tiles, const StitchLayout& layout);

}  // namespace skel::registration
