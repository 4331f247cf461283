// SMOOTHDOGTT (thesis Algorithm 3): distance ordered thinning of grid cell complexes.
#include "thinning/grid_cell.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <bit>
#include <functional>
#include <queue>
#include <unordered_map>
#include <numeric>
#include <vector>

#include "skel/error.hpp"
#include "skel/parallel.hpp"
#include "skel/union_find.hpp"

namespace skel::thinning {

int coface_count(const GridCells& c, int64_t kx, int64_t ky, int64_t kz) {
  int n = 0;
  if (!(kx & 1)) n += static_cast<int>(c.has(kx - 1, ky, kz)) + static_cast<int>(c.has(kx + 1, ky, kz));
  if (!(ky & 1)) n += static_cast<int>(c.has(kx, ky - 1, kz)) + static_cast<int>(c.has(kx, ky + 1, kz));
  if (!(kz & 1)) n += static_cast<int>(c.has(kx, ky, kz - 1)) + static_cast<int>(c.has(kx, ky, kz + 1));
  return n;
}

namespace {

// The only 1-cell of 0-cell k other than `skip` (dx, dy, dz: its direction); false unless there is
// exactly one such 1-cell.
bool other_edge(const GridCells& c, const std::array<int64_t, 3>& k, const std::array<int64_t, 3>& skip,
                std::array<int64_t, 3>& dir) {
  int found = 0;
  for (int a = 0; a < 3; ++a)
    for (int s = -1; s <= 1; s += 2) {
      std::array<int64_t, 3> e = k;
      e[static_cast<size_t>(a)] += s;
      if (e == skip || !c.has(e[0], e[1], e[2])) continue;
      if (++found > 1) return false;
      dir = {0, 0, 0};
      dir[static_cast<size_t>(a)] = s;
    }
  return found == 1;
}

}  // namespace

int end_point_importance(const GridCells& c, int64_t kx, int64_t ky, int64_t kz, int cap) {
  std::array<int64_t, 3> v{kx, ky, kz}, dir{}, skip{-9, -9, -9};
  if (coface_count(c, kx, ky, kz) != 1) return 0;
  int n = 0;
  // c_i is a local end point after removing the pairs before it iff it has exactly one 1-cell besides
  // the one the path arrived by (and then no 2-cell: a 2-cell at c_i would hold two of its 1-cells).
  while (n < cap && other_edge(c, v, skip, dir)) {
    ++n;
    skip = {v[0] + dir[0], v[1] + dir[1], v[2] + dir[2]};  // the 1-cell c_i^1 ...
    v = {v[0] + 2 * dir[0], v[1] + 2 * dir[1], v[2] + 2 * dir[2]};  // ... and its other 0-cell
    if (v == std::array<int64_t, 3>{kx, ky, kz}) break;  // a cycle has no end point; defensive
  }
  return n;
}

namespace {

// Voxel weights for cell priorities, read from the priority volume when needed (no copy): priority -
// min + 1 at object voxels (>= 1), 0 at background.
template <class PV>
struct Weights {
  const VolumeU8& mask;
  const PV& pr;
  double lo;
  [[nodiscard]] float operator[](int64_t i) const {
    return mask[i] ? static_cast<float>(static_cast<double>(pr[i]) - lo + 1.0) : 0.0f;
  }
  [[nodiscard]] const Dims& dims() const { return mask.dims(); }
};

// The lowest priority at an object voxel; InputError on other dims or a NaN at an object voxel.
template <class PV>
double lowest_priority(const VolumeU8& mask, const PV& pr) {
  if (pr.dims() != mask.dims())
    throw InputError("priority: dims " + std::to_string(pr.nx()) + "x" + std::to_string(pr.ny()) + "x" +
                     std::to_string(pr.nz()) + " differ from the mask's " + std::to_string(mask.nx()) + "x" +
                     std::to_string(mask.ny()) + "x" + std::to_string(mask.nz()));
  double lo = INFINITY;
  for (int64_t i = 0; i < mask.size(); ++i)
    if (mask[i]) {
      const auto p = static_cast<double>(pr[i]);
      if (std::isnan(p)) throw InputError("priority: NaN at an object voxel (index " + std::to_string(i) + ")");
      lo = std::min(lo, p);
    }
  return lo;
}

// Bucket of the queue: cell priority, then the dimension of the (lower) cell, as one integer with the
// same order: priorities are >= 0 (or +inf), whose float bit patterns ascend with their values.
inline uint64_t bucket_key(float priority, int dim) {
  return (static_cast<uint64_t>(std::bit_cast<uint32_t>(priority)) << 2) | static_cast<uint64_t>(dim);
}

// Code: a cell's linear Khalimsky index, 32-bit where the Khalimsky box allows (queue memory).
template <class PV, class Code>
class Thinner {
public:
  Thinner(const Weights<PV>& weights, const GridCells* locked, GridCells& cells, int l)
      : w_(weights), locked_(locked), c_(cells), l_(l), kd_(cells.cell_dims()), lx_(cells.lattice_dims()[0]),
        ly_(cells.lattice_dims()[1]), queued_(static_cast<size_t>(cells.lattice_size()), 0) {}

