// The registration family and its file modules through run_module: ports, parameters, errors,
// thread independence, a landmark → transform → apply → file chain.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "registration/registration.hpp"
#include "skel/run_module.hpp"
#include "test_util.hpp"

using namespace skel;
using namespace skel::test;
namespace fs = std::filesystem;

namespace {

std::shared_ptr<const LandmarkSet> pair_set(const Transform& truth) {
  const auto moving = random_points(6, 77);
  return std::make_shared<LandmarkSet>(std::vector<std::vector<Vec3>>{apply_all(truth, moving), moving});
}

ParamValue str(const char* s) { return ParamValue(std::string(s)); }

fs::path dir() {
  const fs::path d = fs::path(SKEL_BINARY_DIR) / "test_scratch" / "registration_modules";
  fs::create_directories(d);
  return d;
}

}  // namespace

TEST(RegistrationModules, LandmarksFromOneObjectOrTwo) {
  const Transform truth = known_similarity();
  auto lm = pair_set(truth);
  auto r = run_module("registration.landmarks", {{"landmarks", lm}}, {{"model", str("similarity")}}, {.threads = 2});
  EXPECT_LT(r.get<Transform>("transform")->max_difference(truth), 1e-9);
  auto table = r.get<Table>("table");
  EXPECT_EQ(table->rows(), 7);
  EXPECT_EQ(table->strings("landmark")[0], "L1");
  EXPECT_LT(table->reals("distance").back(), 1e-9);
  // Sets swapped: the inverse transform.
  auto inv = run_module("registration.landmarks", {{"landmarks", lm}},
                        {{"model", str("similarity")}, {"fixed_set", ParamValue(int64_t{1})}, {"moving_set", ParamValue(int64_t{0})}});
  EXPECT_LT(inv.get<Transform>("transform")->max_difference(truth.inverse()), 1e-9);
  // fixed + moving inputs.
  auto f = std::make_shared<LandmarkSet>(lm->single_set(0)), m = std::make_shared<LandmarkSet>(lm->single_set(1));
  auto r2 = run_module("registration.landmarks", {{"fixed", f}, {"moving", m}}, {{"model", str("affine")}});
  EXPECT_LT(r2.get<Transform>("transform")->max_difference(truth), 1e-9);
  EXPECT_EQ(r2.get<Transform>("transform")->kind(), TransformKind::Affine);
  // Errors name the ports and parameters.
  EXPECT_THROW(run_module("registration.landmarks", {}), InputError);
  EXPECT_THROW(run_module("registration.landmarks", {{"landmarks", lm}, {"fixed", f}, {"moving", m}}), InputError);
  EXPECT_THROW(run_module("registration.landmarks", {{"landmarks", f}}), InputError);
  try {
    run_module("registration.landmarks", {{"landmarks", lm}}, {{"moving_set", ParamValue(int64_t{5})}});
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("moving_set"), std::string::npos) << e.what();
  }
  auto two = std::make_shared<LandmarkSet>(std::vector<std::vector<Vec3>>{{{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}});
  try {
    run_module("registration.landmarks", {{"landmarks", two}});
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("at least 3"), std::string::npos) << e.what();
  }
}

TEST(RegistrationModules, ApplyTransformRoundTripAndThreads) {
  const Grid g({30, 26, 20}, {0.8, 0.8, 1.0}, {1, 2, 3});
  auto mask = std::make_shared<VolumeU8>(g);
  for (int64_t z = 5; z < 15; ++z)
    for (int64_t y = 4; y < 20; ++y)
      for (int64_t x = 6; x < 25; ++x) (*mask)(x, y, z) = 1;
  auto t = std::make_shared<Transform>(known_rigid());
  DataPtr out1;
  for (int th : {1, 2, 4}) {
    auto r = run_module("registration.apply_transform", {{"transform", t}, {"volume", mask}}, {}, {.threads = th});
    if (!out1) out1 = r.data("volume");
    EXPECT_TRUE(*r.get<VolumeU8>("volume") == *std::dynamic_pointer_cast<const VolumeU8>(out1)) << th;
  }
  // Back onto the original grid with `inverse` and `reference`: the 6 faces are the only changes
  // (nearest neighbour, one voxel at most).
  auto back = run_module("registration.apply_transform", {{"transform", t}, {"volume", out1}, {"reference", mask}},
                         {{"inverse", ParamValue(true)}})
                  .get<VolumeU8>("volume");
  EXPECT_EQ(back->grid(), g);
  int64_t diff = 0;
  for (int64_t i = 0; i < g.voxel_count(); ++i) diff += (*back)[i] != (*mask)[i];
  EXPECT_LT(diff, 2 * (19 * 16 + 19 * 10 + 16 * 10));
  // Float images are interpolated linearly by default, masks by nearest.
  auto img = std::make_shared<VolumeF32>(g, 2.5f);
  auto rf = run_module("registration.apply_transform", {{"transform", t}, {"volume", img}});
  {
    // The voxel nearest to the image of the volume's centre lies deep inside the moved volume.
    const auto& o = *rf.get<VolumeF32>("volume");
    const Vec3 c = t->apply(g.position(14.5, 12.5, 9.5));
    int64_t ix[3];
    for (int a = 0; a < 3; ++a) ix[a] = std::lround((c[a] - o.grid().origin[a]) / o.grid().spacing[a]);
    ASSERT_TRUE(o.grid().contains(ix[0], ix[1], ix[2]));
    EXPECT_FLOAT_EQ(o(ix[0], ix[1], ix[2]), 2.5f);
  }
  // Graph and landmarks.
  SpatialGraph sg;
  sg.add_node({1, 2, 3});
  sg.add_node({4, 5, 6});
  sg.add_edge(0, 1);
  auto gr = run_module("registration.apply_transform", {{"transform", t}, {"graph", std::make_shared<SpatialGraph>(sg)}});
  EXPECT_LT(distance(gr.get<SpatialGraph>("graph")->positions[1], t->apply({4, 5, 6})), 1e-12);
  auto lm = pair_set(*t);
  auto lr = run_module("registration.apply_transform", {{"transform", t}, {"landmarks", lm}});
  EXPECT_LT(distance(lr.get<LandmarkSet>("landmarks")->sets[1][0], lm->sets[0][0]), 1e-9);
  EXPECT_THROW(run_module("registration.apply_transform", {{"transform", t}}), InputError);
  EXPECT_THROW(run_module("registration.apply_transform", {{"transform", t}, {"volume", mask}, {"landmarks", lm}}), InputError);
}

