#include "registration/registration.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>
#include <numeric>

#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::registration {
namespace {

using Eigen::Matrix3d;
using Eigen::Matrix3Xd;
using Eigen::Vector3d;

Matrix3Xd to_matrix(const std::vector<Vec3>& p) {
  Matrix3Xd m(3, static_cast<Eigen::Index>(p.size()));
  for (size_t i = 0; i < p.size(); ++i) m.col(static_cast<Eigen::Index>(i)) = Vector3d(p[i][0], p[i][1], p[i][2]);
  return m;
}

// Square roots of the eigenvalues of the centred scatter matrix, descending: the spread of the point
// set along its principal axes (0 along an axis means the set is flat in that direction).
Vector3d principal_spreads(const Matrix3Xd& centred) {
  const Matrix3d scatter = centred * centred.transpose();
  Eigen::SelfAdjointEigenSolver<Matrix3d> es(scatter, Eigen::EigenvaluesOnly);
  Vector3d ev = es.eigenvalues();  // ascending
  Vector3d s;
  for (int i = 0; i < 3; ++i) s[i] = std::sqrt(std::max(0.0, ev[2 - i]));
  return s;
}

void check_configuration(const Matrix3Xd& centred, TransformKind model, const std::string& what,
                         const std::string& which) {
  const Vector3d s = principal_spreads(centred);
  constexpr double kRelative = 1e-7;
  if (!(s[0] > 0.0)) throw InputError(what + ": all " + which + " landmarks coincide; the fit is undetermined");
  if (s[1] <= kRelative * s[0]) {
    throw InputError(what + ": the " + which + " landmarks are collinear; a " + to_string(model) +
                     " fit needs at least 3 points not on one line");
  }
  if (model == TransformKind::Affine && s[2] <= kRelative * s[0]) {
    throw InputError(what + ": the " + which +
                     " landmarks are coplanar; an affine fit needs at least 4 points not in one plane");
  }
}

}  // namespace

LandmarkFit fit_landmarks(const std::vector<Vec3>& fixed, const std::vector<Vec3>& moving, TransformKind model,
                          const std::string& what) {
  if (fixed.size() != moving.size()) {
    throw InputError(what + ": " + std::to_string(fixed.size()) + " fixed but " + std::to_string(moving.size()) +
                     " moving landmarks; they must correspond one to one");
  }
  const size_t needed = model == TransformKind::Affine ? 4 : 3;
  if (fixed.size() < needed) {
    throw InputError(what + ": " + std::to_string(fixed.size()) + " landmark pair(s); a " + to_string(model) +
                     " fit needs at least " + std::to_string(needed));
  }
  for (const auto* set : {&fixed, &moving})
    for (const auto& p : *set)
      for (double c : p)
        if (!std::isfinite(c)) throw InputError(what + ": a landmark has a non-finite coordinate");

  const Matrix3Xd x = to_matrix(moving), y = to_matrix(fixed);
  const double n = static_cast<double>(fixed.size());
  const Vector3d mx = x.rowwise().sum() / n, my = y.rowwise().sum() / n;
  const Matrix3Xd xc = x.colwise() - mx, yc = y.colwise() - my;
  check_configuration(xc, model, what, "moving");
  check_configuration(yc, model, what, "fixed");

  Matrix3d a;
  if (model == TransformKind::Affine) {
    // yc ≈ A xc in least squares: xcᵀ Aᵀ = ycᵀ, solved by column-pivoting QR.
    const Eigen::MatrixXd xt = xc.transpose(), yt = yc.transpose();
    a = xt.colPivHouseholderQr().solve(yt).transpose();
  } else {
    // Umeyama (1991): rotation from the SVD of the cross-covariance with the reflection fix.
    const Matrix3d sigma = yc * xc.transpose() / n;
    Eigen::JacobiSVD<Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Matrix3d s = Matrix3d::Identity();
    if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s(2, 2) = -1.0;
    const Matrix3d r = svd.matrixU() * s * svd.matrixV().transpose();
    double c = 1.0;
    if (model == TransformKind::Similarity) {
      const double var_x = xc.squaredNorm() / n;
      c = (svd.singularValues().asDiagonal() * s).trace() / var_x;
    }
    a = c * r;
  }
  const Vector3d t = my - a * mx;

  Matrix3 lin{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) lin[r][c] = a(r, c);
  LandmarkFit fit;
  fit.transform = Transform(lin, {t[0], t[1], t[2]}, model);
  fit.residual.resize(fixed.size());
  fit.distance.resize(fixed.size());
  double sum = 0.0;
  for (size_t i = 0; i < fixed.size(); ++i) {
    const Vec3 q = fit.transform.apply(moving[i]);
    fit.residual[i] = {q[0] - fixed[i][0], q[1] - fixed[i][1], q[2] - fixed[i][2]};
    const double d2 = fit.residual[i][0] * fit.residual[i][0] + fit.residual[i][1] * fit.residual[i][1] +
                      fit.residual[i][2] * fit.residual[i][2];
    fit.distance[i] = std::sqrt(d2);
    sum += d2;
  }
  fit.rms = std::sqrt(sum / n);
  return fit;
}

