#pragma once
// Pre-processing and segmentation (thesis §6.1–6.2): threshold (manual or Otsu), separable Gaussian
// smoothing, median filter, illumination correction along z, connected components, cavity filling,
// binary morphology with a ball. Masks are uint8 0/1; any integer volume counts as a mask with
// "voxel > 0 is object"; float volumes where a mask is expected are an InputError naming the port.
// Every function returns identical results for any thread count.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/connectivity.hpp"
#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/table.hpp"
#include "skel/out_of_core.hpp"
#include "skel/volume.hpp"

namespace skel::segmentation {

// Otsu's threshold of any volume (256-bin histogram between min and max; exact bins for uint8).
double otsu_threshold(const DataObject& image, int threads = 0);

// low <= value <= high -> 1.
VolumeU8 threshold(const DataObject& image, double low, double high, int threads = 0);

// Manual thresholds, or Otsu's: low = the next value above Otsu's threshold, high = +inf.
enum class ThresholdMethod { manual, otsu };
constexpr auto enum_names(ThresholdMethod) {
  return std::to_array<EnumName<ThresholdMethod>>({{ThresholdMethod::manual, "manual"}, {ThresholdMethod::otsu, "otsu"}});
}
struct ThresholdOptions {
  ThresholdMethod method = ThresholdMethod::manual;
  double low = 0.5;                                    // inclusive
  double high = std::numeric_limits<double>::infinity();  // inclusive
  int threads = 0;
};
struct ThresholdResult {
  VolumeU8 mask;
  double low = 0, high = 0;  // the thresholds used
  int64_t object_voxels = 0;
};
ThresholdResult threshold(const DataObject& image, const ThresholdOptions& options);

// Block-wise threshold (out-of-core, docs/architecture.md): reads `image` (in memory or on disk)
// in blocks of `block` voxels and writes the mask into `mask` (on disk, the image's grid); the
// same voxels and thresholds as threshold() (Otsu: two more block passes, value range and
// histogram). Progress "threshold k/n blocks".
struct BlockThresholdResult {
  double low = 0, high = 0;
  int64_t object_voxels = 0;
};
BlockThresholdResult threshold_blocks(const DataObject& image, const ChunkedVolume& mask, const ThresholdOptions& options,
                                      const Dims& block, const Interrupter& interrupter = {});

struct GaussianOptions {
  Vec3 sigma{1, 1, 1};  // physical units per axis; 0 on an axis skips it
  double truncate = 3.5;  // kernel radius in sigmas
  int threads = 0;
  Interrupter interrupter;
};
VolumeF32 gaussian(const DataObject& image, const GaussianOptions& options = {});
// gaussian() of a float32 image written into the image itself (segmentation.gaussian when the
// executor hands it its input): the same bytes, without the output volume and the copy.
void gaussian_in_place(VolumeF32& image, const GaussianOptions& options);
// Block-wise Gaussian (out-of-core): every block of `block` voxels is read with the kernel's radius
// around it (gaussian_halo, per axis), smoothed as in memory and its interior written into `out`
// (float32 on disk, the image's grid). The same values as gaussian(). Progress "gaussian k/n blocks".
void gaussian_blocks(const DataObject& image, const ChunkedVolume& out, const GaussianOptions& options, const Dims& block);
// Kernel radius in voxels per axis (0 where an axis is skipped) for this grid and these options.
Dims gaussian_halo(const Grid& grid, const GaussianOptions& options);

// How the sampled kernel is rounded and its taps summed: the same filter up to float rounding, each
// kept because outputs made with it must stay bit-identical.
enum class GaussianSum {
  paired,      // weights normalised in double; centre + Σ k_j·(left_j + right_j)   (segmentation.gaussian)
  sequential,  // weights rounded to float, then normalised; Σ from -r to r  (synthetic phantoms)
};
// The separable Gaussian of `image` in place (what `gaussian` runs after converting to float):
// sigma in voxels per axis (0 skips an axis), kernel radius max(1, ceil(truncate·sigma)), border
// values replicated. Progress: one third per axis. Per-thread buffers of one slice only.
void gaussian_in_place(VolumeF32& image, const Vec3& sigma, double truncate, GaussianSum sum, int threads = 0,
                       const Interrupter& interrupter = {});

struct ComponentOptions {
  Connectivity connectivity = Connectivity::c26;
  int64_t min_size = 0;       // smaller components are removed (voxels)
  double min_fraction = 0.0;  // components smaller than this fraction of the largest are removed
  bool keep_largest = false;
  bool labels = true;  // false: no label volume (ComponentsResult::labels stays empty; 4 bytes per voxel less)
  int threads = 0;
  Interrupter interrupter;
};
struct ComponentsResult {
  VolumeU32 labels;  // 0 background; 1 = largest kept component, 2 = next, ... (ties: first voxel in raster order)
  VolumeU8 mask;     // kept components
  Table table;       // label, voxels, volume, bbox, centroid
  int64_t count = 0; // kept components
  std::string warning;  // non-empty when the selection removed a large component (see selection_warning)
};
ComponentsResult connected_components(const VolumeU8& mask, const ComponentOptions& options = {});
// The same, with the kept components written into `mask` itself as 0/1 (ComponentsResult::mask
// stays empty): 1 byte per voxel less. Labels, table, count and warning as connected_components.
ComponentsResult connected_components_in_place(VolumeU8& mask, const ComponentOptions& options = {});

// Block-wise connected components (out-of-core), two passes over the blocks: components inside
// every block of `block` voxels (union-find over runs, as in memory) become pieces, kept in memory
// with the piece runs on the block's six faces; pieces touching across block faces, edges and
// corners (per connectivity) are united in memory; then every block is read and labelled again.
// Labels, mask and table are the same as connected_components() gives (size descending, ties by
// first voxel in raster order). `labels` (uint32) and `kept` (uint8) are on disk with the mask's
// grid; nothing else is written. Memory: one block (mask 1 + labels 4 + kept 1 bytes per voxel, and
// its runs) plus ~100 bytes per piece and 24 per piece run on a block face. Progress "components
// k/n blocks" (two passes).
struct BlockComponentsResult {
  Table table;
  int64_t count = 0;
  std::string warning;  // as ComponentsResult::warning
};
BlockComponentsResult connected_components_blocks(const DataObject& mask, const ChunkedVolume& labels,
                                                  const ChunkedVolume& kept, const ComponentOptions& options,
                                                  const Dims& block);

// Counts components without labelling: of the object (non-zero) voxels, or of the background (zero)
// voxels when `background`; touching_border = those with a voxel on an array face. Union-find over
// x-runs as connected_components; memory ~ 24 bytes per run, no label volume.
struct ComponentCount {
  int64_t components = 0;
  int64_t touching_border = 0;
};
ComponentCount count_components(const VolumeU8& mask, int connectivity, bool background, int threads = 0,
                                const Interrupter& interrupter = {});

// Background components not 6-connected to the volume border become object (thesis §6.2). Union-find
// over background x-runs (as count_components); `filled` receives the number of filled voxels.
VolumeU8 fill_cavities(const VolumeU8& mask, int64_t* filled = nullptr, int threads = 0);
// Block-wise fill_cavities (out-of-core): background 6-components found per block of `block` voxels
// and united across block faces in memory (as connected_components_blocks); those without a voxel on
// an array face are written as object into `out` (uint8 on disk) when each block is read again. The
// same mask as fill_cavities(); returns the number of filled voxels. Progress "fill_cavities k/n
// blocks" (two passes).
int64_t fill_cavities_blocks(const DataObject& mask, const ChunkedVolume& out, const Dims& block, int threads = 0,
                             const Interrupter& interrupter = {});

// Median over the (2·radius+1)³ cube around each voxel; voxels outside the volume take the value of
// the nearest border voxel (replicated border, SciPy mode "nearest"). Output has the input's type.
// radius 1: a vectorised forgetful-selection network over x-rows; radius > 1: nth_element per voxel.
struct MedianOptions {
  int radius = 1;  // voxels, >= 0 (0 = copy)
  int threads = 0;
  Interrupter interrupter;
};
DataPtr median(const DataObject& image, const MedianOptions& options = {});
template <class T> Volume<T> median_as(const Volume<T>& image, const MedianOptions& options = {});
// Block-wise median (out-of-core): every block of `block` voxels is read with `radius` voxels around
// it, filtered as in memory and its interior written into `out` (on disk, the image's type and
// grid). The same values as median(). Progress "median k/n blocks".
void median_blocks(const DataObject& image, const ChunkedVolume& out, const MedianOptions& options, const Dims& block);

// Depth-attenuation correction of confocal stacks (thesis §6.1): every z-slice is multiplied by a
// factor f(z). Given mode: f(z) = intercept + slope·z (z = slice index). Fitted mode: per slice the
// mean of the brightest `percentile` fraction of voxels m(z) is computed, a line L(z) = a + b·z is
// fitted to m(z) by least squares, and f(z) = L(0) / L(z) flattens the fitted profile (slices whose
// fitted value is <= 0 are an InputError). Output float32.
enum class IlluminationMode { fit, given };
constexpr auto enum_names(IlluminationMode) {
  return std::to_array<EnumName<IlluminationMode>>({{IlluminationMode::fit, "fit"}, {IlluminationMode::given, "given"}});
}
struct IlluminationOptions {
  IlluminationMode mode = IlluminationMode::fit;
  double slope = 0.0, intercept = 1.0;  // given mode
  double percentile = 0.01;             // fitted mode: brightest fraction of each slice, (0, 1]
  int threads = 0;
  Interrupter interrupter;
};
struct IlluminationResult {
  VolumeF32 image;
  std::vector<double> slice_statistic;  // m(z) (fitted mode; empty otherwise)
  std::vector<double> factor;           // f(z)
  double fit_intercept = 0, fit_slope = 0;  // L(z) (fitted mode)
};
IlluminationResult illumination_z(const DataObject& image, const IlluminationOptions& options = {});
// Block-wise (out-of-core): the same factors and voxels as illumination_z; the corrected image goes
// to `out` (float32, the image's grid; result.image stays empty). Fit mode first reads slabs of
// `slab` whole slices (the statistic needs a whole slice: 8 bytes per voxel of a slice per thread
// plus the slab), then every block of `block` is scaled by its slices' factors (halo 0).
IlluminationResult illumination_z_blocks(const DataObject& image, const ChunkedVolume& out,
                                         const IlluminationOptions& options, const Dims& block, int64_t slab);

// Binary morphology with the exact digital ball {(dx,dy,dz): dx²+dy²+dz² <= radius²} (voxel units).
// Dilation: object where the squared Euclidean distance to the nearest object voxel is <= radius²;
// erosion: object where the squared distance to the nearest background voxel is > radius², voxels
// outside the volume counting as background for erosion (and contributing nothing to dilation);
// open = erode then dilate; close = dilate then erode. Computed by exact separable squared distance
// transforms (integer lower envelopes), O(voxels) for any radius.
enum class MorphologyOp { erode, dilate, open, close };
constexpr auto enum_names(MorphologyOp) {
  return std::to_array<EnumName<MorphologyOp>>({{MorphologyOp::erode, "erode"}, {MorphologyOp::dilate, "dilate"},
                                               {MorphologyOp::open, "open"}, {MorphologyOp::close, "close"}});
}
struct MorphologyOptions {
  MorphologyOp op = MorphologyOp::dilate;
  double radius = 1.0;  // voxels, >= 0
  int threads = 0;
  Interrupter interrupter;
};
VolumeU8 morphology(const VolumeU8& mask, const MorphologyOptions& options = {});

}  // namespace skel::segmentation