  // Priority of cell k: the voxel priority interpolated at the cell's centre - the mean over the 2^(3-d)
  // voxels sharing it (the cell sits at their mean position, thesis §2.3.1), background voxels counting
  // as one below the lowest object priority. Boundary cells thus go before interior cells of the same
  // distance, and the cells shared by the most object voxels - junction centres - stay longest.
  [[nodiscard]] float priority(int64_t kx, int64_t ky, int64_t kz) const {
    int64_t lo[3], hi[3];
    const int64_t k[3] = {kx, ky, kz};
    int n = 1;
    for (int a = 0; a < 3; ++a) {
      lo[a] = (k[a] & 1) ? (k[a] - 1) / 2 : k[a] / 2 - 1;
      hi[a] = (k[a] & 1) ? (k[a] - 1) / 2 : k[a] / 2;
      n *= (k[a] & 1) ? 1 : 2;
      lo[a] = std::max<int64_t>(lo[a], 0);
      hi[a] = std::min<int64_t>(hi[a], w_.dims()[static_cast<size_t>(a)] - 1);
    }
    const int64_t nx = w_.dims()[0], nxy = nx * w_.dims()[1];
    double sum = 0;
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
      for (int64_t y = lo[1]; y <= hi[1]; ++y)
        for (int64_t x = lo[0]; x <= hi[0]; ++x) sum += w_[x + nx * y + nxy * z];
    return static_cast<float>(sum / n);
  }
  // GridCells::has, inlined here (the hot path: compilers do not always inline it into this class).
  [[gnu::always_inline]] inline bool has(const GridCells& g, int64_t kx, int64_t ky, int64_t kz) const {
    if (static_cast<uint64_t>(kx) >= static_cast<uint64_t>(kd_[0]) || static_cast<uint64_t>(ky) >= static_cast<uint64_t>(kd_[1]) ||
        static_cast<uint64_t>(kz) >= static_cast<uint64_t>(kd_[2]))
      return false;
    return (g.bytes_data()[static_cast<size_t>((kx >> 1) + lx_ * ((ky >> 1) + ly_ * (kz >> 1)))] >> GridCells::bit(kx, ky, kz)) & 1;
  }
  [[nodiscard]] Code code(int64_t kx, int64_t ky, int64_t kz) const {
    return static_cast<Code>(kx + kd_[0] * (ky + kd_[1] * kz));
  }
  [[nodiscard]] std::array<int64_t, 3> decode(Code c) const {
    const auto v = static_cast<int64_t>(c);
    return {v % kd_[0], (v / kd_[0]) % kd_[1], v / (kd_[0] * kd_[1])};
  }
  [[nodiscard]] bool is_queued(int64_t kx, int64_t ky, int64_t kz) const {
    return (queued_[static_cast<size_t>(c_.lattice_index(kx, ky, kz))] >> GridCells::bit(kx, ky, kz)) & 1;
  }
  void set_queued(int64_t kx, int64_t ky, int64_t kz, bool on) {
    uint8_t& b = queued_[static_cast<size_t>(c_.lattice_index(kx, ky, kz))];
    const auto m = static_cast<uint8_t>(1u << GridCells::bit(kx, ky, kz));
    b = on ? static_cast<uint8_t>(b | m) : static_cast<uint8_t>(b & ~m);
  }
  void push(int64_t kx, int64_t ky, int64_t kz) {
    const int dim = static_cast<int>((kx & 1) + (ky & 1) + (kz & 1));
    const uint64_t key = bucket_key(priority(kx, ky, kz), dim);
    auto [it, fresh] = q_.try_emplace(key);
    if (fresh) {
      heap_.push(key);
      if (!spare_.empty()) {
        it->second = std::move(spare_.back());
        spare_.pop_back();
      }
      peak_buckets_ = std::max(peak_buckets_, static_cast<int64_t>(q_.size()));
    }
    it->second.push_back(code(kx, ky, kz));
    set_queued(kx, ky, kz, true);
    peak_ = std::max(peak_, ++size_);
  }

