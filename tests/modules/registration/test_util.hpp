#pragma once
// Shared helpers for the registration tests: seeded random points and transforms.
#include <cmath>
#include <random>
#include <vector>

#include "skel/transform.hpp"

namespace skel::test {

inline std::vector<Vec3> random_points(size_t n, uint32_t seed, double extent = 50.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<Vec3> p(n);
  for (auto& q : p) q = {u(rng), u(rng), u(rng)};
  return p;
}

inline std::vector<Vec3> apply_all(const Transform& t, const std::vector<Vec3>& p) {
  std::vector<Vec3> out;
  out.reserve(p.size());
  for (const auto& q : p) out.push_back(t.apply(q));
  return out;
}

inline Transform known_rigid() {
  return Transform::translation({12.5, -7.25, 3.0}).compose(Transform::rotation({0.3, -1.0, 0.7}, 0.9));
}
inline Transform known_similarity() {
  Transform t = known_rigid().compose(Transform::scaling(1.37));
  t.set_kind(TransformKind::Similarity);
  return t;
}
inline Transform known_affine() {
  return Transform(Matrix3{{{1.2, 0.15, -0.3}, {0.05, 0.8, 0.22}, {-0.1, 0.3, 1.4}}}, {4.0, -2.0, 9.5},
                   TransformKind::Affine);
}

inline double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

}  // namespace skel::test
