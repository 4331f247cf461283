// Block-wise thinning (thesis ch. 5.2, Algorithm 5) against the object and the in-memory skeleton:
// equal topology (components, cavities, Euler characteristic, tunnels), no simple non-end voxel
// left, skeleton inside the mask, for odd block shapes, objects crossing block corners, loops
// through block edges and tiny blocks; the voxels differing from the in-memory skeleton are counted
// and must lie near block faces.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <string>

#include "analysis/topology.hpp"
#include "distance/distance.hpp"
#include "io/hdf5_volume.hpp"
#include "shapes.hpp"
#include "skel/out_of_core.hpp"
#include "synthetic/network.hpp"
#include "thinning/local_topology.hpp"
#include "thinning/thinning.hpp"
#include "thinning/thinning_blocks.hpp"

namespace skel::thinning {
namespace {

namespace fs = std::filesystem;
using analysis::TopologyNumbers;
using analysis::topology;

std::shared_ptr<ChunkedVolume> scratch(const Grid& g) {
  static int counter = 0;  // one file per process and volume: ctest runs tests in parallel processes
  const fs::path f = fs::path(SKEL_BINARY_DIR) / "tests" /
                     ("thinning_blocks_" + std::to_string(::getpid()) + "_" + std::to_string(++counter) + ".h5");
  return std::make_shared<ChunkedVolume>(g, type_ids::volume_u8, io::create_scratch_store(f, type_ids::volume_u8, g, {8, 8, 8}));
}

BlockPlan user_blocks(const Dims& block, uint64_t budget = uint64_t{1} << 30) {
  BlockPlan p;
  p.memory_budget = budget;
  p.block = block;
  p.block_from_user = true;
  return p;
}

BlockThinningOptions options(int l, ThinningVariant v = ThinningVariant::Smooth) {
  BlockThinningOptions o;
  o.end_point_length = l;
  o.variant = v;
  o.threads = 1;
  return o;
}

struct BlockRun {
  VolumeU8 skeleton;
  BlockThinningResult result;
};

BlockRun run_blocks(const VolumeU8& mask, const DataObject& priority, const BlockPlan& plan, const BlockThinningOptions& o,
               const VolumeU8* locked = nullptr) {
  auto out = scratch(mask.grid());
  BlockRun r;
  r.result = thin_doht_blocks(mask, priority, locked, *out, o, plan);
  r.skeleton = out->read<uint8_t>({0, 0, 0}, mask.dims());
  return r;
}

// Simple voxels of the skeleton that are not end points (exactly one 26-neighbour) and not locked.
int64_t simple_non_end(const VolumeU8& s, const VolumeU8* locked = nullptr) {
  int64_t n = 0;
  for (int64_t z = 0; z < s.nz(); ++z)
    for (int64_t y = 0; y < s.ny(); ++y)
      for (int64_t x = 0; x < s.nx(); ++x) {
        if (!s(x, y, z) || (locked && (*locked)(x, y, z))) continue;
        const uint32_t nb = neighbourhood_at(s, x, y, z);
        if (__builtin_popcount(nb) != 1 && is_simple(nb)) ++n;
      }
  return n;
}

struct Difference {
  int64_t voxels = 0;     // voxels where the block-wise and in-memory skeletons differ
  int64_t far = 0;        // of those, farther than `near` voxels from every inner block face
  int64_t displaced = 0;  // of those, with no voxel of the other skeleton among their 26 neighbours
  int64_t far_displaced = 0;  // both
  int64_t max_shift = 0;  // largest chessboard distance of a differing voxel to the other skeleton
  int64_t in_core = 0, blocked = 0;  // skeleton sizes
};

// Chessboard distance from (x, y, z) to the nearest voxel of `s` (searched up to 16).
int64_t shift_to(const VolumeU8& s, int64_t x, int64_t y, int64_t z) {
  for (int64_t r = 1; r <= 16; ++r)
    for (int64_t dz = -r; dz <= r; ++dz)
      for (int64_t dy = -r; dy <= r; ++dy)
        for (int64_t dx = -r; dx <= r; ++dx) {
          if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != r) continue;
          const int64_t a = x + dx, b = y + dy, c = z + dz;
          if (a < 0 || b < 0 || c < 0 || a >= s.nx() || b >= s.ny() || c >= s.nz()) continue;
          if (s(a, b, c)) return r;
        }
  return 17;
}

// Distance in voxels from x to the nearest inner block face (a plane between two blocks).
int64_t face_distance(const Dims& p, const Dims& dims, const Dims& block) {
  int64_t best = INT64_MAX;
  for (int a = 0; a < 3; ++a)
    for (int64_t f = block[a]; f < dims[a]; f += block[a]) best = std::min(best, std::min(std::abs(p[a] - f), std::abs(p[a] + 1 - f)));
  return best;
}

Difference compare(const VolumeU8& in_core, const VolumeU8& blocked, const Dims& block, int64_t near) {
  Difference d;
  for (int64_t z = 0; z < in_core.nz(); ++z)
    for (int64_t y = 0; y < in_core.ny(); ++y)
      for (int64_t x = 0; x < in_core.nx(); ++x) {
        d.in_core += in_core(x, y, z) != 0;
        d.blocked += blocked(x, y, z) != 0;
        if ((in_core(x, y, z) != 0) == (blocked(x, y, z) != 0)) continue;
        ++d.voxels;
        const bool far = face_distance({x, y, z}, in_core.dims(), block) > near;
        const int64_t shift = shift_to(in_core(x, y, z) ? blocked : in_core, x, y, z);
        d.far += far;
        d.displaced += shift > 1;
        d.far_displaced += far && shift > 1;
        d.max_shift = std::max(d.max_shift, shift);
      }
  return d;
}

// The invariants of Algorithm 5, and the difference to the in-memory skeleton printed and returned.
Difference expect_thinned(const VolumeU8& mask, const DataObject& priority, const Dims& block,
                          const BlockThinningOptions& o, const std::string& what) {
  const BlockRun r = run_blocks(mask, priority, user_blocks(block), o);
  const TopologyNumbers tm = topology(mask), ts = topology(r.skeleton);
  EXPECT_EQ(ts.components, tm.components) << what;
  EXPECT_EQ(ts.cavities, tm.cavities) << what;
  EXPECT_EQ(ts.euler, tm.euler) << what;
  EXPECT_EQ(ts.tunnels, tm.tunnels) << what;
  EXPECT_EQ(simple_non_end(r.skeleton), 0) << what;
  int64_t outside = 0, voxels = 0;
  for (int64_t i = 0; i < mask.size(); ++i) {
    outside += r.skeleton[i] && !mask[i];
    voxels += r.skeleton[i] != 0;
  }
  EXPECT_EQ(outside, 0) << what;
  EXPECT_EQ(voxels, r.result.stats.skeleton_voxels) << what;
  EXPECT_EQ(tm.object_voxels, r.result.stats.object_voxels) << what;
  if (tm.object_voxels > 100) {
    EXPECT_LT(voxels, tm.object_voxels / 3) << what;
  }
  const ThinningResult in_core = thin_doht(mask, priority, nullptr, o);
  const Difference d = compare(in_core.skeleton, r.skeleton, block, r.result.halo);
  std::printf("%s: halo %lld, %lld blocks, %lld passes, %lld runs; skeleton %lld voxels in memory, %lld "
              "block-wise; %lld differ (%lld farther than the halo from a block face), %lld not next to the other "
              "skeleton (%lld of them far from faces), largest shift %lld\n",
              what.c_str(), static_cast<long long>(r.result.halo), static_cast<long long>(r.result.blocks),
              static_cast<long long>(r.result.passes), static_cast<long long>(r.result.block_runs),
              static_cast<long long>(d.in_core), static_cast<long long>(d.blocked), static_cast<long long>(d.voxels),
              static_cast<long long>(d.far), static_cast<long long>(d.displaced), static_cast<long long>(d.far_displaced),
              static_cast<long long>(d.max_shift));
  return d;
}

TEST(ThinningBlocks, RandomBlobsOddBlocksKeepTopology) {
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    const VolumeU8 m = test::random_blobs(30, seed, 0.47 + 0.01 * (seed % 4), 2);
    const VolumeU32 d = test::chamfer345(m);
    for (const Dims& b : {Dims{7, 9, 11}, Dims{13, 5, 17}, Dims{16, 16, 16}})
      for (int l : {0, 2})
        for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
          const std::string what = "blobs seed " + std::to_string(seed) + " block " + std::to_string(b[0]) + "x" +
                                   std::to_string(b[1]) + "x" + std::to_string(b[2]) + " l " + std::to_string(l) +
                                   (v == ThinningVariant::Basic ? " basic" : " smooth");
          // Noisy blobs are mostly plates and tie-rich: their curve skeleton is not unique, and the
          // in-level order restarting per block moves it by a few voxels.
          const Difference diff = expect_thinned(m, d, b, options(l, v), what);
          EXPECT_LE(diff.max_shift, 4) << what;
        }
  }
}

