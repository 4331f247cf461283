#include "geodesic/surface.hpp"

#include <algorithm>
#include <cmath>
#include <queue>

#include "distance/distance.hpp"
#include "skel/error.hpp"
#include "skel/units.hpp"
#include "skel/parallel.hpp"
#include "thinning/local_topology.hpp"

namespace skel::geodesic {

namespace {
constexpr int kDir[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

void check_same_dims(const Grid& a, const Grid& b, const char* what) {
  if (a.dims != b.dims)
    throw InputError(std::string("input '") + what + "' has dims " + std::to_string(b.dims[0]) + "x" +
                     std::to_string(b.dims[1]) + "x" + std::to_string(b.dims[2]) + ", expected " +
                     std::to_string(a.dims[0]) + "x" + std::to_string(a.dims[1]) + "x" + std::to_string(a.dims[2]));
}
}  // namespace

ThinSurfaceResult thin_surface(const VolumeU8& surface, const ThinSurfaceOptions& o) {
  ThinSurfaceResult r;
  r.surface = VolumeU8(surface.grid(), 0);
  VolumeU8& s = r.surface;
  std::vector<int64_t> members;
  for (int64_t i = 0; i < surface.size(); ++i)
    if (surface[i]) {
      s[i] = 1;
      members.push_back(i);
    }
  const int64_t nx = s.nx(), ny = s.ny();
  auto in = [&](int64_t x, int64_t y, int64_t z) { return s.at_or(x, y, z, 0) != 0; };
  auto removable = [&](int64_t x, int64_t y, int64_t z, int d) {
    const int* v = kDir[d];
    if (in(x + v[0], y + v[1], z + v[2]) || !in(x - v[0], y - v[1], z - v[2])) return false;
    // Surface points, surface edges and curve ends have an axis with both neighbours outside.
    for (int a = 0; a < 3; ++a) {
      const int* u = kDir[2 * a];
      if (!in(x + u[0], y + u[1], z + u[2]) && !in(x - u[0], y - u[1], z - u[2])) return false;
    }
    return thinning::is_simple(thinning::neighbourhood_at(s, x, y, z));
  };
  for (r.passes = 0; r.passes < o.max_passes; ++r.passes) {
    int64_t removed_this_pass = 0;
    for (int d = 0; d < 6; ++d) {
      // Candidates first (on the state at the start of the sub-iteration), then sequential
      // rechecking in raster order on the current state.
      std::vector<int64_t> cand;
      for (int64_t i : members) {
        if (!s[i]) continue;
        const int64_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
        if (removable(x, y, z, d)) cand.push_back(i);
      }
      for (int64_t i : cand) {
        const int64_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
        if (removable(x, y, z, d)) {
          s[i] = 0;
          ++removed_this_pass;
        }
      }
      o.interrupter.check();
    }
    r.removed += removed_this_pass;
    if (removed_this_pass == 0) break;
    members.erase(std::remove_if(members.begin(), members.end(), [&](int64_t i) { return !s[i]; }), members.end());
  }
  return r;
}

VolumeF32 tubularity(const VolumeU8& skeleton, const VolumeF32& importance, const DataObject& distance,
                     const TubularityOptions& o) {
  check_same_dims(skeleton.grid(), importance.grid(), "importance");
  const Grid& dg = volume_grid(distance, "distance");
  check_same_dims(skeleton.grid(), dg, "distance");
  const Vec3& sp = dg.spacing;
  const double scale = o.unit == DistanceUnit::Physical ? 3.0 / (sp[0] + sp[1] + sp[2])
                       : o.unit == DistanceUnit::Chamfer ? 1.0 / o.chamfer_unit
                                                         : 1.0;
  VolumeF32 out(skeleton.grid(), 0.0f);
  visit_volume(distance, "distance", [&](const auto& dv) {
    parallel_for(0, out.size(), o.threads, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        if (!skeleton[i]) continue;
        const double d = static_cast<double>(dv[i]) * scale;
        out[i] = static_cast<float>(importance[i] / std::max(d, 0.5));
      }
    }, 1 << 16);
  });
  return out;
}

