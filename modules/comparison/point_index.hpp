#pragma once
// Internal: a static k-d tree (nanoflann) over points in physical coordinates, shared by the
// comparison algorithms. Queries are const and thread-safe.
#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "skel/volume.hpp"

namespace skel::comparison::detail {

class PointIndex {
public:
  explicit PointIndex(std::vector<Vec3> points) : cloud_{std::move(points)} {
    if (!cloud_.points.empty())
      tree_ = std::make_unique<Tree>(3, cloud_, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  }
  PointIndex(const PointIndex&) = delete;
  PointIndex& operator=(const PointIndex&) = delete;

  [[nodiscard]] size_t size() const { return cloud_.points.size(); }
  [[nodiscard]] const std::vector<Vec3>& points() const { return cloud_.points; }

  // Nearest point: (index, distance); (-1, +inf) when the index is empty.
  [[nodiscard]] std::pair<int64_t, double> nearest(const Vec3& q) const {
    if (!tree_) return {-1, std::numeric_limits<double>::infinity()};
    size_t idx = 0;
    double d2 = 0;
    nanoflann::KNNResultSet<double, size_t, size_t> rs(1);
    rs.init(&idx, &d2);
    tree_->findNeighbors(rs, q.data(), nanoflann::SearchParams());
    return {static_cast<int64_t>(idx), std::sqrt(d2)};
  }

  // Whether some point has distance <= radius: the same test as nearest(q).second <= radius
  // (sqrt of the same squared distance), but the search prunes everything farther than radius and
  // stops at the first point that passes.
  [[nodiscard]] bool any_within(const Vec3& q, double radius) const {
    if (!tree_) return false;
    AnyWithin rs{radius * radius * (1.0 + 1e-12) + 1e-300, radius};
    tree_->findNeighbors(rs, q.data(), nanoflann::SearchParams());
    return rs.found;
  }

  // Indices of all points with distance <= radius, in ascending index order.
  void within(const Vec3& q, double radius, std::vector<std::pair<size_t, double>>& scratch,
              std::vector<int64_t>& out) const {
    out.clear();
    if (!tree_) return;
    scratch.clear();
    nanoflann::SearchParams p;
    p.sorted = false;
    // nanoflann's radius test is strict (d2 < r2): widen by one ulp-scale step so <= radius holds.
    const double r2 = radius * radius * (1.0 + 1e-12) + 1e-300;
    tree_->radiusSearch(q.data(), r2, scratch, p);
    for (const auto& m : scratch)
      if (m.second <= radius * radius) out.push_back(static_cast<int64_t>(m.first));
    std::sort(out.begin(), out.end());
  }

private:
  // nanoflann result set: candidates are points with squared distance < limit (slightly above
  // radius², so no point with sqrt(d²) <= radius is pruned); returning false ends the search.
  struct AnyWithin {
    double limit, radius;
    bool found = false;
    [[nodiscard]] double worstDist() const { return limit; }
    [[nodiscard]] bool full() const { return true; }
    bool addPoint(double d2, size_t) {
      found = std::sqrt(d2) <= radius;
      return !found;
    }
  };
  struct Cloud {
    std::vector<Vec3> points;
    [[nodiscard]] size_t kdtree_get_point_count() const { return points.size(); }
    [[nodiscard]] double kdtree_get_pt(size_t i, size_t dim) const { return points[i][dim]; }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const { return false; }
  };
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3, size_t>;
  Cloud cloud_;
  std::unique_ptr<Tree> tree_;
};

}  // namespace skel::comparison::detail