Table residual_table(const std::vector<std::string>& names, const std::vector<Vec3>& fixed,
                     const std::vector<Vec3>& moving, const LandmarkFit& fit, const std::string& unit) {
  const size_t n = fit.residual.size();
  std::vector<std::string> name_col(names.begin(), names.end());
  name_col.resize(n);
  for (size_t i = 0; i < n; ++i)
    if (name_col[i].empty()) name_col[i] = LandmarkSet::default_name(static_cast<int64_t>(i));
  name_col.push_back("RMS");
  std::array<std::vector<double>, 3> fc, mc, d;
  std::vector<double> dist(fit.distance);
  std::array<double, 3> axis_sum{0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      fc[k].push_back(fixed[i][k]);
      mc[k].push_back(moving[i][k]);
      d[k].push_back(fit.residual[i][k]);
      axis_sum[k] += fit.residual[i][k] * fit.residual[i][k];
    }
  }
  for (int k = 0; k < 3; ++k) {
    fc[k].push_back(0.0);
    mc[k].push_back(0.0);
    d[k].push_back(n ? std::sqrt(axis_sum[k] / static_cast<double>(n)) : 0.0);
  }
  dist.push_back(fit.rms);
  const char* axes = "xyz";
  Table t;
  t.add("landmark", std::move(name_col));
  for (int k = 0; k < 3; ++k) t.add(std::string("fixed_") + axes[k], std::move(fc[k]), unit);
  for (int k = 0; k < 3; ++k) t.add(std::string("moving_") + axes[k], std::move(mc[k]), unit);
  for (int k = 0; k < 3; ++k) t.add(std::string("d") + axes[k], std::move(d[k]), unit);
  t.add("distance", std::move(dist), unit);
  return t;
}

TransformKind classify_transform(const Matrix4& m, double tolerance) {
  Matrix3d a;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a(r, c) = m[r][c];
  if (a.determinant() <= 0.0) return TransformKind::Affine;
  const Matrix3d ata = a.transpose() * a;
  const double s2 = ata.trace() / 3.0;
  if ((ata - s2 * Matrix3d::Identity()).cwiseAbs().maxCoeff() > tolerance * std::max(1.0, s2)) {
    return TransformKind::Affine;
  }
  return std::abs(s2 - 1.0) <= tolerance ? TransformKind::Rigid : TransformKind::Similarity;
}

// ---------------------------------------------------------------- point sets

