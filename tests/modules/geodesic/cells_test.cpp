// Geodesic plate skeleton in the grid cell model (geodesic/cells.hpp, thesis §2.3.2, fig. 4.5): Y_t of a
// slab is one sheet of 2-cells in its middle; the voxels owning a selected 2-cell are exactly the
// surface skeleton of geodesic.boundary_distance; Y_t is a sub-complex of X(P); and locked in grid cell
// thinning it makes a homotopic plate skeleton where plain thinning collapses the slab to a point.
#include <gtest/gtest.h>

#include <random>

#include "geodesic/cells.hpp"
#include "geodesic/geodesic.hpp"
#include "skel/error.hpp"
#include "thinning/grid_cell.hpp"

using namespace skel;
using namespace skel::geodesic;

namespace {

VolumeU8 random_blobs(Dims d, uint64_t seed, double fill) {
  std::mt19937_64 rng(seed);
  VolumeU8 v(d, 0);
  std::uniform_real_distribution<double> u(0, 1);
  for (auto& x : v) x = u(rng) < fill ? 1 : 0;
  VolumeU8 s(d, 0);
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) {
        int c = v(x, y, z);
        c += v.at_or(x - 1, y, z, 0) + v.at_or(x + 1, y, z, 0) + v.at_or(x, y - 1, z, 0) + v.at_or(x, y + 1, z, 0) +
             v.at_or(x, y, z - 1, 0) + v.at_or(x, y, z + 1, 0);
        s(x, y, z) = c >= 4 ? 1 : 0;
      }
  return s;
}

// A slab of `thickness` voxels along z in the middle, `margin` voxels from the x and y borders.
VolumeU8 slab(Dims d, int64_t thickness, int64_t margin) {
  VolumeU8 v(d, 0);
  const int64_t z0 = d[2] / 2 - thickness / 2;
  for (int64_t z = z0; z < z0 + thickness; ++z)
    for (int64_t y = margin; y < d[1] - margin; ++y)
      for (int64_t x = margin; x < d[0] - margin; ++x) v(x, y, z) = 1;
  return v;
}

// Whether every cell of `a` is in `b`.
bool subcomplex(const GridCells& a, const GridCells& b) {
  const auto& x = a.bytes_data();
  const auto& y = b.bytes_data();
  for (size_t i = 0; i < x.size(); ++i)
    if (x[i] & ~y[i]) return false;
  return true;
}

}  // namespace

TEST(PlateCells, SlabGivesOneSheetInTheMiddle) {
  const VolumeU8 m = slab(Dims{48, 48, 16}, 4, 4);  // voxels z = 6..9: the middle is the plane kz = 16
  PlateCellsOptions o;
  o.threshold = 10;
  const PlateCellsResult r = plate_cells(m, o);
  const GridCells& y = r.cells;
  EXPECT_TRUE(subcomplex(y, GridCells::from_mask(m)));
  const auto c = y.counts();
  EXPECT_EQ(c[3], 0);
  EXPECT_GT(c[2], 20 * 20);
  EXPECT_EQ(r.stats.selected_faces, c[2]);
  // Away from the rim every voxel column has its middle 2-cell, and no other 2-cell is selected there.
  for (int64_t ky = 2 * 14; ky <= 2 * 34; ++ky)
    for (int64_t kx = 2 * 14; kx <= 2 * 34; ++kx)
      for (int64_t kz = 0; kz <= 32; ++kz) {
        const bool want = kz == 16 && (kx & 1) && (ky & 1);
        if (GridCells::bit_dimension(GridCells::bit(kx, ky, kz)) != 2) continue;
        EXPECT_EQ(y.has(kx, ky, kz), want) << kx << " " << ky << " " << kz;
      }
  // One sheet: a disk (connected, no tunnel, no cavity).
  const auto t = thinning::cell_topology(y);
  EXPECT_EQ(t.components, 1);
  EXPECT_EQ(t.euler, 1);
  EXPECT_EQ(t.cavities, 0);
  // A higher threshold selects a smaller part of the same sheet.
  o.threshold = 20;
  const PlateCellsResult r20 = plate_cells(m, o);
  EXPECT_TRUE(subcomplex(r20.cells, y));
  EXPECT_LT(r20.cells.counts()[2], c[2]);
  EXPECT_GT(r20.cells.counts()[2], 0);
}

