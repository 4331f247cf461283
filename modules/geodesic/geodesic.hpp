#pragma once
// Geodesic boundary distance (thesis §2.3.2): for every object voxel p, the importance
//   max over the considered 6-neighbours q of g(b(p), b(q)),
// where b is the nearest-background-point transform and g the length of the shortest 6-path inside
// the one-voxel background layer L = {background voxels 26-adjacent to the object}. Considered
// neighbours: the three lower 6-neighbours (x-1, y-1, z-1) always, the three upper ones only where
// they are background. Plate-like parts get high values (the two sides are far apart along the
// boundary), so a threshold t selects a two-dimensional skeleton that is robust to boundary noise.
#include <cstdint>
#include <string>

#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::geodesic {

enum class Mode {
  Threshold,  // propagation stops at t; importance saturates at t (also where no path exists)
  Full        // exact values everywhere (+inf where the two points lie on unconnected parts of L)
};
constexpr auto enum_names(Mode) {
  return std::to_array<EnumName<Mode>>({{Mode::Threshold, "threshold"}, {Mode::Full, "full"}});
}

struct Options {
  Mode mode = Mode::Threshold;
  int64_t threshold = 20;  // t, in 6-steps of the boundary layer
  int threads = 0;
  // Landmark fields for the searches (ALT heuristic): the same importance, fewer closed voxels;
  // off only to compare (tests, benchmarks).
  bool landmarks = true;
  Interrupter interrupter;
};

struct Statistics {
  int64_t object_voxels = 0;
  int64_t layer_voxels = 0;       // |L|
  int64_t base_points = 0;        // distinct b(p) with work to do
  int64_t searches = 0;           // searches run: own A* searches (one per base with targets left that no
                                  // monotone path of at most 4 steps in L settles) + pivots
  int64_t pivots = 0;             // searches extended to t + t/4 to settle neighbouring bases
  int64_t long_searches = 0;      // own searches that ran to t with targets left
  int64_t saturated_by_pivot = 0; // targets proved >= t by a neighbouring base's search
  int64_t visited = 0;            // layer voxels closed (A*) or dequeued (pivot and landmark BFS) over all searches
  int64_t landmarks = 0;          // landmark fields built (bounded BFS from the far target of an expensive search)
  uint64_t bytes = 0;             // peak working memory of the algorithm (without input/output)
  uint64_t bytes_prepare = 0;     // of which: peak of the preparation (bitmaps, b(p), rings)
  uint64_t bytes_search = 0;      // and peak of the searches (bitmaps, b(p), buckets, claims, scratch)
  double seconds_prepare = 0;     // wall time of the bitmaps, b(p), L's components and the buckets
  double seconds_search = 0;      // wall time of the searches (and the importance)
};

struct Result {
  VolumeF32 importance;       // 0 on background; threshold mode: min(value, t); full: value or +inf
  VolumeU8 surface_skeleton;  // importance >= t
  Statistics stats;
};

// The nearest background point b(p) is found by propagating nearest points inward from L ring by ring
// (26-neighbourhood, each voxel takes the candidate of its already reached neighbours that is closest
// in physical distance; ties go to the lower position) — a nearest point "by a chamfer path" as in
// the thesis. Voxels outside the array count as background; the one-voxel ring around the array
// belongs to L where it touches the object.
// The geodesic boundary distance of `mask` (voxel > 0 is object).
Result boundary_distance(const VolumeU8& mask, const Options& options = {});

// Reference implementation for tests: a plain BFS from b(p) over L for every considered pair, with the
// same b(p). O(k * |L|); use only on small volumes.
Result boundary_distance_reference(const VolumeU8& mask, const Options& options = {});

}  // namespace skel::geodesic