  // The coface u of a deletable pair {k, u}, or false: k is present, has exactly one coface, neither is
  // locked, and a 0-cell is not a kept end point.
  bool deletable(const std::array<int64_t, 3>& k, std::array<int64_t, 3>& u) const {
    if (!has(c_, k[0], k[1], k[2])) return false;
    int n = 0;
    for (int a = 0; a < 3 && n < 2; ++a) {
      if (k[static_cast<size_t>(a)] & 1) continue;
      for (int s = -1; s <= 1; s += 2) {
        std::array<int64_t, 3> e = k;
        e[static_cast<size_t>(a)] += s;
        if (has(c_, e[0], e[1], e[2])) {
          u = e;
          ++n;
        }
      }
    }
    if (n != 1) return false;
    if (locked_ && (has(*locked_, k[0], k[1], k[2]) || has(*locked_, u[0], u[1], u[2]))) return false;
    return l_ == 0 || ((k[0] | k[1] | k[2]) & 1) || end_point_importance(c_, k[0], k[1], k[2], l_ + 1) <= l_;
  }

  // Queues the present, unqueued faces (all lower dimensions) of cell k.
  void queue_faces(const std::array<int64_t, 3>& k) {
    const int64_t r[3] = {k[0] & 1, k[1] & 1, k[2] & 1};
    for (int64_t dz = -r[2]; dz <= r[2]; ++dz)
      for (int64_t dy = -r[1]; dy <= r[1]; ++dy)
        for (int64_t dx = -r[0]; dx <= r[0]; ++dx) {
          if (!dx && !dy && !dz) continue;
          const int64_t x = k[0] + dx, y = k[1] + dy, z = k[2] + dz;
          if (has(c_, x, y, z) && !is_queued(x, y, z)) push(x, y, z);
        }
  }

  void run(int threads, const Interrupter& intr, GridCellThinningStatistics& st) {
    const int64_t total = st.cells_before[3] > 0 ? st.cells_before[3] : 1;
    int64_t last_report = 0;
    std::vector<uint8_t> cand;
    std::vector<Code> t;
    while (!heap_.empty()) {
      auto it = q_.find(heap_.top());
      heap_.pop();
      t.swap(it->second);
      q_.erase(it);
      ++st.buckets;
      size_ -= static_cast<int64_t>(t.size());
      const auto nt = static_cast<int64_t>(t.size());
      for (Code code : t) {
        const auto k = decode(code);
        set_queued(k[0], k[1], k[2], false);
      }
      // First, parallel check on the unchanged complex.
      cand.assign(t.size(), 0);
      auto check = [&](int64_t b, int64_t e) {
        std::array<int64_t, 3> u{};
        for (int64_t i = b; i < e; ++i) cand[static_cast<size_t>(i)] = deletable(decode(t[static_cast<size_t>(i)]), u) ? 1 : 0;
      };
      if (nt > 4096) parallel_for(0, nt, threads, check, 1024);
      else check(0, nt);
      st.tests += nt;
      // Sequential rechecking of the candidates.
      for (int64_t i = 0; i < nt; ++i) {
        if (!cand[static_cast<size_t>(i)]) continue;
        const auto k = decode(t[static_cast<size_t>(i)]);
        std::array<int64_t, 3> u{};
        ++st.tests;
        if (!deletable(k, u)) continue;
        c_.set(k[0], k[1], k[2], false);
        c_.set(u[0], u[1], u[2], false);
        ++st.removed_pairs;
        queue_faces(k);
        queue_faces(u);
      }
      if (st.removed_pairs - last_report > (int64_t{1} << 20)) {
        last_report = st.removed_pairs;
        // Every voxel's closed cube yields at most 4 pairs on average (8 cells per voxel).
        intr.check(std::min(0.99, 0.1 + 0.9 * static_cast<double>(st.removed_pairs) / (4.0 * static_cast<double>(total))));
      }
      // Small bucket vectors are reused for new buckets (no allocation churn); large ones are freed.
      t.clear();
      if (t.capacity() <= 1024 && spare_.size() < 256) spare_.push_back(std::move(t));
      t = std::vector<Code>();
    }
  }

