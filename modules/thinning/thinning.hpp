#pragma once
// Distance ordered homotopic thinning (DOHT, thesis §2.3.1, Algorithms 1 and 2): shrinks a binary
// object to a homotopic, medial voxel skeleton in the grid point model with (26, 6) adjacency.
// Voxels are removed in order of increasing priority (usually a distance transform: low = near the
// boundary = eroded first); a voxel is removed only if it is simple, not locked, and not a kept
// end point. Deterministic: results do not depend on the thread count.
#include <cstdint>
#include <string>

#include "skel/data.hpp"
#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::thinning {

enum class ThinningVariant {
  Basic,  // Algorithm 1 (BASICDOHT): one bucket priority queue, sequential removal in queue order
  Smooth  // Algorithm 2 (SMOOTHDOHT): per priority level, directional sub-iterations with a
          // parallel candidate check followed by sequential rechecking
};
constexpr auto enum_names(ThinningVariant) {
  return std::to_array<EnumName<ThinningVariant>>({{ThinningVariant::Basic, "basic"}, {ThinningVariant::Smooth, "smooth"}});
}

struct ThinningOptions {
  ThinningVariant variant = ThinningVariant::Smooth;
  // End-point importance l (thesis §2.3.1): 0 keeps no end points; l > 0 keeps a local end point
  // (exactly one 26-neighbour) of a side branch longer than l: its importance (the number of voxels
  // p_0 = the end point, p_1, ... that are local end points in turn, each after removing its
  // predecessors) exceeds l. l = 1 keeps branches of two or more voxels (sensitive to surface
  // noise); l >= 2 suppresses the short spurs that noise creates.
  int end_point_length = 2;
  int threads = 0;  // 0 = all hardware threads (parallel candidate checks, priority ranking)
  Interrupter interrupter;
};

struct ThinningStatistics {
  int64_t object_voxels = 0;      // |P| at the start
  int64_t skeleton_voxels = 0;    // voxels left
  int64_t priority_levels = 0;    // distinct priority values (buckets of the queue)
  int64_t tests = 0;              // deletability tests performed (n + m of the thesis)
  int64_t removed = 0;
  int64_t sub_iterations = 0;     // smooth variant: sub-iterations processed
  int64_t kept_end_points = 0;    // skeleton voxels that are simple but kept as end points
  int64_t locked_voxels = 0;      // skeleton voxels that were locked by the `locked` input
  // Fig. 2.23 / fig. 2.10: configurations thinning cannot resolve in the grid point model.
  // stuck_components: 26-components of the skeleton that are contractible (one component, no
  // cavity, no tunnel) and have more than one voxel, yet contain no kept end point and no locked
  // voxel - thinning would have reduced them to a single voxel if any of their voxels were simple.
  int64_t stuck_components = 0;
  int64_t stuck_voxels = 0;       // voxels in those components
  int64_t interior_voxels = 0;    // skeleton voxels whose six 6-neighbours are all skeleton
  uint64_t bytes = 0;             // working memory of the algorithm (without input/output)
};

struct ThinningResult {
  VolumeU8 skeleton;  // 0/1, same grid as the mask
  ThinningStatistics stats;
};

// Thins `mask` (non-zero = object). `priority`: any volume (Volume<T>) on the same dims; lower values
// are eroded first; values are ranked into integer levels (exact for integer types; floats are
// sorted and ranked). `locked` (optional, same dims): non-zero voxels are never removed.
// Throws InputError on mismatched dims, Cancelled when the interrupter says so.
ThinningResult thin_doht(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked = nullptr,
                         const ThinningOptions& options = {});
// The same skeleton written into `mask` itself (its buffer holds the state while thinning; 0/1 at
// the end; ThinningResult::skeleton stays empty): 1 byte per voxel less. The same statistics.
ThinningResult thin_doht_in_place(VolumeU8& mask, const DataObject& priority, const VolumeU8* locked = nullptr,
                                  const ThinningOptions& options = {});

// Local tests shared with tests and other thinning code.
// The sub-iteration directions of a voxel (Smooth DOHT, fig. 2.17): bit d (0..5 for +x, -x, +y, -y,
// +z, -z) is set if some mask for a direction v of the 26 neighbour directions matches (neighbour
// at +v is background, neighbour at -v is object) and v has a component along direction d.
// Every simple voxel matches at least one mask (an antipodally symmetric neighbourhood is never
// simple), so every deletable voxel belongs to some sub-iteration.
uint32_t thinning_directions(uint32_t neighbourhood26);

// Number of object voxels in the 26-neighbourhood word.
inline int neighbour_count(uint32_t neighbourhood26) { return __builtin_popcount(neighbourhood26); }

}  // namespace skel::thinning
