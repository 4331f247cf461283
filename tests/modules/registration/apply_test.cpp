// transform_volume / transform_graph / transform_landmarks: brute-force references, round trips
// through the inverse, thread independence.
#include <gtest/gtest.h>

#include "registration/registration.hpp"
#include "test_util.hpp"

using namespace skel;
using namespace skel::registration;
using namespace skel::test;

namespace {

VolumeU8 random_mask(const Grid& g, uint32_t seed) {
  VolumeU8 v(g);
  std::mt19937 rng(seed);
  for (auto& x : v) x = static_cast<uint8_t>(rng() % 3 == 0 ? 1 : 0);
  return v;
}

SpatialGraph sample_graph() {
  SpatialGraph g;
  const auto a = g.add_node({1, 2, 3}), b = g.add_node({10, 4, -2}), c = g.add_node({-5, 7, 8});
  g.add_edge(a, b, {{1, 2, 3}, {4, 3.5, 1}, {7, 3.9, 0}, {10, 4, -2}});
  g.add_edge(b, c);
  g.add_edge(c, c, {{-5, 7, 8}, {-4, 9, 8}, {-6, 9.5, 8.5}, {-5, 7, 8}});
  auto& r = g.ensure_node_attribute("radius");
  r = {1.5f, 2.0f, 0.75f};
  g.ensure_edge_attribute("mean_radius") = {1.25f, 2.5f, 0.5f};
  g.ensure_edge_attribute("tortuosity") = {1.1f, 1.0f, 3.0f};
  g.ensure_edge_label("tree") = {1, 2, 3};
  auto& pr = g.ensure_point_attribute("radius");
  for (size_t e = 0; e < pr.size(); ++e)
    for (size_t i = 0; i < pr[e].size(); ++i) pr[e][i] = 0.5f + static_cast<float>(e + i);
  g.source_grid = Grid({20, 20, 20}, {0.5, 0.5, 0.5}, {-5, -5, -5});
  return g;
}

}  // namespace

// Brute-force nearest-neighbour reference for one output voxel.
TEST(TransformVolume, NearestMatchesBruteForce) {
  const Grid g({13, 9, 7}, {0.7, 0.9, 1.3}, {2.0, -1.0, 0.5});
  const VolumeU8 in = random_mask(g, 3);
  const Transform t = known_similarity();
  const Grid og = transformed_bounding_grid(g, t);
  const VolumeU8 out = transform_volume(in, t, og, {.interpolation = Interpolation::Nearest, .threads = 2});
  const Transform inv = t.inverse();
  int64_t inside = 0, ones = 0;
  for (int64_t z = 0; z < og.dims[2]; ++z)
    for (int64_t y = 0; y < og.dims[1]; ++y)
      for (int64_t x = 0; x < og.dims[0]; ++x) {
        const Vec3 q = inv.apply(og.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
        uint8_t expected = 0;
        int64_t idx[3];
        bool ok = true;
        for (int k = 0; k < 3; ++k) {
          const double c = (q[k] - g.origin[k]) / g.spacing[k];
          idx[k] = static_cast<int64_t>(std::floor(c + 0.5));
          ok = ok && c >= -0.5 && c <= static_cast<double>(g.dims[k]) - 0.5;
          idx[k] = std::min(idx[k], g.dims[k] - 1);
        }
        if (ok) {
          expected = in(idx[0], idx[1], idx[2]);
          ++inside;
        }
        ones += out(x, y, z);
        ASSERT_EQ(out(x, y, z), expected) << x << " " << y << " " << z;
      }
  // The bounding grid holds the whole moved volume: as many inside samples as expected by volume
  // (scale³ · input voxels / output voxel volume ≈ 1.37³ · 819), and some object voxels.
  EXPECT_NEAR(static_cast<double>(inside), std::pow(1.37, 3) * static_cast<double>(g.voxel_count()),
              0.1 * std::pow(1.37, 3) * static_cast<double>(g.voxel_count()));
  EXPECT_GT(ones, 0);
}

TEST(TransformVolume, BoundingGridOfIdentityIsTheGrid) {
  const Grid g({13, 9, 7}, {0.7, 0.9, 1.3}, {2.0, -1.0, 0.5});
  const Grid b = transformed_bounding_grid(g, Transform::identity());
  EXPECT_EQ(b.dims, g.dims);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.origin[k], g.origin[k], 1e-12);
  const VolumeU8 in = random_mask(g, 4);
  EXPECT_TRUE(transform_volume(in, Transform::identity(), g) == in);
}

