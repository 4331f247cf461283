// synthetic::make_altered_network: the element layout reproduces make_network exactly, the after
// scan is the kept elements moved by the known motion, `removed` is exactly what was lost, landmarks
// correspond through the true transform, and nothing depends on the thread count.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "skel/error.hpp"
#include "synthetic/altered.hpp"
#include "synthetic/network.hpp"

using namespace skel;
using namespace skel::synthetic;

namespace {

NetworkOptions small_network(const std::string& shape, int threads = 2) {
  NetworkOptions n;
  n.shape = parse_enum<synthetic::Shape>(shape, "shape");
  n.size = {56, 48, 64};
  n.seed = 3;
  n.period = 16;
  n.radius = 2.0;
  n.threads = threads;
  return n;
}

int64_t border_distance(const Dims& d, int64_t x, int64_t y, int64_t z) {
  return std::min({x, y, z, d[0] - 1 - x, d[1] - 1 - y, d[2] - 1 - z});
}

}  // namespace

TEST(AlteredNetwork, ElementLayoutReproducesMakeNetworkExactly) {
  for (const char* shape : {"rods", "plates", "spheres", "mixed"}) {
    SCOPED_TRACE(shape);
    NetworkOptions n = small_network(shape);
    n.noise = 0.1;
    const NetworkResult ref = make_network(n);
    const Vec3 hi{static_cast<double>(n.size[0] - 1), static_cast<double>(n.size[1] - 1), static_cast<double>(n.size[2] - 1)};
    VolumeF32 img = draw_network_elements(n, network_elements(n, {0, 0, 0}, hi), {0, 0, 0}, n.size);
    add_two_frequency_noise(img, n.seed, n.noise, n.threads);
    ASSERT_EQ(img.dims(), ref.image.dims());
    EXPECT_EQ(0, std::memcmp(img.data(), ref.image.data(), sizeof(float) * static_cast<size_t>(img.size())));
    // A larger box adds elements around the volume but none inside: away from the border (where
    // make_network clamps the Gaussian) the drawing on a padded box is bit-identical.
    n.noise = 0;
    const NetworkResult plain = make_network(n);
    const Dims off{-7, -5, -9}, pd{n.size[0] + 15, n.size[1] + 11, n.size[2] + 18};
    const VolumeF32 big = draw_network_elements(
        n, network_elements(n, {-7, -5, -9}, {static_cast<double>(pd[0] - 8), static_cast<double>(pd[1] - 6), static_cast<double>(pd[2] - 10)}),
        off, pd);
    const int64_t R = 3;  // ceil(3 sigma)
    int64_t compared = 0;
    for (int64_t z = 0; z < n.size[2]; ++z)
      for (int64_t y = 0; y < n.size[1]; ++y)
        for (int64_t x = 0; x < n.size[0]; ++x) {
          if (border_distance(n.size, x, y, z) < R) continue;
          ASSERT_EQ(big(x + 7, y + 5, z + 9), plain.image(x, y, z)) << x << " " << y << " " << z;
          ++compared;
        }
    EXPECT_GT(compared, 100000);
  }
}

TEST(AlteredNetwork, IdentityMotionWithoutRemovalGivesTheBeforeMask) {
  AlteredNetworkOptions o;
  o.network = small_network("mixed");
  o.rotation_degrees = {0, 0, 0};
  o.translation = {0, 0, 0};
  o.remove_fraction = 0;
  o.landmark_noise = 0;
  const auto r = make_altered_network(o);
  // After grid = before grid grown by one voxel on each side.
  EXPECT_EQ(r.after_mask.dims(), (Dims{o.network.size[0] + 2, o.network.size[1] + 2, o.network.size[2] + 2}));
  EXPECT_EQ(r.after_mask.origin(), (Vec3{-1, -1, -1}));
  int64_t removed = 0;
  for (auto v : r.removed) removed += v;
  EXPECT_EQ(removed, 0);
  for (int64_t z = 0; z < o.network.size[2]; ++z)
    for (int64_t y = 0; y < o.network.size[1]; ++y)
      for (int64_t x = 0; x < o.network.size[0]; ++x)
        if (border_distance(o.network.size, x, y, z) >= 3) {
          ASSERT_EQ(r.after_mask(x + 1, y + 1, z + 1), r.before_mask(x, y, z)) << x << " " << y << " " << z;
        }
}

TEST(AlteredNetwork, RemovedIsExactlyTheLostMaterial) {
  AlteredNetworkOptions o;
  o.network = small_network("mixed");
  o.rotation_degrees = {0, 0, 0};
  o.translation = {0, 0, 0};
  o.remove_fraction = 0.3;
  const auto r = make_altered_network(o);
  int64_t removed = 0, lost = 0;
  for (int64_t z = 0; z < o.network.size[2]; ++z)
    for (int64_t y = 0; y < o.network.size[1]; ++y)
      for (int64_t x = 0; x < o.network.size[0]; ++x) {
        if (border_distance(o.network.size, x, y, z) < 3) continue;
        const bool l = r.before_mask(x, y, z) && !r.after_mask(x + 1, y + 1, z + 1);
        ASSERT_EQ(r.removed(x, y, z) != 0, l) << x << " " << y << " " << z;
        removed += r.removed(x, y, z);
        lost += l;
        // Nothing appears that was not there before.
        ASSERT_FALSE(r.after_mask(x + 1, y + 1, z + 1) && !r.before_mask(x, y, z));
      }
  EXPECT_EQ(removed, lost);
  EXPECT_GT(removed, 1000);
  EXPECT_GT(r.summary.ints("removed_capsules")[0], 0);
  EXPECT_LT(r.summary.ints("removed_capsules")[0], r.summary.ints("capsules")[0]);
}

