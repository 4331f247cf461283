#pragma once
// Post-processing and analysis on top of the geodesic boundary distance (thesis §2.3.2–2.3.3, §6.2):
// thinning the selected surface voxels to a one-voxel-thin plate skeleton, the tubularity ratio g/d,
// and the rods/plates decomposition of bone.
#include <cstdint>

#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::geodesic {

struct ThinSurfaceOptions {
  int64_t max_passes = 1000;  // safety bound; every pass that removes nothing ends the loop
  Interrupter interrupter;
};
struct ThinSurfaceResult {
  VolumeU8 surface;
  int64_t removed = 0, passes = 0;
};
// Removes simple voxels (26/6) from `surface` in six directional sub-iterations with sequential
// rechecking (the thesis' fig. 2.35 post-processing, after Borgefors et al. 1999): a voxel v goes in
// sub-iteration d only if its neighbour at +d is not in the set and the one at -d is (it lies on a
// two-voxel-thick part), and if no axis has both 6-neighbours outside the set — such voxels are
// surface points, surface edges or curve ends, which keeps the plate's geometric extent. Topology is
// preserved (every removal is of a simple voxel); the result does not depend on thread count.
ThinSurfaceResult thin_surface(const VolumeU8& surface, const ThinSurfaceOptions& options = {});

// How `distance` values convert to voxel units for the ratio g/d.
enum class DistanceUnit { Physical, Chamfer, Voxels };
constexpr auto enum_names(DistanceUnit) {
  return std::to_array<EnumName<DistanceUnit>>(
      {{DistanceUnit::Physical, "physical"}, {DistanceUnit::Chamfer, "chamfer"}, {DistanceUnit::Voxels, "voxels"}});
}

struct TubularityOptions {
  DistanceUnit unit = DistanceUnit::Physical;  // Physical: divide by the mean spacing
  double chamfer_unit = 3.0;                   // Chamfer: value of one voxel step (3 for 3-4-5)
  int threads = 0;
};
// g/d on skeleton voxels (0 elsewhere): importance (voxel steps) over the distance to the boundary
// (in voxels). Rods give about pi (half the circumference over the radius); plates give far more
// because g grows with the plate's width (up to t/d in threshold mode).
VolumeF32 tubularity(const VolumeU8& skeleton, const VolumeF32& importance, const DataObject& distance,
                     const TubularityOptions& options = {});

struct RodsPlatesOptions {
  double ratio_threshold = 5.0;  // g/d at or above: plate
  TubularityOptions tubularity;
  int threads = 0;
  Interrupter interrupter;
};
struct RodsPlatesResult {
  VolumeU8 labels;  // 0 background, 1 rod, 2 plate (every object voxel, by nearest skeleton voxel)
  VolumeU8 skeleton_labels;  // the same on skeleton voxels only
  Table table;      // one row per class: voxels, volume, surface, skeleton voxels, pieces, mean thickness
};
// Classifies skeleton voxels into rods and plates by g/d and propagates the class to every object
// voxel from its nearest skeleton voxel (exact Euclidean feature transform; thesis fig. 6.14).
RodsPlatesResult rods_plates(const VolumeU8& mask, const VolumeU8& skeleton, const VolumeF32& importance,
                             const DataObject& distance, const RodsPlatesOptions& options = {});

}  // namespace skel::geodesic