TEST(ThinningBlocks, TubesThroughBlockCornersAndLoopsThroughBlockEdges) {
  // Blocks of 12: the capsules run through the corner (12, 12, 12) shared by eight blocks; the
  // torus crosses block edges (x = 24, y = 24 lines) four times and keeps its tunnel.
  VolumeU8 m(Dims{48, 48, 48}, 0);
  test::add_capsule(m, {3, 3, 3}, {20, 20, 20}, 2.6);
  test::add_capsule(m, {12, 2, 12}, {12, 22, 12}, 2.2);
  test::add_capsule(m, {12, 12, 2}, {30, 12, 30}, 3.1);
  const VolumeU8 torus = test::torus(48, 13.5, 3.4);
  for (int64_t i = 0; i < m.size(); ++i) m[i] = m[i] || torus[i];
  const VolumeU32 d = test::chamfer345(m);
  const TopologyNumbers tm = topology(m);
  ASSERT_GE(tm.tunnels, 1);
  for (const Dims& b : {Dims{12, 12, 12}, Dims{24, 24, 24}, Dims{11, 13, 12}})
    for (int l : {0, 2}) {
      const std::string what = "tubes and torus block " + std::to_string(b[0]) + "x" + std::to_string(b[1]) + "x" +
                               std::to_string(b[2]) + " l " + std::to_string(l);
      const Difference diff = expect_thinned(m, d, b, options(l), what);
      EXPECT_EQ(diff.far_displaced, 0) << what;
      EXPECT_LE(diff.max_shift, 4) << what;
    }
}

