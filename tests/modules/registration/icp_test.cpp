// Trimmed ICP: convergence from a perturbed start, robustness to structures present in one set only,
// thread independence, point extraction from volumes and graphs.
#include <gtest/gtest.h>

#include "registration/registration.hpp"
#include "test_util.hpp"

using namespace skel;
using namespace skel::registration;
using namespace skel::test;

namespace {

// Points along a few helices and segments: a skeleton-like, asymmetric cloud.
std::vector<Vec3> curve_cloud() {
  std::vector<Vec3> p;
  for (int i = 0; i < 600; ++i) {
    const double s = i * 0.05;
    p.push_back({10 * std::cos(s), 10 * std::sin(s), 1.5 * s});
  }
  for (int i = 0; i < 300; ++i) p.push_back({-20.0 + 0.13 * i, 5.0 + 0.05 * i, -8.0 + 0.02 * i * i / 30.0});
  for (int i = 0; i < 200; ++i) p.push_back({15.0 + 0.1 * i, -12.0, 3.0 + 0.2 * i});
  return p;
}

Transform perturbation() {
  return Transform::translation({1.2, -0.8, 0.9}).compose(Transform::rotation({0.2, 1.0, -0.4}, 4.0 * M_PI / 180));
}

}  // namespace

TEST(Icp, ConvergesFromPerturbedStart) {
  const auto fixed = curve_cloud();
  const Transform truth = known_rigid();
  const auto moving = apply_all(truth.inverse(), fixed);  // truth maps moving → fixed
  const Transform initial = perturbation().compose(truth);
  IcpOptions o;
  o.trim_fraction = 1.0;
  o.iterations = 200;
  o.tolerance = 1e-12;
  o.threads = 2;
  const IcpResult r = refine_icp(fixed, moving, initial, o);
  ASSERT_FALSE(r.history.empty());
  EXPECT_TRUE(r.converged);
  EXPECT_GT(r.history.front().rms_before, 0.5);
  EXPECT_LT(r.history.back().rms_after, 1e-6);
  EXPECT_LT(r.transform.max_difference(truth), 1e-6);
  EXPECT_EQ(r.transform.kind(), TransformKind::Rigid);
  for (const auto& it : r.history) EXPECT_LE(it.rms_after, it.rms_before + 1e-12);
  const Table t = icp_table(r, "mm");
  EXPECT_EQ(t.rows(), static_cast<int64_t>(r.history.size()));
  EXPECT_EQ(t.reals("rms_before").front(), r.history.front().rms_before);
  EXPECT_EQ(t.column("rms_after").unit, "mm");
}

TEST(Icp, TrimmingIgnoresStructuresMissingFromTheFixedSet) {
  auto fixed = curve_cloud();
  const Transform truth = known_similarity();
  auto moving = apply_all(truth.inverse(), fixed);
  // 15% extra moving points far from every fixed point (a structure that vanished).
  const size_t extra = fixed.size() * 15 / 100;
  for (size_t i = 0; i < extra; ++i) {
    moving.push_back(truth.inverse().apply({60.0 + 0.1 * static_cast<double>(i), 60.0, 60.0}));
  }
  IcpOptions o;
  o.model = TransformKind::Similarity;
  o.trim_fraction = 0.8;
  o.iterations = 300;
  o.tolerance = 1e-12;
  const IcpResult r = refine_icp(fixed, moving, perturbation().compose(truth), o);
  EXPECT_LT(r.history.back().rms_after, 1e-6);
  EXPECT_LT(r.transform.max_difference(truth), 1e-6);
  // Without trimming the vanished structure pulls the fit away.
  o.trim_fraction = 1.0;
  const IcpResult untrimmed = refine_icp(fixed, moving, perturbation().compose(truth), o);
  EXPECT_GT(untrimmed.transform.max_difference(truth), 1e-3);
  // A maximum correspondence distance alone also removes it.
  o.max_distance = 10.0;
  const IcpResult limited = refine_icp(fixed, moving, perturbation().compose(truth), o);
  EXPECT_LT(limited.transform.max_difference(truth), 1e-6);
}

TEST(Icp, IdenticalForAnyThreadCount) {
  const auto fixed = curve_cloud();
  auto moving = apply_all(known_rigid().inverse(), fixed);
  moving.resize(moving.size() - 100);  // not a perfect match: ties and trimming matter
  IcpOptions o;
  o.iterations = 20;
  o.threads = 1;
  const IcpResult r1 = refine_icp(fixed, moving, perturbation().compose(known_rigid()), o);
  for (int th : {2, 4}) {
    o.threads = th;
    const IcpResult r = refine_icp(fixed, moving, perturbation().compose(known_rigid()), o);
    EXPECT_TRUE(r.transform == r1.transform);
    ASSERT_EQ(r.history.size(), r1.history.size());
    for (size_t i = 0; i < r.history.size(); ++i) EXPECT_EQ(r.history[i].rms_after, r1.history[i].rms_after);
  }
}

TEST(Icp, SubsamplingAndErrors) {
  const auto fixed = curve_cloud();
  const auto moving = apply_all(known_rigid().inverse(), fixed);
  IcpOptions o;
  o.max_points = 250;
  o.trim_fraction = 1.0;
  o.iterations = 200;
  o.tolerance = 1e-12;
  const IcpResult r = refine_icp(fixed, moving, perturbation().compose(known_rigid()), o);
  EXPECT_LE(r.history.front().pairs, 250);
  EXPECT_LT(r.transform.max_difference(known_rigid()), 1e-6);
  EXPECT_THROW((void)refine_icp({}, moving, Transform{}, o), InputError);
  EXPECT_THROW((void)refine_icp(fixed, {}, Transform{}, o), InputError);
  o.max_distance = 1e-6;  // nothing within reach of a perturbed start
  try {
    (void)refine_icp(fixed, moving, perturbation().compose(known_rigid()), o);
    ADD_FAILURE() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("max_distance"), std::string::npos) << e.what();
  }
}

TEST(PointSets, VolumeAndGraphPoints) {
  VolumeU8 v(Dims{4, 3, 2}, 0, {0.5, 2.0, 3.0}, {1.0, 1.0, 1.0});
  v(1, 2, 0) = 1;
  v(3, 0, 1) = 7;
  const auto p = points_of(v, "input 'fixed'");
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0], (Vec3{1.5, 5.0, 1.0}));
  EXPECT_EQ(p[1], (Vec3{2.5, 1.0, 4.0}));
  SpatialGraph g;
  g.add_node({0, 0, 0});
  g.add_node({3, 0, 0});
  g.add_edge(0, 1, {{0, 0, 0}, {1, 0.5, 0}, {2, 0.5, 0}, {3, 0, 0}});
  const auto gp = points_of(g, "input 'moving'");
  ASSERT_EQ(gp.size(), 4u);
  EXPECT_EQ(gp[2], (Vec3{1, 0.5, 0}));
  EXPECT_THROW((void)points_of(Table{}, "input 'fixed'"), InputError);
}
