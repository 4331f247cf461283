#pragma once
// Transform: a 3D affine map in physical units as a 4x4 homogeneous matrix (type id "transform"),
// with its kind (rigid, similarity, affine). Points are column vectors: p' = A p + t, where
// A = matrix[0..2][0..2] and t = matrix[0..2][3]; the bottom row is always (0 0 0 1).
// A registration result maps *moving* coordinates onto *fixed* coordinates.
#include <array>
#include <string>

#include "skel/data.hpp"
#include "skel/enum_names.hpp"
#include "skel/volume.hpp"

namespace skel {

enum class TransformKind { Rigid, Similarity, Affine };
constexpr auto enum_names(TransformKind) {
  return std::to_array<EnumName<TransformKind>>(
      {{TransformKind::Rigid, "rigid"}, {TransformKind::Similarity, "similarity"}, {TransformKind::Affine, "affine"}});
}

// "rigid" | "similarity" | "affine".
std::string to_string(TransformKind kind);
// Parses the names above; throws InputError naming `what` otherwise.
TransformKind parse_transform_kind(const std::string& text, const std::string& what = "kind");

using Matrix3 = std::array<std::array<double, 3>, 3>;  // row-major: m[row][col]
using Matrix4 = std::array<std::array<double, 4>, 4>;  // row-major: m[row][col]

class Transform final : public DataObject {
public:
  Transform() = default;  // identity, rigid
  // Throws InputError if the bottom row is not (0 0 0 1) or an entry is not finite.
  explicit Transform(const Matrix4& matrix, TransformKind kind = TransformKind::Affine);
  // p' = linear * p + translation.
  Transform(const Matrix3& linear, const Vec3& translation, TransformKind kind = TransformKind::Affine);

  [[nodiscard]] static Transform identity() { return {}; }
  [[nodiscard]] static Transform translation(const Vec3& t);
  // Rotation by `angle` radians about the unit-normalised `axis` through the origin (rigid).
  [[nodiscard]] static Transform rotation(const Vec3& axis, double angle);
  [[nodiscard]] static Transform scaling(double s);  // uniform scale about the origin (similarity)

  [[nodiscard]] const Matrix4& matrix() const { return m_; }
  [[nodiscard]] Matrix3 linear() const;
  [[nodiscard]] Vec3 translation_part() const { return {m_[0][3], m_[1][3], m_[2][3]}; }
  [[nodiscard]] TransformKind kind() const { return kind_; }
  void set_kind(TransformKind kind) { kind_ = kind; }

  // A p + t.
  [[nodiscard]] Vec3 apply(const Vec3& p) const {
    return {m_[0][0] * p[0] + m_[0][1] * p[1] + m_[0][2] * p[2] + m_[0][3],
            m_[1][0] * p[0] + m_[1][1] * p[1] + m_[1][2] * p[2] + m_[1][3],
            m_[2][0] * p[0] + m_[2][1] * p[1] + m_[2][2] * p[2] + m_[2][3]};
  }
  // A v (directions, displacements).
  [[nodiscard]] Vec3 apply_vector(const Vec3& v) const {
    return {m_[0][0] * v[0] + m_[0][1] * v[1] + m_[0][2] * v[2],
            m_[1][0] * v[0] + m_[1][1] * v[1] + m_[1][2] * v[2],
            m_[2][0] * v[0] + m_[2][1] * v[1] + m_[2][2] * v[2]};
  }
  // The inverse map (same kind); throws InputError if the linear part is singular.
  [[nodiscard]] Transform inverse() const;
  // this ∘ first: applies `first`, then this. Kind is the more general of both.
  [[nodiscard]] Transform compose(const Transform& first) const;
  // Determinant of the linear part (< 0: the map contains a reflection).
  [[nodiscard]] double determinant() const;
  // Uniform scale factor: |det|^(1/3) (1 for rigid, s for a similarity). Radii and lengths scale by
  // it exactly for rigid and similarity maps, on average for affine ones.
  [[nodiscard]] double scale() const;
  // Largest absolute difference of matrix entries.
  [[nodiscard]] double max_difference(const Transform& o) const;

  bool operator==(const Transform& o) const { return m_ == o.m_ && kind_ == o.kind_; }

  // DataObject
  [[nodiscard]] std::string type_id() const override { return type_ids::transform; }
  [[nodiscard]] uint64_t bytes() const override { return sizeof(Transform); }
  [[nodiscard]] std::string describe() const override;

private:
  Matrix4 m_{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}};
  TransformKind kind_ = TransformKind::Rigid;
};

// World coordinates of a point p of a volume's axis-aligned frame (origin + index·spacing, where
// the algorithms work): origin + direction·(p − origin). What graph and mesh files hold, so that
// they overlay the image in other tools (io/graph_io.cpp, io/mesh_io.cpp).
inline Vec3 world_position(const Vec3& p, const Vec3& origin, const Direction& d) {
  const Vec3 q{p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]};
  return {origin[0] + d[0] * q[0] + d[1] * q[1] + d[2] * q[2], origin[1] + d[3] * q[0] + d[4] * q[1] + d[5] * q[2],
          origin[2] + d[6] * q[0] + d[7] * q[1] + d[8] * q[2]};
}

}  // namespace skel
