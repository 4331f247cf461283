// comparison::skeleton_distance: distance of every reference skeleton point to the other skeleton
// (thesis §6.2: a distance transformation seeded at the skeleton), with statistics and change masks.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

#include "comparison/comparison.hpp"
#include "comparison/point_index.hpp"
#include "distance/distance.hpp"
#include "skel/error.hpp"
#include "skel/units.hpp"
#include "skel/mask.hpp"
#include "skel/parallel.hpp"

namespace skel::comparison {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Points of one side with their weights; `voxel` holds the linear voxel index for volumes.
struct SidePoints {
  std::vector<Vec3> positions;
  std::vector<double> weights;
  std::vector<int64_t> voxel;
};

bool is_integer_volume(const DataObject& d) {
  const std::string t = d.type_id();
  return t != type_ids::volume_f32 && t != type_ids::volume_f64;
}

// Linear indices of voxels > 0, x-fastest order. Fixed chunks (z-slabs) concatenated in order, so
// the list does not depend on the thread count.
std::vector<int64_t> skeleton_voxels(const DataObject& volume, const std::string& port, int threads,
                                     const Interrupter& intr) {
  return visit_volume(volume, port, [&](const auto& v) -> std::vector<int64_t> {
    using T = typename std::decay_t<decltype(v)>::value_type;
    if constexpr (std::is_floating_point_v<T>) {
      throw InputError(port + ": expected an integer skeleton volume (voxel > 0 = skeleton) or a graph, got a " +
                       std::string(VoxelTraits<T>::name) + " volume");
    } else {
      const int64_t slab = std::max<int64_t>(1, v.nx() * v.ny());
      const int64_t chunks = std::max<int64_t>(1, std::min<int64_t>(v.nz(), 256));
      std::vector<std::vector<int64_t>> parts(static_cast<size_t>(chunks));
      std::atomic<int64_t> done{0};
      parallel_chunks(0, v.nz(), chunks, threads, [&](int64_t c, int64_t z0, int64_t z1) {
        const T* d = v.data();
        auto& out = parts[static_cast<size_t>(c)];
        for (int64_t i = z0 * slab, e = z1 * slab; i < e; ++i)
          if (d[i] > 0) out.push_back(i);
        intr.check(0.1 * static_cast<double>(++done) / static_cast<double>(chunks));
      });
      size_t total = 0;
      for (const auto& p : parts) total += p.size();
      std::vector<int64_t> all;
      all.reserve(total);
      for (auto& p : parts) all.insert(all.end(), p.begin(), p.end());
      return all;
    }
  });
}

Vec3 voxel_position(const Grid& g, int64_t i) {
  const int64_t x = i % g.dims[0], r = i / g.dims[0];
  const int64_t y = r % g.dims[1], z = r / g.dims[1];
  return g.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
}

double seg_length(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// Reference-side points: voxel centres (weight 1) or every polyline point (weight = half of each
// adjacent segment; node points repeat per edge, so the weights add up to the total length).
SidePoints reference_points(const SkeletonInput& in, const std::vector<int64_t>* voxels) {
  SidePoints p;
  if (in.graph) {
    const SpatialGraph& g = *in.graph;
    const size_t n = static_cast<size_t>(g.point_count());
    p.positions.reserve(n);
    p.weights.reserve(n);
    for (const GraphEdge& e : g.edges) {
      const size_t m = e.points.size();
      for (size_t i = 0; i < m; ++i) {
        double w = 0;
        if (i > 0) w += 0.5 * seg_length(e.points[i - 1], e.points[i]);
        if (i + 1 < m) w += 0.5 * seg_length(e.points[i], e.points[i + 1]);
        p.positions.push_back(e.points[i]);
        p.weights.push_back(w);
      }
    }
  } else {
    const Grid& grid = volume_grid(*in.volume, in.name);
    p.voxel = *voxels;
    p.positions.resize(p.voxel.size());
    for (size_t i = 0; i < p.voxel.size(); ++i) p.positions[i] = voxel_position(grid, p.voxel[i]);
    p.weights.assign(p.voxel.size(), 1.0);
  }
  return p;
}

// Target-side points: voxel centres, or graph nodes plus polylines resampled at `spacing`.
std::vector<Vec3> target_points(const SkeletonInput& in, const std::vector<int64_t>* voxels, double spacing) {
  std::vector<Vec3> pts;
  if (in.graph) {
    pts = in.graph->positions;
    std::vector<Vec3> s;
    std::vector<double> w;
    for (const GraphEdge& e : in.graph->edges) {
      resample_polyline(e.points, spacing, s, w);
      pts.insert(pts.end(), s.begin(), s.end());
      // Keep the original polyline points too: identical graphs then give exact zeros.
      pts.insert(pts.end(), e.points.begin(), e.points.end());
    }
  } else {
    const Grid& grid = volume_grid(*in.volume, in.name);
    pts.resize(voxels->size());
    for (size_t i = 0; i < voxels->size(); ++i) pts[i] = voxel_position(grid, (*voxels)[i]);
  }
  return pts;
}

DistanceStatistics statistics(const std::vector<double>& values, const std::vector<double>& weights, double threshold) {
  DistanceStatistics s;
  s.points = static_cast<int64_t>(values.size());
  if (values.empty()) return s;
  std::vector<std::pair<double, double>> vw(values.size());
  double sum = 0, wsum = 0, mx = 0;
  for (size_t i = 0; i < values.size(); ++i) {
    vw[i] = {values[i], weights[i]};
    wsum += weights[i];
    sum += values[i] * weights[i];
    mx = std::max(mx, values[i]);
    if (values[i] > threshold) {
      ++s.changed_points;
      s.changed_weight += weights[i];
    }
  }
  s.weight = wsum;
  s.max = mx;
  s.mean = wsum > 0 ? sum / wsum : 0.0;
  s.changed_fraction = wsum > 0 ? s.changed_weight / wsum : 0.0;
  std::sort(vw.begin(), vw.end());
  s.median = weighted_quantile(vw, 0.5);
  s.p95 = weighted_quantile(std::move(vw), 0.95);
  return s;
}

// Fills the per-side outputs (volume or graph copy) from the per-point values.
void fill_side(SideDistances& side, const SkeletonInput& in, const SidePoints& pts, double threshold, bool nan_off,
               int threads) {
  side.stats = statistics(side.values, side.weights, threshold);
  if (in.graph) {
    side.is_graph = true;
    side.graph = *in.graph;
    auto& dist = side.graph.ensure_point_attribute("distance");
    auto& changed = side.graph.ensure_point_attribute("changed");
    auto& frac = side.graph.ensure_edge_attribute("changed_fraction");
    size_t k = 0;
    for (size_t e = 0; e < side.graph.edges.size(); ++e) {
      double w = 0, wc = 0;
      for (size_t i = 0; i < side.graph.edges[e].points.size(); ++i, ++k) {
        dist[e][i] = static_cast<float>(side.values[k]);
        const bool c = side.values[k] > threshold;
        changed[e][i] = c ? 1.0f : 0.0f;
        w += side.weights[k];
        if (c) wc += side.weights[k];
      }
      frac[e] = w > 0 ? static_cast<float>(wc / w) : 0.0f;
    }
  } else {
    const Grid& grid = volume_grid(*in.volume, in.name);
    side.distance = VolumeF32(grid, nan_off ? std::numeric_limits<float>::quiet_NaN() : 0.0f);
    side.changed = VolumeU8(grid, 0);
    const int64_t n = static_cast<int64_t>(pts.voxel.size());
    parallel_for(0, n, threads, [&](int64_t a, int64_t b) {
      for (int64_t k = a; k < b; ++k) {
        const int64_t i = pts.voxel[static_cast<size_t>(k)];
        side.distance[i] = static_cast<float>(side.values[static_cast<size_t>(k)]);
        side.changed[i] = side.values[static_cast<size_t>(k)] > threshold ? 1 : 0;
      }
    }, 1 << 16);
  }
}

double auto_spacing(const SkeletonInput& a, const SkeletonInput& b) {
  double s = kInf;
  for (const SkeletonInput* in : {&a, &b}) {
    const Grid* g = nullptr;
    if (in->volume) g = &volume_grid(*in->volume, in->name);
    else if (in->graph && in->graph->source_grid.voxel_count() > 0) g = &in->graph->source_grid;
    if (g) s = std::min({s, g->spacing[0], g->spacing[1], g->spacing[2]});
  }
  return std::isfinite(s) ? 0.5 * s : 0.5;
}

// Distances from `from` points to the nearest point of `to`, by the k-d tree.
std::vector<double> kd_distances(const SidePoints& from, const std::vector<Vec3>& to, int threads,
                                 const Interrupter& intr) {
  detail::PointIndex index(to);
  std::vector<double> d(from.positions.size());
  const int64_t n = static_cast<int64_t>(d.size());
  const int64_t chunks = std::max<int64_t>(1, std::min<int64_t>(64, n / 4096 + 1));
  std::atomic<int64_t> done{0};
  parallel_chunks(0, n, chunks, threads, [&](int64_t, int64_t a, int64_t b) {
    for (int64_t i = a; i < b; ++i) d[static_cast<size_t>(i)] = index.nearest(from.positions[static_cast<size_t>(i)]).second;
    intr.check(static_cast<double>(++done) / static_cast<double>(chunks));
  });
  return d;
}

// Distances from the `from` voxels to the nearest voxel > 0 of `to` by the seeded EDT on the grid.
std::vector<double> transform_distances(const SidePoints& from, const DataObject& to, const std::string& to_name,
                                        int threads, const Interrupter& intr) {
  VolumeU8 copy;
  const VolumeU8* seeds = dynamic_cast<const VolumeU8*>(&to);
  if (!seeds) {
    copy = to_mask(to, to_name);
    seeds = &copy;
  }
  distance::SeededOptions so;
  so.threads = threads;
  so.interrupter = intr;
  const VolumeF32 edt = distance::seeded(*seeds, so);
  std::vector<double> d(from.voxel.size());
  for (size_t k = 0; k < d.size(); ++k) d[k] = static_cast<double>(edt[from.voxel[k]]);
  return d;
}

void validate_input(const SkeletonInput& in) {
  if ((in.volume == nullptr) == (in.graph == nullptr))
    throw InputError(in.name + ": expected a skeleton volume or a graph");
  if (in.volume && !is_integer_volume(*in.volume))
    throw InputError(in.name + ": expected an integer skeleton volume (voxel > 0 = skeleton) or a graph, got " +
                     in.volume->type_id());
}

}  // namespace

DistanceMethod parse_distance_method(const std::string& text, const std::string& what) {
  return parse_enum<DistanceMethod>(text, what);
}

double weighted_quantile(std::vector<std::pair<double, double>> vw, double q) {
  if (vw.empty()) return 0.0;
  if (!std::is_sorted(vw.begin(), vw.end())) std::sort(vw.begin(), vw.end());
  double total = 0;
  for (const auto& p : vw) total += p.second;
  if (!(total > 0)) {  // all weights 0: unweighted
    const size_t k = static_cast<size_t>(std::ceil(q * static_cast<double>(vw.size())));
    return vw[std::min(vw.size() - 1, k == 0 ? 0 : k - 1)].first;
  }
  const double target = q * total;
  double acc = 0;
  for (const auto& p : vw) {
    acc += p.second;
    if (acc >= target * (1 - 1e-12) && p.second > 0) return p.first;
  }
  return vw.back().first;
}

SkeletonDistanceResult skeleton_distance(const SkeletonInput& reference, const SkeletonInput& other,
                                         const SkeletonDistanceOptions& o) {
  validate_input(reference);
  validate_input(other);
  const auto unit_of = [](const SkeletonInput& in) {
    return in.volume ? in.volume->physical_unit() : in.graph ? in.graph->unit : std::string(kDefaultUnit);
  };
  const std::string unit = unit_of(reference);
  units::check_same(unit, "input '" + reference.name + "'", unit_of(other), "input '" + other.name + "'");
  if (!(o.threshold >= 0)) throw InputError("threshold: expected >= 0 (physical units)");
  const bool both_volumes = reference.volume && other.volume;
  const bool same_grid =
      both_volumes && volume_grid(*reference.volume, reference.name) == volume_grid(*other.volume, other.name);
  DistanceMethod method = o.method;
  if (method == DistanceMethod::Automatic) method = same_grid ? DistanceMethod::Transform : DistanceMethod::KdTree;
  if (method == DistanceMethod::Transform && !same_grid)
    throw InputError("method: 'transform' needs two skeleton volumes on the same grid (dims, spacing, origin); use "
                     "'kdtree' or 'automatic' for graphs or different grids");
  const double spacing = o.sample_spacing > 0 ? o.sample_spacing : auto_spacing(reference, other);
  const int th = o.threads;
  const Interrupter& intr = o.interrupter;
  const int passes = o.symmetric ? 2 : 1;

  std::vector<int64_t> ref_vox, oth_vox;
  if (reference.volume) ref_vox = skeleton_voxels(*reference.volume, reference.name, th, intr.sub(0.0, 0.05));
  if (other.volume) oth_vox = skeleton_voxels(*other.volume, other.name, th, intr.sub(0.05, 0.1));

  SkeletonDistanceResult res;
  res.method_used = method;
  auto one_direction = [&](const SkeletonInput& from, const std::vector<int64_t>& from_vox, const SkeletonInput& to,
                           const std::vector<int64_t>& to_vox, SideDistances& side, const Interrupter& part) {
    const SidePoints pts = reference_points(from, &from_vox);
    side.weights = pts.weights;
    if (method == DistanceMethod::Transform) side.values = transform_distances(pts, *to.volume, to.name, th, part);
    else side.values = kd_distances(pts, target_points(to, &to_vox, spacing), th, part);
    fill_side(side, from, pts, o.threshold, o.nan_off_skeleton, th);
  };
  one_direction(reference, ref_vox, other, oth_vox, res.reference, intr.sub(0.1, passes == 2 ? 0.55 : 1.0));
  if (o.symmetric) {
    one_direction(other, oth_vox, reference, ref_vox, res.other, intr.sub(0.55, 1.0));
    std::vector<double> v = res.reference.values, w = res.reference.weights;
    v.insert(v.end(), res.other.values.begin(), res.other.values.end());
    w.insert(w.end(), res.other.weights.begin(), res.other.weights.end());
    res.symmetric = statistics(v, w, o.threshold);
  }

  std::vector<std::string> dir{"reference_to_other"};
  std::vector<const DistanceStatistics*> rows{&res.reference.stats};
  if (o.symmetric) {
    dir.push_back("other_to_reference");
    dir.push_back("symmetric");
    rows.push_back(&res.other.stats);
    rows.push_back(&res.symmetric);
  }
  std::vector<int64_t> points, changed;
  std::vector<double> weight, mean, median, p95, hd, cw, cf, thr;
  for (const DistanceStatistics* s : rows) {
    points.push_back(s->points);
    weight.push_back(s->weight);
    mean.push_back(s->mean);
    median.push_back(s->median);
    p95.push_back(s->p95);
    hd.push_back(s->max);
    changed.push_back(s->changed_points);
    cw.push_back(s->changed_weight);
    cf.push_back(s->changed_fraction);
    thr.push_back(o.threshold);
  }
  res.table.add("direction", dir)
      .add("points", points)
      .add("weight", weight)
      .add("mean", mean, unit)
      .add("median", median, unit)
      .add("p95", p95, unit)
      .add("hausdorff", hd, unit)
      .add("changed_points", changed)
      .add("changed_weight", cw)
      .add("changed_fraction", cf)
      .add("threshold", thr, unit);
  intr.check(1.0);
  return res;
}

void resample_polyline(const std::vector<Vec3>& points, double spacing, std::vector<Vec3>& samples,
                       std::vector<double>& weights) {
  samples.clear();
  weights.clear();
  if (points.empty()) return;
  if (!(spacing > 0)) throw InputError("sample_spacing: expected > 0 (physical units)");
  std::vector<double> cum(points.size(), 0.0);
  for (size_t i = 1; i < points.size(); ++i) cum[i] = cum[i - 1] + seg_length(points[i - 1], points[i]);
  const double L = cum.back();
  if (!(L > 0)) {
    samples.push_back(points.front());
    weights.push_back(0.0);
    return;
  }
  const int64_t steps = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(L / spacing - 1e-9)));
  const double h = L / static_cast<double>(steps);
  size_t seg = 0;
  for (int64_t k = 0; k <= steps; ++k) {
    if (k == steps) {
      samples.push_back(points.back());
    } else {
      const double s = h * static_cast<double>(k);
      while (seg + 2 < points.size() && cum[seg + 1] <= s) ++seg;
      const double len = cum[seg + 1] - cum[seg];
      const double t = len > 0 ? std::clamp((s - cum[seg]) / len, 0.0, 1.0) : 0.0;
      const Vec3& a = points[seg];
      const Vec3& b = points[seg + 1];
      samples.push_back({a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])});
    }
    weights.push_back((k == 0 || k == steps) ? 0.5 * h : h);
  }
}

}  // namespace skel::comparison
