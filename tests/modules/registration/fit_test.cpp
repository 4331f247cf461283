// Transform / LandmarkSet data objects and the closed-form landmark fit.
#include <gtest/gtest.h>

#include "registration/registration.hpp"
#include "test_util.hpp"

using namespace skel;
using namespace skel::registration;
using namespace skel::test;

TEST(TransformObject, InverseComposeAndKinds) {
  const Transform t = known_similarity();
  EXPECT_EQ(t.type_id(), "transform");
  EXPECT_NEAR(t.scale(), 1.37, 1e-12);
  EXPECT_NEAR(t.determinant(), 1.37 * 1.37 * 1.37, 1e-12);
  const Transform id = t.compose(t.inverse());
  EXPECT_LT(id.max_difference(Transform::identity()), 1e-12);
  EXPECT_EQ(t.inverse().kind(), TransformKind::Similarity);
  // compose applies the argument first.
  const Transform a = Transform::translation({1, 0, 0}), b = Transform::rotation({0, 0, 1}, M_PI / 2);
  const Vec3 p = b.compose(a).apply({0, 0, 0});  // translate, then rotate
  EXPECT_NEAR(p[0], 0.0, 1e-15);
  EXPECT_NEAR(p[1], 1.0, 1e-15);
  EXPECT_EQ(b.compose(a).kind(), TransformKind::Rigid);
  EXPECT_EQ(known_affine().compose(a).kind(), TransformKind::Affine);
  EXPECT_NE(t.describe().find("similarity"), std::string::npos);
  EXPECT_EQ(parse_transform_kind("affine"), TransformKind::Affine);
  EXPECT_THROW((void)parse_transform_kind("projective"), InputError);
  Matrix4 bad = Transform::identity().matrix();
  bad[3][0] = 0.5;
  EXPECT_THROW((void)Transform{bad}, InputError);
  EXPECT_THROW((void)Transform(Matrix3{{{1, 0, 0}, {0, 1, 0}, {1, 1, 0}}}, {0, 0, 0}).inverse(), InputError);
}

TEST(LandmarkSetObject, SetsNamesAndErrors) {
  LandmarkSet lm({{{0, 0, 0}, {1, 0, 0}}, {{2, 0, 0}, {3, 0, 0}}});
  EXPECT_EQ(lm.type_id(), "landmarks");
  EXPECT_EQ(lm.set_count(), 2);
  EXPECT_EQ(lm.point_count(), 2);
  EXPECT_EQ(lm.names, (std::vector<std::string>{"L1", "L2"}));
  EXPECT_TRUE(lm.check_invariants().empty());
  EXPECT_THROW(lm.add_set({{0, 0, 0}}), InputError);
  EXPECT_THROW((void)lm.set(2), InputError);
  EXPECT_THROW(LandmarkSet({{{0, 0, 0}}, {{0, 0, 0}, {1, 1, 1}}}), InputError);
  EXPECT_THROW(LandmarkSet({{{0, 0, 0}}}, {"a", "b"}), InputError);
  EXPECT_EQ(lm.single_set(1).sets.front()[1][0], 3.0);
  LandmarkSet empty;
  empty.add_set({{1, 2, 3}});
  EXPECT_EQ(empty.names, (std::vector<std::string>{"L1"}));
  EXPECT_NE(lm.describe().find("2 set(s) of 2 point(s)"), std::string::npos);
}

TEST(LandmarkFit, ExactRecoveryOfKnownTransforms) {
  for (size_t n : {3u, 4u, 7u, 40u}) {
    const auto moving = random_points(n, 17 + static_cast<uint32_t>(n));
    for (const Transform& truth : {known_rigid(), known_similarity(), known_affine()}) {
      if (truth.kind() == TransformKind::Affine && n < 4) continue;
      SCOPED_TRACE(to_string(truth.kind()) + " n=" + std::to_string(n));
      const auto fixed = apply_all(truth, moving);
      const LandmarkFit fit = fit_landmarks(fixed, moving, truth.kind());
      EXPECT_LT(fit.transform.max_difference(truth), 1e-9);
      EXPECT_EQ(fit.transform.kind(), truth.kind());
      EXPECT_LT(fit.rms, 1e-9);
      ASSERT_EQ(fit.distance.size(), n);
    }
  }
  // Coplanar (but not collinear) landmarks determine rigid and similarity fits.
  std::vector<Vec3> planar{{0, 0, 5}, {10, 0, 5}, {0, 7, 5}, {4, 9, 5}};
  for (const Transform& truth : {known_rigid(), known_similarity()}) {
    const LandmarkFit fit = fit_landmarks(apply_all(truth, planar), planar, truth.kind());
    EXPECT_LT(fit.transform.max_difference(truth), 1e-9);
  }
}

// With isotropic Gaussian noise of sigma per coordinate on one set, E[RMS²] = σ²(3N − p)/N for a
// model with p parameters (6 rigid, 7 similarity, 12 affine); the std of RMS² is σ²·sqrt(6/N).
TEST(LandmarkFit, NoisyRmsMatchesTheory) {
  const size_t n = 4000;
  const double sigma = 0.2;
  const auto moving = random_points(n, 5);
  for (const Transform& truth : {known_rigid(), known_similarity(), known_affine()}) {
    SCOPED_TRACE(to_string(truth.kind()));
    auto fixed = apply_all(truth, moving);
    std::mt19937_64 rng(99);
    std::normal_distribution<double> noise(0.0, sigma);
    for (auto& p : fixed)
      for (auto& c : p) c += noise(rng);
    const double params = truth.kind() == TransformKind::Rigid ? 6 : truth.kind() == TransformKind::Similarity ? 7 : 12;
    const double expected = sigma * std::sqrt((3.0 * n - params) / n);
    const LandmarkFit fit = fit_landmarks(fixed, moving, truth.kind());
    // 4 standard deviations of RMS (half the relative std of RMS²).
    EXPECT_NEAR(fit.rms, expected, expected * 4 * 0.5 * std::sqrt(6.0 / n));
    // The transform is still close: the error of the fit is ~σ/sqrt(N) per parameter.
    EXPECT_LT(fit.transform.max_difference(truth), 0.05);
  }
}

