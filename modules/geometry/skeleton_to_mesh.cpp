#include "geometry/skeleton_to_mesh.hpp"

#include <algorithm>
#include <bit>

#include "geometry/skeleton_to_graph.hpp"
#include "geometry/skeleton_to_graph_phases.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::geometry {
namespace {

constexpr int kPairs = 28;
constexpr int kStates = 6561;  // 3^8

int pair_index(int a, int b) {
  for (int p = 0; p < kPairs; ++p) {
    const auto q = dual_cube_pair(p);
    if ((q[0] == a && q[1] == b) || (q[0] == b && q[1] == a)) return p;
  }
  return -1;
}

// The corners of a cycle (pair mask) in cyclic order.
std::vector<int> cycle_order(uint32_t edges) {
  std::array<std::vector<int>, 8> nb;
  for (int p = 0; p < kPairs; ++p)
    if (edges >> p & 1) {
      const auto q = dual_cube_pair(p);
      nb[q[0]].push_back(q[1]);
      nb[q[1]].push_back(q[0]);
    }
  const int start = dual_cube_pair(std::countr_zero(edges))[0];
  std::vector<int> order{start};
  int prev = -1, cur = start;
  for (;;) {
    const int next = nb[cur][0] != prev ? nb[cur][0] : nb[cur][1];
    if (next == start) break;
    order.push_back(next);
    prev = cur;
    cur = next;
  }
  return order;
}

MeshCubeTemplate build_template(int config, bool improved) {
  const DualCubeEntry& e = dual_cube_table()[config];
  MeshCubeTemplate t;
  const int nv = std::popcount(static_cast<unsigned>(config));
  const bool special = improved && e.cell3 && nv >= 4 && nv <= 6;
  auto add = [&](int a, int b, int c, unsigned voxels, bool reduced) {
    t.triangles.push_back({{static_cast<uint8_t>(a), static_cast<uint8_t>(b), static_cast<uint8_t>(c)},
                           static_cast<uint8_t>(voxels), reduced});
  };
  for (const auto& cell : e.cells2) {
    t.bounded_edges |= cell.edges;
    if (special && cell.face < 0) continue;  // replaced below
    const bool reduced = cell.face < 0 || cell.face % 2 == 0;
    const auto cyc = cycle_order(cell.edges);
    const int n = static_cast<int>(cyc.size());
    if (n == 3) {
      add(cyc[0], cyc[1], cyc[2], cell.vertices, reduced);
      continue;
    }
    int centre;
    if (cell.face >= 0) {
      centre = kFaceCentre + cell.face;
    } else {
      centre = kInterior + static_cast<int>(t.interior.size());
      t.interior.push_back(cell.vertices);
    }
    for (int i = 0; i < n; ++i) add(centre, cyc[i], cyc[(i + 1) % n], cell.vertices, reduced);
  }
  if (!special) return t;
  if (nv == 4) {
    // Case 13: four voxels, pairwise face-diagonal; a cone from their centroid (the cube centre) over
    // the six diagonals.
    const int centre = kInterior + static_cast<int>(t.interior.size());
    t.interior.push_back(static_cast<uint8_t>(config));
    for (int p = 0; p < kPairs; ++p)
      if (e.edges >> p & 1) {
        const auto q = dual_cube_pair(p);
        add(centre, q[0], q[1], 1u << q[0] | 1u << q[1], true);
      }
  } else if (nv == 5) {
    // Case 14: two voxels of degree 3 (opposite ends of a body diagonal) joined to the same three
    // voxels; the diagonal becomes a new edge and carries three triangles, one per common neighbour.
    std::array<int, 8> degree{};
    for (int p = 0; p < kPairs; ++p)
      if (e.edges >> p & 1) {
        const auto q = dual_cube_pair(p);
        ++degree[q[0]];
        ++degree[q[1]];
      }
    std::vector<int> hubs, rim;
    for (int k = 0; k < 8; ++k)
      if (config >> k & 1) (degree[k] == 3 ? hubs : rim).push_back(k);
    if (hubs.size() != 2 || rim.size() != 3) throw Error("dual cube case 14: unexpected configuration " + std::to_string(config));
    for (int a : rim) add(hubs[0], a, hubs[1], 1u << hubs[0] | 1u << a | 1u << hubs[1], true);
  } else {
    // Case 18: a full face and an edge u-w opposite its diagonal u'-w'. The face keeps its fan; a fin
    // u'-u-w-w' stands on the face's diagonal, fanned from the face centre.
    int face = -1;
    uint8_t on_face = 0;
    for (const auto& cell : e.cells2)
      if (cell.face >= 0) {
        face = cell.face;
        on_face = cell.vertices;
      }
    std::vector<int> off;
    for (int k = 0; k < 8; ++k)
      if ((config >> k & 1) && !(on_face >> k & 1)) off.push_back(k);
    if (face < 0 || off.size() != 2 || pair_index(off[0], off[1]) < 0 ||
        !(e.edges >> pair_index(off[0], off[1]) & 1))
      throw Error("dual cube case 18: unexpected configuration " + std::to_string(config));
    const int axis = face / 2, u = off[0], w = off[1], u1 = u ^ (1 << axis), w1 = w ^ (1 << axis);
    const unsigned mask = 1u << u | 1u << w | 1u << u1 | 1u << w1;
    const int centre = kFaceCentre + face;
    add(centre, u1, u, mask, true);
    add(centre, u, w, mask, true);
    add(centre, w, w1, mask, true);
  }
  return t;
}

// The 3^8 table: for every state of the eight voxels (0 background, 1 2-manifold or 2-boundary,
// 2 other) the triangles its dual cube makes (reduced) with their class.
struct StateTable {
  std::vector<int32_t> offsets;           // kStates + 1
  std::vector<uint16_t> triangle;         // index into the template's triangles
  std::vector<uint8_t> all_manifold;      // 1 all-manifold, 0 not
};
StateTable build_state_table(bool improved) {
  StateTable s;
  s.offsets.reserve(kStates + 1);
  s.offsets.push_back(0);
  for (int st = 0; st < kStates; ++st) {
    int config = 0, manifold = 0;
    for (int k = 0, r = st; k < 8; ++k, r /= 3) {
      if (r % 3 != 0) config |= 1 << k;
      if (r % 3 == 1) manifold |= 1 << k;
    }
    const auto& t = mesh_cube_template(config, improved);
    for (size_t i = 0; i < t.triangles.size(); ++i) {
      if (!t.triangles[i].reduced) continue;
      s.triangle.push_back(static_cast<uint16_t>(i));
      s.all_manifold.push_back((t.triangles[i].voxels & ~manifold) == 0 ? 1 : 0);
    }
    s.offsets.push_back(static_cast<int32_t>(s.triangle.size()));
  }
  return s;
}
const StateTable& state_table(bool improved) {
  static const StateTable with = build_state_table(true), without = build_state_table(false);
  return improved ? with : without;
}

// A vertex reference made while scanning: a voxel id, a face centre (subdivided grid key) or an
// interior centroid (index into its chunk's list).
struct VRef {
  int64_t id = 0;
  uint8_t kind = 0;  // 0 voxel, 1 face centre, 2 interior
};
struct ChunkOut {
  std::vector<std::array<VRef, 3>> tris;
  std::vector<uint8_t> tri_manifold;
  std::vector<Vec3> interior;  // positions
  std::vector<std::array<int64_t, 2>> bounded;  // 1-cells bounding a 2-cell (voxel ids, a < b)
  std::vector<std::array<int64_t, 2>> cells1;   // the 1-cells of the reduced cubes
};

std::array<int64_t, 2> ordered(int64_t a, int64_t b) { return a < b ? std::array<int64_t, 2>{a, b} : std::array<int64_t, 2>{b, a}; }

}  // namespace

