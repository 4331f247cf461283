#pragma once
// A synthetic microvascular network (thesis §6.1): arterial and venous trees whose radii shrink at
// branchings (Murray's law), joined by capillaries that close loops. The ground-truth graph is kept
// for evaluating reconstructions (branch points, end points, length).
#include <cstdint>
#include <string>

#include "skel/interrupter.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::synthetic {

struct VesselTreeOptions {
  Dims size{128, 128, 128};
  uint64_t seed = 1;
  double noise = 0.0;             // 0..1, two-frequency noise added to the image
  Vec3 spacing{1, 1, 1};
  std::string unit = kDefaultUnit;  // physical unit of spacing, of the truth graph and of its tables
  int roots = 4;                  // number of trees: half arterial, half venous (at least one each)
  double root_radius = 5.0;       // voxels
  double min_radius = 2.0;        // voxels; branching stops below; capillary radius
  double capillary_length = 50.0; // longest capillary, voxels (longer ones only to join separate trees)
  double length_scale = 0;        // vessel and capillary lengths × this; 0 = max(1, min(size) / 128)
  double sigma = 0.7;             // smooth edge width, voxels
  int threads = 0;
  Interrupter interrupter;
};

struct VesselTreeResult {
  VolumeF32 image;
  VolumeU8 mask;
  SpatialGraph truth;  // point attribute `radius` (physical), edge label `tree` (0 artery, 1 vein,
                       // 2 capillary), node label `kind` (0 root, 1 branch, 2 end, 3 capillary joint)
  Table nodes;  // id, x, y, z (physical), kind (root | branch | end | junction), degree
  Table edges;  // id, node0, node1, length (physical), radius (physical), tree (artery | vein | capillary)
  // Summary of the ground truth (the same numbers follow from the tables).
  double total_length = 0;    // sum of the edge lengths, physical units
  int64_t branch_points = 0;  // nodes of degree >= 3
  int64_t end_points = 0;     // nodes of degree 1 (the roots included)
};

VesselTreeResult make_vessel_tree(const VesselTreeOptions& options);

}  // namespace skel::synthetic
