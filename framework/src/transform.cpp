#include "skel/transform.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "skel/error.hpp"

namespace skel {

std::string to_string(TransformKind kind) { return enum_name(kind); }

TransformKind parse_transform_kind(const std::string& text, const std::string& what) {
  return parse_enum<TransformKind>(text, what);
}

Transform::Transform(const Matrix4& matrix, TransformKind kind) : m_(matrix), kind_(kind) {
  for (const auto& row : m_) {
    for (double v : row) {
      if (!std::isfinite(v)) throw InputError("transform: matrix has a non-finite entry");
    }
  }
  if (m_[3][0] != 0.0 || m_[3][1] != 0.0 || m_[3][2] != 0.0 || m_[3][3] != 1.0) {
    throw InputError("transform: the bottom row of a homogeneous matrix must be 0 0 0 1");
  }
}

Transform::Transform(const Matrix3& a, const Vec3& t, TransformKind kind)
    : Transform(Matrix4{{{a[0][0], a[0][1], a[0][2], t[0]},
                         {a[1][0], a[1][1], a[1][2], t[1]},
                         {a[2][0], a[2][1], a[2][2], t[2]},
                         {0, 0, 0, 1}}},
                kind) {}

Transform Transform::translation(const Vec3& t) {
  return Transform(Matrix3{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}, t, TransformKind::Rigid);
}

Transform Transform::rotation(const Vec3& axis, double angle) {
  const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  if (!(len > 0.0)) throw InputError("transform: rotation axis must not be zero");
  const double x = axis[0] / len, y = axis[1] / len, z = axis[2] / len;
  const double c = std::cos(angle), s = std::sin(angle), C = 1.0 - c;
  const Matrix3 r{{{c + x * x * C, x * y * C - z * s, x * z * C + y * s},
                   {y * x * C + z * s, c + y * y * C, y * z * C - x * s},
                   {z * x * C - y * s, z * y * C + x * s, c + z * z * C}}};
  return Transform(r, {0, 0, 0}, TransformKind::Rigid);
}

Transform Transform::scaling(double s) {
  if (!(s > 0.0)) throw InputError("transform: scale must be > 0");
  return Transform(Matrix3{{{s, 0, 0}, {0, s, 0}, {0, 0, s}}}, {0, 0, 0}, TransformKind::Similarity);
}

Matrix3 Transform::linear() const {
  Matrix3 a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r][c] = m_[r][c];
  return a;
}

double Transform::determinant() const {
  const auto& m = m_;
  return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
         m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

double Transform::scale() const { return std::cbrt(std::abs(determinant())); }

Transform Transform::inverse() const {
  const auto& m = m_;
  const double det = determinant();
  double norm = 0.0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) norm = std::max(norm, std::abs(m[r][c]));
  if (!(std::abs(det) > 1e-300) || std::abs(det) <= 1e-14 * norm * norm * norm) {
    throw InputError("transform: the linear part is singular (determinant " + std::to_string(det) +
                     "); it has no inverse");
  }
  Matrix3 inv{};
  inv[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / det;
  inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
  inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
  inv[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / det;
  inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
  inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
  inv[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / det;
  inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
  inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
  Vec3 t{};
  for (int r = 0; r < 3; ++r) t[r] = -(inv[r][0] * m[0][3] + inv[r][1] * m[1][3] + inv[r][2] * m[2][3]);
  return Transform(inv, t, kind_);
}

Transform Transform::compose(const Transform& first) const {
  Matrix4 out{};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      double s = 0.0;
      for (int k = 0; k < 4; ++k) s += m_[r][k] * first.m_[k][c];
      out[r][c] = s;
    }
  out[3] = {0, 0, 0, 1};
  const TransformKind kind = static_cast<int>(kind_) >= static_cast<int>(first.kind_) ? kind_ : first.kind_;
  return Transform(out, kind);
}

double Transform::max_difference(const Transform& o) const {
  double d = 0.0;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) d = std::max(d, std::abs(m_[r][c] - o.m_[r][c]));
  return d;
}

std::string Transform::describe() const {
  std::ostringstream s;
  s.precision(6);
  s << type_ids::transform << " " << to_string(kind_) << " [";
  for (int r = 0; r < 3; ++r) {
    if (r) s << "; ";
    s << m_[r][0] << " " << m_[r][1] << " " << m_[r][2] << " " << m_[r][3];
  }
  s << "], scale " << scale();
  return s.str();
}

}  // namespace skel
