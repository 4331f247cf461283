#pragma once
// Rods and plates per skeleton element (thesis §6.2, fig. 6.14): the mixed (plate + curve) skeleton is
// cut into structural elements — curve pieces between junctions (rods, the edges of its graph part)
// and surface patches between junction lines (plate candidates) — each element is classified rod or
// plate as a whole, and every object voxel takes the element of its nearest skeleton voxel. Unlike the
// per-voxel g/d threshold (geodesic::rods_plates), which the thesis shows fails at plate borders (g/d
// there behaves as on a rod), a plate's border belongs to its patch and so to the plate.
#include <cstdint>
#include <string>
#include <vector>

#include "skel/interrupter.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::analysis {

// Kind of a skeleton element by the manifold types of its voxels (fig. 3.9).
enum class ElementKind : uint8_t {
  curve = 1,    // 1-manifold voxels and 1-boundaries (and isolated voxels): a piece of curve
  surface = 2,  // 2-manifold voxels and 2-boundaries: a surface patch
  cluster = 3,  // junction voxels that touch no curve or surface element (e.g. a solid 2x2x2 block)
};
// Class of an element and of the object voxels it owns (values of the `classes` volume).
enum class RodPlateClass : uint8_t { background = 0, rod = 1, plate = 2 };

// The skeleton cut into elements. Voxel ids index the skeleton voxels in raster order.
struct SkeletonSegmentation {
  std::vector<int64_t> voxels;   // linear index per voxel id (ascending)
  std::vector<uint8_t> manifold; // geometry::ManifoldType per voxel id
  std::vector<int32_t> own;      // element (1-based) of curve/surface voxels, 0 on junction voxels
  std::vector<int32_t> element;  // element of every voxel: junction voxels joined to a neighbouring one
  std::vector<int32_t> junction; // junction cluster (1-based) of junction voxels, else 0
  std::vector<ElementKind> kind; // per element (index id - 1)
  int32_t junction_clusters = 0;
  // Per junction cluster (index id - 1): the elements it touches through 1-cells (ascending).
  std::vector<std::vector<int32_t>> cluster_elements;
  // The 1-cells (fig. 3.6) as CSR over voxel ids: neighbours of i are adj[off[i] .. off[i+1]).
  std::vector<int64_t> off, adj;
};

// Segmentation of a voxel skeleton (value > 0) into elements (phase 1). Curve voxels (line, line end,
// isolated point) and surface voxels (surface, surface edge) form elements as components of the
// dual-cube 1-cells within their kind; junction voxels (junction, 1-x-junction) form junction clusters
// (components through 1-cells) and are joined to the nearest element through 1-cells, preferring
// `preferred` elements (e.g. plates), then the lowest element id; clusters that touch no element
// become elements of kind `cluster`. Curve and surface elements are numbered in the order of their
// first voxel, cluster elements after them.
// Deterministic for any thread count.
SkeletonSegmentation segment_skeleton(const VolumeU8& skeleton, int threads = 0, const Interrupter& interrupter = {});
// (Re)joins the junction voxels of `seg` to elements: breadth-first through the 1-cells from the
// elements' own voxels, a voxel reached from several elements in the same step taking the one with
// `priority[element - 1]` highest, then the lowest id.
void join_junctions(SkeletonSegmentation& seg, const std::vector<int>& priority);

struct RodsPlatesElementOptions {
  // A surface patch is a plate when sqrt(area) >= plate_aspect x thickness (its extent is at least
  // plate_aspect times its thickness); every other element is a rod.
  double plate_aspect = 2.0;
  int threads = 0;
  Interrupter interrupter;
};

struct RodsPlatesElementResult {
  VolumeI32 elements;           // element id of every object voxel (nearest skeleton voxel's), 0 outside
  VolumeU8 classes;             // RodPlateClass of every object voxel
  VolumeI32 skeleton_elements;  // element id on the skeleton voxels only
  Table table;                  // one row per element
  Table indices;                // one row: the structural indices (BV/TV, rBV/BV, ...)
  SkeletonSegmentation segmentation;
  std::vector<RodPlateClass> element_class;  // per element (index id - 1)
};

// `distance`: distance to the boundary in physical units on the mask's grid (distance.euclidean; any
// volume type). Skeleton voxels outside the mask are ignored. Throws InputError on grid mismatch.
RodsPlatesElementResult rods_plates_elements(const VolumeU8& mask, const VolumeU8& skeleton, const DataObject& distance,
                                             const RodsPlatesElementOptions& options = {});

}  // namespace skel::analysis
