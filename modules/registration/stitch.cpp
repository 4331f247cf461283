// Stitching of overlapping tiles (thesis §6.1): pairwise NCC, global least squares, linear blending.
#include "registration/stitch.hpp"

#include <Eigen/Sparse>
#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <tuple>

#include "skel/parallel.hpp"
#include "skel/text.hpp"
#include "skel/units.hpp"

namespace skel::registration {

// ---------------------------------------------------------------- tile list

namespace {

// Splits one CSV line into fields; double quotes protect commas ("" is a quote inside quotes).
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') { out.back() += '"'; ++i; }
      else if (c == '"') quoted = false;
      else out.back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  for (auto& f : out) f = text::trim(f);
  return out;
}

}  // namespace

std::vector<TileListEntry> parse_tile_list(const std::string& content, const std::filesystem::path& list_path) {
  std::vector<TileListEntry> tiles;
  const auto lines = text::split_lines(content);
  const std::string list = list_path.string();
  bool first = true;
  for (size_t i = 0; i < lines.size(); ++i) {
    const std::string line = text::trim(lines[i]);
    const std::string where = list + ":" + std::to_string(i + 1);
    if (line.empty() || line[0] == '#') continue;
    const auto f = csv_fields(line);
    double probe = 0.0;
    if (first && f.size() >= 2 && !text::parse_double(f[1], probe)) {  // a header line
      first = false;
      continue;
    }
    first = false;
    if (f.size() != 4) {
      throw InputError(where + ": expected 4 fields (file,x,y,z), got " + std::to_string(f.size()));
    }
    if (f[0].empty()) throw InputError(where + ": empty file name");
    TileListEntry e;
    const std::filesystem::path p(f[0]);
    e.name = f[0];
    e.file = p.is_absolute() ? p : list_path.parent_path() / p;
    e.line = static_cast<int64_t>(i + 1);
    static const char* axis[3] = {"x", "y", "z"};
    for (int a = 0; a < 3; ++a) {
      if (!text::parse_double(f[static_cast<size_t>(a) + 1], e.position[static_cast<size_t>(a)]) ||
          !std::isfinite(e.position[static_cast<size_t>(a)])) {
        throw InputError(where + ": " + axis[a] + " position '" + f[static_cast<size_t>(a) + 1] + "' is not a finite number");
      }
    }
    tiles.push_back(std::move(e));
  }
  if (tiles.empty()) throw InputError(list + ": no tiles (expected lines file,x,y,z)");
  return tiles;
}

// ---------------------------------------------------------------- pairwise NCC

namespace {

std::string tile_label(const StitchTile& t) {
  return (t.where.empty() ? std::string() : t.where + ": ") + "tile '" + t.name + "'";
}

// A box of a tile as float voxels (x fastest).
struct Region {
  Dims begin{0, 0, 0}, size{0, 0, 0};
  std::vector<float> voxels;
  [[nodiscard]] int64_t index(int64_t x, int64_t y, int64_t z) const {
    return (x - begin[0]) + size[0] * ((y - begin[1]) + size[1] * (z - begin[2]));
  }
};

Region load_region(const StitchTile& t, const Dims& begin, const Dims& size) {
  Region r;
  r.begin = begin;
  r.size = size;
  const DataPtr box = t.read_box(begin, size);
  r.voxels = visit_volume(*box, tile_label(t), [&](const auto& v) {
    if (v.dims() != size) throw Error(tile_label(t) + ": the reader returned a box of the wrong size");
    std::vector<float> out(static_cast<size_t>(v.size()));
    for (int64_t i = 0; i < v.size(); ++i) out[static_cast<size_t>(i)] = static_cast<float>(v.data()[i]);
    return out;
  });
  return r;
}

struct NccValue {
  double value = -2.0;  // -2: not computable (overlap too small or flat)
  int64_t voxels = 0;
};

// NCC of tile a (region A, a-local) and tile b placed at offset `off` (b-local = a-local − off) over
// their overlap, sampled every `step` voxels along each axis.
NccValue ncc(const Region& A, const Region& B, const Dims& da, const Dims& db, const Dims& off, int64_t step,
             int64_t min_overlap) {
  Dims lo{}, hi{};
  for (size_t a = 0; a < 3; ++a) {
    lo[a] = std::max({int64_t{0}, off[a], A.begin[a], B.begin[a] + off[a]});
    hi[a] = std::min({da[a], off[a] + db[a], A.begin[a] + A.size[a], B.begin[a] + B.size[a] + off[a]});
    if (hi[a] - lo[a] < min_overlap) return {};
  }
  const auto& va = A.voxels;
  const auto& vb = B.voxels;
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  int64_t n = 0;
  for (int64_t z = lo[2]; z < hi[2]; z += step)
    for (int64_t y = lo[1]; y < hi[1]; y += step) {
      const int64_t ia = A.index(lo[0], y, z), ib = B.index(lo[0] - off[0], y - off[1], z - off[2]);
      for (int64_t x = 0; x < hi[0] - lo[0]; x += step) {
        const double p = va[static_cast<size_t>(ia + x)], q = vb[static_cast<size_t>(ib + x)];
        sa += p; sb += q; saa += p * p; sbb += q * q; sab += p * q;
        ++n;
      }
    }
  const double dn = static_cast<double>(n);
  const double vara = saa - sa * sa / dn, varb = sbb - sb * sb / dn;
  if (n < 2 || !(vara > 0.0) || !(varb > 0.0)) return {-2.0, n};
  return {(sab - sa * sb / dn) / std::sqrt(vara * varb), n};
}

}  // namespace

