// Grid cell complexes and grid cell thinning (thesis §2.3.1, Proposition 1, Algorithm 3): the complex of
// a voxel object has its topology numbers; thinning keeps them, leaves no simple pair but kept end
// points, and retracts the configurations of figs. 2.21 and 2.23 that lock voxel thinning.
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "analysis/topology.hpp"
#include "shapes.hpp"
#include "skel/grid_cells.hpp"
#include "thinning/grid_cell.hpp"
#include "thinning/local_topology.hpp"
#include "thinning/thinning.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

namespace skel {
namespace {

GridCellThinningOptions gopts(int l, int threads = 1) {
  GridCellThinningOptions o;
  o.end_point_length = l;
  o.threads = threads;
  return o;
}

VolumeU8 random_voxels(int64_t n, uint32_t seed, double p) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution b(p);
  VolumeU8 m(Dims{n, n, n}, 0);
  for (int64_t z = 1; z < n - 1; ++z)
    for (int64_t y = 1; y < n - 1; ++y)
      for (int64_t x = 1; x < n - 1; ++x) m(x, y, z) = b(rng) ? 1 : 0;
  return m;
}

CellTopology voxel_topology(const VolumeU8& m) {
  const TopologyNumbers t = topology(m);
  return CellTopology{t.components, t.cavities, t.euler, t.tunnels};
}

// Degree of each 0-cell: its number of 1-cells.
std::vector<int> vertex_degrees(const GridCells& c) {
  std::vector<int> deg;
  const Dims kd = c.cell_dims();
  for (int64_t z = 0; z < kd[2]; z += 2)
    for (int64_t y = 0; y < kd[1]; y += 2)
      for (int64_t x = 0; x < kd[0]; x += 2)
        if (c.has(x, y, z)) deg.push_back(coface_count(c, x, y, z));
  return deg;
}

// Simple pairs left whose lower cell is not a kept end point (importance > l) and not locked.
int64_t free_pairs_left(const GridCells& c, int l, const GridCells* locked = nullptr) {
  int64_t n = 0;
  const Dims kd = c.cell_dims();
  for (int64_t z = 0; z < kd[2]; ++z)
    for (int64_t y = 0; y < kd[1]; ++y)
      for (int64_t x = 0; x < kd[0]; ++x) {
        if (!has_free_pair(c, x, y, z)) continue;
        if (locked && locked->has(x, y, z)) continue;
        const bool vertex = !((x | y | z) & 1);
        if (vertex && l > 0 && end_point_importance(c, x, y, z, l + 1) > l) continue;
        if (locked) {  // the coface may be locked
          bool lockedu = false;
          for (int a = 0; a < 3; ++a)
            for (int s = -1; s <= 1; s += 2) {
              int64_t u[3] = {x, y, z};
              if (u[a] & 1) continue;
              u[a] += s;
              if (c.has(u[0], u[1], u[2]) && locked->has(u[0], u[1], u[2])) lockedu = true;
            }
          if (lockedu) continue;
        }
        ++n;
      }
  return n;
}

TEST(GridCells, OneVoxelIsAClosedCube) {
  VolumeU8 m(Dims{3, 3, 3}, 0);
  m(1, 1, 1) = 1;
  const GridCells c = GridCells::from_mask(m);
  EXPECT_EQ(c.counts(), (std::array<int64_t, 4>{8, 12, 6, 1}));
  EXPECT_EQ(c.euler(), 1);
  EXPECT_EQ(c.lattice_size(), 4 * 4 * 4);
  EXPECT_EQ(c.bytes(), 64u);
  EXPECT_TRUE(c.has(3, 3, 3));
  EXPECT_TRUE(c.has(2, 2, 2));
  EXPECT_TRUE(c.has(4, 3, 2));
  EXPECT_FALSE(c.has(5, 3, 3));
  EXPECT_FALSE(c.has(-1, 3, 3));
  EXPECT_EQ(c.type_id(), "cells");
  EXPECT_NE(c.describe().find("euler 1"), std::string::npos) << c.describe();
  // Two face neighbours share a 2-cell: 12 0-cells, 20 1-cells, 11 2-cells, 2 3-cells.
  m(2, 1, 1) = 1;
  EXPECT_EQ(GridCells::from_mask(m).counts(), (std::array<int64_t, 4>{12, 20, 11, 2}));
}

// χ from cell counts equals the (26, 6) voxel χ of analysis.topology, and components and cavities of
// the complex equal the voxel numbers, on random objects (noise and blobs, touching the array faces).
TEST(GridCells, EulerAndTopologyMatchVoxelTopology) {
  for (uint32_t seed = 0; seed < 30; ++seed) {
    const VolumeU8 m = seed % 2 ? random_voxels(9, seed, 0.35 + 0.01 * seed) : test::random_blobs(14, seed, 0.5, 1);
    const GridCells c = GridCells::from_mask(m, seed % 3);
    EXPECT_EQ(c.euler(), topology(m).euler) << seed;
    EXPECT_EQ(cell_topology(c), voxel_topology(m)) << seed;
  }
  // Objects touching the array border (no background margin).
  for (uint32_t seed = 0; seed < 10; ++seed) {
    std::mt19937 rng(seed);
    VolumeU8 m(Dims{6, 5, 7}, 0);
    for (int64_t i = 0; i < m.size(); ++i) m[i] = rng() % 3 == 0 ? 0 : 1;
    EXPECT_EQ(GridCells::from_mask(m).euler(), topology(m).euler) << seed;
    EXPECT_EQ(cell_topology(GridCells::from_mask(m)), voxel_topology(m)) << seed;
  }
}

TEST(GridCells, FromMaskIsIndependentOfThreads) {
  const VolumeU8 m = test::random_blobs(20, 7, 0.5, 1);
  EXPECT_TRUE(GridCells::from_mask(m, 1) == GridCells::from_mask(m, 4));
}

// Proposition 1: removing simple pairs keeps components, cavities, tunnels and χ; the result is thin
// (no simple pair left except kept end points) and has no 3-cell unless locked.
TEST(GridCellThinning, KeepsHomotopyOnRandomObjects) {
  for (uint32_t seed = 0; seed < 40; ++seed) {
    const VolumeU8 m = seed % 2 ? random_voxels(10, seed, 0.45) : test::random_blobs(16, seed, 0.49, 1);
    const VolumeU32 d = test::chamfer345(m);
    const CellTopology before = voxel_topology(m);
    for (int l : {0, 3}) {
      const GridCellThinningResult r = thin_grid_cells(m, d, nullptr, gopts(l));
      EXPECT_EQ(cell_topology(r.skeleton), before) << "seed " << seed << " l " << l;
      EXPECT_EQ(r.stats.cells_after, r.skeleton.counts());
      EXPECT_EQ(r.stats.cells_after[3], 0) << seed;
      EXPECT_EQ(free_pairs_left(r.skeleton, l), 0) << "seed " << seed << " l " << l;
      // Every removal is one pair: the cell count drops by exactly 2 per removed pair.
      int64_t before_cells = 0, after_cells = 0;
      for (size_t k = 0; k < 4; ++k) before_cells += r.stats.cells_before[k], after_cells += r.stats.cells_after[k];
      EXPECT_EQ(before_cells - after_cells, 2 * r.stats.removed_pairs);
      // The skeleton is a sub-complex of X(P).
      const GridCells x = GridCells::from_mask(m);
      for (size_t i = 0; i < x.bytes_data().size(); ++i)
        ASSERT_EQ(r.skeleton.bytes_data()[i] & ~x.bytes_data()[i], 0);
      if (l == 0 && before.cavities == 0 && before.tunnels == 0 && before.components == 1) {
        EXPECT_EQ(r.skeleton.counts(), (std::array<int64_t, 4>{1, 0, 0, 0})) << seed;  // a point
      }
    }
  }
}

TEST(GridCellThinning, ShapesRetractToTheirSkeletons) {
  // A solid ball retracts to one 0-cell; a torus to one loop of 1-cells (every 0-cell of degree 2).
  VolumeU8 ball(Dims{15, 15, 15}, 0);
  test::add_ball(ball, 7, 7, 7, 5.5);
  EXPECT_EQ(thin_grid_cells(ball, test::chamfer345(ball), nullptr, gopts(0)).skeleton.counts(),
            (std::array<int64_t, 4>{1, 0, 0, 0}));
  const VolumeU8 t = test::torus(24, 7, 3);
  const GridCells s = thin_grid_cells(t, test::chamfer345(t), nullptr, gopts(0)).skeleton;
  const auto c = s.counts();
  EXPECT_EQ(c[0], c[1]);
  EXPECT_EQ(c[2], 0);
  for (int deg : vertex_degrees(s)) EXPECT_EQ(deg, 2);
  // A hollow ball (a cavity) keeps a closed surface of 2-cells: χ = 2.
  VolumeU8 shell(Dims{17, 17, 17}, 0);
  test::add_ball(shell, 8, 8, 8, 7.0);
  test::add_ball(shell, 8, 8, 8, 3.5, 0);
  const GridCells sh = thin_grid_cells(shell, test::chamfer345(shell), nullptr, gopts(0)).skeleton;
  EXPECT_EQ(cell_topology(sh), (CellTopology{1, 1, 2, 0}));
  EXPECT_GT(sh.counts()[2], 0);
  EXPECT_EQ(sh.counts()[3], 0);
}

// Fig. 4.2: end points of side branches are kept by their (0,1)-cell path length; l = 0 keeps none.
TEST(GridCellThinning, EndPointLengthKeepsBranches) {
  const VolumeU8 m = test::rods_clean();
  const VolumeU32 d = test::chamfer345(m);
  auto ends = [&](int l) {
    const GridCells s = thin_grid_cells(m, d, nullptr, gopts(l, 2)).skeleton;
    int n = 0;
    for (int deg : vertex_degrees(s)) n += deg == 1;
    EXPECT_EQ(cell_topology(s), voxel_topology(m)) << l;
    return n;
  };
  EXPECT_EQ(ends(0), 0);   // the loop alone
  EXPECT_EQ(ends(6), 4);   // the four free branches of the phantom
}

TEST(GridCellThinning, DeterministicForAnyThreadCount) {
  const VolumeU8 m = test::random_blobs(40, 11, 0.49, 2);
  const VolumeU32 d = test::chamfer345(m);
  const GridCells a = thin_grid_cells(m, d, nullptr, gopts(4, 1)).skeleton;
  const GridCells b = thin_grid_cells(m, d, nullptr, gopts(4, 4)).skeleton;
  EXPECT_TRUE(a == b);
}

// Working memory: the queued flags (1 byte per voxel corner), 4 bytes per queued cell (32-bit codes
// while the Khalimsky box has < 2^32 cells) and the buckets; priorities are read from the input, not
// copied (was 4 bytes per voxel of float weights plus 8 bytes per queued cell: > 5 bytes per voxel).
// On rods (random blobs are all boundary: nearly every cell is queued at once, 16 bytes per voxel).
TEST(GridCellThinning, WorkingMemoryBelowFourBytesPerVoxel) {
  const VolumeU8 m = test::rods_clean();
  const VolumeU32 d = test::chamfer345(m);
  const auto r = thin_grid_cells(m, d, nullptr, gopts(4, 2));
  EXPECT_GT(r.stats.removed_pairs, 10000);
  EXPECT_GT(r.stats.bytes, static_cast<uint64_t>(m.size()));  // at least the queued flags
  EXPECT_LT(static_cast<double>(r.stats.bytes) / static_cast<double>(m.size()), 4.0) << r.stats.bytes;
}

TEST(GridCellThinning, LockedVoxelsKeepTheirCells) {
  for (uint32_t seed = 0; seed < 8; ++seed) {
    const VolumeU8 m = test::random_blobs(16, seed + 100, 0.48, 1);
    VolumeU8 locked(m.dims(), 0);
    std::mt19937 rng(seed);
    for (int64_t i = 0; i < m.size(); ++i) locked[i] = m[i] && rng() % 40 == 0 ? 1 : 0;
    const GridCellThinningResult r = thin_grid_cells(m, test::chamfer345(m), &locked, gopts(0));
    const GridCells lc = GridCells::from_mask(locked);
    for (size_t i = 0; i < lc.bytes_data().size(); ++i)
      ASSERT_EQ(r.skeleton.bytes_data()[i] & lc.bytes_data()[i], lc.bytes_data()[i]);
    EXPECT_EQ(cell_topology(r.skeleton), voxel_topology(m));
    EXPECT_EQ(free_pairs_left(r.skeleton, 0, &lc), 0);
    int64_t n = 0;
    for (uint8_t b : lc.bytes_data()) n += __builtin_popcount(b);
    EXPECT_EQ(r.stats.locked_cells, n);
  }
}

// Thesis fig. 2.23 (of this kind): Bing's house with two rooms, contractible, locked for voxel thinning
// (a thick contractible blob remains). Grid cell thinning goes further - no 3-cell remains, the result is
// a thin 2-complex (no simple pair at all) with the object's topology - but it cannot reach a point: the
// medial surface it retracts to is Bing's house itself, the classic contractible 2-complex without a
// free face, which no sequence of simple pairs collapses.
TEST(GridCellThinning, BingsHouseRetractsToAThinComplex) {
  for (int w : {1, 2}) {
    const VolumeU8 m = test::bing_house(w);
    const VolumeU32 d = test::chamfer345(m);
    ThinningOptions vo;
    vo.end_point_length = 0;
    const ThinningResult voxel = thin_doht(m, d, nullptr, vo);
    EXPECT_EQ(voxel.stats.stuck_components, 1);
    EXPECT_GT(voxel.stats.interior_voxels + voxel.stats.stuck_voxels, 1);
    for (int l : {0, 6}) {
      const GridCellThinningResult r = thin_grid_cells(m, d, nullptr, gopts(l));
      EXPECT_EQ(cell_topology(r.skeleton), (CellTopology{1, 0, 1, 0})) << "w " << w << " l " << l;
      EXPECT_EQ(r.skeleton.counts()[3], 0);
      EXPECT_EQ(free_pairs_left(r.skeleton, 0), 0) << "no free face at all: Bing's house";
      // Every 1-cell bounds at least two 2-cells (no free edge) and the 2-cells form the walls.
      EXPECT_GT(r.skeleton.counts()[2], 0);
    }
  }
}

// Thesis fig. 2.21/2.22: two rings of 2x2 (or 1x2) tubes meeting at a junction block, ring A leaving it
// towards -x and +y, ring B towards +x and -y. Voxel thinning leaves a cluster of junction voxels of
// unclear interpretation; the grid cell skeleton is two loops of 1-cells joined at one 0-cell of degree
// 4 at the block's centre.
VolumeU8 two_rings(int thickness) {
  VolumeU8 m(Dims{22, 22, 4}, 0);
  auto box = [&](int64_t x0, int64_t x1, int64_t y0, int64_t y1) {
    for (int64_t z = 1; z <= thickness; ++z)
      for (int64_t y = y0; y <= y1; ++y)
        for (int64_t x = x0; x <= x1; ++x) m(x, y, z) = 1;
  };
  box(2, 11, 10, 11), box(10, 11, 10, 19), box(2, 3, 10, 19), box(2, 11, 18, 19);  // ring A
  box(10, 19, 10, 11), box(10, 11, 2, 11), box(18, 19, 2, 11), box(10, 19, 2, 3);  // ring B
  return m;
}

TEST(GridCellThinning, TwoRingsMeetAtOneNodeOfDegreeFour) {
  for (int t : {1, 2}) {
    const VolumeU8 m = two_rings(t);
    EXPECT_EQ(voxel_topology(m), (CellTopology{1, 0, -1, 2}));
    const VolumeU32 d = test::chamfer345(m);
    ThinningOptions vo;
    vo.end_point_length = 0;
    const ThinningResult voxel = thin_doht(m, d, nullptr, vo);
    int junction_voxels = 0;
    for (int64_t z = 0; z < m.nz(); ++z)
      for (int64_t y = 0; y < m.ny(); ++y)
        for (int64_t x = 0; x < m.nx(); ++x)
          if (voxel.skeleton(x, y, z) && __builtin_popcount(neighbourhood_at(voxel.skeleton, x, y, z)) >= 3) ++junction_voxels;
    EXPECT_GT(junction_voxels, 1) << "voxel thinning: a cluster of junction voxels";
    for (int l : {0, 6}) {
      const GridCells s = thin_grid_cells(m, d, nullptr, gopts(l)).skeleton;
      EXPECT_EQ(cell_topology(s), (CellTopology{1, 0, -1, 2}));
      const auto c = s.counts();
      EXPECT_EQ(c[2], 0);
      EXPECT_EQ(c[3], 0);
      const std::vector<int> deg = vertex_degrees(s);
      EXPECT_EQ(std::count(deg.begin(), deg.end(), 4), 1) << "t " << t << " l " << l;
      EXPECT_EQ(std::count(deg.begin(), deg.end(), 2), static_cast<long>(deg.size()) - 1) << "t " << t << " l " << l;
      EXPECT_EQ(coface_count(s, 22, 22, 4), 4) << "the node lies on the block's central axis";
    }
  }
}

TEST(GridCellThinning, RejectsBadInputs) {
  VolumeU8 m(Dims{4, 4, 4}, 1);
  VolumeU32 d(Dims{4, 4, 5}, 1);
  EXPECT_THROW(thin_grid_cells(m, d), InputError);
  VolumeF32 nan(Dims{4, 4, 4}, std::nanf(""));
  EXPECT_THROW(thin_grid_cells(m, nan), InputError);
  VolumeU8 locked(Dims{3, 4, 4}, 0);
  EXPECT_THROW(thin_grid_cells(m, VolumeU32(Dims{4, 4, 4}, 1), &locked), InputError);
}

}  // namespace
}  // namespace skel
