#pragma once

/// @file volume_term.hpp
/// @brief VolumeTerm: an optional volume-preserving penalty per tetrahedron, the missing bulk
/// stiffness of a central-spring network (whose Poisson's ratio is 1/4 whatever E is).

#include <string>

#include "fsm/error.hpp"
#include "fsm/types.hpp"

namespace fsm {

/// @brief A volume-preserving penalty on the tetrahedra of a filling.
///
/// For each tetrahedron \f$T = (a, b, c, d)\f$ with signed volume
/// \f$V = \frac16 (\mathbf{x}_b - \mathbf{x}_a)\cdot[(\mathbf{x}_c - \mathbf{x}_a)\times
/// (\mathbf{x}_d - \mathbf{x}_a)]\f$ and rest volume \f$V_0\f$, the energy is
/// \f[ E_T = \frac{\kappa}{2}\,\frac{(V - V_0)^2}{V_0}, \f]
/// and the force on vertex \f$k\f$ is its exact negative gradient
/// \f$\mathbf{F}_k = -\kappa\,\frac{V - V_0}{V_0}\,\partial V/\partial\mathbf{x}_k\f$. Since V is
/// invariant under translation and rotation, the four forces sum to zero and so do their torques.
///
/// For a uniform dilation \f$\varepsilon\f$ the term stores \f$\frac{9}{2}\kappa
/// V_0\varepsilon^2\f$, i.e. it adds exactly \f$\kappa\f$ (Pa) to the bulk modulus and nothing to
/// the shear modulus. A Van Gelder network of modulus \f$E\f$ has \f$\mu = 2E/5\f$, \f$K = 2E/3\f$
/// (docs/physics.md section 2); bulk_modulus_for() gives the \f$\kappa\f$ that makes it a material
/// of Poisson's ratio \f$\nu\f$ with the same shear modulus.
///
/// **Use.** The term is applied explicitly: before each step, set the simulation's external forces
/// to the term's forces at the current positions (add_forces()). Its stiffness is then not seen by
/// the implicit solver, so the step must resolve it: with \f$\omega_V\f$ the highest angular
/// frequency of the term alone (omega_max_squared()), explicit treatment needs
/// \f$h\,\omega_V < 2\f$ (the symplectic-Euler bound without damping; docs/validation.md measures
/// it). Inversion (\f$V \to 0\f$ or negative) is not prevented, only penalised.
///
/// add_forces() and energy() allocate nothing and never throw.
template <typename Scalar>
class VolumeTerm {
 public:
  using ConstPositionsRef = Eigen::Ref<const Positions<Scalar>>;
  using PositionsRef = Eigen::Ref<Positions<Scalar>>;

  VolumeTerm() = default;
  /// @brief Holds the tetrahedra and their rest volumes.
  /// @param tetrahedra `|T| x 4` node indices; @param rest_positions `|V| x 3` (m);
  /// @param bulk_modulus \f$\kappa\f$ (Pa), >= 0. fsm::Error for an index out of range, a
  /// repeated node, a non-finite position, or a rest volume whose magnitude is below 1e-12 of
  /// its mean edge cubed (a flat element has no volume to preserve).
  VolumeTerm(const TetrahedronArray& tetrahedra, const ConstPositionsRef& rest_positions,
             Scalar bulk_modulus);

  /// @brief \f$\kappa\f$ (Pa) that gives a network of Young's modulus `youngs_modulus` (Pa) the
  /// Poisson's ratio `poisson` in [0.25, 0.5) at unchanged shear modulus:
  /// \f$\kappa = \frac{2\mu(1+\nu)}{3(1-2\nu)} - \frac{2E}{3}\f$ with \f$\mu = 2E/5\f$.
  [[nodiscard]] static Scalar bulk_modulus_for(Scalar youngs_modulus, Scalar poisson);

  [[nodiscard]] Index num_tetrahedra() const noexcept { return Index(m_tets.rows()); }
  [[nodiscard]] Index num_nodes() const noexcept { return m_num_nodes; }
  [[nodiscard]] const TetrahedronArray& tetrahedra() const noexcept { return m_tets; }
  /// @brief Signed rest volumes (m^3), `|T|`.
  [[nodiscard]] const ScalarArray<Scalar>& rest_volumes() const noexcept { return m_rest_volume; }
  [[nodiscard]] Scalar bulk_modulus() const noexcept { return m_kappa; }
  /// @brief Changes \f$\kappa\f$ (Pa); fsm::Error if negative or not finite.
  void set_bulk_modulus(Scalar bulk_modulus);

  /// @brief Energy (J) at positions `x` (`|V| x 3`, m).
  [[nodiscard]] Scalar energy(const ConstPositionsRef& x) const noexcept;
  /// @brief Adds the term's forces (N) at positions `x` (`|V| x 3`, m) into `f` (`|V| x 3`).
  /// Rows of fixed nodes receive forces too (harmless: their inverse mass is 0).
  void add_forces(const ConstPositionsRef& x, PositionsRef f) const noexcept;
  /// @brief Upper bound (rad^2/s^2) on the squared highest angular frequency of the term alone,
  /// at rest, for node masses `masses` (`|V|`, kg); `fixed` (`|V|`, 1 = fixed) drops fixed
  /// nodes. Block Gershgorin on \f$\mathbf{M}^{-1/2}\mathbf{H}\mathbf{M}^{-1/2}\f$ with
  /// \f$\mathbf{H} = \sum_T (\kappa/V_0)\,\mathbf{g}_T\mathbf{g}_T^T\f$,
  /// \f$\mathbf{g}_T = \partial V/\partial\mathbf{x}\f$.
  [[nodiscard]] Scalar omega_max_squared(
      const Eigen::Ref<const ScalarArray<Scalar>>& masses,
      const Eigen::Ref<const Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1>>& fixed) const;

 private:
  TetrahedronArray m_tets;
  ScalarArray<Scalar> m_rest_volume;
  Positions<Scalar> m_rest;  ///< for omega_max_squared()
  Index m_num_nodes{0};
  Scalar m_kappa{0};
};

extern template class VolumeTerm<float>;
extern template class VolumeTerm<double>;

}  // namespace fsm

#include "fsm/impl/volume_term-inl.hpp"