StitchPair measure_pair(const StitchTile& ta, const StitchTile& tb, int64_t ia, int64_t ib, const StitchOptions& o) {
  StitchPair pair;
  pair.a = ia;
  pair.b = ib;
  const int64_t R = o.search_radius;
  const Dims& da = ta.grid.dims;
  const Dims& db = tb.grid.dims;
  Dims nominal{}, a_begin{}, a_size{}, b_begin{}, b_size{};
  int64_t min_extent = std::numeric_limits<int64_t>::max();
  for (size_t a = 0; a < 3; ++a) {
    pair.nominal[a] = tb.position[a] - ta.position[a];
    nominal[a] = static_cast<int64_t>(std::llround(pair.nominal[a]));
    const int64_t lo = std::max(int64_t{0}, nominal[a] - R), hi = std::min(da[a], nominal[a] + db[a] + R);
    a_begin[a] = lo;
    a_size[a] = std::max(int64_t{0}, hi - lo);
    const int64_t blo = std::max(int64_t{0}, lo - nominal[a] - R), bhi = std::min(db[a], hi - nominal[a] + R);
    b_begin[a] = blo;
    b_size[a] = std::max(int64_t{0}, bhi - blo);
    min_extent = std::min({min_extent, a_size[a], b_size[a]});
  }
  const int64_t min_overlap = std::max<int64_t>(2, std::min(o.min_overlap, min_extent));
  const Region A = load_region(ta, a_begin, a_size);
  const Region B = load_region(tb, b_begin, b_size);
  // Search: every integer offset within ±R, with the overlap sampled every `stride` voxels per axis
  // (at least 4096 voxels), so the fine texture that tells positions along an elongated
  // structure apart is kept (box-averaged pyramids blur it away and leave ridges of equal NCC along
  // vessels); then the best candidates at full resolution, hill climbing, and the parabola fit.
  int64_t overlap_voxels = 1;
  for (size_t a = 0; a < 3; ++a)
    overlap_voxels *= std::max<int64_t>(1, std::min(da[a], nominal[a] + db[a]) - std::max(int64_t{0}, nominal[a]));
  int64_t stride = 1;
  while (stride < 4 && overlap_voxels / ((2 * stride) * (2 * stride) * (2 * stride)) >= 4096) stride *= 2;
  using Shift = std::array<int64_t, 3>;
  auto offset = [&](const Shift& s) { return Dims{nominal[0] + s[0], nominal[1] + s[1], nominal[2] + s[2]}; };
  auto evaluate = [&](const std::vector<Shift>& shifts, int64_t step) {
    std::vector<NccValue> v(shifts.size());
    parallel_for(0, static_cast<int64_t>(shifts.size()), o.threads, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i)
        v[static_cast<size_t>(i)] = ncc(A, B, da, db, offset(shifts[static_cast<size_t>(i)]), step, min_overlap);
    });
    return v;
  };
  std::vector<Shift> all;
  for (int64_t z = -R; z <= R; ++z)
    for (int64_t y = -R; y <= R; ++y)
      for (int64_t x = -R; x <= R; ++x) all.push_back({x, y, z});
  std::vector<size_t> order(all.size());
  std::iota(order.begin(), order.end(), size_t{0});
  {
    const auto coarse = evaluate(all, stride);
    const size_t keep = std::min<size_t>(order.size(), stride == 1 ? 1 : 8);
    std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(keep), order.end(), [&](size_t i, size_t j) {
      return coarse[i].value != coarse[j].value ? coarse[i].value > coarse[j].value : i < j;
    });
    order.resize(keep);
  }
  Shift best = all[order.front()];
  {
    std::vector<Shift> candidates;
    for (size_t i : order) candidates.push_back(all[i]);
    const auto fine = evaluate(candidates, 1);
    double bv = -3.0;
    for (size_t i = 0; i < candidates.size(); ++i)
      if (fine[i].value > bv) { bv = fine[i].value; best = candidates[i]; }
  }
  auto neighbourhood = [&](const Shift& c) {
    std::vector<Shift> shifts;
    for (int64_t z = -1; z <= 1; ++z)
      for (int64_t y = -1; y <= 1; ++y)
        for (int64_t x = -1; x <= 1; ++x)
          shifts.push_back({std::clamp(c[0] + x, -R, R), std::clamp(c[1] + y, -R, R), std::clamp(c[2] + z, -R, R)});
    return shifts;
  };
  // Full resolution: climb until the centre is the best of its 26 neighbours.
  NccValue peak;
  for (int64_t iter = 0; iter <= 6 * R + 6; ++iter) {
    o.interrupter.check();
    const auto shifts = neighbourhood(best);
    const auto v = evaluate(shifts, 1);
    Shift next = shifts[13];  // the centre
    double bv = v[13].value;
    for (size_t i = 0; i < shifts.size(); ++i)
      if (v[i].value > bv) { bv = v[i].value; next = shifts[i]; }
    peak = v[13];
    if (next == best) break;
    best = next;
  }
  pair.correlation = peak.value < -1.5 ? 0.0 : peak.value;
  pair.overlap_voxels = peak.voxels;
  for (size_t a = 0; a < 3; ++a) {
    Shift m = best, p = best;
    m[a] -= 1;
    p[a] += 1;
    const double cm = ncc(A, B, da, db, offset(m), 1, min_overlap).value;
    const double cp = ncc(A, B, da, db, offset(p), 1, min_overlap).value;
    const double c0 = peak.value;
    double delta = 0.0;
    const double denom = cm - 2.0 * c0 + cp;
    if (cm > -1.5 && cp > -1.5 && denom < 0.0) delta = std::clamp(0.5 * (cm - cp) / denom, -0.5, 0.5);
    pair.measured[a] = static_cast<double>(nominal[a] + best[a]) + delta;
  }
  if (pair.correlation < o.min_correlation) pair.status = PairStatus::low_correlation;
  return pair;
}