TEST(AlteredNetwork, LandmarksCorrespondThroughTheTrueTransform) {
  AlteredNetworkOptions o;
  o.network = small_network("mixed");
  o.network.spacing = {0.8, 0.8, 1.2};
  o.rotation_degrees = {4, -3, 10};
  o.translation = {3.0, -2.0, 1.5};
  o.landmark_noise = 0;
  o.landmarks = 10;
  const auto r = make_altered_network(o);
  ASSERT_EQ(r.landmarks.set_count(), 2);
  ASSERT_EQ(r.landmarks.point_count(), 10);
  EXPECT_LT(std::abs(r.transform.determinant() - 1.0), 1e-12);
  EXPECT_LT(r.transform.compose(r.motion).max_difference(Transform::identity()), 1e-12);
  const Grid& bg = r.before_mask.grid();
  const Grid& ag = r.after_mask.grid();
  for (int64_t i = 0; i < 10; ++i) {
    const Vec3 p = r.landmarks.set(0)[static_cast<size_t>(i)], q = r.landmarks.set(1)[static_cast<size_t>(i)];
    const Vec3 back = r.transform.apply(q);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[static_cast<size_t>(k)], p[static_cast<size_t>(k)], 1e-9);
    // Each landmark sits on the object in both scans.
    auto voxel = [](const Grid& g, const Vec3& x, int k) { return std::llround((x[static_cast<size_t>(k)] - g.origin[static_cast<size_t>(k)]) / g.spacing[static_cast<size_t>(k)]); };
    EXPECT_EQ(r.before_mask(voxel(bg, p, 0), voxel(bg, p, 1), voxel(bg, p, 2)), 1) << "landmark " << i;
    EXPECT_EQ(r.after_mask(voxel(ag, q, 0), voxel(ag, q, 1), voxel(ag, q, 2)), 1) << "landmark " << i;
  }
  // The after grid contains the moved before volume.
  for (int c = 0; c < 8; ++c) {
    Vec3 p{};
    for (int k = 0; k < 3; ++k)
      p[static_cast<size_t>(k)] = bg.origin[static_cast<size_t>(k)] + (((c >> k) & 1) ? static_cast<double>(bg.dims[static_cast<size_t>(k)]) - 0.5 : -0.5) * bg.spacing[static_cast<size_t>(k)];
    const Vec3 q = r.motion.apply(p);
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(q[static_cast<size_t>(k)], ag.origin[static_cast<size_t>(k)] - 0.5 * ag.spacing[static_cast<size_t>(k)]);
      EXPECT_LE(q[static_cast<size_t>(k)], ag.origin[static_cast<size_t>(k)] + (static_cast<double>(ag.dims[static_cast<size_t>(k)]) - 0.5) * ag.spacing[static_cast<size_t>(k)]);
    }
  }
  // The kept before object, moved, is (almost everywhere) object in the after scan.
  int64_t object = 0, agree = 0;
  for (int64_t z = 0; z < bg.dims[2]; ++z)
    for (int64_t y = 0; y < bg.dims[1]; ++y)
      for (int64_t x = 0; x < bg.dims[0]; ++x) {
        if (!r.before_mask(x, y, z) || r.removed(x, y, z)) continue;
        const Vec3 q = r.motion.apply(bg.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
        const int64_t ax = std::llround((q[0] - ag.origin[0]) / ag.spacing[0]), ay = std::llround((q[1] - ag.origin[1]) / ag.spacing[1]),
                      az = std::llround((q[2] - ag.origin[2]) / ag.spacing[2]);
        ++object;
        agree += r.after_mask.at_or(ax, ay, az, 0);
      }
  EXPECT_GT(static_cast<double>(agree), 0.9 * static_cast<double>(object));
  // Picking noise has the requested size.
  o.landmark_noise = 0.5;
  o.landmarks = 40;
  o.network.size = {96, 96, 96};
  const auto noisy = make_altered_network(o);
  EXPECT_NEAR(noisy.summary.reals("landmark_rms_noise")[0], 0.5, 0.1);
}

TEST(AlteredNetwork, ResultsDoNotDependOnThreads) {
  AlteredNetworkOptions o;
  o.network = small_network("mixed", 1);
  o.network.noise = 0.1;
  const auto a = make_altered_network(o);
  o.network.threads = 3;
  const auto b = make_altered_network(o);
  EXPECT_TRUE(a.after_image == b.after_image);
  EXPECT_TRUE(a.after_mask == b.after_mask);
  EXPECT_TRUE(a.removed == b.removed);
  EXPECT_TRUE(a.before_mask == b.before_mask);
  EXPECT_TRUE(a.landmarks == b.landmarks);
  EXPECT_TRUE(a.transform == b.transform);
}

TEST(AlteredNetwork, InvalidOptionsAreInputErrors) {
  AlteredNetworkOptions o;
  o.network = small_network("mixed");
  o.remove_fraction = 1.5;
  EXPECT_THROW((void)make_altered_network(o), InputError);
  o.remove_fraction = 0.1;
  o.landmarks = 2;
  EXPECT_THROW((void)make_altered_network(o), InputError);
  o.landmarks = 100000;
  try {
    (void)make_altered_network(o);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("landmarks"), std::string::npos);
  }
  o.landmarks = 8;
  o.network.shape = static_cast<synthetic::Shape>(99);
  EXPECT_THROW((void)make_altered_network(o), InputError);
}