  // Kept end points of the final skeleton.
  int64_t count_kept_end_points() const {
    if (l_ <= 0) return 0;
    int64_t n = 0;
    for (int64_t kz = 0; kz < kd_[2]; kz += 2)
      for (int64_t ky = 0; ky < kd_[1]; ky += 2)
        for (int64_t kx = 0; kx < kd_[0]; kx += 2)
          if (c_.has(kx, ky, kz) && coface_count(c_, kx, ky, kz) == 1 &&
              !(locked_ && locked_->has(kx, ky, kz)))
            ++n;
    return n;
  }

  // Queued flags, the queued codes and the buckets (hash node, key in the heap, vector header).
  [[nodiscard]] uint64_t working_bytes() const {
    uint64_t spare = 0;
    for (const auto& v : spare_) spare += v.capacity() * sizeof(Code);
    return queued_.size() + static_cast<uint64_t>(peak_) * sizeof(Code) + static_cast<uint64_t>(peak_buckets_) * 72 + spare;
  }

private:
  Weights<PV> w_;
  const GridCells* locked_;
  GridCells& c_;
  int l_;
  Dims kd_;
  int64_t lx_, ly_;
  std::vector<uint8_t> queued_;
  std::unordered_map<uint64_t, std::vector<Code>> q_;  // bucket key -> cells in push order
  std::priority_queue<uint64_t, std::vector<uint64_t>, std::greater<>> heap_;  // the keys of q_
  std::vector<std::vector<Code>> spare_;
  int64_t size_ = 0, peak_ = 0, peak_buckets_ = 0;
};

// Lines 2-9 of Algorithm 3 and the thinning loop, for one priority type and code width.
template <class PV, class Code>
void thin_with(const Weights<PV>& w, const GridCells* locked, GridCells& skel, const GridCellThinningOptions& o,
               GridCellThinningStatistics& st) {
  Thinner<PV, Code> th(w, locked, skel, o.end_point_length);
  // Line 2-9: every 2-cell incident with a background 3-cell (or the outside) is queued, raster order.
  // Raster order of the Khalimsky cells (kz, ky, kx ascending): kz = 2l + c, ky = 2j + b, kx = 2i + a; only
  // lattice bytes holding a 2-cell are looked at.
  const Dims ld = skel.lattice_dims();
  const auto& bytes = skel.bytes_data();
  for (int64_t l = 0; l < ld[2]; ++l)
    for (int c = 0; c < 2; ++c)
      for (int64_t j = 0; j < ld[1]; ++j)
        for (int b = 0; b < 2; ++b) {
          const uint8_t* row = bytes.data() + ld[0] * (j + ld[1] * l);
          for (int64_t i = 0; i < ld[0]; ++i) {
            if (!(row[i] & GridCells::kDimMask[2])) continue;
            for (int a = 0; a < 2; ++a) {
              const int bit = a | (b << 1) | (c << 2);
              if (GridCells::bit_dimension(bit) != 2 || !((row[i] >> bit) & 1)) continue;
              const int64_t kx = 2 * i + a, ky = 2 * j + b, kz = 2 * l + c;
              if (coface_count(skel, kx, ky, kz) < 2) th.push(kx, ky, kz);
            }
          }
        }
  o.interrupter.check(0.1);
  th.run(o.threads, o.interrupter, st);
  st.kept_end_points = th.count_kept_end_points();
  st.bytes = th.working_bytes();
}

}  // namespace

GridCellThinningResult thin_grid_cells(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                                       const GridCellThinningOptions& o, const GridCells* locked_cells_in) {
  if (o.end_point_length < 0) throw InputError("end_point_length: must be >= 0, got " + std::to_string(o.end_point_length));
  if (locked && locked->dims() != mask.dims()) throw InputError("locked: dims differ from the mask's");
  if (locked_cells_in && locked_cells_in->grid().dims != mask.dims()) {
    const Dims d = locked_cells_in->grid().dims;
    throw InputError("locked_cells: complex of " + std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" +
                     std::to_string(d[2]) + " voxels differs from the mask's " + std::to_string(mask.nx()) + "x" +
                     std::to_string(mask.ny()) + "x" + std::to_string(mask.nz()));
  }
  GridCellThinningResult r;
  auto& st = r.stats;
  const double lo = visit_volume(priority, "priority", [&](const auto& pr) { return lowest_priority(mask, pr); });
  for (int64_t i = 0; i < mask.size(); ++i) st.object_voxels += mask[i] ? 1 : 0;
  r.skeleton = GridCells::from_mask(mask, o.threads);
  st.cells_before = r.skeleton.counts();
  o.interrupter.check(0.05);
  GridCells locked_cells;
  if (locked) locked_cells = GridCells::from_mask(*locked, o.threads);
  if (locked_cells_in) {
    if (!locked) locked_cells = GridCells(mask.grid());
    auto& lb = locked_cells.bytes_data();
    const auto& ib = locked_cells_in->bytes_data();
    for (size_t i = 0; i < lb.size(); ++i) lb[i] = static_cast<uint8_t>(lb[i] | ib[i]);
  }
  const bool any_locked = locked || locked_cells_in;
  const bool narrow = static_cast<uint64_t>(r.skeleton.cell_dims()[0]) * static_cast<uint64_t>(r.skeleton.cell_dims()[1]) *
                          static_cast<uint64_t>(r.skeleton.cell_dims()[2]) <= std::numeric_limits<uint32_t>::max();
  visit_volume(priority, "priority", [&](const auto& pr) {
    using PV = std::decay_t<decltype(pr)>;
    const Weights<PV> w{mask, pr, lo};
    const GridCells* lk = any_locked ? &locked_cells : nullptr;
    if (narrow) thin_with<PV, uint32_t>(w, lk, r.skeleton, o, st);
    else thin_with<PV, uint64_t>(w, lk, r.skeleton, o, st);
  });
  st.cells_after = r.skeleton.counts();
  if (any_locked) {
    const auto& a = r.skeleton.bytes_data();
    const auto& b = locked_cells.bytes_data();
    for (size_t i = 0; i < a.size(); ++i) st.locked_cells += __builtin_popcount(static_cast<unsigned>(a[i] & b[i]));
  }
  st.bytes += any_locked ? locked_cells.bytes() : 0;
  o.interrupter.check(1.0);
  return r;
}

CellTopology cell_topology(const GridCells& c) {
  CellTopology t;
  t.euler = c.euler();
  const Dims kd = c.cell_dims();
  // Components: present cells joined to their present immediate faces (a complex is closed, so chains of
  // immediate faces connect every incidence).
  {
    const int64_t n = kd[0] * kd[1] * kd[2];
    UnionFind uf(n);
    auto id = [&](int64_t x, int64_t y, int64_t z) { return x + kd[0] * (y + kd[1] * z); };
    for (int64_t z = 0; z < kd[2]; ++z)
      for (int64_t y = 0; y < kd[1]; ++y)
        for (int64_t x = 0; x < kd[0]; ++x) {
          if (!c.has(x, y, z)) continue;
          if (c.has(x - 1, y, z)) uf.unite(id(x, y, z), id(x - 1, y, z));
          if (c.has(x, y - 1, z)) uf.unite(id(x, y, z), id(x, y - 1, z));
          if (c.has(x, y, z - 1)) uf.unite(id(x, y, z), id(x, y, z - 1));
        }
    for (int64_t z = 0; z < kd[2]; ++z)
      for (int64_t y = 0; y < kd[1]; ++y)
        for (int64_t x = 0; x < kd[0]; ++x)
          if (c.has(x, y, z) && uf.find(id(x, y, z)) == id(x, y, z)) ++t.components;
  }
  // Complement: absent open cells in a box padded by one cell, joined to absent immediate neighbours
  // (if a face of an absent cell is absent, every cell between them is absent too).
  {
    const int64_t px = kd[0] + 2, py = kd[1] + 2, pz = kd[2] + 2;
    UnionFind uf(px * py * pz);
    auto id = [&](int64_t x, int64_t y, int64_t z) { return (x + 1) + px * ((y + 1) + py * (z + 1)); };
    for (int64_t z = -1; z <= kd[2]; ++z)
      for (int64_t y = -1; y <= kd[1]; ++y)
        for (int64_t x = -1; x <= kd[0]; ++x) {
          if (c.has(x, y, z)) continue;
          if (x > -1 && !c.has(x - 1, y, z)) uf.unite(id(x, y, z), id(x - 1, y, z));
          if (y > -1 && !c.has(x, y - 1, z)) uf.unite(id(x, y, z), id(x, y - 1, z));
          if (z > -1 && !c.has(x, y, z - 1)) uf.unite(id(x, y, z), id(x, y, z - 1));
        }
    int64_t comps = 0;
    for (int64_t z = -1; z <= kd[2]; ++z)
      for (int64_t y = -1; y <= kd[1]; ++y)
        for (int64_t x = -1; x <= kd[0]; ++x)
          if (!c.has(x, y, z) && uf.find(id(x, y, z)) == id(x, y, z)) ++comps;
    t.cavities = comps - 1;
  }
  t.tunnels = t.components + t.cavities - t.euler;
  return t;
}

}  // namespace skel::thinning