std::vector<Vec3> volume_points(const DataObject& data, const std::string& what) {
  return visit_volume(data, what, [](const auto& v) {
    const Grid& g = v.grid();
    const int64_t nz = g.dims[2], plane = g.dims[0] * g.dims[1];
    std::vector<std::vector<Vec3>> per_slice(static_cast<size_t>(nz));
    parallel_for(0, nz, 0, [&](int64_t z0, int64_t z1) {
      for (int64_t z = z0; z < z1; ++z) {
        const auto* s = v.data() + z * plane;
        auto& out = per_slice[static_cast<size_t>(z)];
        for (int64_t y = 0, i = 0; y < g.dims[1]; ++y)
          for (int64_t x = 0; x < g.dims[0]; ++x, ++i)
            if (s[i] != 0) out.push_back(g.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
      }
    });
    size_t total = 0;
    for (const auto& s : per_slice) total += s.size();
    std::vector<Vec3> out;
    out.reserve(total);
    for (auto& s : per_slice) out.insert(out.end(), s.begin(), s.end());
    return out;
  });
}

std::vector<Vec3> graph_points(const SpatialGraph& graph) {
  std::vector<Vec3> out(graph.positions);
  for (const auto& e : graph.edges)
    for (size_t i = 1; i + 1 < e.points.size(); ++i) out.push_back(e.points[i]);
  return out;
}

std::vector<Vec3> points_of(const DataObject& data, const std::string& what) {
  if (const auto* g = dynamic_cast<const SpatialGraph*>(&data)) return graph_points(*g);
  if (data.type_id().rfind("volume.", 0) == 0) return volume_points(data, what);
  throw InputError(what + ": expected a volume or a graph, got " + data.type_id());
}

// ---------------------------------------------------------------- ICP
namespace {

struct Cloud {
  const std::vector<Vec3>* pts;
  [[nodiscard]] size_t kdtree_get_point_count() const { return pts->size(); }
  [[nodiscard]] double kdtree_get_pt(size_t i, size_t d) const { return (*pts)[i][d]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const { return false; }
};
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3, size_t>;

}  // namespace

IcpResult refine_icp(const std::vector<Vec3>& fixed, const std::vector<Vec3>& moving_all, const Transform& initial,
                     const IcpOptions& o) {
  const std::string what = "registration.refine";
  if (fixed.empty()) throw InputError(what + ": the fixed point set is empty");
  if (moving_all.empty()) throw InputError(what + ": the moving point set is empty");
  if (!(o.trim_fraction > 0.0 && o.trim_fraction <= 1.0)) {
    throw InputError(what + ": trim_fraction must be in (0, 1], got " + std::to_string(o.trim_fraction));
  }
  if (o.iterations < 1) throw InputError(what + ": iterations must be >= 1");
  if (!(o.max_distance > 0.0)) throw InputError(what + ": max_distance must be > 0");

  // Deterministic regular subsample of the moving points.
  std::vector<Vec3> moving;
  const auto n_all = static_cast<int64_t>(moving_all.size());
  if (o.max_points > 0 && n_all > o.max_points) {
    const int64_t stride = (n_all + o.max_points - 1) / o.max_points;
    moving.reserve(static_cast<size_t>(n_all / stride + 1));
    for (int64_t i = 0; i < n_all; i += stride) moving.push_back(moving_all[static_cast<size_t>(i)]);
  } else {
    moving = moving_all;
  }
  const auto n = static_cast<int64_t>(moving.size());

  Cloud cloud{&fixed};
  KdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  o.interrupter.check(0.0);

  const size_t needed = o.model == TransformKind::Affine ? 4 : 3;
  const double max_d2 = std::isinf(o.max_distance) ? std::numeric_limits<double>::infinity()
                                                   : o.max_distance * o.max_distance;
  std::vector<size_t> partner(static_cast<size_t>(n));
  std::vector<double> dist2(static_cast<size_t>(n));
  std::vector<int64_t> order;
  IcpResult result;
  result.transform = initial;
  result.transform.set_kind(o.model);
  for (int it = 0; it < o.iterations; ++it) {
    const Transform current = result.transform;
    parallel_for(0, n, o.threads, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        const Vec3 q = current.apply(moving[static_cast<size_t>(i)]);
        size_t idx = 0;
        double d2 = 0.0;
        tree.knnSearch(q.data(), 1, &idx, &d2);
        partner[static_cast<size_t>(i)] = idx;
        dist2[static_cast<size_t>(i)] = d2;
      }
    }, 1024);
    order.clear();
    for (int64_t i = 0; i < n; ++i)
      if (dist2[static_cast<size_t>(i)] <= max_d2) order.push_back(i);
    std::sort(order.begin(), order.end(), [&](int64_t a, int64_t b) {
      const double da = dist2[static_cast<size_t>(a)], db = dist2[static_cast<size_t>(b)];
      return da < db || (da == db && a < b);
    });
    const auto keep = static_cast<size_t>(std::ceil(o.trim_fraction * static_cast<double>(order.size())));
    order.resize(std::min(order.size(), keep));
    if (order.size() < needed) {
      throw InputError(what + ": only " + std::to_string(order.size()) + " correspondence(s) within max_distance " +
                       "after trimming in iteration " + std::to_string(it + 1) + "; a " + to_string(o.model) +
                       " fit needs at least " + std::to_string(needed) +
                       " (increase max_distance or improve the initial transform)");
    }
    std::vector<Vec3> f, m;
    f.reserve(order.size());
    m.reserve(order.size());
    double sum = 0.0;
    for (int64_t i : order) {
      f.push_back(fixed[partner[static_cast<size_t>(i)]]);
      m.push_back(moving[static_cast<size_t>(i)]);
      sum += dist2[static_cast<size_t>(i)];
    }
    const LandmarkFit fit = fit_landmarks(f, m, o.model, what + ": correspondences of iteration " + std::to_string(it + 1));
    IcpIteration rec;
    rec.pairs = static_cast<int64_t>(order.size());
    rec.rms_before = std::sqrt(sum / static_cast<double>(order.size()));
    rec.rms_after = fit.rms;
    result.history.push_back(rec);
    result.transform = fit.transform;
    o.interrupter.check(static_cast<double>(it + 1) / o.iterations);
    if (rec.rms_before - rec.rms_after <= o.tolerance) {
      result.converged = true;
      break;
    }
  }
  return result;
}

