#pragma once

/// @file voigt_link.hpp
/// @brief VoigtLink: the force law of one link (spring and dashpot in parallel, along the link).

#include <cmath>
#include <limits>

#include "fsm/types.hpp"

namespace fsm {

/// @brief How a link's dashpot sees the relative velocity of its two spheres.
enum class DampingModel {
  /// Damp only the rate of change of the link's length, \f$k_d\,(\mathbf{v}_{ij}\cdot\mathbf{n})\,
  /// \mathbf{n}\f$. The force stays along the link, so rigid motion (translation and rotation)
  /// is never damped and angular momentum is conserved. The default.
  along_link,
  /// The paper's eq. 5, \f$k_d\,\mathbf{v}_{ij}\f$: damps the full relative velocity. Also damps
  /// rigid rotation and does not conserve angular momentum; offered for comparison only.
  full_relative_velocity,
};

/// @brief The Voigt element of one link: an elastic spring and a dashpot in parallel.
///
/// With \f$\mathbf{d} = \mathbf{x}_j - \mathbf{x}_i\f$, \f$l = |\mathbf{d}|\f$,
/// \f$\mathbf{n} = \mathbf{d}/l\f$ and \f$\mathbf{u} = \mathbf{v}_j - \mathbf{v}_i\f$, the force
/// on sphere \f$i\f$ is (the paper's eq. 4-6 with the sign that pulls a stretched link together,
/// see docs/physics.md section 10.1)
/// \f[ \mathbf{F}_i = \big[f_e(l - l_0) + k_d\,(\mathbf{u}\cdot\mathbf{n})\big]\,\mathbf{n},
///     \qquad \mathbf{F}_j = -\mathbf{F}_i, \f]
/// where the elastic force is linear, \f$f_e(e) = k_s e\f$, or bilinear: \f$k_s e\f$ up to the
/// switch extension \f$e_s = \varepsilon_s l_0\f$ and \f$\mathrm{sign}(e)\,[k_s e_s + k_L(|e| -
/// e_s)]\f$ beyond it (the paper's small- and large-deformation moduli, continuous at the switch).
///
/// Units: lengths in m, \f$k_s, k_L\f$ in N/m, \f$k_d\f$ in N s/m, forces in N.
template <typename Scalar>
struct VoigtLink {
  Scalar rest_length{0};      ///< \f$l_0\f$ (m), > 0.
  Scalar stiffness{0};        ///< \f$k_s\f$ (N/m), > 0: small-strain spring constant.
  Scalar damping{0};          ///< \f$k_d\f$ (N s/m), >= 0: dashpot constant.
  Scalar large_stiffness{0};  ///< \f$k_L\f$ (N/m), > 0: beyond the switch strain.
  /// \f$\varepsilon_s\f$ (dimensionless), > 0: |strain| at which \f$k_s\f$ gives way to
  /// \f$k_L\f$; +infinity for a linear link.
  Scalar switch_strain{std::numeric_limits<Scalar>::infinity()};

  /// @brief A linear link (no modulus switch).
  static VoigtLink linear(Scalar rest_length, Scalar stiffness, Scalar damping) {
    return {rest_length, stiffness, damping, stiffness, std::numeric_limits<Scalar>::infinity()};
  }

  /// @brief A bilinear link: \f$k_s\f$ up to |strain| = switch_strain, \f$k_L\f$ beyond.
  static VoigtLink bilinear(Scalar rest_length, Scalar stiffness, Scalar damping,
                            Scalar large_stiffness, Scalar switch_strain) {
    return {rest_length, stiffness, damping, large_stiffness, switch_strain};
  }

  /// @brief True when the modulus switches at a finite strain.
  [[nodiscard]] bool is_bilinear() const noexcept { return std::isfinite(switch_strain); }

  /// @brief Elastic force magnitude (N) for an extension \f$e = l - l_0\f$ (m); positive pulls
  /// the spheres together.
  [[nodiscard]] Scalar elastic_force(Scalar extension) const noexcept {
    const Scalar es = switch_strain * rest_length;
    const Scalar a = std::abs(extension);
    if (a <= es) return stiffness * extension;
    return std::copysign(stiffness * es + large_stiffness * (a - es), extension);
  }

  /// @brief \f$d f_e / d e\f$ (N/m) at an extension (m).
  [[nodiscard]] Scalar tangent_stiffness(Scalar extension) const noexcept {
    return std::abs(extension) <= switch_strain * rest_length ? stiffness : large_stiffness;
  }

  /// @brief Elastic energy (J) stored at an extension (m): the integral of elastic_force.
  [[nodiscard]] Scalar energy(Scalar extension) const noexcept {
    const Scalar es = switch_strain * rest_length;
    const Scalar a = std::abs(extension);
    if (a <= es) return Scalar(0.5) * stiffness * a * a;
    const Scalar b = a - es;
    return Scalar(0.5) * stiffness * es * es + stiffness * es * b +
           Scalar(0.5) * large_stiffness * b * b;
  }

