#pragma once
// Screen-space picking and box selection on a SpatialGraph for the graph edit mode (thesis §6.1).
// No Qt and no VTK: the caller passes the camera's world -> normalized-device matrix (row-major 4x4,
// e.g. vtkCamera::GetCompositeProjectionTransformMatrix) and the viewport size in pixels.
//
// Picking projects every node and every polyline segment to the screen (one pass over the points,
// parallel over fixed chunks, combined in chunk order: the result does not depend on the thread
// count) and takes the nearest within a pixel radius. No locator has to be rebuilt after an edit,
// so picking stays O(points) ≈ a few ms per 10⁶ points, and box selection uses the same projection.
#include <array>
#include <cstdint>
#include <vector>

#include "skel/spatial_graph.hpp"

namespace skel::gui {

struct ScreenProjection {
  std::array<double, 16> m{};  // world (x, y, z, 1) -> clip coordinates, row-major
  double width = 1, height = 1;  // viewport size in pixels; y grows downwards (Qt convention)
  // Screen position (pixels) and depth (NDC z in [-1, 1]); false if behind the camera / clipped.
  bool project(const Vec3& p, double& sx, double& sy, double& depth) const;
};

struct GraphPick {
  enum class Kind { None, Node, EdgePoint };
  Kind kind = Kind::None;
  int64_t node = -1;   // Kind::Node
  int64_t edge = -1;   // Kind::EdgePoint: edge and polyline vertex nearest to the cursor
  int64_t point = -1;
  Vec3 position{};     // world position of the node / vertex
  double pixels = 0;   // screen distance from the cursor
  [[nodiscard]] bool valid() const { return kind != Kind::None; }
};

// Nearest node or edge within `radius_px` of screen point (x, y). A node wins over an edge unless
// the edge's segment is more than 3 pixels closer; among equally near candidates the one nearer to
// the camera wins. Edges are measured to their projected segments; the reported vertex is the
// segment end nearer to the cursor.
GraphPick pick_graph(const SpatialGraph& g, const ScreenProjection& proj, double x, double y, double radius_px,
                     int threads = 0);

struct BoxSelection {
  std::vector<int64_t> nodes;                          // node ids inside the box (sorted)
  std::vector<std::pair<int64_t, int64_t>> edge_points;  // (edge, vertex) of edges with a vertex inside
};
// Nodes whose projection lies in the box [x0, x1] x [y0, y1] and edges with at least one polyline
// vertex in it (the first such vertex is reported).
BoxSelection select_box(const SpatialGraph& g, const ScreenProjection& proj, double x0, double y0, double x1,
                        double y1, int threads = 0);

}  // namespace skel::gui