TEST(LandmarkFit, RigidAndSimilarityNeverReflect) {
  const auto fixed = random_points(30, 3);
  std::vector<Vec3> mirrored;
  for (const auto& p : fixed) mirrored.push_back({-p[0], p[1], p[2]});
  for (TransformKind k : {TransformKind::Rigid, TransformKind::Similarity}) {
    const LandmarkFit fit = fit_landmarks(fixed, mirrored, k);
    EXPECT_GT(fit.transform.determinant(), 0.0) << to_string(k);
    if (k == TransformKind::Rigid) {
      EXPECT_NEAR(fit.transform.determinant(), 1.0, 1e-12);
    }
    EXPECT_GT(fit.rms, 1.0);  // a mirror cannot be matched by a rotation
  }
  // Exactly planar mirrored sets: a rotation by 180° matches them; still det = +1.
  std::vector<Vec3> planar{{0, 0, 0}, {10, 0, 0}, {0, 7, 0}, {4, 9, 0}}, planar_m;
  for (const auto& p : planar) planar_m.push_back({p[0], p[1], -p[2]});
  const LandmarkFit pf = fit_landmarks(planar, planar_m, TransformKind::Rigid);
  EXPECT_NEAR(pf.transform.determinant(), 1.0, 1e-12);
  EXPECT_LT(pf.rms, 1e-12);
  // The affine model may reflect: it recovers the mirror exactly.
  const LandmarkFit af = fit_landmarks(fixed, mirrored, TransformKind::Affine);
  EXPECT_NEAR(af.transform.determinant(), -1.0, 1e-9);
  EXPECT_LT(af.rms, 1e-9);
}

TEST(LandmarkFit, DegenerateInputsAreClearErrors) {
  const auto expect_error = [](const std::vector<Vec3>& f, const std::vector<Vec3>& m, TransformKind k,
                               const std::string& text) {
    try {
      (void)fit_landmarks(f, m, k, "input 'landmarks'");
      ADD_FAILURE() << "no error for " << text;
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(text), std::string::npos) << msg;
      EXPECT_NE(msg.find("input 'landmarks'"), std::string::npos) << msg;
    }
  };
  const std::vector<Vec3> two{{0, 0, 0}, {1, 2, 3}};
  expect_error(two, two, TransformKind::Rigid, "needs at least 3");
  const auto three = random_points(3, 1);
  expect_error(three, three, TransformKind::Affine, "needs at least 4");
  expect_error(three, random_points(4, 2), TransformKind::Rigid, "correspond one to one");
  std::vector<Vec3> line;
  for (int i = 0; i < 6; ++i) line.push_back({1.0 + 2.0 * i, 3.0 - i, 0.5 * i});
  for (TransformKind k : {TransformKind::Rigid, TransformKind::Similarity, TransformKind::Affine})
    expect_error(line, line, k, "collinear");
  // Moving set fine, fixed set collinear: also an error (the fit would be undetermined).
  expect_error(line, random_points(6, 4), TransformKind::Rigid, "fixed landmarks are collinear");
  std::vector<Vec3> plane{{0, 0, 1}, {5, 0, 1}, {0, 5, 1}, {5, 5, 1}, {2, 3, 1}};
  expect_error(plane, plane, TransformKind::Affine, "coplanar");
  const std::vector<Vec3> same(4, Vec3{1, 1, 1});
  expect_error(same, same, TransformKind::Rigid, "coincide");
}

TEST(LandmarkFit, ResidualTableAndClassification) {
  const auto moving = random_points(5, 8);
  auto fixed = apply_all(known_rigid(), moving);
  fixed[2][0] += 3.0;  // one bad landmark
  const LandmarkFit fit = fit_landmarks(fixed, moving, TransformKind::Rigid);
  const Table t = residual_table({"a", "b", "c", "d", "e"}, fixed, moving, fit, "mm");
  ASSERT_EQ(t.rows(), 6);
  EXPECT_EQ(t.strings("landmark").back(), "RMS");
  EXPECT_EQ(t.column("distance").unit, "mm");  // the landmarks' unit, never a fixed one
  EXPECT_EQ(t.strings("landmark")[2], "c");
  double s = 0.0;
  for (int i = 0; i < 5; ++i) s += t.reals("distance")[i] * t.reals("distance")[i];
  EXPECT_NEAR(t.reals("distance")[5], std::sqrt(s / 5), 1e-12);
  EXPECT_NEAR(fit.rms, std::sqrt(s / 5), 1e-12);
  // The bad landmark has the largest residual.
  for (int i = 0; i < 5; ++i) {
    if (i != 2) {
      EXPECT_LT(t.reals("distance")[i], t.reals("distance")[2]);
    }
  }
  EXPECT_EQ(classify_transform(known_rigid().matrix()), TransformKind::Rigid);
  EXPECT_EQ(classify_transform(known_similarity().matrix()), TransformKind::Similarity);
  EXPECT_EQ(classify_transform(known_affine().matrix()), TransformKind::Affine);
  Matrix4 mirror = Transform::identity().matrix();
  mirror[0][0] = -1;
  EXPECT_EQ(classify_transform(mirror), TransformKind::Affine);
}