TEST(RegistrationModules, RefineOnSkeletonVolumes) {
  // Fixed: a skeleton-like set of voxel lines; moving: the same lines under a known rigid motion,
  // rasterised as graph points.
  const Grid g({40, 40, 40});
  auto fixed = std::make_shared<VolumeU8>(g);
  for (int i = 5; i < 35; ++i) {
    (*fixed)(i, 10, 12) = 1;
    (*fixed)(20, i, 30) = 1;
    (*fixed)(8, 25, i) = 1;
    (*fixed)(i, i, 20) = 1;
  }
  const Transform truth = Transform::translation({0.7, -0.4, 0.3}).compose(Transform::rotation({1, 1, 0}, 0.03));
  SpatialGraph moving;
  for (const Vec3& p : registration::volume_points(*fixed, "fixed")) moving.add_node(truth.inverse().apply(p));
  auto r = run_module("registration.refine",
                      {{"fixed", fixed}, {"moving", std::make_shared<SpatialGraph>(moving)}},
                      {{"trim_fraction", ParamValue(1.0)}, {"tolerance", ParamValue(1e-12)}, {"iterations", ParamValue(int64_t{200})}},
                      {.threads = 2});
  auto table = r.get<Table>("table");
  EXPECT_GT(table->reals("rms_before").front(), table->reals("rms_after").back());
  EXPECT_LT(table->reals("rms_after").back(), 1e-6);
  EXPECT_LT(r.get<Transform>("transform")->max_difference(truth), 1e-6);
  EXPECT_THROW(run_module("registration.refine", {{"fixed", fixed}}), InputError);
}

TEST(RegistrationModules, FileModulesRoundTrip) {
  const auto d = dir();
  auto lm = pair_set(known_rigid());
  for (const char* name : {"p.landmarkAscii", "p.csv"}) {
    const auto path = (d / name).string();
    run_module("io.write_landmarks", {{"landmarks", lm}}, {{"path", ParamValue(path)}});
    auto back = run_module("io.read_landmarks", {}, {{"path", ParamValue(path)}}).get<LandmarkSet>("landmarks");
    EXPECT_EQ(back->sets, lm->sets) << name;
  }
  // Two Slicer files → one object with two sets.
  const auto f0 = (d / "fixed.fcsv").string(), f1 = (d / "moving.fcsv").string();
  EXPECT_THROW(run_module("io.write_landmarks", {{"landmarks", lm}}, {{"path", ParamValue(f0)}}), InputError);
  run_module("io.write_landmarks", {{"landmarks", lm}}, {{"path", ParamValue(f0)}, {"set", ParamValue(int64_t{0})}});
  run_module("io.write_landmarks", {{"landmarks", lm}}, {{"path", ParamValue(f1)}, {"set", ParamValue(int64_t{1})}});
  auto both = run_module("io.read_landmarks", {}, {{"path", ParamValue(f0)}, {"path2", ParamValue(f1)}}).get<LandmarkSet>("landmarks");
  EXPECT_EQ(both->sets, lm->sets);
  auto t = std::make_shared<Transform>(known_affine());
  for (const char* name : {"t.tfm", "t.txt"}) {
    const auto path = (d / name).string();
    run_module("io.write_transform", {{"transform", t}}, {{"path", ParamValue(path)}});
    auto back = run_module("io.read_transform", {}, {{"path", ParamValue(path)}}).get<Transform>("transform");
    EXPECT_LT(back->max_difference(*t), 1e-12) << name;
  }
  const auto& ins = Registry::instance().inspectors();
  auto it = std::find_if(ins.begin(), ins.end(), [](const FileInspector& i) { return i.name == "ITK transform"; });
  ASSERT_NE(it, ins.end());
  EXPECT_NE(it->describe(d / "t.tfm").find("transform affine"), std::string::npos);
  auto il = std::find_if(ins.begin(), ins.end(), [](const FileInspector& i) { return i.name == "Amira landmarks"; });
  ASSERT_NE(il, ins.end());
  EXPECT_NE(il->describe(d / "p.landmarkAscii").find("2 set(s) of 6 point(s)"), std::string::npos);
  EXPECT_THROW(run_module("io.read_landmarks", {}, {{"path", ParamValue((d / "none.fcsv").string())}}), InputError);
}
