#pragma once

/// @file stability.hpp
/// @brief Bounds on a model's highest eigenfrequency and damping rate, and the largest stable
/// step of each explicit scheme for them (docs/physics.md section 10.2).

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

#include <Eigen/Eigenvalues>

#include "fsm/detail/continuum.hpp"
#include "fsm/sphere_model.hpp"

namespace fsm {

/// @brief What the explicit schemes' stability depends on.
///
/// For a mode with angular frequency \f$\omega\f$ and damping rate \f$c\f$ the linearised
/// motion is \f$\ddot q = -\omega^2 q - c\dot q\f$.
template <typename Scalar>
struct SpectralBound {
  /// Upper bound on the highest angular eigenfrequency \f$\omega_{max}\f$ (rad/s) of
  /// \f$\mathbf{M}^{-1}\mathbf{K}\f$.
  Scalar omega_max{0};
  /// Upper bound on the highest damping rate \f$c_{max}\f$ (1/s), eigenvalue of
  /// \f$\mathbf{M}^{-1}\mathbf{D}\f$.
  Scalar damping_max{0};
  /// Smallest ratio \f$\tau = k_d/k\f$ (s) over links: a lower bound on \f$c/\omega^2\f$ per mode
  /// when damping is proportional to stiffness (a Voigt material: \f$\tau = \eta/E\f$).
  Scalar retardation_min{0};

