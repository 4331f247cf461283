#pragma once
// Registration of two scans of one specimen (thesis §6.2, "Analyzing Architectural Alterations"):
// closed-form landmark fits (rigid / similarity / affine), ICP refinement on skeleton or graph point
// sets, and application of a transform to volumes, SpatialGraphs and landmarks.
//
// Convention: every transform produced here maps *moving* physical coordinates onto *fixed* ones
// (p_fixed ≈ T p_moving). Resampling a moving volume onto a fixed grid therefore samples the input
// at T⁻¹(p) for each output voxel centre p.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "skel/interrupter.hpp"
#include "skel/landmarks.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/transform.hpp"
#include "skel/volume.hpp"

namespace skel::registration {

// ---------------------------------------------------------------- landmark fit
struct LandmarkFit {
  Transform transform;              // moving → fixed
  std::vector<Vec3> residual;       // T(moving[i]) - fixed[i]
  std::vector<double> distance;     // |residual[i]|
  double rms = 0.0;                 // sqrt(mean distance²)
};

// Least-squares fit of `model` mapping moving[i] onto fixed[i] in closed form: Kabsch/Umeyama with
// the determinant sign fix (a rigid or similarity fit never contains a reflection) or linear least
// squares (affine). Throws InputError for different counts, fewer than 3 points (4 for affine), or
// degenerate configurations (collinear points for rigid/similarity, coplanar for affine), naming
// `what` (e.g. "registration.landmarks: input 'landmarks'").
LandmarkFit fit_landmarks(const std::vector<Vec3>& fixed, const std::vector<Vec3>& moving,
                          TransformKind model, const std::string& what = "landmarks");

// Residual table: one row per landmark (columns landmark, fixed_x/y/z, moving_x/y/z, dx, dy, dz,
// distance) and a final row named "RMS" (dx/dy/dz = RMS per axis, distance = overall RMS; the
// coordinate columns are 0 there). Lengths are in `unit` (the landmarks').
Table residual_table(const std::vector<std::string>& names, const std::vector<Vec3>& fixed,
                     const std::vector<Vec3>& moving, const LandmarkFit& fit, const std::string& unit);

// Kind of a matrix: rigid if AᵀA = I and det > 0, similarity if AᵀA = s²I and det > 0, else
// affine (tolerance relative to the scale).
TransformKind classify_transform(const Matrix4& m, double tolerance = 1e-9);

// ---------------------------------------------------------------- point sets
// Physical centres of the non-zero voxels of any volume, in index order. Throws InputError naming
// `what` if `data` is not a volume.
std::vector<Vec3> volume_points(const DataObject& data, const std::string& what);
// Node positions followed by the interior polyline points of every edge (end points are nodes).
std::vector<Vec3> graph_points(const SpatialGraph& graph);
// Points of a volume or graph (dispatch on the type); throws InputError naming `what` otherwise.
std::vector<Vec3> points_of(const DataObject& data, const std::string& what);

// ---------------------------------------------------------------- ICP
struct IcpOptions {
  TransformKind model = TransformKind::Rigid;
  int iterations = 50;          // maximum number of iterations
  // Fraction of the correspondences kept in each iteration (the closest ones); 1 = no trimming.
  double trim_fraction = 0.9;
  // Correspondences farther apart than this (physical units) are dropped; infinity = no limit.
  double max_distance = std::numeric_limits<double>::infinity();
  // Stop when the RMS improves by less than this (physical units) between iterations.
  double tolerance = 1e-9;
  // Use at most this many moving points (a regular, deterministic subsample); 0 = all.
  int64_t max_points = 200000;
  int threads = 0;
  Interrupter interrupter{};
};

struct IcpIteration {
  int64_t pairs = 0;        // correspondences used
  double rms_before = 0.0;  // RMS of these pairs under the transform entering the iteration
  double rms_after = 0.0;   // RMS of the same pairs under the updated transform
};

struct IcpResult {
  Transform transform;                 // refined moving → fixed
  std::vector<IcpIteration> history;   // one entry per iteration
  bool converged = false;              // stopped by `tolerance` before `iterations`
};

// Point-to-point ICP: nearest fixed point (nanoflann k-d tree) for every moving point under the
// current transform, pairs beyond max_distance dropped, then the closest trim_fraction kept, then
// a closed-form fit (fit_landmarks) of the original moving points to their partners. Deterministic
// for any thread count. Throws InputError if a set is empty or too few pairs survive.
IcpResult refine_icp(const std::vector<Vec3>& fixed, const std::vector<Vec3>& moving,
                     const Transform& initial, const IcpOptions& options = {});

// Table of an ICP run: iteration, pairs, rms_before, rms_after (one row per iteration; RMS in `unit`).
Table icp_table(const IcpResult& result, const std::string& unit);

// ---------------------------------------------------------------- applying transforms
enum class Interpolation { Auto, Nearest, Linear };
constexpr auto enum_names(Interpolation) {
  return std::to_array<EnumName<Interpolation>>(
      {{Interpolation::Auto, "auto"}, {Interpolation::Nearest, "nearest"}, {Interpolation::Linear, "linear"}});
}
// "auto" | "nearest" | "linear"; throws InputError naming `what` otherwise.
Interpolation parse_interpolation(const std::string& text, const std::string& what = "interpolation");

struct ResampleOptions {
  Interpolation interpolation = Interpolation::Auto;  // auto: nearest for integer, linear for float
  int threads = 0;
  Interrupter interrupter{};
};

// Grid at `grid`'s spacing covering the transformed box of `grid`'s voxels (each voxel a box of
// one spacing around its centre).
Grid transformed_bounding_grid(const Grid& grid, const Transform& transform);

// Resamples `moving` onto `output_grid` through `transform` (moving → fixed): output voxel centre p
// gets the input value at T⁻¹(p). Nearest neighbour or trilinear; positions outside the input's voxel
// boxes get 0; within half a voxel of the border the edge value is replicated. Linear results of
// integer volumes are rounded and clamped to the type's range. Output type = input type.
template <class T>
Volume<T> transform_volume(const Volume<T>& moving, const Transform& transform, const Grid& output_grid,
                           const ResampleOptions& options = {});

// Nodes and polyline points mapped by `transform`; float attributes named radius, thickness,
// diameter or length (or containing one of these words, e.g. mean_radius, radius_min) are multiplied
// by transform.scale(); other attributes and labels are kept. `source_grid` becomes `output_grid`
// if it has voxels, else the transformed bounding grid of the old source grid (if it had voxels).
SpatialGraph transform_graph(const SpatialGraph& graph, const Transform& transform,
                             const Grid& output_grid = Grid{});

// Every point of every set mapped by `transform` (names kept).
LandmarkSet transform_landmarks(const LandmarkSet& landmarks, const Transform& transform);

// Length-like attributes (scaled by transform_graph): the one rule of skel/spatial_graph.hpp.
using skel::is_length_attribute;

}  // namespace skel::registration
