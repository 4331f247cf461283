#include "analysis/rods_plates.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <type_traits>

#include "distance/distance.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "geometry/skeleton_to_graph_phases.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"
#include "skel/units.hpp"

namespace skel::analysis {

namespace {

using geometry::ManifoldType;

bool is_curve(uint8_t m) {
  return m == static_cast<uint8_t>(ManifoldType::line) || m == static_cast<uint8_t>(ManifoldType::line_end) ||
         m == static_cast<uint8_t>(ManifoldType::point);
}
bool is_surface(uint8_t m) {
  return m == static_cast<uint8_t>(ManifoldType::surface) || m == static_cast<uint8_t>(ManifoldType::surface_edge);
}
// Kind of the element a voxel of manifold type m starts; 0 for junction voxels.
int kind_of(uint8_t m) { return is_curve(m) ? 1 : is_surface(m) ? 2 : 0; }

void check_dims(const Grid& a, const Grid& b, const char* what) {
  if (a.dims != b.dims)
    throw InputError(std::string("input '") + what + "' has dims " + std::to_string(b.dims[0]) + "x" +
                     std::to_string(b.dims[1]) + "x" + std::to_string(b.dims[2]) + ", expected " +
                     std::to_string(a.dims[0]) + "x" + std::to_string(a.dims[1]) + "x" + std::to_string(a.dims[2]) +
                     " (the mask's)");
}

// Labels the components of the voxels with `in_set(i)` through the 1-cells, ids from next_id upwards
// in the order of their first voxel; returns the next free id.
template <class InSet>
int32_t label_components(const SkeletonSegmentation& s, std::vector<int32_t>& label, int32_t next_id, InSet in_set,
                         std::vector<int64_t>& stack) {
  const int64_t n = static_cast<int64_t>(s.voxels.size());
  for (int64_t i = 0; i < n; ++i) {
    if (label[i] != 0 || !in_set(i)) continue;
    const int32_t id = next_id++;
    label[i] = id;
    stack.assign(1, i);
    while (!stack.empty()) {
      const int64_t v = stack.back();
      stack.pop_back();
      for (int64_t k = s.off[v]; k < s.off[v + 1]; ++k) {
        const int64_t w = s.adj[k];
        if (label[w] != 0 || !in_set(w)) continue;
        label[w] = id;
        stack.push_back(w);
      }
    }
  }
  return next_id;
}

}  // namespace

void join_junctions(SkeletonSegmentation& s, const std::vector<int>& priority) {
  const int64_t n = static_cast<int64_t>(s.voxels.size());
  s.element = s.own;
  std::vector<int64_t> frontier, next;
  for (int64_t i = 0; i < n; ++i)
    if (s.element[i] != 0) frontier.push_back(i);
  std::vector<int32_t> proposal(static_cast<size_t>(n), 0);
  auto better = [&](int32_t a, int32_t b) {  // a better than b (b may be 0)
    if (b == 0) return true;
    const int pa = priority[static_cast<size_t>(a - 1)], pb = priority[static_cast<size_t>(b - 1)];
    return pa != pb ? pa > pb : a < b;
  };
  while (!frontier.empty()) {
    next.clear();
    for (int64_t u : frontier)
      for (int64_t k = s.off[u]; k < s.off[u + 1]; ++k) {
        const int64_t w = s.adj[k];
        if (s.element[w] != 0) continue;
        if (proposal[w] == 0) next.push_back(w);
        if (better(s.element[u], proposal[w])) proposal[w] = s.element[u];
      }
    for (int64_t w : next) {
      s.element[w] = proposal[w];
      proposal[w] = 0;
    }
    std::sort(next.begin(), next.end());
    frontier.swap(next);
  }
}

SkeletonSegmentation segment_skeleton(const VolumeU8& skeleton, int threads, const Interrupter& intr) {
  auto sv = geometry::detail::collect_voxels(skeleton, threads, intr);
  geometry::detail::classify_voxels(sv, threads, intr);
  geometry::detail::connect_one_cells(sv, threads, intr);
  SkeletonSegmentation s;
  s.voxels = std::move(sv.vox);
  s.manifold = std::move(sv.cls);
  s.off = std::move(sv.off);
  s.adj = std::move(sv.adj);
  const int64_t n = static_cast<int64_t>(s.voxels.size());
  s.own.assign(static_cast<size_t>(n), 0);
  s.junction.assign(static_cast<size_t>(n), 0);
  std::vector<int64_t> stack;
  // Curve and surface elements: components of the voxels of one kind through the 1-cells (a 1-cell
  // between a curve and a surface voxel does not join them).
  for (int64_t i = 0; i < n; ++i) {
    const int kind = kind_of(s.manifold[i]);
    if (s.own[i] != 0 || kind == 0) continue;
    s.kind.push_back(static_cast<ElementKind>(kind));
    const auto id = static_cast<int32_t>(s.kind.size());
    s.own[i] = id;
    stack.assign(1, i);
    while (!stack.empty()) {
      const int64_t v = stack.back();
      stack.pop_back();
      for (int64_t e = s.off[v]; e < s.off[v + 1]; ++e) {
        const int64_t w = s.adj[e];
        if (s.own[w] != 0 || kind_of(s.manifold[w]) != kind) continue;
        s.own[w] = id;
        stack.push_back(w);
      }
    }
  }
  intr.check(0.3);
  // Junction clusters: components of the remaining (junction) voxels.
  s.junction_clusters = label_components(s, s.junction, 1, [&](int64_t i) { return s.own[i] == 0; }, stack) - 1;
  s.cluster_elements.assign(static_cast<size_t>(s.junction_clusters), {});
  for (int64_t i = 0; i < n; ++i) {
    if (s.junction[i] == 0) continue;
    auto& touched = s.cluster_elements[static_cast<size_t>(s.junction[i] - 1)];
    for (int64_t e = s.off[i]; e < s.off[i + 1]; ++e)
      if (const int32_t el = s.own[s.adj[e]]; el != 0) touched.push_back(el);
  }
  // Clusters that touch no element become elements of their own (after the curve and surface ones).
  std::vector<int32_t> cluster_element(static_cast<size_t>(s.junction_clusters), 0);
  for (int32_t c = 0; c < s.junction_clusters; ++c) {
    auto& t = s.cluster_elements[static_cast<size_t>(c)];
    std::sort(t.begin(), t.end());
    t.erase(std::unique(t.begin(), t.end()), t.end());
    if (t.empty()) {
      s.kind.push_back(ElementKind::cluster);
      cluster_element[static_cast<size_t>(c)] = static_cast<int32_t>(s.kind.size());
    }
  }
  for (int64_t i = 0; i < n; ++i)
    if (s.junction[i] != 0 && cluster_element[static_cast<size_t>(s.junction[i] - 1)] != 0) {
      s.own[i] = cluster_element[static_cast<size_t>(s.junction[i] - 1)];
      s.junction[i] = 0;
    }
  // Renumber the clusters without the ones that became elements.
  {
    std::vector<int32_t> map(static_cast<size_t>(s.junction_clusters) + 1, 0);
    std::vector<std::vector<int32_t>> kept;
    for (int32_t c = 0; c < s.junction_clusters; ++c)
      if (cluster_element[static_cast<size_t>(c)] == 0) {
        kept.push_back(std::move(s.cluster_elements[static_cast<size_t>(c)]));
        map[static_cast<size_t>(c) + 1] = static_cast<int32_t>(kept.size());
      }
    for (auto& j : s.junction) j = map[static_cast<size_t>(j)];
    s.cluster_elements = std::move(kept);
    s.junction_clusters = static_cast<int32_t>(s.cluster_elements.size());
  }
  join_junctions(s, std::vector<int>(s.kind.size(), 0));
  intr.check(0.4);
  return s;
}

RodsPlatesElementResult rods_plates_elements(const VolumeU8& mask, const VolumeU8& skeleton, const DataObject& distance,
                                             const RodsPlatesElementOptions& o) {
  check_dims(mask.grid(), skeleton.grid(), "skeleton");
  const Grid& dg = volume_grid(distance, "distance");
  check_dims(mask.grid(), dg, "distance");
  units::check_same(mask.unit(), "mask", dg.unit, "distance");
  RodsPlatesElementResult r;
  // Skeleton voxels inside the object; later reused as "not skeleton" for the feature transform.
  VolumeU8 work(mask.grid(), 0);
  for (int64_t i = 0; i < mask.size(); ++i) work[i] = (skeleton[i] && mask[i]) ? 1 : 0;
  r.segmentation = segment_skeleton(work, o.threads, o.interrupter);
  SkeletonSegmentation& s = r.segmentation;
  const int64_t n = static_cast<int64_t>(s.voxels.size());
  const auto ne = static_cast<int32_t>(s.kind.size());

  const Vec3 sp = mask.spacing();
  const double mean_spacing = (sp[0] + sp[1] + sp[2]) / 3.0;
  const double voxel_area = mean_spacing * mean_spacing;
  const double voxel_volume = sp[0] * sp[1] * sp[2];

  // Thickness (2 x mean distance over the element's own voxels) and own voxel counts.
  std::vector<double> dsum(static_cast<size_t>(ne), 0.0);
  std::vector<int64_t> own_count(static_cast<size_t>(ne), 0), skel_count(static_cast<size_t>(ne), 0);
  visit_volume(distance, "distance", [&](const auto& dv) {
    for (int64_t i = 0; i < n; ++i) {
      if (const int32_t e = s.own[i]; e != 0) {
        dsum[static_cast<size_t>(e - 1)] += static_cast<double>(dv[s.voxels[i]]);
        ++own_count[static_cast<size_t>(e - 1)];
      }
    }
  });
  std::vector<double> thickness(static_cast<size_t>(ne), 0.0);
  r.element_class.assign(static_cast<size_t>(ne), RodPlateClass::rod);
  std::vector<int> priority(static_cast<size_t>(ne), 1);
  for (int32_t e = 0; e < ne; ++e) {
    const auto k = static_cast<size_t>(e);
    thickness[k] = own_count[k] ? 2.0 * dsum[k] / static_cast<double>(own_count[k]) : 0.0;
    const double own_area = static_cast<double>(own_count[k]) * voxel_area;
    if (s.kind[k] == ElementKind::surface && std::sqrt(own_area) >= o.plate_aspect * thickness[k]) {
      r.element_class[k] = RodPlateClass::plate;
      priority[k] = 2;
    }
  }
  // Junction voxels join a neighbouring plate before a rod (a rod ends on the plate it meets).
  join_junctions(s, priority);
  o.interrupter.check(0.45);

  r.skeleton_elements = VolumeI32(mask.grid(), 0);
  for (int64_t i = 0; i < n; ++i) {
    r.skeleton_elements[s.voxels[i]] = s.element[i];
    ++skel_count[static_cast<size_t>(s.element[i] - 1)];
  }
  // Every object voxel takes the element of its nearest skeleton voxel (exact Euclidean feature
  // transform of "not skeleton").
  r.elements = VolumeI32(mask.grid(), 0);
  r.classes = VolumeU8(mask.grid(), 0);
  if (n > 0) {
    for (int64_t i = 0; i < work.size(); ++i) work[i] = work[i] ? 0 : 1;
    distance::DistanceOptions dopt;
    dopt.threads = o.threads;
    dopt.border_is_object = true;  // the outside is not skeleton
    DataPtr ft = distance::feature_transform(work, dopt);
    work = VolumeU8();
    visit_volume(*ft, "nearest", [&](const auto& near) {
      using Index = typename std::decay_t<decltype(near)>::value_type;
      if constexpr (std::is_integral_v<Index>) {
        parallel_for(0, mask.size(), o.threads, [&](int64_t b, int64_t e) {
          for (int64_t i = b; i < e; ++i) {
            if (!mask[i]) continue;
            const auto nb = near[i];
            if (static_cast<uint64_t>(nb) >= static_cast<uint64_t>(mask.size())) continue;
            const int32_t el = r.skeleton_elements[static_cast<int64_t>(nb)];
            r.elements[i] = el;
            if (el) r.classes[i] = static_cast<uint8_t>(r.element_class[static_cast<size_t>(el - 1)]);
          }
        }, 1 << 16);
      }
    });
  }
  o.interrupter.check(0.85);

  // Per element: object voxels, 1-cell length (each 1-cell counts half to each end's element).
  std::vector<int64_t> voxels(static_cast<size_t>(ne), 0);
  int64_t object_voxels = 0;
  for (int64_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    ++object_voxels;
    if (r.elements[i]) ++voxels[static_cast<size_t>(r.elements[i] - 1)];
  }
  std::vector<double> cell_length(static_cast<size_t>(ne), 0.0);
  const int64_t nx = mask.nx(), ny = mask.ny();
  for (int64_t i = 0; i < n; ++i)
    for (int64_t k = s.off[i]; k < s.off[i + 1]; ++k) {
      const int64_t a = s.voxels[i], b = s.voxels[s.adj[k]];
      const double dx = static_cast<double>(a % nx - b % nx) * sp[0];
      const double dy = static_cast<double>(a / nx % ny - b / nx % ny) * sp[1];
      const double dz = static_cast<double>(a / (nx * ny) - b / (nx * ny)) * sp[2];
      // Each 1-cell is listed at both ends: a quarter of its length per listing and end.
      const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
      cell_length[static_cast<size_t>(s.element[i] - 1)] += 0.25 * len;
      cell_length[static_cast<size_t>(s.element[s.adj[k]] - 1)] += 0.25 * len;
    }
  std::vector<int64_t> junctions_of(static_cast<size_t>(ne), 0);
  int64_t rod_plate_junctions = 0;
  for (const auto& touched : s.cluster_elements) {
    bool rod = false, plate = false;
    for (int32_t e : touched) {
      ++junctions_of[static_cast<size_t>(e - 1)];
      (r.element_class[static_cast<size_t>(e - 1)] == RodPlateClass::plate ? plate : rod) = true;
    }
    if (rod && plate) ++rod_plate_junctions;
  }

  // The per-element table.
  const std::string unit = mask.unit();
  std::vector<int64_t> ids, tskel, tvox, tjunc;
  std::vector<std::string> tcls, tkind;
  std::vector<double> tvol, tthick, tlen, tarea;
  double rod_volume = 0, plate_volume = 0, rod_th = 0, rod_len = 0, plate_th = 0, plate_area = 0;
  int64_t rods = 0, plates = 0;
  for (int32_t e = 0; e < ne; ++e) {
    const auto k = static_cast<size_t>(e);
    const bool plate = r.element_class[k] == RodPlateClass::plate;
    const double volume = static_cast<double>(voxels[k]) * voxel_volume;
    double length = 0.0, area = 0.0;
    if (plate) {
      // Mid-surface area of a plate of uniform thickness: volume / thickness (the one-voxel-thin patch
      // ends short of the rim and counts inclined voxels once, so its voxel count underestimates).
      area = thickness[k] > 0 ? volume / thickness[k] : 0.0;
    } else if (s.kind[k] == ElementKind::curve) {
      length = cell_length[k];
    } else {
      // A surface fragment or block classed as rod: the length of a cylinder of its volume and thickness.
      const double rad = thickness[k] / 2.0;
      length = rad > 0 ? volume / (std::numbers::pi * rad * rad) : 0.0;
    }
    ids.push_back(e + 1);
    tcls.emplace_back(plate ? "plate" : "rod");
    tkind.emplace_back(s.kind[k] == ElementKind::curve ? "curve" : s.kind[k] == ElementKind::surface ? "surface" : "cluster");
    tskel.push_back(skel_count[k]);
    tvox.push_back(voxels[k]);
    tvol.push_back(volume);
    tthick.push_back(thickness[k]);
    tlen.push_back(length);
    tarea.push_back(area);
    tjunc.push_back(junctions_of[k]);
    if (plate) {
      ++plates;
      plate_volume += volume;
      plate_th += thickness[k];
      plate_area += area;
    } else {
      ++rods;
      rod_volume += volume;
      rod_th += thickness[k];
      rod_len += length;
    }
  }
  r.table.add("element", ids);
  r.table.add("class", tcls);
  r.table.add("kind", tkind);
  r.table.add("skeleton_voxels", tskel);
  r.table.add("voxels", tvox);
  r.table.add("volume", tvol, units::power(unit, 3));
  r.table.add("thickness", tthick, unit);
  r.table.add("length", tlen, unit);
  r.table.add("area", tarea, units::power(unit, 2));
  r.table.add("junctions", tjunc);

  // The structural indices (one row).
  const double bv = static_cast<double>(object_voxels) * voxel_volume;
  const double tv = static_cast<double>(mask.size()) * voxel_volume;
  auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  auto one = [](double v) { return std::vector<double>{v}; };
  r.indices.add("TV", one(tv), units::power(unit, 3));
  r.indices.add("BV", one(bv), units::power(unit, 3));
  r.indices.add("BV_TV", one(ratio(bv, tv)));
  r.indices.add("rBV_BV", one(ratio(rod_volume, bv)));
  r.indices.add("pBV_BV", one(ratio(plate_volume, bv)));
  r.indices.add("rods", std::vector<int64_t>{rods});
  r.indices.add("plates", std::vector<int64_t>{plates});
  r.indices.add("rod_thickness", one(ratio(rod_th, static_cast<double>(rods))), unit);
  r.indices.add("rod_length", one(ratio(rod_len, static_cast<double>(rods))), unit);
  r.indices.add("plate_thickness", one(ratio(plate_th, static_cast<double>(plates))), unit);
  r.indices.add("plate_area", one(ratio(plate_area, static_cast<double>(plates))), units::power(unit, 2));
  r.indices.add("junctions", std::vector<int64_t>{static_cast<int64_t>(s.junction_clusters)});
  r.indices.add("rod_plate_junctions", std::vector<int64_t>{rod_plate_junctions});
  r.indices.add("plate_to_rod_ratio", one(ratio(plate_volume, rod_volume)));
  o.interrupter.check(1.0);
  return r;
}

}  // namespace skel::analysis