  /// @brief Force (N) on sphere i; the force on sphere j is its negative.
  /// @param xi, xj positions (m); @param vi, vj velocities (m/s).
  /// Coincident spheres (l = 0) have no direction: no elastic force and no along-link damping;
  /// full relative-velocity damping, which needs no direction, still acts.
  [[nodiscard]] Vector3<Scalar> force(
      const Vector3<Scalar>& xi, const Vector3<Scalar>& xj, const Vector3<Scalar>& vi,
      const Vector3<Scalar>& vj, DampingModel model = DampingModel::along_link) const noexcept {
    const Vector3<Scalar> d = xj - xi;
    const Vector3<Scalar> u = vj - vi;
    const Scalar l = d.norm();
    if (!(l > Scalar(0)))
      return model == DampingModel::along_link ? Vector3<Scalar>::Zero()
                                               : Vector3<Scalar>(damping * u);
    const Vector3<Scalar> n = d / l;
    if (model == DampingModel::along_link) {
      return (elastic_force(l - rest_length) + damping * u.dot(n)) * n;
    }
    return elastic_force(l - rest_length) * n + damping * u;
  }

  /// @brief The two Jacobians of the force on sphere i with respect to sphere j's state.
  struct Jacobian {
    Matrix3<Scalar> dx;  ///< \f$\partial\mathbf{F}_i/\partial\mathbf{x}_j\f$ (N/m).
    Matrix3<Scalar> dv;  ///< \f$\partial\mathbf{F}_i/\partial\mathbf{v}_j\f$ (N s/m).
  };

  /// @brief \f$\partial\mathbf{F}_i/\partial\mathbf{x}_j\f$ and
  /// \f$\partial\mathbf{F}_i/\partial\mathbf{v}_j\f$. The other three blocks follow from
  /// \f$\mathbf{F}_j = -\mathbf{F}_i\f$ and the dependence on differences only:
  /// \f$\partial\mathbf{F}_i/\partial\mathbf{x}_i = \partial\mathbf{F}_j/\partial\mathbf{x}_j =
  /// -\mathbf{K}\f$, \f$\partial\mathbf{F}_j/\partial\mathbf{x}_i = \mathbf{K}\f$ (same for v).
  ///
  /// With \f$\mathbf{P} = \mathbf{I} - \mathbf{n}\mathbf{n}^T\f$ and total scalar force \f$f\f$:
  /// along the link,
  /// \f$\mathbf{K} = f_e'\,\mathbf{n}\mathbf{n}^T + \frac{f}{l}\mathbf{P}
  ///   + \frac{k_d}{l}\,\mathbf{n}(\mathbf{P}\mathbf{u})^T\f$ and
  /// \f$\mathbf{D} = k_d\,\mathbf{n}\mathbf{n}^T\f$; with full relative-velocity damping,
  /// \f$\mathbf{K} = f_e'\,\mathbf{n}\mathbf{n}^T + \frac{f_e}{l}\mathbf{P}\f$ and
  /// \f$\mathbf{D} = k_d\mathbf{I}\f$. The last term of the first K is not symmetric.
  [[nodiscard]] Jacobian jacobian(const Vector3<Scalar>& xi, const Vector3<Scalar>& xj,
                                  const Vector3<Scalar>& vi, const Vector3<Scalar>& vj,
                                  DampingModel model = DampingModel::along_link) const noexcept {
    Jacobian J{Matrix3<Scalar>::Zero(), Matrix3<Scalar>::Zero()};
    const Vector3<Scalar> d = xj - xi;
    const Vector3<Scalar> u = vj - vi;
    const Scalar l = d.norm();
    if (!(l > Scalar(0))) {
      if (model == DampingModel::full_relative_velocity)
        J.dv = damping * Matrix3<Scalar>::Identity();
      return J;
    }
    const Vector3<Scalar> n = d / l;
    const Matrix3<Scalar> nn = n * n.transpose();
    const Matrix3<Scalar> P = Matrix3<Scalar>::Identity() - nn;
    const Scalar e = l - rest_length;
    const Scalar fe = elastic_force(e);
    if (model == DampingModel::along_link) {
      const Scalar f = fe + damping * u.dot(n);
      J.dx = tangent_stiffness(e) * nn + (f / l) * P + (damping / l) * n * (P * u).transpose();
      J.dv = damping * nn;
    } else {
      J.dx = tangent_stiffness(e) * nn + (fe / l) * P;
      J.dv = damping * Matrix3<Scalar>::Identity();
    }
    return J;
  }
};

}  // namespace fsm
