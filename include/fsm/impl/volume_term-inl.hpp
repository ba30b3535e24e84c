#pragma once

// Definitions for fsm/volume_term.hpp.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace fsm {

namespace detail {

/// Signed volume of (a, b, c, d) and its gradient with respect to the four corners.
template <typename Scalar>
inline Scalar tet_volume_gradient(const Vector3<Scalar>& a, const Vector3<Scalar>& b,
                                  const Vector3<Scalar>& c, const Vector3<Scalar>& d,
                                  Vector3<Scalar> g[4]) noexcept {
  const Vector3<Scalar> e1 = b - a, e2 = c - a, e3 = d - a;
  const Scalar sixth = Scalar(1) / Scalar(6);
  g[1] = sixth * e2.cross(e3);
  g[2] = sixth * e3.cross(e1);
  g[3] = sixth * e1.cross(e2);
  g[0] = -(g[1] + g[2] + g[3]);
  return e1.dot(g[1]);
}

}  // namespace detail

template <typename Scalar>
VolumeTerm<Scalar>::VolumeTerm(const TetrahedronArray& tetrahedra,
                               const ConstPositionsRef& rest_positions, Scalar bulk_modulus)
    : m_tets(tetrahedra),
      m_rest_volume(tetrahedra.rows()),
      m_rest(rest_positions),
      m_num_nodes(Index(rest_positions.rows())) {
  set_bulk_modulus(bulk_modulus);
  const std::string what = "volume term";
  if (!rest_positions.allFinite()) throw Error("", what, "rest positions are not finite");
  for (Index t = 0; t < Index(m_tets.rows()); ++t) {
    const std::string tet = "tetrahedron " + std::to_string(t);
    Vector3<Scalar> p[4];
    for (int k = 0; k < 4; ++k) {
      const Index i = m_tets(t, k);
      if (i < 0 || i >= m_num_nodes)
        throw Error("", what,
                    tet + " names node " + std::to_string(i) + ", out of range [0, " +
                        std::to_string(m_num_nodes) + ")");
      for (int q = 0; q < k; ++q)
        if (m_tets(t, q) == i) throw Error("", what, tet + " repeats node " + std::to_string(i));
      p[k] = rest_positions.row(i).transpose();
    }
    Vector3<Scalar> g[4];
    const Scalar v = detail::tet_volume_gradient(p[0], p[1], p[2], p[3], g);
    Scalar edge = 0;
    for (int k = 0; k < 4; ++k)
      for (int q = 0; q < k; ++q) edge += (p[k] - p[q]).norm();
    edge /= Scalar(6);
    if (!(std::abs(v) > Scalar(1e-12) * edge * edge * edge))
      throw Error("", what, tet + " is flat (rest volume " + std::to_string(double(v)) + " m^3)");
    m_rest_volume[t] = v;
  }
}

template <typename Scalar>
Scalar VolumeTerm<Scalar>::bulk_modulus_for(Scalar youngs_modulus, Scalar poisson) {
  if (!(std::isfinite(youngs_modulus) && youngs_modulus > 0))
    throw Error("", "volume term", "Young's modulus must be positive");
  if (!(poisson >= Scalar(0.25) && poisson < Scalar(0.5)))
    throw Error("", "volume term",
                "Poisson's ratio " + std::to_string(double(poisson)) +
                    " outside [0.25, 0.5) (a spring network already has 0.25)");
  const Scalar mu = Scalar(0.4) * youngs_modulus;
  const Scalar k_target = Scalar(2) * mu * (1 + poisson) / (Scalar(3) * (1 - 2 * poisson));
  return std::max(Scalar(0), k_target - Scalar(2) * youngs_modulus / Scalar(3));
}