// ---------------------------------------------------------------- global least squares

std::vector<Vec3> solve_positions(const std::vector<Vec3>& nominal, std::vector<StitchPair>& pairs, int64_t fixed) {
  const auto n = static_cast<int64_t>(nominal.size());
  // Connected groups of tiles over the used pairs; in each group one tile is anchored.
  std::vector<int64_t> group(static_cast<size_t>(n));
  std::iota(group.begin(), group.end(), 0);
  std::function<int64_t(int64_t)> find = [&](int64_t i) {
    while (group[static_cast<size_t>(i)] != i) i = group[static_cast<size_t>(i)] = group[static_cast<size_t>(group[static_cast<size_t>(i)])];
    return i;
  };
  for (const auto& p : pairs)
    if (p.status == PairStatus::used) {
      const int64_t ra = find(p.a), rb = find(p.b);
      if (ra != rb) group[static_cast<size_t>(std::max(ra, rb))] = std::min(ra, rb);
    }
  std::vector<bool> anchored(static_cast<size_t>(n), false);
  std::vector<bool> group_has_anchor(static_cast<size_t>(n), false);
  if (fixed >= 0 && fixed < n) {
    anchored[static_cast<size_t>(fixed)] = true;
    group_has_anchor[static_cast<size_t>(find(fixed))] = true;
  }
  for (int64_t i = 0; i < n; ++i) {
    const int64_t r = find(i);
    if (!group_has_anchor[static_cast<size_t>(r)]) {
      group_has_anchor[static_cast<size_t>(r)] = true;
      anchored[static_cast<size_t>(i)] = true;
    }
  }
  std::vector<Vec3> pos = nominal;
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
  Eigen::VectorXd diag = Eigen::VectorXd::Zero(n);
  for (const auto& p : pairs) {
    if (p.status != PairStatus::used) continue;
    const double w = std::max(p.correlation, 1e-3);
    const auto a = p.a, b = p.b;
    const bool fa = anchored[static_cast<size_t>(a)], fb = anchored[static_cast<size_t>(b)];
    for (int k = 0; k < 3; ++k) {
      // rows of the normal equations: (P_b − P_a − m) w added to row b, subtracted from row a
      if (!fb) rhs(b, k) += w * p.measured[static_cast<size_t>(k)];
      if (!fa) rhs(a, k) -= w * p.measured[static_cast<size_t>(k)];
      if (!fb && fa) rhs(b, k) += w * nominal[static_cast<size_t>(a)][static_cast<size_t>(k)];
      if (!fa && fb) rhs(a, k) += w * nominal[static_cast<size_t>(b)][static_cast<size_t>(k)];
    }
    if (!fa) diag(a) += w;
    if (!fb) diag(b) += w;
    if (!fa && !fb) {
      triplets.emplace_back(a, b, -w);
      triplets.emplace_back(b, a, -w);
    }
  }
  for (int64_t i = 0; i < n; ++i) {
    if (anchored[static_cast<size_t>(i)]) {
      triplets.emplace_back(i, i, 1.0);
      for (int k = 0; k < 3; ++k) rhs(i, k) = nominal[static_cast<size_t>(i)][static_cast<size_t>(k)];
    } else {
      triplets.emplace_back(i, i, diag(i));
    }
  }
  Eigen::SparseMatrix<double> L(n, n);
  L.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(L);
  if (solver.info() != Eigen::Success) throw Error("stitching: the least-squares system of tile positions is singular");
  const Eigen::MatrixXd x = solver.solve(rhs);
  for (int64_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) pos[static_cast<size_t>(i)][static_cast<size_t>(k)] = x(i, k);
  for (auto& p : pairs) {
    p.residual = {0, 0, 0};
    if (p.status != PairStatus::used) continue;
    for (size_t k = 0; k < 3; ++k)
      p.residual[k] = pos[static_cast<size_t>(p.b)][k] - pos[static_cast<size_t>(p.a)][k] - p.measured[k];
  }
  return pos;
}

