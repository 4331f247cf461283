// The distance.* modules through run_module: ports, parameters, output types, mask rules.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "distance/distance.hpp"
#include "skel/run_module.hpp"

namespace skel {
namespace {

std::shared_ptr<VolumeU8> ball_mask() {
  auto m = std::make_shared<VolumeU8>(Dims{15, 13, 11}, 0, Vec3{1.0, 1.0, 1.0});
  for (int64_t z = 0; z < 11; ++z)
    for (int64_t y = 0; y < 13; ++y)
      for (int64_t x = 0; x < 15; ++x)
        if ((x - 7) * (x - 7) + (y - 6) * (y - 6) + (z - 5) * (z - 5) <= 16) (*m)(x, y, z) = 1;
  return m;
}

TEST(DistanceModules, EuclideanMatchesLibraryAndAcceptsOtherIntegerTypes) {
  auto m = ball_mask();
  auto r = run_module("distance.euclidean", {{"mask", m}}, {{"squared", true}}, {.threads = 2});
  auto d = r.get<VolumeF32>("distance");
  distance::EuclideanOptions o;
  o.squared = true;
  EXPECT_TRUE(*d == distance::euclidean(*m, o));
  // centre of the ball x²+y²+z² <= 16: the nearest background offsets have squared length 17 (4,1,0)
  EXPECT_FLOAT_EQ(17.0f, (*d)(7, 6, 5));
  // a uint16 label image: voxel > 0 is object
  auto labels = std::make_shared<VolumeU16>(m->grid(), 0);
  for (int64_t i = 0; i < m->size(); ++i) (*labels)[i] = (*m)[i] ? 300 : 0;
  auto r2 = run_module("distance.euclidean", {{"mask", labels}}, {{"squared", true}}, {.threads = 1});
  EXPECT_TRUE(*r2.get<VolumeF32>("distance") == *d);
}

TEST(DistanceModules, FloatMaskIsAnErrorNamingThePort) {
  auto f = std::make_shared<VolumeF32>(Dims{4, 4, 4}, 1.0f);
  for (const char* name : {"distance.euclidean", "distance.chamfer", "distance.feature_transform"}) {
    try {
      (void)run_module(name, {{"mask", f}});
      FAIL() << name << " accepted a float mask";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("mask"), std::string::npos) << e.what();
    }
  }
}

TEST(DistanceModules, ChamferOutputTypeAndWeights) {
  auto m = ball_mask();
  auto r = run_module("distance.chamfer", {{"mask", m}}, {});
  auto c = r.get<VolumeU16>("distance");
  EXPECT_EQ(12, (*c)(7, 6, 5));  // background offset (3,3,0): 3 edge steps of weight 4
  auto r2 = run_module("distance.chamfer", {{"mask", m}},
                       {{"weights", std::vector<int64_t>{10000, 14142, 17321}}, {"border_is_object", true}});
  auto c2 = r2.get<VolumeU32>("distance");  // bound 10000 * (14 + 12 + 10) does not fit uint16
  EXPECT_EQ(3u * 14142u, (*c2)(7, 6, 5));  // (3,3,0) beats (4,1,0) = 44142 and (3,2,2) = 44642
}

TEST(DistanceModules, ChamferNarrowGivesUint8WhereEveryValueFits) {
  auto m = ball_mask();
  auto r = run_module("distance.chamfer", {{"mask", m}}, {{"narrow", true}});
  auto c8 = r.get<VolumeU8>("distance");
  auto c16 = run_module("distance.chamfer", {{"mask", m}}, {}).get<VolumeU16>("distance");
  ASSERT_EQ(c8->size(), c16->size());
  for (int64_t i = 0; i < c8->size(); ++i) EXPECT_EQ((*c16)[i], (*c8)[i]) << "voxel " << i;
  // weights whose values reach 255: uint16 as without `narrow`
  auto r2 = run_module("distance.chamfer", {{"mask", m}},
                       {{"narrow", true}, {"weights", std::vector<int64_t>{100, 141, 173}}});
  auto w16 = r2.get<VolumeU16>("distance");
  EXPECT_EQ(3 * 141, (*w16)(7, 6, 5));  // (3,3,0) beats (4,1,0) = 441 and (3,2,2) = 446
}

TEST(DistanceModules, FeatureTransformMethods) {
  auto m = ball_mask();
  auto e = run_module("distance.feature_transform", {{"mask", m}}, {}).get<VolumeU32>("nearest");
  EXPECT_TRUE(*e == distance::feature_transform_as<uint32_t>(*m));
  EXPECT_EQ(static_cast<uint32_t>(m->index(0, 0, 0)), (*e)(0, 0, 0));  // background: itself
  // centre (7,6,5): nearest background voxels at squared distance 17; of these, the smallest (z, y, x) is
  // offset (0,-1,-4), i.e. voxel (7, 5, 1)
  EXPECT_EQ(static_cast<uint32_t>(m->index(7, 5, 1)), (*e)(7, 6, 5));
  auto b = run_module("distance.feature_transform", {{"mask", m}}, {{"method", std::string("chamfer_bp")}})
               .get<VolumeU32>("nearest");
  EXPECT_TRUE(*b == *std::dynamic_pointer_cast<const VolumeU32>(distance::chamfer_nearest(*m).nearest));
  const uint32_t bp = (*b)(7, 6, 5);
  EXPECT_EQ(0, (*m)[bp]);
}

TEST(DistanceModules, SeededWithOptionalMask) {
  auto seeds = std::make_shared<VolumeU8>(Dims{9, 8, 7}, 0, Vec3{0.5, 0.5, 0.5});
  (*seeds)(4, 4, 3) = 1;
  auto d = run_module("distance.seeded", {{"seeds", seeds}}, {}).get<VolumeF32>("distance");
  EXPECT_FLOAT_EQ(0.0f, (*d)(4, 4, 3));
  EXPECT_FLOAT_EQ(1.5f, (*d)(4, 4, 0));
  EXPECT_FLOAT_EQ(std::sqrt(3.0f) * 0.5f, (*d)(5, 5, 4));
  auto region = std::make_shared<VolumeU8>(seeds->grid(), 0);
  (*region)(4, 4, 0) = 1;
  auto dm = run_module("distance.seeded", {{"seeds", seeds}, {"mask", region}}, {}).get<VolumeF32>("distance");
  EXPECT_FLOAT_EQ(1.5f, (*dm)(4, 4, 0));
  EXPECT_FLOAT_EQ(0.0f, (*dm)(5, 5, 4));  // outside the mask: 0
  auto wrong = std::make_shared<VolumeU8>(Dims{3, 3, 3}, 1);
  EXPECT_THROW(run_module("distance.seeded", {{"seeds", seeds}, {"mask", wrong}}, {}), InputError);
}

}  // namespace
}  // namespace skel