const MeshCubeTemplate& mesh_cube_template(int config, bool improved) {
  static const auto tables = [] {
    std::array<std::vector<MeshCubeTemplate>, 2> t;
    for (int imp = 0; imp < 2; ++imp)
      for (int c = 0; c < 256; ++c) t[imp].push_back(build_template(c, imp == 1));
    return t;
  }();
  if (config < 0 || config > 255) throw Error("dual cube configuration out of range: " + std::to_string(config));
  return tables[improved ? 1 : 0][config];
}

Mesh skeleton_to_mesh(const VolumeU8& skeleton, const SkeletonToMeshOptions& options) {
  const Interrupter& intr = options.interrupter;
  auto sv = detail::collect_voxels(skeleton, options.threads, intr);
  detail::classify_voxels(sv, options.threads, intr);
  const int64_t n = sv.size();
  const int64_t nx = skeleton.nx(), ny = skeleton.ny(), nz = skeleton.nz(), nxy = nx * ny;
  const uint8_t* data = skeleton.data();
  auto fg = [&](int64_t x, int64_t y, int64_t z) {
    return x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz && data[x + nx * (y + ny * z)] != 0;
  };
  auto is_surface = [&](int64_t id) {
    return sv.cls[id] == static_cast<uint8_t>(ManifoldType::surface) ||
           sv.cls[id] == static_cast<uint8_t>(ManifoldType::surface_edge);
  };
  // Face centres live on the 2x2x2 subdivided grid, shifted by 2 so that cubes at -1 fit.
  const int64_t wx = 2 * nx + 3, wy = 2 * ny + 3;
  const auto& table = state_table(options.improved);
  const Grid& grid = skeleton.grid();

  const int64_t chunks = std::clamp<int64_t>(n / 4096, 1, 256);
  std::vector<ChunkOut> parts(chunks);
  parallel_chunks(0, n, chunks, options.threads, [&](int64_t c, int64_t b, int64_t e) {
    ChunkOut& out = parts[c];
    std::array<int64_t, 8> ids{};
    std::array<int64_t, 8> interior_ref{};
    for (int64_t i = b; i < e; ++i) {
      const int64_t idx = sv.vox[i];
      const int64_t x = idx % nx, y = idx / nx % ny, z = idx / nxy;
      for (int k = 0; k < 8; ++k) {
        const int64_t cx = x - (k & 1), cy = y - (k >> 1 & 1), cz = z - (k >> 2 & 1);
        int cfg = 0;
        for (int j = 0; j < 8; ++j)
          if (fg(cx + (j & 1), cy + (j >> 1 & 1), cz + (j >> 2 & 1))) cfg |= 1 << j;
        if (std::countr_zero(static_cast<unsigned>(cfg)) != k) continue;  // the cube's lowest voxel makes it
        int state = 0;
        for (int j = 7; j >= 0; --j) {
          state *= 3;
          if (!(cfg >> j & 1)) continue;
          const int64_t cidx = (cx + (j & 1)) + nx * ((cy + (j >> 1 & 1)) + ny * (cz + (j >> 2 & 1)));
          ids[j] = j == k ? i : sv.id_from(i, cidx);
          state += is_surface(ids[j]) ? 1 : 2;
        }
        const MeshCubeTemplate& tpl = mesh_cube_template(cfg, options.improved);
        const DualCubeEntry& entry = dual_cube_table()[cfg];
        for (uint32_t m = tpl.bounded_edges; m; m &= m - 1) {
          const auto q = dual_cube_pair(std::countr_zero(m));
          out.bounded.push_back(ordered(ids[q[0]], ids[q[1]]));
        }
        for (uint32_t m = entry.reduced_edges; m; m &= m - 1) {
          const auto q = dual_cube_pair(std::countr_zero(m));
          out.cells1.push_back(ordered(ids[q[0]], ids[q[1]]));
        }
        interior_ref.fill(-1);
        for (int32_t s = table.offsets[state]; s < table.offsets[state + 1]; ++s) {
          const MeshTriangleTemplate& tt = tpl.triangles[table.triangle[s]];
          std::array<VRef, 3> tri;
          for (int a = 0; a < 3; ++a) {
            const int code = tt.v[a];
            if (code < kFaceCentre) {
              tri[a] = {ids[code], 0};
            } else if (code < kInterior) {
              const int f = code - kFaceCentre, axis = f / 2, side = f % 2;
              std::array<int64_t, 3> d{2 * cx + 1 + 2, 2 * cy + 1 + 2, 2 * cz + 1 + 2};
              d[axis] = 2 * ((axis == 0 ? cx : axis == 1 ? cy : cz) + side) + 2;
              tri[a] = {d[0] + wx * (d[1] + wy * d[2]), 1};
            } else {
              const int j = code - kInterior;
              if (interior_ref[j] < 0) {
                const uint8_t mask = tpl.interior[j];
                double sx = 0, sy = 0, sz = 0;
                const int cnt = std::popcount(static_cast<unsigned>(mask));
                for (int q = 0; q < 8; ++q)
                  if (mask >> q & 1) {
                    sx += static_cast<double>(cx + (q & 1));
                    sy += static_cast<double>(cy + (q >> 1 & 1));
                    sz += static_cast<double>(cz + (q >> 2 & 1));
                  }
                interior_ref[j] = static_cast<int64_t>(out.interior.size());
                out.interior.push_back(grid.position(sx / cnt, sy / cnt, sz / cnt));
              }
              tri[a] = {interior_ref[j], 2};
            }
          }
          out.tris.push_back(tri);
          out.tri_manifold.push_back(table.all_manifold[s]);
        }
      }
    }
    intr.check();
  });

  // 1-cells bounding no 2-cell become lines.
  std::vector<std::array<int64_t, 2>> bounded, bare;
  for (auto& p : parts) {
    bounded.insert(bounded.end(), p.bounded.begin(), p.bounded.end());
    p.bounded = {};
  }
  std::sort(bounded.begin(), bounded.end());
  bounded.erase(std::unique(bounded.begin(), bounded.end()), bounded.end());
  for (auto& p : parts) {
    for (const auto& c1 : p.cells1)
      if (!std::binary_search(bounded.begin(), bounded.end(), c1)) bare.push_back(c1);
    p.cells1 = {};
  }
  bounded = {};
  std::sort(bare.begin(), bare.end());
  intr.check();

  // Vertex numbering: used voxels (ascending), face centres (ascending key), interior centroids.
  std::vector<int64_t> voxel_vertex(n, -1);
  std::vector<int64_t> face_keys;
  for (const auto& p : parts)
    for (const auto& t : p.tris)
      for (const auto& r : t) {
        if (r.kind == 0) voxel_vertex[r.id] = 0;
        else if (r.kind == 1) face_keys.push_back(r.id);
      }
  for (const auto& s : bare) voxel_vertex[s[0]] = voxel_vertex[s[1]] = 0;
  std::sort(face_keys.begin(), face_keys.end());
  face_keys.erase(std::unique(face_keys.begin(), face_keys.end()), face_keys.end());
  Mesh mesh;
  mesh.unit = grid.unit;  // coordinates are in the skeleton's physical unit
  mesh.frame_origin = grid.origin;  // and its axis-aligned frame; files get the direction applied
  mesh.frame_direction = grid.direction;
  std::vector<int32_t> vclass;
  for (int64_t i = 0; i < n; ++i) {
    if (voxel_vertex[i] < 0) continue;
    voxel_vertex[i] = mesh.vertex_count();
    const Vec3 p = sv.position(i);
    mesh.add_vertex({static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
    vclass.push_back(sv.cls[i]);
  }
  const int64_t face_base = mesh.vertex_count();
  for (int64_t key : face_keys) {
    const int64_t dx = key % wx - 2, dy = key / wx % wy - 2, dz = key / (wx * wy) - 2;
    const Vec3 p = grid.position(dx / 2.0, dy / 2.0, dz / 2.0);
    mesh.add_vertex({static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
    vclass.push_back(-1);
  }
  std::vector<int64_t> interior_base(chunks);
  for (int64_t c = 0; c < chunks; ++c) {
    interior_base[c] = mesh.vertex_count();
    for (const auto& p : parts[c].interior) {
      mesh.add_vertex({static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
      vclass.push_back(-1);
    }
  }
  std::vector<int32_t> tri_class;
  std::vector<uint8_t> centre_all(mesh.vertex_count(), 1);
  for (int64_t c = 0; c < chunks; ++c) {
    const auto& p = parts[c];
    for (size_t t = 0; t < p.tris.size(); ++t) {
      Mesh::Triangle tri{};
      for (int a = 0; a < 3; ++a) {
        const VRef& r = p.tris[t][a];
        if (r.kind == 0) tri[a] = voxel_vertex[r.id];
        else if (r.kind == 1)
          tri[a] = face_base + (std::lower_bound(face_keys.begin(), face_keys.end(), r.id) - face_keys.begin());
        else tri[a] = interior_base[c] + r.id;
        if (!p.tri_manifold[t]) centre_all[tri[a]] = 0;
      }
      mesh.triangles.push_back(tri);
      tri_class.push_back(p.tri_manifold[t]);
    }
  }
  parts = {};
  for (int64_t v = 0; v < mesh.vertex_count(); ++v)
    if (vclass[v] < 0)
      vclass[v] = static_cast<int32_t>(centre_all[v] ? ManifoldType::surface : ManifoldType::junction);
  intr.check();

  // Lines: chains of bare 1-cells, broken at vertices where their number is not 2.
  const int64_t nvtx = mesh.vertex_count();
  std::vector<int64_t> off(nvtx + 1, 0), adj(2 * bare.size());
  for (const auto& s : bare) {
    ++off[voxel_vertex[s[0]] + 1];
    ++off[voxel_vertex[s[1]] + 1];
  }
  for (int64_t v = 0; v < nvtx; ++v) off[v + 1] += off[v];
  {
    std::vector<int64_t> fill(off.begin(), off.end() - 1);
    for (size_t s = 0; s < bare.size(); ++s) {
      adj[fill[voxel_vertex[bare[s][0]]]++] = static_cast<int64_t>(s);
      adj[fill[voxel_vertex[bare[s][1]]]++] = static_cast<int64_t>(s);
    }
  }
  std::vector<uint8_t> used(bare.size(), 0);
  std::vector<int32_t> line_class;
  auto other = [&](int64_t s, int64_t v) {
    const int64_t a = voxel_vertex[bare[s][0]], b = voxel_vertex[bare[s][1]];
    return a == v ? b : a;
  };
  auto trace = [&](int64_t v, int64_t s) {
    std::vector<int64_t> ids{v};
    for (;;) {
      used[s] = 1;
      v = other(s, v);
      ids.push_back(v);
      if (off[v + 1] - off[v] != 2) break;
      const int64_t s2 = adj[off[v]] == s ? adj[off[v] + 1] : adj[off[v]];
      if (used[s2]) break;
      s = s2;
    }
    bool all_line = true;
    for (int64_t id : ids)
      all_line = all_line && (vclass[id] == static_cast<int32_t>(ManifoldType::line) ||
                              vclass[id] == static_cast<int32_t>(ManifoldType::line_end));
    mesh.add_line(ids);
    line_class.push_back(all_line ? 1 : 0);
  };
  for (int64_t v = 0; v < nvtx; ++v)
    if (off[v + 1] - off[v] != 2)
      for (int64_t a = off[v]; a < off[v + 1]; ++a)
        if (!used[adj[a]]) trace(v, adj[a]);
  for (int64_t v = 0; v < nvtx; ++v)  // closed rings
    for (int64_t a = off[v]; a < off[v + 1]; ++a)
      if (!used[adj[a]]) trace(v, adj[a]);

  std::vector<int32_t> fixed(nvtx, 0);
  for (int64_t v = 0; v < nvtx; ++v) fixed[v] = vclass[v] == static_cast<int32_t>(ManifoldType::line_junction) ? 1 : 0;
  mesh.vertex_attributes["manifold"] = std::move(vclass);
  mesh.vertex_attributes["fixed"] = std::move(fixed);
  mesh.triangle_attributes["manifold"] = std::move(tri_class);
  mesh.line_attributes["manifold"] = std::move(line_class);
  return mesh;
}

}  // namespace skel::geometry
