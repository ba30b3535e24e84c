#pragma once

// Definitions for fsm/skinning.hpp.

#include <cmath>

namespace fsm {

namespace detail {
// Unit quaternion (w, x, y, z) of the smallest rotation taking unit vector a to unit vector b.
// Antiparallel vectors turn about an axis perpendicular to a.
template <typename Scalar>
Eigen::Matrix<Scalar, 4, 1> minimal_rotation(const Vector3<Scalar>& a,
                                             const Vector3<Scalar>& b) noexcept {
  Eigen::Matrix<Scalar, 4, 1> q;
  const Scalar w = Scalar(1) + a.dot(b);
  if (w < Scalar(1e-6)) {
    Vector3<Scalar> axis = a.cross(Vector3<Scalar>::UnitX());
    if (axis.squaredNorm() < Scalar(1e-6)) axis = a.cross(Vector3<Scalar>::UnitY());
    axis.normalize();
    q << Scalar(0), axis;
    return q;
  }
  q << w, a.cross(b);
  return q / q.norm();
}

template <typename Scalar>
Vector3<Scalar> rotate(const Eigen::Matrix<Scalar, 4, 1>& q, const Vector3<Scalar>& v) noexcept {
  const Vector3<Scalar> u = q.template tail<3>();
  const Vector3<Scalar> t = Scalar(2) * u.cross(v);
  return v + q[0] * t + u.cross(t);
}

template <typename Scalar>
Vector3<Scalar> unit_or_zero(const Vector3<Scalar>& v) noexcept {
  const Scalar n = v.norm();
  return n > Scalar(0) ? Vector3<Scalar>(v / n) : Vector3<Scalar>::Zero();
}
}  // namespace detail

template <typename Scalar>
void Skin<Scalar>::validate(Index num_spheres) const {
  const Index n = rest.num_vertices();
  auto fail = [](const std::string& where, const std::string& why) { throw Error("", where, why); };
  rest.validate("skin");
  if (kind.rows() != n || nodes.rows() != n || weights.rows() != n || offsets.rows() != n)
    fail("skin", "per-vertex arrays do not match the " + std::to_string(n) + " render vertices");
  if (chain_rest_tangents.rows() != chain_nodes.rows())
    fail("skin", "chain tables have different lengths");
  // Ranges in 64 bits: a crafted first index near 2^31 plus a count must not wrap.
  const auto inside = [](Index first, Index count, Index size) {
    return first >= 0 && count >= 0 && std::int64_t(first) + std::int64_t(count) <= size;
  };
  for (const Surface& s : surfaces)
    if (!inside(s.first_vertex, s.num_vertices, n) ||
        !inside(s.first_face, s.num_faces, rest.num_faces()))
      fail("surface '" + s.name + "'", "range outside the skin");
  if ((chain_nodes.array() < 0).any() || (chain_nodes.array() >= num_spheres).any())
    fail("skin", "a chain node names a sphere out of range");
  if (!chain_rest_tangents.allFinite() || !weights.allFinite() || !offsets.allFinite())
    fail("skin", "a weight, offset or tangent is not finite");
  for (Index v = 0; v < n; ++v) {
    const std::string where = "skin vertex " + std::to_string(v);
    if (kind[v] == std::uint8_t(SkinKind::barycentric)) {
      for (int k = 0; k < 4; ++k)
        if (nodes(v, k) < 0 || nodes(v, k) >= num_spheres) fail(where, "sphere index out of range");
      if (std::abs(weights.row(v).sum() - Scalar(1)) > Scalar(1e-4))
        fail(where, "barycentric weights do not sum to 1");
    } else if (kind[v] == std::uint8_t(SkinKind::chain)) {
      for (int k = 0; k < 2; ++k)
        if (nodes(v, k) < 0 || nodes(v, k) >= Index(chain_nodes.rows()))
          fail(where, "chain node index out of range");
      // The two rows are blended by (w0, w1): a convex pair, or the blended rotation is 0 / 0.
      if (!(weights(v, 0) >= Scalar(0) && weights(v, 1) >= Scalar(0)) ||
          std::abs(weights(v, 0) + weights(v, 1) - Scalar(1)) > Scalar(1e-4))
        fail(where, "chain weights must be non-negative and sum to 1");
    } else {
      fail(where, "unknown binding kind " + std::to_string(int(kind[v])));
    }
  }
}

template <typename Scalar>
void Skin<Scalar>::evaluate(const Eigen::Ref<const Positions<Scalar>>& x, Workspace& ws,
                            Eigen::Ref<Positions<Scalar>> out) const noexcept {
  using V3 = Vector3<Scalar>;
  using Q = Eigen::Matrix<Scalar, 4, 1>;
  // Each chain node's rotation: rest tangent to current tangent.
  for (Index k = 0; k < Index(chain_nodes.rows()); ++k) {
    const V3 t = detail::unit_or_zero<Scalar>(
        (x.row(chain_nodes(k, 2)) - x.row(chain_nodes(k, 0))).transpose());
    const Q q = t.squaredNorm() > Scalar(0)
                    ? detail::minimal_rotation<Scalar>(chain_rest_tangents.row(k).transpose(), t)
                    : Q(Scalar(1), Scalar(0), Scalar(0), Scalar(0));
    ws.rotation.row(k) = q.transpose();
  }
  for (Index v = 0; v < rest.num_vertices(); ++v) {
    const auto w = weights.row(v);
    if (kind[v] == std::uint8_t(SkinKind::barycentric)) {
      out.row(v) = w[0] * x.row(nodes(v, 0)) + w[1] * x.row(nodes(v, 1)) +
                   w[2] * x.row(nodes(v, 2)) + w[3] * x.row(nodes(v, 3));
    } else {
      const Index a = nodes(v, 0), b = nodes(v, 1);
      const V3 p = (w[0] * x.row(chain_nodes(a, 1)) + w[1] * x.row(chain_nodes(b, 1))).transpose();
      Q qa = ws.rotation.row(a).transpose(), qb = ws.rotation.row(b).transpose();
      if (qa.dot(qb) < Scalar(0)) qb = -qb;  // same hemisphere: the short way round
      Q q = w[0] * qa + w[1] * qb;
      q *= Scalar(1) / q.norm();
      out.row(v) = (p + detail::rotate<Scalar>(q, offsets.row(v).transpose())).transpose();
    }
  }
}

}  // namespace fsm
