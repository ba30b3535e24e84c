#pragma once

/// @file stability.hpp
/// @brief Bounds on a model's highest eigenfrequency and damping rate, and the largest stable
/// step of each explicit scheme for them (REFERENCE.md section 2).

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

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

/// @brief Gershgorin (block) bounds for a model at rest.
///
/// For each free node i, \f$\lambda_{max}(\mathbf{M}^{-1/2}\mathbf{K}\mathbf{M}^{-1/2}) \le
/// \max_i \sum_{l\ni i} k_l\,(1/m_i + [j\ \text{free}]/\sqrt{m_i m_j})\f$, with \f$k_l\f$ the larger
/// of the link's two stiffnesses; the same with \f$k_d\f$ bounds the damping rate (for full
/// relative-velocity damping the blocks are \f$k_d\mathbf{I}\f$, same norm). Exact for two equal
/// spheres; the geometric stiffness of pre-stressed links is not included.
template <typename Scalar>
[[nodiscard]] SpectralBound<Scalar> spectral_bound(const SphereModel<Scalar>& model) {
  const Index n = model.num_nodes();
  ScalarArray<Scalar> ks = ScalarArray<Scalar>::Zero(n), kd = ScalarArray<Scalar>::Zero(n);
  const auto links = model.links();
  const auto mass = model.masses();
  const auto fixed = model.fixed();
  const auto stiff = model.stiffness();
  const auto large = model.large_stiffness();
  const auto damp = model.damping();
  Scalar tau = std::numeric_limits<Scalar>::infinity();
  for (Index l = 0; l < model.num_links(); ++l) {
    const Index i = links(l, 0), j = links(l, 1);
    const Scalar k = std::max(stiff[l], large[l]);
    tau = std::min(tau, damp[l] / k);
    const Scalar cross = Scalar(1) / std::sqrt(mass[i] * mass[j]);
    if (!fixed[i]) {
      const Scalar w = Scalar(1) / mass[i] + (fixed[j] ? Scalar(0) : cross);
      ks[i] += k * w;
      kd[i] += damp[l] * w;
    }
    if (!fixed[j]) {
      const Scalar w = Scalar(1) / mass[j] + (fixed[i] ? Scalar(0) : cross);
      ks[j] += k * w;
      kd[j] += damp[l] * w;
    }
  }
  SpectralBound<Scalar> b;
  b.omega_max = n > 0 ? std::sqrt(ks.maxCoeff()) : Scalar(0);
  b.damping_max = n > 0 ? kd.maxCoeff() : Scalar(0);
  b.retardation_min = model.num_links() > 0 ? tau : Scalar(0);
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
/// \f$h < \min(2c/\omega^2, 2/c)\f$ per mode; over all modes \f$h < \min(2\tau_{min}, 2/c_{max})\f$.
/// Zero without damping: the scheme then grows at every step size.
template <typename Scalar>
[[nodiscard]] Scalar improved_euler_limit(const SpectralBound<Scalar>& b) noexcept {
  if (!(b.damping_max > 0)) return b.omega_max > 0 ? Scalar(0) : std::numeric_limits<Scalar>::infinity();
  return std::min(2 * b.retardation_min, Scalar(2) / b.damping_max);
}

/// @brief Largest stable step of Heun's method (eq. 9, explicit RK2): the largest h with
/// \f$|1 + h\lambda + (h\lambda)^2/2| \le 1\f$ for the top mode's eigenvalues
/// \f$\lambda = -c/2 \pm \sqrt{c^2/4 - \omega^2}\f$, \f$c = \min(c_{max}, \tau_{min}\omega_{max}^2)\f$.
/// Zero without damping (\f$|R(i\omega h)| = \sqrt{1 + (\omega h)^4/4} > 1\f$).
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
  return Scalar(lo);
}

}  // namespace fsm