TEST(ThinningBlocks, EuclideanPriorityOnSyntheticNetworks) {
  for (const char* shape : {"rods", "plates", "mixed"}) {
    synthetic::NetworkOptions no;
    no.shape = parse_enum<synthetic::Shape>(shape, "shape");
    no.size = {48, 48, 48};
    no.seed = 5;
    no.threads = 1;
    const VolumeU8 m = synthetic::make_network(no).mask;
    const VolumeF32 d = distance::euclidean(m);
    const Difference diff = expect_thinned(m, d, {16, 16, 16}, options(2), std::string(shape) + " euclidean");
    // Rods have one medial curve: the block-wise one lies on it or next to it. Plates thinned to
    // curves have none (any curve inside the plate is homotopic and thin): only the invariants hold.
    if (std::string(shape) == "rods") {
      EXPECT_EQ(diff.displaced, 0) << shape;
      EXPECT_LE(diff.max_shift, 1) << shape;
    }
  }
}

// Thesis fig. 5.8: without end points a long rod retracts to one voxel, across several blocks; the
// blocks it leaves run again until nothing changes.
TEST(ThinningBlocks, RodWithoutEndPointsNeedsMorePasses) {
  VolumeU8 m(Dims{60, 9, 9}, 0);
  test::add_cylinder_x(m, 2, 57, 4, 4, 1.5);
  const VolumeU32 d = test::chamfer345(m);
  const BlockRun r = run_blocks(m, d, user_blocks({10, 9, 9}), options(0));
  EXPECT_GT(r.result.passes, 1);
  EXPECT_GT(r.result.block_runs, r.result.blocks);
  EXPECT_EQ(r.result.stats.skeleton_voxels, 1);
  EXPECT_EQ(topology(r.skeleton).components, 1);
}

TEST(ThinningBlocks, HaloFromThePriority) {
  VolumeU8 m(Dims{40, 40, 40}, 0);
  test::add_ball(m, 20, 20, 20, 9.5);
  // Integer priorities are read as (3, 4, 5) chamfer distances, float ones as Euclidean distances in
  // physical units; the scan goes block by block (blocks of 16 here).
  const VolumeU32 d = test::chamfer345(m);
  const VolumeF32 e = distance::euclidean(m);
  uint32_t dmax = 0;
  float emax = 0;
  for (int64_t i = 0; i < m.size(); ++i) {
    dmax = std::max(dmax, d[i]);
    emax = std::max(emax, e[i]);
  }
  EXPECT_DOUBLE_EQ(priority_max_distance(m, d, {16, 16, 16}), dmax / 3.0);
  EXPECT_NEAR(priority_max_distance(m, e, {16, 16, 16}), emax, 1e-6);
  EXPECT_EQ(halo_for_distance(10.0), 12);
  EXPECT_EQ(halo_for_distance(0.0), 1);
  const BlockRun r = run_blocks(m, d, user_blocks({13, 13, 13}), options(2));
  EXPECT_EQ(r.result.halo, halo_for_distance(dmax / 3.0));
  EXPECT_EQ(topology(r.skeleton).components, 1);
  EXPECT_EQ(topology(r.skeleton).euler, 1);
  EXPECT_EQ(simple_non_end(r.skeleton), 0);
}