Table icp_table(const IcpResult& r, const std::string& unit) {
  std::vector<int64_t> iteration, pairs;
  std::vector<double> before, after;
  for (size_t i = 0; i < r.history.size(); ++i) {
    iteration.push_back(static_cast<int64_t>(i + 1));
    pairs.push_back(r.history[i].pairs);
    before.push_back(r.history[i].rms_before);
    after.push_back(r.history[i].rms_after);
  }
  Table t;
  t.add("iteration", std::move(iteration));
  t.add("pairs", std::move(pairs));
  t.add("rms_before", std::move(before), unit);
  t.add("rms_after", std::move(after), unit);
  return t;
}

// ---------------------------------------------------------------- applying transforms

Interpolation parse_interpolation(const std::string& text, const std::string& what) {
  return parse_enum<Interpolation>(text, what);
}

Grid transformed_bounding_grid(const Grid& grid, const Transform& transform) {
  grid.validate();
  Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          std::numeric_limits<double>::infinity()};
  Vec3 hi{-lo[0], -lo[1], -lo[2]};
  for (int corner = 0; corner < 8; ++corner) {
    Vec3 p{};
    for (int k = 0; k < 3; ++k) {
      const double idx = (corner >> k) & 1 ? static_cast<double>(grid.dims[k]) - 0.5 : -0.5;
      p[k] = grid.origin[k] + idx * grid.spacing[k];
    }
    const Vec3 q = transform.apply(p);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], q[k]);
      hi[k] = std::max(hi[k], q[k]);
    }
  }
  Grid out;
  out.spacing = grid.spacing;
  out.unit = grid.unit;
  out.direction = grid.direction;
  for (int k = 0; k < 3; ++k) {
    const double extent = (hi[k] - lo[k]) / grid.spacing[k];
    out.dims[k] = grid.dims[k] == 0 ? 0 : std::max<int64_t>(1, static_cast<int64_t>(std::ceil(extent - 1e-9)));
    // Centre the grid on the box.
    const double centre = 0.5 * (lo[k] + hi[k]);
    out.origin[k] = centre - 0.5 * static_cast<double>(out.dims[k] - 1) * grid.spacing[k];
  }
  return out;
}