  /// @brief The bound for one damped oscillator \f$\ddot q = -\omega^2 q - c\dot q\f$.
  static SpectralBound oscillator(Scalar omega, Scalar c) {
    return {omega, c, omega > 0 ? c / (omega * omega) : std::numeric_limits<Scalar>::infinity()};
  }
};

/// @brief Block-Gershgorin bounds for a model at rest.
///
/// In \f$\mathbf{A} = \mathbf{M}^{-1/2}\mathbf{K}\mathbf{M}^{-1/2}\f$ the diagonal block of a
/// free node is \f$\mathbf{S}_i/m_i\f$ with \f$\mathbf{S}_i = \sum_{l\ni i} k_l\mathbf{n}_l
/// \mathbf{n}_l^T\f$ and the off-diagonal block of a link to a free node has norm
/// \f$k_l/\sqrt{m_i m_j}\f$, so (Feingold and Varga's block Gershgorin theorem)
/// \f[ \omega_{max}^2 \le \max_i \Big[\lambda_{max}(\mathbf{S}_i)/m_i +
///     \sum_{l\ni i,\,j\,\text{free}} k_l/\sqrt{m_i m_j}\Big], \f]
/// with \f$k_l\f$ the larger of a bilinear link's two stiffnesses. The same with \f$k_d\f$ bounds
/// the damping rate (blocks \f$k_d\mathbf{n}\mathbf{n}^T\f$ along the link, \f$k_d\mathbf{I}\f$ for
/// full relative-velocity damping). Exact for two equal spheres; the geometric stiffness of
/// pre-stressed links is not included. Links inside continuum regions carry no force and are left
/// out; a continuum region's elements add, per node, the Gershgorin row sum of their rest tangent
/// (edge springs and volumetric term, ContinuumTerm::add_node_stiffness) over its mass, and the
/// same times the region's retardation time for damping.
template <typename Scalar>
[[nodiscard]] SpectralBound<Scalar> spectral_bound(
    const SphereModel<Scalar>& model, DampingModel damping = DampingModel::along_link) {
  const Index n = model.num_nodes();
  // Per node: the upper triangle of S_i (xx, xy, xz, yy, yz, zz) for stiffness and damping, and
  // the off-diagonal sums.
  Eigen::Matrix<double, Eigen::Dynamic, 6> ks =
      Eigen::Matrix<double, Eigen::Dynamic, 6>::Zero(n, 6);
  Eigen::Matrix<double, Eigen::Dynamic, 6> kd = ks;
  Eigen::VectorXd ks_off = Eigen::VectorXd::Zero(n), kd_off = Eigen::VectorXd::Zero(n);
  const auto links = model.links();
  const auto x = model.rest_positions();
  const auto mass = model.masses();
  const auto fixed = model.fixed();
  const auto stiff = model.stiffness();
  const auto large = model.large_stiffness();
  const auto damp = model.damping();
  double tau = std::numeric_limits<double>::infinity();
  const auto region = model.node_regions();
  for (Index l = 0; l < model.num_links(); ++l) {
    const Index i = links(l, 0), j = links(l, 1);
    if (region[i] == region[j] && model.region(region[i]).law == ForceLaw::continuum) continue;
    const bool bilinear = std::isfinite(double(model.switch_strain()[l]));
    const double k = bilinear ? std::max(double(stiff[l]), double(large[l])) : double(stiff[l]);
    const double c = double(damp[l]);
    tau = std::min(tau, c / k);
    const Eigen::Vector3d d = (x.row(j) - x.row(i)).template cast<double>().transpose();
    const double eye[6] = {1, 0, 0, 1, 0, 1};
    double nn[6] = {1, 0, 0, 1, 0, 1};  // no rest direction: bound the block by k I
    if (d.norm() > 0) {
      const Eigen::Vector3d u = d / d.norm();
      const double v[6] = {u.x() * u.x(), u.x() * u.y(), u.x() * u.z(),
                           u.y() * u.y(), u.y() * u.z(), u.z() * u.z()};
      std::copy(v, v + 6, nn);
    }
    const double* dshape = damping == DampingModel::along_link ? nn : eye;
    const double cross = 1.0 / std::sqrt(double(mass[i]) * double(mass[j]));
    for (const auto& [a, b] : {std::pair{i, j}, std::pair{j, i}}) {
      if (fixed[a]) continue;
      for (int e = 0; e < 6; ++e) {
        ks(a, e) += k * nn[e];
        kd(a, e) += c * dshape[e];
      }
      if (!fixed[b]) {
        ks_off[a] += k * cross;
        kd_off[a] += c * cross;
      }
    }
  }
  auto lmax = [](const auto& row) {
    Eigen::Matrix3d S;
    S << row(0), row(1), row(2), row(1), row(3), row(4), row(2), row(4), row(5);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(S, Eigen::EigenvaluesOnly);
    return es.eigenvalues().maxCoeff();
  };
  // The continuum elements: a Gershgorin row-sum bound per node.
  std::vector<Scalar> element_k;
  detail::ContinuumTerm<Scalar> elements;
  if (model.has_continuum()) {
    elements.refresh(model);
    element_k.assign(std::size_t(n), Scalar(0));
    elements.add_node_stiffness(model, element_k.data());
    for (const Region<Scalar>& r : model.regions())
      if (r.law == ForceLaw::continuum) tau = std::min(tau, double(r.material.retardation_time()));
  }
  double w2 = 0, c = 0;
  for (Index i = 0; i < n; ++i) {
    if (fixed[i]) continue;
    const double ke = element_k.empty() ? 0.0 : double(element_k[std::size_t(i)]);
    const double ce = element_k.empty() ? 0.0 : double(elements.node_tau(i)) * ke;
    w2 = std::max(w2, lmax(ks.row(i)) / double(mass[i]) + ks_off[i] + ke / double(mass[i]));
    c = std::max(c, lmax(kd.row(i)) / double(mass[i]) + kd_off[i] + ce / double(mass[i]));
  }
  SpectralBound<Scalar> b;
  b.omega_max = Scalar(std::sqrt(w2));
  b.damping_max = Scalar(c);
  b.retardation_min = std::isfinite(tau) ? Scalar(tau) : Scalar(0);
  return b;
}

/// @brief Largest stable step of symplectic Euler: \f$\omega^2 h^2 + 2ch - 4 < 0\f$, i.e.
/// \f$h < (\sqrt{c^2 + 4\omega^2} - c)/\omega^2\f$ (\f$2/\omega\f$ undamped).
template <typename Scalar>
[[nodiscard]] Scalar symplectic_euler_limit(const SpectralBound<Scalar>& b) noexcept {
  const Scalar w = b.omega_max, c = b.damping_max;
  if (!(w > 0)) return c > 0 ? Scalar(2) / c : std::numeric_limits<Scalar>::infinity();
  return (std::sqrt(c * c + 4 * w * w) - c) / (w * w);
}

/// @brief Largest stable step of the paper's eq. 10: the update's determinant
/// \f$1 - ch + \omega^2h^2/2\f$ must stay below 1 and the trace condition gives \f$ch < 2\f$, so
/// \f$h < \min(2c/\omega^2, 2/c)\f$ per mode; over all modes \f$h < \min(2\tau_{min},
/// 2/c_{max})\f$. Zero without damping: the scheme then grows at every step size.
template <typename Scalar>
[[nodiscard]] Scalar improved_euler_limit(const SpectralBound<Scalar>& b) noexcept {
  if (!(b.damping_max > 0))
    return b.omega_max > 0 ? Scalar(0) : std::numeric_limits<Scalar>::infinity();
  return std::min(2 * b.retardation_min, Scalar(2) / b.damping_max);
}

/// @brief Largest stable step of Heun's method (eq. 9, explicit RK2): the largest h with
/// \f$|1 + h\lambda + (h\lambda)^2/2| \le 1\f$ for the top mode's eigenvalues
/// \f$\lambda = -c/2 \pm \sqrt{c^2/4 - \omega^2}\f$, \f$c = \min(c_{max},
/// \tau_{min}\omega_{max}^2)\f$. Zero without damping (\f$|R(i\omega h)| = \sqrt{1 + (\omega
/// h)^4/4} > 1\f$). A model whose links have different retardation times can also have a heavily
/// damped mode with eigenvalue near \f$-c_{max}\f$, stable only for \f$h \le 2/c_{max}\f$ (the
/// region's real interval): when \f$c_{max} > \tau_{min}\omega_{max}^2\f$ the result is the
/// smaller of the two.
template <typename Scalar>
[[nodiscard]] Scalar heun_limit(const SpectralBound<Scalar>& b) noexcept {
  const double w = double(b.omega_max);
  if (!(w > 0)) return std::numeric_limits<Scalar>::infinity();
  const double c = std::min(double(b.damping_max), double(b.retardation_min) * w * w);
  if (!(c > 0)) return Scalar(0);
  const std::complex<double> disc = std::sqrt(std::complex<double>(c * c / 4 - w * w, 0));
  const std::complex<double> l1 = -c / 2 + disc, l2 = -c / 2 - disc;
  auto stable = [&](double h) {
    auto r = [&](std::complex<double> z) { return std::abs(1.0 + z + z * z / 2.0); };
    return r(h * l1) <= 1.0 && r(h * l2) <= 1.0;
  };
  // Scan up from a tiny step to the first unstable one, then bisect.
  double lo = 1e-9 / std::max(w, c), hi = lo;
  while (stable(hi)) {
    lo = hi;
    hi *= 1.01;
    if (hi > 1e6 / w) return std::numeric_limits<Scalar>::infinity();
  }
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    (stable(mid) ? lo : hi) = mid;
  }
  // With damping proportional to stiffness (one retardation time: c_max = tau w_max^2) the top
  // mode decides. Otherwise a mode may be damped far more than it is stiff, with an eigenvalue
  // near -c_max on the real axis, stable only for h <= 2 / c_max.
  const bool proportional = double(b.damping_max) <= c * (1 + 1e-9);
  return Scalar(proportional ? lo : std::min(lo, 2.0 / double(b.damping_max)));
}

}  // namespace fsm