TEST(PlateCells, OwnersAreTheSurfaceSkeletonOnRandomObjects) {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const VolumeU8 m = random_blobs(Dims{30, 26, 22}, seed, 0.5);
    for (int64_t t : {3, 6, 12}) {
      PlateCellsOptions o;
      o.threshold = t;
      o.threads = 1;
      const PlateCellsResult r = plate_cells(m, o);
      Options g;
      g.threshold = t;
      const Result b = boundary_distance(m, g);
      int64_t selected = 0;
      for (int64_t i = 0; i < m.size(); ++i) {
        ASSERT_EQ(r.faces[i] != 0, b.surface_skeleton[i] != 0) << "seed " << seed << " t " << t << " voxel " << i;
        if (!m[i]) {
          ASSERT_EQ(r.faces[i], 0);
        }
        selected += __builtin_popcount(r.faces[i]);
      }
      EXPECT_EQ(selected, r.stats.selected_faces);
      EXPECT_TRUE(subcomplex(r.cells, GridCells::from_mask(m)));
      EXPECT_EQ(r.cells.counts()[3], 0);
      o.threads = 4;
      const PlateCellsResult r4 = plate_cells(m, o);
      EXPECT_TRUE(r4.cells == r.cells);
      EXPECT_TRUE(r4.faces == r.faces);
    }
  }
}

TEST(PlateCells, LockedInGridCellThinningKeepsTheSheet) {
  const VolumeU8 m = slab(Dims{40, 40, 16}, 4, 4);
  PlateCellsOptions o;
  o.threshold = 10;
  const PlateCellsResult y = plate_cells(m, o);
  VolumeF32 distance(m.grid(), 0.0f);
  for (int64_t z = 0; z < 16; ++z)
    for (int64_t yy = 0; yy < 40; ++yy)
      for (int64_t x = 0; x < 40; ++x)
        if (m(x, yy, z)) distance(x, yy, z) = static_cast<float>(std::min<int64_t>(std::min(z - 5, 10 - z), 100));
  thinning::GridCellThinningOptions to;
  to.end_point_length = 0;
  // Plain thinning retracts the slab to one 0-cell.
  const auto plain = thinning::thin_grid_cells(m, distance, nullptr, to);
  EXPECT_EQ(plain.skeleton.counts(), (std::array<int64_t, 4>{1, 0, 0, 0}));
  // With Y_t locked: Y_t stays, nothing else (a disk is already a deformation retract of the slab).
  const auto locked = thinning::thin_grid_cells(m, distance, nullptr, to, &y.cells);
  EXPECT_TRUE(subcomplex(y.cells, locked.skeleton));
  EXPECT_TRUE(locked.skeleton == y.cells);
  EXPECT_EQ(locked.stats.locked_cells, y.cells.counts()[0] + y.cells.counts()[1] + y.cells.counts()[2]);
  // A complex of another size is refused, naming the input.
  const GridCells other(Grid{Dims{8, 8, 8}});
  try {
    (void)thinning::thin_grid_cells(m, distance, nullptr, to, &other);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("locked_cells"), std::string::npos) << e.what();
  }
}

TEST(PlateCells, EmptyAndInvalid) {
  const VolumeU8 empty(Dims{8, 8, 8}, 0);
  const PlateCellsResult r = plate_cells(empty);
  EXPECT_EQ(r.cells.counts(), (std::array<int64_t, 4>{0, 0, 0, 0}));
  PlateCellsOptions o;
  o.threshold = 0;
  EXPECT_THROW(plate_cells(empty, o), InputError);
}
