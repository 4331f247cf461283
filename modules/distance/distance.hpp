#pragma once
// Distance transforms of binary masks (thesis §2.3.1 chamfer DT, §2.3.2 nearest background point
// transform b(p), ch. 5.1 raster scans): chamfer (integer weights, two raster scans), exact
// Euclidean (separable lower envelopes, anisotropic, multi-threaded), exact Euclidean feature
// transform (index of the nearest background voxel), the chamfer b(p), and the Euclidean distance
// to a seed set.
//
// Conventions shared by every function here:
// - Mask: a voxel is object where its value is > 0, background where it is 0.
// - Outside the array: background by default (the one-voxel ring around the array counts as
//   background voxels), object with `border_is_object = true`.
// - Indices are linear voxel indices x + nx*(y + ny*z) of the input grid; `kOutside*` marks a nearest
//   point that lies in the ring outside the array.
// - Ties between equidistant background voxels (Euclidean feature transform): the smallest (z, y, x)
//   in lexicographic order wins, positions outside the array counting as coordinate -1 or n; this is
//   the smallest linear index when all candidates are inside the array.
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "skel/data.hpp"
#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/out_of_core.hpp"
#include "skel/volume.hpp"

namespace skel::distance {

inline constexpr uint32_t kOutside32 = std::numeric_limits<uint32_t>::max();
inline constexpr uint64_t kOutside64 = std::numeric_limits<uint64_t>::max();

struct DistanceOptions {
  bool border_is_object = false;  // voxels outside the array are object instead of background
  int threads = 0;                // <= 0: all hardware threads
  Interrupter interrupter;
};

// Integer chamfer weights of the 26 neighbour steps: face steps along x, y, z; edge steps in the
// xy, xz, yz planes; the vertex (body diagonal) step. The default is Borgefors' (3, 4, 5).
struct ChamferWeights {
  uint32_t face_x = 3, face_y = 3, face_z = 3;
  uint32_t edge_xy = 4, edge_xz = 4, edge_yz = 4;
  uint32_t vertex = 5;
  static ChamferWeights isotropic(uint32_t a, uint32_t b, uint32_t c) { return {a, a, a, b, b, b, c}; }
  bool operator==(const ChamferWeights&) const = default;
};

// Weights for an anisotropic grid (after Fouard & Malandain 2005): each step weighs
// round(scale * physical step length / smallest spacing), at least 1. scale = 3 gives (3, 4, 5) on
// isotropic grids; one chamfer unit is then (smallest spacing / scale) in physical units.
// Throws InputError unless spacing > 0 and scale >= 1.
ChamferWeights chamfer_weights_from_spacing(const Vec3& spacing, double scale = 3.0);

struct ChamferOptions : DistanceOptions {
  using OptionsBase = DistanceOptions;
  ChamferWeights weights{};
  bool derive_from_spacing = false;  // replace `weights` by chamfer_weights_from_spacing(spacing)
  double spacing_scale = 3.0;        // scale used when derive_from_spacing is true
  // chamfer(): a VolumeU8 when every distance of this mask is below 255 (1 byte per voxel instead of
  // 2; the values equal the uint16 result), else the uint16/uint32 output as without it. The uint8
  // scans saturate at 255; a saturated value makes chamfer() recompute in the wider type.
  bool narrow = false;
};

// Largest finite chamfer value any mask on `grid` can produce with these options (a path of face
// steps to the nearest possible background voxel). Decides the output type before computing.
uint64_t chamfer_upper_bound(const Grid& grid, const ChamferOptions& options);
// 16 if chamfer_upper_bound < 65535 (uint16 output), else 32 (uint32 output); throws InputError if
// even uint32 cannot hold the bound.
int chamfer_output_bits(const Grid& grid, const ChamferOptions& options);

// Chamfer distance transform by the forward and backward raster scans of §2.3.1: a VolumeU16 or a
// VolumeU32 (see chamfer_output_bits), 0 on background, in chamfer units. Object voxels that no
// background voxel reaches (border_is_object and no background at all) get the type's maximum,
// which is above every finite value. Memory: 2 or 4 bytes per voxel (output only).
DataPtr chamfer(const VolumeU8& mask, const ChamferOptions& options = {});
// The chamfer distance in uint8 if every value is below 255: equal to chamfer_as<uint16_t> voxel for
// voxel; nullopt if some object voxel's distance is 255 or more (or unreached). Memory: 1 byte per
// voxel plus a few rows of scratch.
std::optional<VolumeU8> chamfer_u8(const VolumeU8& mask, const ChamferOptions& options = {});
// Same, with a fixed output type; throws InputError if T cannot hold chamfer_upper_bound.
template <class T> Volume<T> chamfer_as(const VolumeU8& mask, const ChamferOptions& options = {});

// The chamfer nearest-background-point transform b(p) of §2.3.2: during both raster scans each
// voxel takes, together with the smaller value d(n) + w, the nearest point b(n) of the neighbour n it
// came from (strictly smaller only, so the first neighbour in mask order wins ties; forward mask
// order: z-1 plane (y-1..y+1, x-1..x+1), then (x-1..x+1, y-1), then (x-1, y); backward mask: the
// mirror order). Background voxels get their own index; voxels reached from outside the array get
// kOutside32/kOutside64; unreachable voxels (no background at all) also get kOutside*.
struct ChamferNearest {
  DataPtr distance;  // VolumeU16 or VolumeU32, as chamfer()
  DataPtr nearest;   // VolumeU32 if the grid has < 2^32 - 1 voxels, else VolumeU64
};
ChamferNearest chamfer_nearest(const VolumeU8& mask, const ChamferOptions& options = {});

// Block-wise chamfer (out-of-core, thesis ch. 5.1, Algorithm 4): `mask` (any integer volume, in
// memory or on disk) in blocks of `block` voxels with a one-voxel overlap, eight block-wise raster
// scans (each layer of blocks row by row there and back, each row there and back), the distances
// written into `out` (on disk, the mask's grid, of chamfer_output_type). Bit-identical to chamfer()
// for weights obeying the chamfer-norm conditions (see distance.chamfer). Blocks visited:
// n + 2·nz·(2nx-1)·(2ny-1) for n = nx·ny·nz blocks; progress "chamfer k/total blocks".
const char* chamfer_output_type(const Grid& grid, const ChamferOptions& options);  // volume.u16 or volume.u32
void chamfer_blocks(const DataObject& mask, const ChunkedVolume& out, const ChamferOptions& options, const Dims& block);

struct EuclideanOptions : DistanceOptions {
  using OptionsBase = DistanceOptions;
  bool squared = false;  // output squared distances (physical units squared)
};

// Exact Euclidean distance transform in physical units (spacing per axis), 0 on background.
// Separable: one pass per axis computing lower envelopes of parabolas (Felzenszwalb & Huttenlocher /
// Meijster), multi-threaded over rows and column blocks; identical for every thread count.
// Isotropic grids are computed in integer voxel units (exact up to squared distances of 2^24
// voxels², i.e. any grid up to ~2400³), anisotropic ones in double precision per line.
// No background at all with border_is_object: +inf everywhere. Empty mask: all zeros.
// Memory: 4 bytes per voxel (output), 1 byte per 64 voxels (row segments holding object) and
// per-thread line buffers.
VolumeF32 euclidean(const VolumeU8& mask, const EuclideanOptions& options = {});

// Block-wise exact Euclidean DT (out-of-core): the three separable passes of euclidean(), each over
// slabs of whole lines along its axis (`cross` voxels across: pass x reads slabs of nx x cross[1] x
// cross[2], pass y cross[0] x ny x cross[2], pass z cross[0] x cross[1] x nz), from `mask` (any
// integer volume, in memory or on disk) into `out` (float32 on disk, the mask's grid), which holds
// the squared distances between passes. Bit-identical to euclidean(), anisotropic grids included.
// Progress "euclidean k/n blocks" (slabs).
void euclidean_blocks(const DataObject& mask, const ChunkedVolume& out, const EuclideanOptions& options, const Dims& cross);
// The slab cross-section for a budget: a quarter of it holds one slab along the longest axis.
Dims euclidean_cross_section(uint64_t budget, const Dims& grid_dims);

// Exact Euclidean feature transform: for every voxel the linear index of its nearest background voxel
// (ties as described at the top); background voxels get their own index; kOutside* where the
// nearest point is outside the array, and everywhere if there is no background at all.
// Returns VolumeU32 if the grid has < 2^32 - 1 voxels, else VolumeU64. Memory: 4 (or 8) bytes per
// voxel output plus 4 bytes per voxel of squared distances during the computation.
DataPtr feature_transform(const VolumeU8& mask, const DistanceOptions& options = {});
template <class Index> Volume<Index> feature_transform_as(const VolumeU8& mask, const DistanceOptions& options = {});

// How distance.feature_transform finds the nearest background point.
enum class FeatureMethod { euclidean, chamfer_bp };
constexpr auto enum_names(FeatureMethod) {
  return std::to_array<EnumName<FeatureMethod>>({{FeatureMethod::euclidean, "euclidean"}, {FeatureMethod::chamfer_bp, "chamfer_bp"}});
}

struct SeededOptions {
  bool squared = false;
  int threads = 0;
  Interrupter interrupter;
};

// Euclidean distance (physical units) from every voxel to the nearest seed voxel (value > 0), e.g.
// a skeleton: the exact EDT of the seed complement, with nothing outside the array acting as a seed.
// 0 on seeds; +inf everywhere when there is no seed. Memory: 4 bytes per voxel.
VolumeF32 seeded(const VolumeU8& seeds, const SeededOptions& options = {});

}  // namespace skel::distance