// ---------------------------------------------------------------- alignment

namespace {

bool same_spacing(const Vec3& a, const Vec3& b) {
  for (size_t k = 0; k < 3; ++k)
    if (std::abs(a[k] - b[k]) > 1e-6 * std::max(std::abs(a[k]), std::abs(b[k]))) return false;
  return true;
}

std::string spacing_text(const Vec3& s) {
  return "(" + text::format_double(s[0], 9) + ", " + text::format_double(s[1], 9) + ", " + text::format_double(s[2], 9) + ")";
}

// Nominal overlap of two tiles along each axis (voxels; may be negative).
Dims nominal_overlap(const StitchTile& a, const StitchTile& b) {
  Dims o{};
  for (size_t k = 0; k < 3; ++k) {
    const double lo = std::max(a.position[k], b.position[k]);
    const double hi = std::min(a.position[k] + static_cast<double>(a.grid.dims[k]),
                               b.position[k] + static_cast<double>(b.grid.dims[k]));
    o[k] = static_cast<int64_t>(std::floor(hi - lo + 1e-9));
  }
  return o;
}

}  // namespace

StitchLayout align_tiles(const std::vector<StitchTile>& tiles, const StitchOptions& o) {
  if (tiles.empty()) throw InputError("stitching: no tiles");
  const auto n = static_cast<int64_t>(tiles.size());
  if (o.fixed_tile < 0 || o.fixed_tile >= n)
    throw InputError("param 'fixed_tile': " + std::to_string(o.fixed_tile) + " is not a tile index (0.." +
                     std::to_string(n - 1) + ")");
  const StitchTile& t0 = tiles.front();
  for (const auto& t : tiles) {
    if (t.type_id != t0.type_id)
      throw InputError(tile_label(t) + " holds " + t.type_id + " voxels, but " + tile_label(t0) + " holds " + t0.type_id +
                       " (all tiles need one voxel type)");
    if (!same_spacing(t.grid.spacing, t0.grid.spacing))
      throw InputError(tile_label(t) + " has spacing " + spacing_text(t.grid.spacing) + ", but " + tile_label(t0) + " has " +
                       spacing_text(t0.grid.spacing) + " (all tiles need one spacing)");
    if (t.grid.unit != t0.grid.unit)
      throw InputError(tile_label(t) + " is in " + t.grid.unit + ", but " + tile_label(t0) + " is in " + t0.grid.unit);
    for (size_t k = 0; k < 3; ++k)
      if (t.grid.dims[k] < 1) throw InputError(tile_label(t) + " is empty");
  }
  StitchLayout layout;
  layout.type_id = t0.type_id;
  for (const auto& t : tiles) layout.nominal.push_back(t.position);
  // Pairs: nominal overlap of at least min_overlap voxels along every axis.
  std::vector<std::pair<int64_t, int64_t>> candidates;
  std::vector<int64_t> partners(static_cast<size_t>(n), 0);
  for (int64_t i = 0; i < n; ++i)
    for (int64_t j = i + 1; j < n; ++j) {
      const Dims ov = nominal_overlap(tiles[static_cast<size_t>(i)], tiles[static_cast<size_t>(j)]);
      if (ov[0] >= o.min_overlap && ov[1] >= o.min_overlap && ov[2] >= o.min_overlap) {
        candidates.emplace_back(i, j);
        ++partners[static_cast<size_t>(i)];
        ++partners[static_cast<size_t>(j)];
      }
    }
  if (n > 1)
    for (int64_t i = 0; i < n; ++i)
      if (partners[static_cast<size_t>(i)] == 0)
        throw InputError(tile_label(tiles[static_cast<size_t>(i)]) + " overlaps no other tile by at least min_overlap = " +
                         std::to_string(o.min_overlap) + " voxels along every axis (check its position and the positions' unit)");
  const auto total = static_cast<int64_t>(candidates.size());
  for (int64_t k = 0; k < total; ++k) {
    o.interrupter.note("pair " + std::to_string(k + 1) + "/" + std::to_string(total));
    o.interrupter.check(static_cast<double>(k) / static_cast<double>(std::max<int64_t>(total, 1)));
    const auto [i, j] = candidates[static_cast<size_t>(k)];
    layout.pairs.push_back(measure_pair(tiles[static_cast<size_t>(i)], tiles[static_cast<size_t>(j)], i, j, o));
  }
  layout.positions = solve_positions(layout.nominal, layout.pairs, o.fixed_tile);
  std::vector<int64_t> used(static_cast<size_t>(n), 0);
  for (const auto& p : layout.pairs)
    if (p.status == PairStatus::used) { ++used[static_cast<size_t>(p.a)]; ++used[static_cast<size_t>(p.b)]; }
  if (n > 1)
    for (int64_t i = 0; i < n; ++i)
      if (used[static_cast<size_t>(i)] == 0) layout.unconnected.push_back(i);
  // Merged grid: positions rounded to whole voxels, shifted so that the lowest is 0.
  Dims lo{std::numeric_limits<int64_t>::max(), std::numeric_limits<int64_t>::max(), std::numeric_limits<int64_t>::max()};
  Dims hi{std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::min()};
  // Rounded relative to the fixed tile, so that tiles placed within half a voxel of their true
  // relative positions land exactly there, whatever the fraction of the fixed tile's position.
  std::vector<Dims> rounded;
  const Vec3& pf = layout.positions[static_cast<size_t>(o.fixed_tile)];
  for (int64_t i = 0; i < n; ++i) {
    Dims r{};
    for (size_t k = 0; k < 3; ++k) {
      r[k] = static_cast<int64_t>(std::llround(pf[k])) +
             static_cast<int64_t>(std::llround(layout.positions[static_cast<size_t>(i)][k] - pf[k]));
      lo[k] = std::min(lo[k], r[k]);
      hi[k] = std::max(hi[k], r[k] + tiles[static_cast<size_t>(i)].grid.dims[k]);
    }
    rounded.push_back(r);
  }
  for (auto& r : rounded) layout.placed.push_back({r[0] - lo[0], r[1] - lo[1], r[2] - lo[2]});
  layout.grid = Grid(Dims{hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}, t0.grid.spacing,
                     Vec3{static_cast<double>(lo[0]) * t0.grid.spacing[0], static_cast<double>(lo[1]) * t0.grid.spacing[1],
                          static_cast<double>(lo[2]) * t0.grid.spacing[2]},
                     t0.grid.unit);
  o.interrupter.check(1.0);
  return layout;
}