template <typename Scalar>
void VolumeTerm<Scalar>::set_bulk_modulus(Scalar bulk_modulus) {
  if (!(std::isfinite(bulk_modulus) && bulk_modulus >= 0))
    throw Error("", "volume term",
                "bulk modulus " + std::to_string(double(bulk_modulus)) +
                    " Pa must be finite and non-negative");
  m_kappa = bulk_modulus;
}

template <typename Scalar>
Scalar VolumeTerm<Scalar>::energy(const ConstPositionsRef& x) const noexcept {
  Scalar e = 0;
  Vector3<Scalar> g[4];
  for (Index t = 0; t < Index(m_tets.rows()); ++t) {
    const Scalar v = detail::tet_volume_gradient<Scalar>(
        x.row(m_tets(t, 0)).transpose(), x.row(m_tets(t, 1)).transpose(),
        x.row(m_tets(t, 2)).transpose(), x.row(m_tets(t, 3)).transpose(), g);
    const Scalar dv = v - m_rest_volume[t];
    e += dv * dv / std::abs(m_rest_volume[t]);
  }
  return Scalar(0.5) * m_kappa * e;
}

template <typename Scalar>
void VolumeTerm<Scalar>::add_forces(const ConstPositionsRef& x, PositionsRef f) const noexcept {
  if (m_kappa == Scalar(0)) return;
  Vector3<Scalar> g[4];
  for (Index t = 0; t < Index(m_tets.rows()); ++t) {
    const Scalar v = detail::tet_volume_gradient<Scalar>(
        x.row(m_tets(t, 0)).transpose(), x.row(m_tets(t, 1)).transpose(),
        x.row(m_tets(t, 2)).transpose(), x.row(m_tets(t, 3)).transpose(), g);
    // |V0| so that a tetrahedron stored with negative orientation is penalised the same way.
    const Scalar s = -m_kappa * (v - m_rest_volume[t]) / std::abs(m_rest_volume[t]);
    for (int k = 0; k < 4; ++k) f.row(m_tets(t, k)) += (s * g[k]).transpose();
  }
}

template <typename Scalar>
Scalar VolumeTerm<Scalar>::omega_max_squared(
    const Eigen::Ref<const ScalarArray<Scalar>>& masses,
    const Eigen::Ref<const Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1>>& fixed) const {
  if (masses.size() != m_num_nodes || fixed.size() != m_num_nodes)
    throw Error("", "volume term",
                "masses and fixed flags must have " + std::to_string(m_num_nodes) + " entries");
  // Row i of M^-1/2 H M^-1/2 in 3x3 blocks: (kappa/V0) g_i g_k^T / sqrt(m_i m_k), whose norm is
  // (kappa/V0) |g_i| |g_k| / sqrt(m_i m_k); the diagonal block's largest eigenvalue is the same
  // expression with k = i. Block Gershgorin: the largest row sum bounds the largest eigenvalue.
  std::vector<double> row(std::size_t(m_num_nodes), 0.0);
  Vector3<Scalar> g[4];
  for (Index t = 0; t < Index(m_tets.rows()); ++t) {
    detail::tet_volume_gradient<Scalar>(
        m_rest.row(m_tets(t, 0)).transpose(), m_rest.row(m_tets(t, 1)).transpose(),
        m_rest.row(m_tets(t, 2)).transpose(), m_rest.row(m_tets(t, 3)).transpose(), g);
    const double c = double(m_kappa) / std::abs(double(m_rest_volume[t]));
    for (int k = 0; k < 4; ++k) {
      const Index i = m_tets(t, k);
      if (fixed[i]) continue;
      for (int q = 0; q < 4; ++q) {
        const Index j = m_tets(t, q);
        if (fixed[j]) continue;
        row[std::size_t(i)] += c * double(g[k].norm()) * double(g[q].norm()) /
                               std::sqrt(double(masses[i]) * double(masses[j]));
      }
    }
  }
  double w2 = 0;
  for (double r : row) w2 = std::max(w2, r);
  return Scalar(w2);
}

}  // namespace fsm