RodsPlatesResult rods_plates(const VolumeU8& mask, const VolumeU8& skeleton, const VolumeF32& importance,
                             const DataObject& distance, const RodsPlatesOptions& o) {
  check_same_dims(mask.grid(), skeleton.grid(), "skeleton");
  const VolumeF32 ratio = tubularity(skeleton, importance, distance, o.tubularity);
  RodsPlatesResult r;
  r.skeleton_labels = VolumeU8(mask.grid(), 0);
  int64_t skel_count = 0;
  for (int64_t i = 0; i < mask.size(); ++i)
    if (skeleton[i] && mask[i]) {
      r.skeleton_labels[i] = ratio[i] >= o.ratio_threshold ? 2 : 1;
      ++skel_count;
    }
  o.interrupter.check(0.2);
  // Nearest skeleton voxel of every voxel: the feature transform of "not skeleton".
  r.labels = VolumeU8(mask.grid(), 0);
  if (skel_count > 0) {
    VolumeU8 not_skel(mask.grid(), 1);
    for (int64_t i = 0; i < mask.size(); ++i)
      if (r.skeleton_labels[i]) not_skel[i] = 0;
    distance::DistanceOptions dopt;
    dopt.threads = o.threads;
    dopt.border_is_object = true;  // the outside is not skeleton
    DataPtr ft = distance::feature_transform(not_skel, dopt);
    visit_volume(*ft, "nearest", [&](const auto& near) {
      using Index = typename std::decay_t<decltype(near)>::value_type;
      if constexpr (std::is_integral_v<Index>) {
        parallel_for(0, mask.size(), o.threads, [&](int64_t b, int64_t e) {
          for (int64_t i = b; i < e; ++i) {
            if (!mask[i]) continue;
            const auto n = near[i];
            if (static_cast<uint64_t>(n) < static_cast<uint64_t>(mask.size()))
              r.labels[i] = r.skeleton_labels[static_cast<int64_t>(n)];
          }
        }, 1 << 16);
      }
    });
  }
  o.interrupter.check(0.8);
  // Statistics per class.
  const Vec3 sp = mask.spacing();
  const double voxel_volume = sp[0] * sp[1] * sp[2];
  const double face_area[3] = {sp[1] * sp[2], sp[0] * sp[2], sp[0] * sp[1]};
  std::vector<int64_t> voxels(3, 0), skel_voxels(3, 0), pieces(3, 0);
  std::vector<double> surface(3, 0.0), thickness_sum(3, 0.0);
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  const double to_physical = 1.0;  // thickness from the distance map in its own units (documented)
  visit_volume(distance, "distance", [&](const auto& dv) {
    for (int64_t z = 0; z < nz; ++z)
      for (int64_t y = 0; y < ny; ++y)
        for (int64_t x = 0; x < nx; ++x) {
          const int64_t i = mask.index(x, y, z);
          const int c = r.labels[i];
          if (!mask[i] || c == 0) continue;
          ++voxels[c];
          const int64_t nb[6][3] = {{x - 1, y, z}, {x + 1, y, z}, {x, y - 1, z}, {x, y + 1, z}, {x, y, z - 1}, {x, y, z + 1}};
          for (int k = 0; k < 6; ++k)
            if (!mask.at_or(nb[k][0], nb[k][1], nb[k][2], 0)) surface[c] += face_area[k / 2];
          if (r.skeleton_labels[i]) {
            ++skel_voxels[c];
            thickness_sum[c] += 2.0 * static_cast<double>(dv[i]) * to_physical;
          }
        }
  });
  // Pieces: 26-connected components of each class's skeleton voxels.
  {
    std::vector<uint8_t> seen(static_cast<size_t>(mask.size()), 0);
    std::vector<int64_t> stack;
    for (int64_t i = 0; i < mask.size(); ++i) {
      const int c = r.skeleton_labels[i];
      if (!c || seen[i]) continue;
      ++pieces[c];
      stack.assign(1, i);
      seen[i] = 1;
      while (!stack.empty()) {
        const int64_t v = stack.back();
        stack.pop_back();
        const int64_t x = v % nx, y = (v / nx) % ny, z = v / (nx * ny);
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int64_t X = x + dx, Y = y + dy, Z = z + dz;
              if (!mask.grid().contains(X, Y, Z)) continue;
              const int64_t j = mask.index(X, Y, Z);
              if (seen[j] || r.skeleton_labels[j] != c) continue;
              seen[j] = 1;
              stack.push_back(j);
            }
      }
    }
  }
  std::vector<std::string> cls{"rod", "plate"};
  std::vector<int64_t> tv, ts, tp;
  std::vector<double> tvol, tsurf, tthick, tfrac;
  const double total = static_cast<double>(voxels[1] + voxels[2]);
  for (int c = 1; c <= 2; ++c) {
    tv.push_back(voxels[c]);
    tvol.push_back(static_cast<double>(voxels[c]) * voxel_volume);
    tsurf.push_back(surface[c]);
    ts.push_back(skel_voxels[c]);
    tp.push_back(pieces[c]);
    tthick.push_back(skel_voxels[c] ? thickness_sum[c] / static_cast<double>(skel_voxels[c]) : 0.0);
    tfrac.push_back(total > 0 ? static_cast<double>(voxels[c]) / total : 0.0);
  }
  r.table.add("class", cls);
  r.table.add("voxels", tv);
  r.table.add("volume", tvol, units::power(mask.unit(), 3));
  r.table.add("volume_fraction", tfrac);
  r.table.add("surface", tsurf, units::power(mask.unit(), 2));
  r.table.add("skeleton_voxels", ts);
  r.table.add("pieces", tp);
  r.table.add("mean_thickness", tthick, "distance units");
  r.table.add("plate_to_rod_ratio",
              std::vector<double>(2, voxels[1] > 0 ? static_cast<double>(voxels[2]) / static_cast<double>(voxels[1]) : 0.0));
  o.interrupter.check(1.0);
  return r;
}

}  // namespace skel::geodesic