TEST(ThinningBlocks, HaloTooSmallIsAnErrorNamingTheParameter) {
  VolumeU8 m(Dims{40, 40, 40}, 0);
  test::add_ball(m, 20, 20, 20, 9.5);
  const VolumeU32 d = test::chamfer345(m);
  BlockThinningOptions o = options(2);
  o.halo = 3;
  try {
    run_blocks(m, d, user_blocks({13, 13, 13}), o);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("param 'halo'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("farther from the object border than the halo of 3 voxels"),
              std::string::npos) << e.what();
  }
  // A priority that is no distance (the mask itself: d_max read as 1/3 voxel) is caught the same way.
  try {
    run_blocks(m, m, user_blocks({13, 13, 13}), options(2));
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is no distance to the border"), std::string::npos) << e.what();
  }
}

TEST(ThinningBlocks, SubBlockLargerThanTheBudgetIsRefused) {
  VolumeU8 m(Dims{64, 64, 64}, 0);
  test::add_ball(m, 32, 32, 32, 20);
  const VolumeU32 d = test::chamfer345(m);
  BlockPlan p = user_blocks({16, 16, 16}, 64 * 1024);
  try {
    run_blocks(m, d, p, options(2));
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("more than the memory budget of 64 KiB"), std::string::npos) << e.what();
  }
  // Chosen from the budget: the largest cube whose sub-block takes a quarter of it.
  p.block_from_user = false;
  p.memory_budget = 64ull << 20;
  const BlockRun r = run_blocks(m, d, p, options(2));
  const int64_t s = r.result.block[0] + 2 * r.result.halo;
  EXPECT_LE(s * s * s * r.result.bytes_per_voxel, static_cast<int64_t>(p.memory_budget / 4));
  EXPECT_EQ(topology(r.skeleton).euler, 1);
}

TEST(ThinningBlocks, UserLocksAreKept) {
  VolumeU8 m(Dims{36, 20, 20}, 0);
  test::add_cylinder_x(m, 2, 33, 10, 10, 4.5);
  const VolumeU32 d = test::chamfer345(m);
  VolumeU8 locked(m.dims(), 0);
  for (int64_t z = 6; z < 14; ++z)
    for (int64_t y = 6; y < 14; ++y) locked(17, y, z) = m(17, y, z);  // a disk across the rod
  const BlockRun r = run_blocks(m, d, user_blocks({9, 9, 9}), options(2), &locked);
  for (int64_t i = 0; i < m.size(); ++i)
    if (locked[i]) {
      ASSERT_EQ(r.skeleton[i], 1);
    }
  EXPECT_EQ(simple_non_end(r.skeleton, &locked), 0);
  EXPECT_EQ(topology(r.skeleton).euler, 1);
}

TEST(ThinningBlocks, ProgressInBlocksAndCancellation) {
  VolumeU8 m(Dims{30, 30, 30}, 0);
  test::add_ball(m, 15, 15, 15, 6);
  const VolumeU32 d = test::chamfer345(m);
  BlockThinningOptions o = options(2);
  std::vector<std::string> notes;
  o.interrupter = Interrupter([](double) {}, nullptr, [&](const std::string& t) { notes.push_back(t); });
  const BlockRun r = run_blocks(m, d, user_blocks({10, 10, 10}), o);
  ASSERT_EQ(r.result.blocks, 27);
  EXPECT_NE(std::find(notes.begin(), notes.end(), "thinning 27/27 blocks"), notes.end());
  EXPECT_NE(std::find(notes.begin(), notes.end(), "thinning 13/27 blocks"), notes.end());
  std::atomic<bool> cancel{true};
  o.interrupter = Interrupter([](double) {}, &cancel);
  EXPECT_THROW(run_blocks(m, d, user_blocks({10, 10, 10}), o), Cancelled);
}

}  // namespace
}  // namespace skel::thinning