// ---------------------------------------------------------------- merging

namespace {

template <class T>
T from_double(double v) {
  if constexpr (std::is_integral_v<T>) {
    const double r = std::round(v);
    if (r <= static_cast<double>(std::numeric_limits<T>::lowest())) return std::numeric_limits<T>::lowest();
    if (r >= static_cast<double>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
    return static_cast<T>(r);
  } else {
    return static_cast<T>(v);
  }
}

// Linear weight of voxel i of n along one axis: 1 at the border voxels, rising towards the centre.
inline double tent(int64_t i, int64_t n) { return static_cast<double>(std::min(i + 1, n - i)); }

template <class T>
Volume<T> merge_block(const std::vector<StitchTile>& tiles, const StitchLayout& layout, const Dims& begin,
                      const Dims& size, int threads) {
  const int64_t nv = size[0] * size[1] * size[2];
  std::vector<double> sum(static_cast<size_t>(nv), 0.0), weight(static_cast<size_t>(nv), 0.0);
  for (size_t t = 0; t < tiles.size(); ++t) {
    const Dims& p = layout.placed[t];
    const Dims& d = tiles[t].grid.dims;
    Dims lo{}, hi{};
    bool empty = false;
    for (size_t k = 0; k < 3; ++k) {
      lo[k] = std::max(begin[k], p[k]);
      hi[k] = std::min(begin[k] + size[k], p[k] + d[k]);
      empty = empty || hi[k] <= lo[k];
    }
    if (empty) continue;
    const Dims tb{lo[0] - p[0], lo[1] - p[1], lo[2] - p[2]};
    const Dims ts{hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    const DataPtr box = tiles[t].read_box(tb, ts);
    const auto* v = dynamic_cast<const Volume<T>*>(box.get());
    if (!v || v->dims() != ts) throw Error(tile_label(tiles[t]) + ": the reader returned a box of another type or size");
    parallel_for(0, ts[2], threads, [&](int64_t z0, int64_t z1) {
      for (int64_t z = z0; z < z1; ++z)
        for (int64_t y = 0; y < ts[1]; ++y) {
          const double wyz = tent(tb[1] + y, d[1]) * tent(tb[2] + z, d[2]);
          const int64_t o = (lo[0] - begin[0]) + size[0] * ((lo[1] + y - begin[1]) + size[1] * (lo[2] + z - begin[2]));
          for (int64_t x = 0; x < ts[0]; ++x) {
            const double w = wyz * tent(tb[0] + x, d[0]);
            sum[static_cast<size_t>(o + x)] += w * static_cast<double>((*v)(x, y, z));
            weight[static_cast<size_t>(o + x)] += w;
          }
        }
    });
  }
  Grid g = layout.grid;
  g.dims = size;
  g.origin = layout.grid.position(static_cast<double>(begin[0]), static_cast<double>(begin[1]), static_cast<double>(begin[2]));
  Volume<T> out = Volume<T>::uninitialized(g);
  for (int64_t i = 0; i < nv; ++i) {
    const double w = weight[static_cast<size_t>(i)];
    out.data()[i] = w > 0.0 ? from_double<T>(sum[static_cast<size_t>(i)] / w) : T{};
  }
  return out;
}

}  // namespace

void merge_tiles(const std::vector<StitchTile>& tiles, const StitchLayout& layout, const Dims& block,
                 const MergeSink& sink, const StitchOptions& o) {
  const BlockLayout blocks(layout.grid.dims, block);
  visit_voxel_type(layout.type_id, "stitching", [&](auto zero) {
    using T = decltype(zero);
    for_each_block(blocks, o.interrupter, "merge", [&](const Block& b) {
      sink(merge_block<T>(tiles, layout, b.begin, b.size, o.threads), b.begin);
    });
  });
}

DataPtr merge_tiles_in_memory(const std::vector<StitchTile>& tiles, const StitchLayout& layout, const StitchOptions& o) {
  return visit_voxel_type(layout.type_id, "stitching", [&](auto zero) -> DataPtr {
    using T = decltype(zero);
    auto out = std::make_shared<Volume<T>>(Volume<T>::uninitialized(layout.grid));
    const Dims d = layout.grid.dims;
    // z-slabs of about 16 M voxels, so the double accumulators stay small next to the output
    const int64_t slab = std::max<int64_t>(1, (int64_t{1} << 24) / std::max<int64_t>(1, d[0] * d[1]));
    merge_tiles(tiles, layout, Dims{std::max<int64_t>(d[0], 1), std::max<int64_t>(d[1], 1), std::min(slab, std::max<int64_t>(d[2], 1))},
                [&](const DataObject& block, const Dims& begin) {
                  const auto& b = dynamic_cast<const Volume<T>&>(block);
                  if (b.size() > 0) std::memcpy(&(*out)(0, 0, begin[2]), b.data(), static_cast<size_t>(b.size()) * sizeof(T));
                },
                o);
    return out;
  });
}

void merge_tiles_into(const std::vector<StitchTile>& tiles, const StitchLayout& layout, ChunkedVolume& out,
                      const Dims& block, const StitchOptions& o) {
  if (out.dims() != layout.grid.dims || out.type_id() != layout.type_id)
    throw Error("stitching: the volume on disk does not match the merged grid");
  merge_tiles(tiles, layout, block,
              [&](const DataObject& b, const Dims& begin) {
                visit_volume(b, "merged block", [&](const auto& v) { out.write(v, begin); });
              },
              o);
}

// ---------------------------------------------------------------- tables

Table tile_table(const std::vector<StitchTile>& tiles, const StitchLayout& layout) {
  Table t;
  const auto n = tiles.size();
  const Vec3 s = layout.grid.spacing;
  std::vector<int64_t> index(n), pairs(n, 0);
  std::vector<std::string> file(n);
  std::array<std::vector<double>, 3> nominal, pos;
  std::array<std::vector<int64_t>, 3> placed;
  for (const auto& p : layout.pairs)
    if (p.status == PairStatus::used) { ++pairs[static_cast<size_t>(p.a)]; ++pairs[static_cast<size_t>(p.b)]; }
  for (size_t i = 0; i < n; ++i) {
    index[i] = static_cast<int64_t>(i);
    file[i] = tiles[i].name;
    for (size_t k = 0; k < 3; ++k) {
      nominal[k].push_back(layout.nominal[i][k] * s[k]);
      pos[k].push_back(layout.positions[i][k] * s[k]);
      placed[k].push_back(layout.placed[i][k]);
    }
  }
  const std::string& u = layout.grid.unit;
  t.add("tile", index).add("file", file);
  t.add("nominal_x", nominal[0], u).add("nominal_y", nominal[1], u).add("nominal_z", nominal[2], u);
  t.add("x", pos[0], u).add("y", pos[1], u).add("z", pos[2], u);
  t.add("placed_x", placed[0], "voxels").add("placed_y", placed[1], "voxels").add("placed_z", placed[2], "voxels");
  t.add("pairs", pairs);
  return t;
}

Table pair_table(const std::vector<StitchTile>& tiles, const StitchLayout& layout) {
  Table t;
  const Vec3 s = layout.grid.spacing;
  std::vector<int64_t> a, b, voxels;
  std::vector<std::string> fa, fb, status;
  std::vector<double> corr, dx, dy, dz, res;
  for (const auto& p : layout.pairs) {
    a.push_back(p.a);
    b.push_back(p.b);
    fa.push_back(tiles[static_cast<size_t>(p.a)].name);
    fb.push_back(tiles[static_cast<size_t>(p.b)].name);
    voxels.push_back(p.overlap_voxels);
    corr.push_back(p.correlation);
    dx.push_back(p.measured[0] * s[0]);
    dy.push_back(p.measured[1] * s[1]);
    dz.push_back(p.measured[2] * s[2]);
    const double r0 = p.residual[0] * s[0], r1 = p.residual[1] * s[1], r2 = p.residual[2] * s[2];
    res.push_back(std::sqrt(r0 * r0 + r1 * r1 + r2 * r2));
    status.emplace_back(p.status == PairStatus::used ? "used" : "low_correlation");
  }
  const std::string& u = layout.grid.unit;
  t.add("tile_a", a).add("tile_b", b).add("file_a", fa).add("file_b", fb).add("overlap_voxels", voxels);
  t.add("correlation", corr).add("dx", dx, u).add("dy", dy, u).add("dz", dz, u).add("residual", res, u);
  t.add("status", status);
  return t;
}

}  // namespace skel::registration