namespace {

template <class T>
T from_double(double v) {
  if constexpr (std::is_floating_point_v<T>) {
    return static_cast<T>(v);
  } else {
    const double r = std::nearbyint(v);
    if (r <= static_cast<double>(std::numeric_limits<T>::lowest())) return std::numeric_limits<T>::lowest();
    if (r >= static_cast<double>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
    return static_cast<T>(r);
  }
}

}  // namespace

template <class T>
Volume<T> transform_volume(const Volume<T>& in, const Transform& transform, const Grid& og,
                           const ResampleOptions& o) {
  og.validate();
  const Transform inv = transform.inverse();
  const Grid& ig = in.grid();
  Interpolation mode = o.interpolation;
  if (mode == Interpolation::Auto) mode = std::is_floating_point_v<T> ? Interpolation::Linear : Interpolation::Nearest;

  // Output voxel index → input continuous index: q = G (x, y, z, 1).
  const Matrix4& mi = inv.matrix();
  const Vec3 base = inv.apply(og.origin);
  double g[3][4];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) g[r][c] = mi[r][c] * og.spacing[c] / ig.spacing[r];
    g[r][3] = (base[r] - ig.origin[r]) / ig.spacing[r];
  }
  Volume<T> out = Volume<T>::uninitialized(og);
  const int64_t nx = og.dims[0], ny = og.dims[1], rows = og.dims[1] * og.dims[2];
  const int64_t inx = ig.dims[0], iny = ig.dims[1], inz = ig.dims[2];
  const T* src = in.data();
  T* dst = out.data();
  const bool empty_input = in.size() == 0;
  const int64_t check_rows = std::max<int64_t>(1, (int64_t{1} << 22) / std::max<int64_t>(1, nx));
  parallel_for(0, rows, o.threads, [&](int64_t r0, int64_t r1) {
    for (int64_t row = r0; row < r1; ++row) {
      if ((row - r0) % check_rows == check_rows - 1) o.interrupter.check(static_cast<double>(row) / static_cast<double>(rows));
      const auto y = static_cast<double>(row % ny), z = static_cast<double>(row / ny);
      const double b0 = g[0][1] * y + g[0][2] * z + g[0][3];
      const double b1 = g[1][1] * y + g[1][2] * z + g[1][3];
      const double b2 = g[2][1] * y + g[2][2] * z + g[2][3];
      T* d = dst + row * nx;
      for (int64_t x = 0; x < nx; ++x) {
        const auto xd = static_cast<double>(x);
        const double q0 = b0 + g[0][0] * xd, q1 = b1 + g[1][0] * xd, q2 = b2 + g[2][0] * xd;
        if (empty_input || !(q0 >= -0.5 && q0 <= static_cast<double>(inx) - 0.5 && q1 >= -0.5 &&
                             q1 <= static_cast<double>(iny) - 0.5 && q2 >= -0.5 && q2 <= static_cast<double>(inz) - 0.5)) {
          d[x] = T{};
          continue;
        }
        if (mode == Interpolation::Nearest) {
          const int64_t i0 = std::min<int64_t>(inx - 1, static_cast<int64_t>(std::floor(q0 + 0.5)));
          const int64_t i1 = std::min<int64_t>(iny - 1, static_cast<int64_t>(std::floor(q1 + 0.5)));
          const int64_t i2 = std::min<int64_t>(inz - 1, static_cast<int64_t>(std::floor(q2 + 0.5)));
          d[x] = src[i0 + inx * (i1 + iny * i2)];
          continue;
        }
        // Trilinear with the edge value replicated within half a voxel of the border.
        int64_t lo[3];
        double f[3];
        const double q[3] = {q0, q1, q2};
        const int64_t n[3] = {inx, iny, inz};
        for (int k = 0; k < 3; ++k) {
          const double c = std::clamp(q[k], 0.0, static_cast<double>(n[k] - 1));
          lo[k] = std::min<int64_t>(static_cast<int64_t>(std::floor(c)), std::max<int64_t>(0, n[k] - 2));
          f[k] = c - static_cast<double>(lo[k]);
        }
        const int64_t sx = inx > 1 ? 1 : 0, sy = iny > 1 ? inx : 0, sz = inz > 1 ? inx * iny : 0;
        const T* p = src + lo[0] + inx * (lo[1] + iny * lo[2]);
        const double c00 = static_cast<double>(p[0]) * (1 - f[0]) + static_cast<double>(p[sx]) * f[0];
        const double c10 = static_cast<double>(p[sy]) * (1 - f[0]) + static_cast<double>(p[sy + sx]) * f[0];
        const double c01 = static_cast<double>(p[sz]) * (1 - f[0]) + static_cast<double>(p[sz + sx]) * f[0];
        const double c11 = static_cast<double>(p[sz + sy]) * (1 - f[0]) + static_cast<double>(p[sz + sy + sx]) * f[0];
        const double c0 = c00 * (1 - f[1]) + c10 * f[1];
        const double c1 = c01 * (1 - f[1]) + c11 * f[1];
        d[x] = from_double<T>(c0 * (1 - f[2]) + c1 * f[2]);
      }
    }
  }, std::max<int64_t>(1, 4096 / std::max<int64_t>(1, nx)));
  o.interrupter.check(1.0);
  return out;
}