// A transform mapping the grid onto itself (90° about z, whole-voxel translation): forward then
// inverse with nearest neighbour returns the volume exactly.
TEST(TransformVolume, GridPreservingRoundTripIsExact) {
  const Grid g({16, 11, 9}, {0.5, 0.5, 0.8}, {1.0, 2.0, 3.0});
  const VolumeU8 in = random_mask(g, 5);
  const Transform t = Transform::translation({1.5, -2.0, 1.6}).compose(Transform::rotation({0, 0, 1}, M_PI / 2));
  const VolumeU8 fwd = transform_volume(in, t, transformed_bounding_grid(g, t));
  EXPECT_EQ(fwd.nx(), g.dims[1]);
  EXPECT_EQ(fwd.ny(), g.dims[0]);
  const VolumeU8 back = transform_volume(fwd, t.inverse(), g);
  EXPECT_TRUE(back == in);
}

// Trilinear interpolation reproduces a linear function exactly, so a general similarity there and
// back returns it to 1e-9 away from the border.
TEST(TransformVolume, LinearRoundTripOfLinearFunction) {
  const Grid g({24, 20, 18}, {0.8, 1.0, 1.2}, {-3.0, 4.0, 1.0});
  VolumeF64 in(g);
  const auto f = [](const Vec3& p) { return 2.5 * p[0] - 1.25 * p[1] + 0.75 * p[2] + 10.0; };
  for (int64_t z = 0; z < g.dims[2]; ++z)
    for (int64_t y = 0; y < g.dims[1]; ++y)
      for (int64_t x = 0; x < g.dims[0]; ++x)
        in(x, y, z) = f(g.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
  Transform t = Transform::translation({3.0, -1.0, 2.0})
                    .compose(Transform::rotation({1, 2, 3}, 0.3))
                    .compose(Transform::scaling(1.1));
  const VolumeF64 fwd = transform_volume(in, t, transformed_bounding_grid(g, t), {.threads = 2});
  const VolumeF64 back = transform_volume(fwd, t.inverse(), g, {.threads = 2});
  int64_t checked = 0;
  const int64_t m = 3;
  for (int64_t z = m; z < g.dims[2] - m; ++z)
    for (int64_t y = m; y < g.dims[1] - m; ++y)
      for (int64_t x = m; x < g.dims[0] - m; ++x, ++checked) ASSERT_NEAR(back(x, y, z), in(x, y, z), 1e-9);
  EXPECT_GT(checked, 1000);
}

// Nearest neighbour there and back under a general rotation moves every sample by less than one
// voxel per axis: each voxel's value comes from its own 3x3x3 neighbourhood, and a smooth object
// changes only at its surface.
TEST(TransformVolume, NearestRoundTripStaysWithinOneVoxel) {
  const Grid g({30, 30, 30});
  VolumeU8 in(g);
  for (int64_t z = 0; z < 30; ++z)
    for (int64_t y = 0; y < 30; ++y)
      for (int64_t x = 0; x < 30; ++x)
        in(x, y, z) = (x - 14.5) * (x - 14.5) + (y - 15.2) * (y - 15.2) + (z - 14.8) * (z - 14.8) < 81.0 ? 1 : 0;
  const Transform t = Transform::translation({0.3, 0.2, -0.4}).compose(Transform::rotation({1, -1, 2}, 0.5));
  const VolumeU8 back = transform_volume(transform_volume(in, t, transformed_bounding_grid(g, t)), t.inverse(), g);
  int64_t changed = 0;
  for (int64_t z = 1; z < 29; ++z)
    for (int64_t y = 1; y < 29; ++y)
      for (int64_t x = 1; x < 29; ++x) {
        if (back(x, y, z) == in(x, y, z)) continue;
        ++changed;
        bool found = false;
        for (int dz = -1; dz <= 1 && !found; ++dz)
          for (int dy = -1; dy <= 1 && !found; ++dy)
            for (int dx = -1; dx <= 1 && !found; ++dx) found = in(x + dx, y + dy, z + dz) == back(x, y, z);
        ASSERT_TRUE(found) << x << " " << y << " " << z;
      }
  // Only surface voxels change: fewer than the ~4πr² = 1018 voxels of the sphere's surface shell.
  EXPECT_LT(changed, 1018);
  EXPECT_GT(changed, 0) << "nearest neighbour twice under a rotation is not the identity";
}

TEST(TransformVolume, IntegerLinearRoundsAndClamps) {
  VolumeU8 in(Dims{2, 1, 1});
  in(0, 0, 0) = 0;
  in(1, 0, 0) = 255;
  const Grid og(Dims{3, 1, 1}, {0.5, 1, 1}, {0, 0, 0});  // samples at x = 0, 0.5, 1
  const VolumeU8 out = transform_volume(in, Transform::identity(), og, {.interpolation = Interpolation::Linear});
  EXPECT_EQ(out(0, 0, 0), 0);
  EXPECT_EQ(out(1, 0, 0), 128);  // 127.5 rounds to even = 128
  EXPECT_EQ(out(2, 0, 0), 255);
  EXPECT_EQ(parse_interpolation("linear"), Interpolation::Linear);
  EXPECT_THROW((void)parse_interpolation("cubic"), InputError);
}

TEST(TransformVolume, ThreadCountDoesNotChangeResults) {
  const Grid g({40, 33, 21}, {1.0, 0.8, 1.5}, {0, 0, 0});
  const VolumeU8 mask = random_mask(g, 9);
  VolumeF32 img(g);
  std::mt19937 rng(4);
  for (auto& v : img) v = static_cast<float>(rng() % 1000) * 0.01f;
  const Transform t = known_affine();
  const Grid og = transformed_bounding_grid(g, t);
  const VolumeU8 m1 = transform_volume(mask, t, og, {.threads = 1});
  const VolumeF32 f1 = transform_volume(img, t, og, {.threads = 1});
  for (int th : {2, 4}) {
    EXPECT_TRUE(transform_volume(mask, t, og, {.threads = th}) == m1);
    EXPECT_TRUE(transform_volume(img, t, og, {.threads = th}) == f1);
  }
}

TEST(TransformGraph, RoundTripAndRadiusScaling) {
  const SpatialGraph g = sample_graph();
  const Transform t = known_similarity();
  const SpatialGraph fwd = transform_graph(g, t);
  EXPECT_TRUE(fwd.check_invariants().empty());
  EXPECT_NEAR(fwd.total_length(), 1.37 * g.total_length(), 1e-9);
  EXPECT_NEAR(fwd.node_attributes.at("radius")[1], 1.37f * 2.0f, 1e-5);
  EXPECT_NEAR(fwd.edge_attributes.at("mean_radius")[1], 1.37f * 2.5f, 1e-5);
  EXPECT_EQ(fwd.edge_attributes.at("tortuosity"), g.edge_attributes.at("tortuosity"));  // not a length
  EXPECT_EQ(fwd.edge_labels.at("tree"), g.edge_labels.at("tree"));
  EXPECT_NEAR(fwd.point_attributes.at("radius")[0][2], 1.37f * 2.5f, 1e-5);
  const Vec3 p = t.apply(g.positions[1]);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(fwd.positions[1][k], p[k]);
  const SpatialGraph back = transform_graph(fwd, t.inverse());
  ASSERT_EQ(back.node_count(), g.node_count());
  ASSERT_EQ(back.edge_count(), g.edge_count());
  for (int64_t n = 0; n < g.node_count(); ++n)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(back.positions[static_cast<size_t>(n)][k], g.positions[static_cast<size_t>(n)][k], 1e-9);
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    const auto& a = back.edges[static_cast<size_t>(e)];
    const auto& b = g.edges[static_cast<size_t>(e)];
    EXPECT_EQ(a.node0, b.node0);
    EXPECT_EQ(a.node1, b.node1);
    ASSERT_EQ(a.points.size(), b.points.size());
    for (size_t i = 0; i < a.points.size(); ++i)
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(a.points[i][k], b.points[i][k], 1e-9);
  }
  for (size_t n = 0; n < 3; ++n)
    EXPECT_NEAR(back.node_attributes.at("radius")[n], g.node_attributes.at("radius")[n], 1e-6);
  // Source grid follows the transform (bounding box) or the reference grid.
  EXPECT_GT(fwd.source_grid.voxel_count(), 0);
  const Grid ref({5, 6, 7});
  EXPECT_EQ(transform_graph(g, t, ref).source_grid, ref);
}

TEST(TransformLandmarks, AllSetsMoved) {
  const LandmarkSet lm({random_points(4, 1), random_points(4, 2)}, {"a", "b", "c", "d"});
  const LandmarkSet out = transform_landmarks(lm, known_affine());
  EXPECT_EQ(out.names, lm.names);
  for (int s = 0; s < 2; ++s)
    for (size_t i = 0; i < 4; ++i) EXPECT_EQ(out.sets[s][i], known_affine().apply(lm.sets[s][i]));
  const LandmarkSet back = transform_landmarks(out, known_affine().inverse());
  for (int s = 0; s < 2; ++s)
    for (size_t i = 0; i < 4; ++i) EXPECT_LT(distance(back.sets[s][i], lm.sets[s][i]), 1e-9);
}