template Volume<uint8_t> transform_volume(const Volume<uint8_t>&, const Transform&, const Grid&, const ResampleOptions&);
template Volume<uint16_t> transform_volume(const Volume<uint16_t>&, const Transform&, const Grid&, const ResampleOptions&);
template Volume<uint32_t> transform_volume(const Volume<uint32_t>&, const Transform&, const Grid&, const ResampleOptions&);
template Volume<uint64_t> transform_volume(const Volume<uint64_t>&, const Transform&, const Grid&, const ResampleOptions&);
template Volume<int32_t> transform_volume(const Volume<int32_t>&, const Transform&, const Grid&, const ResampleOptions&);
template Volume<float> transform_volume(const Volume<float>&, const Transform&, const Grid&, const ResampleOptions&);
template Volume<double> transform_volume(const Volume<double>&, const Transform&, const Grid&, const ResampleOptions&);

SpatialGraph transform_graph(const SpatialGraph& graph, const Transform& transform, const Grid& output_grid) {
  SpatialGraph out = graph;
  for (auto& p : out.positions) p = transform.apply(p);
  for (auto& e : out.edges)
    for (auto& p : e.points) p = transform.apply(p);
  // End points must stay bitwise equal to the node positions (SpatialGraph invariant).
  for (auto& e : out.edges) {
    if (e.points.size() >= 2) {
      e.points.front() = out.positions[static_cast<size_t>(e.node0)];
      e.points.back() = out.positions[static_cast<size_t>(e.node1)];
    }
  }
  const auto s = static_cast<float>(transform.scale());
  for (auto& [name, values] : out.node_attributes)
    if (is_length_attribute(name)) for (auto& v : values) v *= s;
  for (auto& [name, values] : out.edge_attributes)
    if (is_length_attribute(name)) for (auto& v : values) v *= s;
  for (auto& [name, values] : out.point_attributes)
    if (is_length_attribute(name))
      for (auto& per_edge : values)
        for (auto& v : per_edge) v *= s;
  if (output_grid.voxel_count() > 0) {
    out.source_grid = output_grid;
  } else if (graph.source_grid.voxel_count() > 0) {
    out.source_grid = transformed_bounding_grid(graph.source_grid, transform);
  }
  return out;
}

LandmarkSet transform_landmarks(const LandmarkSet& landmarks, const Transform& transform) {
  LandmarkSet out = landmarks;
  for (auto& set : out.sets)
    for (auto& p : set) p = transform.apply(p);
  return out;
}

}  // namespace skel::registration
