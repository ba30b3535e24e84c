#pragma once

/// @file force_model.hpp
/// @brief ForceModel: every force on the spheres (links, gravity, external loads), their
/// energies and Jacobians. The `forces` argument of every integrator's step(model, forces, dt).

#include <Eigen/SparseCore>
#include <vector>

#include "fsm/sphere_model.hpp"
#include "fsm/types.hpp"
#include "fsm/voigt_link.hpp"

namespace fsm {

/// @brief Which Jacobian \f$\partial\mathbf{F}/\partial\mathbf{x}\f$ to build.
enum class JacobianForm {
  /// The exact derivative of the link forces, including the non-symmetric damping term
  /// \f$\frac{k_d}{l}\mathbf{n}(\mathbf{P}\mathbf{u})^T\f$ (VoigtLink::jacobian).
  exact,
  /// The symmetric part used by Baraff and Witkin (1998): the non-symmetric damping term dropped.
  symmetric,
  /// Symmetric, and the transverse term \f$\frac{f}{l}\mathbf{P}\f$ of compressed links dropped,
  /// so \f$-\partial\mathbf{F}/\partial\mathbf{x}\f$ is positive semi-definite and the implicit
  /// system stays symmetric positive definite at every step size.
  definite,
};

/// @brief The force field of a SphereModel: Voigt links, gravity and per-node external forces.
///
/// \f$\mathbf{F}(\mathbf{x},\mathbf{v}) = \sum_{\text{links}} \mathbf{F}_{\text{link}}
/// + \mathbf{M}\mathbf{g} + \mathbf{F}_{\text{ext}}\f$. Holds what the force evaluation needs
/// besides the model: options, the external forces, inverse masses (0 for fixed nodes) and
/// per-thread buffers. Everything is sized by refresh(); evaluate() and the other per-step
/// functions allocate nothing and never throw.
template <typename Scalar>
class ForceModel {
 public:
  using ConstPositionsRef = Eigen::Ref<const Positions<Scalar>>;
  using PositionsRef = Eigen::Ref<Positions<Scalar>>;
  using SparseMatrix = Eigen::SparseMatrix<Scalar>;

  struct Options {
    /// Gravitational acceleration (m/s^2). z is up by default.
    Vector3<Scalar> gravity{Scalar(0), Scalar(0), Scalar(-9.81)};
    /// How the dashpots see relative velocity (VoigtLink).
    DampingModel damping{DampingModel::along_link};
    /// Threads for the force loop; more than 1 needs a build with OpenMP. No thread is started
    /// until a step runs with threads > 1.
    int threads{1};
    /// Drag of the surroundings (1/s): a force \f$-\gamma m_i \mathbf{v}_i\f$ on every node, the
    /// mass-proportional damping that stands in for the tissue and fluid around an organ. It damps
    /// rigid motion (a tube swinging like a pendulum), which link damping cannot. 0 = none.
    Scalar drag{0};
  };

  ForceModel() = default;
  /// @brief Sized for `model`; see refresh().
  explicit ForceModel(const SphereModel<Scalar>& model, const Options& options = Options{});

  /// @brief Re-reads sizes, masses and fixed flags from the model (call after changing them).
  /// Keeps the external forces when the node count is unchanged, else clears them.
  void refresh(const SphereModel<Scalar>& model);

  [[nodiscard]] const Options& options() const noexcept { return m_options; }
  /// @brief Changes the options (thread buffers are resized here, not in the step); fsm::Error
  /// for threads < 1 or non-finite gravity.
  void set_options(const Options& options);

  /// @brief External force per node (N), `|V| x 3`; added to every evaluation until changed.
  Eigen::Map<Positions<Scalar>> external_forces() noexcept {
    return {m_external.data(), m_num_nodes, 3};
  }
  [[nodiscard]] Eigen::Map<const Positions<Scalar>> external_forces() const noexcept {
    return {m_external.data(), m_num_nodes, 3};
  }
  /// @brief Sets every external force to zero.
  void clear_external_forces() noexcept;

  /// @name Sleeping
  /// An asleep node is held still like a fixed one (inverse mass 0), and links none of whose ends
  /// can move are skipped by the force loops. Simulation's sleep policy drives this.
  /// @{
  /// @brief Marks nodes asleep (1) or awake (0), `|V|` entries; recomputes the active link ranges
  /// without allocating (capacity is reserved by refresh()). Returns false on a size mismatch.
  bool set_asleep(const std::vector<std::uint8_t>& asleep,
                  const SphereModel<Scalar>& model) noexcept;
  [[nodiscard]] const std::vector<std::uint8_t>& asleep() const noexcept { return m_asleep; }
  /// @brief 1 for a node that cannot move now (fixed or asleep).
  [[nodiscard]] const std::vector<std::uint8_t>& immobile() const noexcept { return m_immobile; }
  /// @brief Links the force loops visit: [begin, end) ranges with at least one mobile end.
  [[nodiscard]] const std::vector<std::pair<Index, Index>>& active_links() const noexcept {
    return m_ranges;
  }
  /// @}

  /// @brief \f$1/m_i\f$ (1/kg), 0 for fixed and asleep nodes, `|V|`.
  [[nodiscard]] const ScalarArray<Scalar>& inverse_masses() const noexcept {
    return m_inverse_mass;
  }

  /// @brief Total force \f$\mathbf{F}(\mathbf{x},\mathbf{v})\f$ (N) into `f` (`|V| x 3`).
  /// @param x positions (m), @param v velocities (m/s), both `|V| x 3`.
  void evaluate(const SphereModel<Scalar>& model, const ConstPositionsRef& x,
                const ConstPositionsRef& v, PositionsRef f) noexcept;

  /// @brief Elastic energy (J) of all links at positions x: \f$\sum_l \int f_e\,de\f$.
  [[nodiscard]] Scalar elastic_energy(const SphereModel<Scalar>& model,
                                      const ConstPositionsRef& x) const noexcept;
  /// @brief Kinetic energy (J): \f$\frac12\sum_i m_i|\mathbf{v}_i|^2\f$.
  [[nodiscard]] Scalar kinetic_energy(const SphereModel<Scalar>& model,
                                      const ConstPositionsRef& v) const noexcept;
  /// @brief Gravitational energy (J) relative to the rest configuration:
  /// \f$-\sum_i m_i\,\mathbf{g}\cdot(\mathbf{x}_i - \bar{\mathbf{x}}_i)\f$.
  [[nodiscard]] Scalar gravity_energy(const SphereModel<Scalar>& model,
                                      const ConstPositionsRef& x) const noexcept;

  /// @name Matrix-free implicit Euler support
  /// Per link, the symmetric block \f$\mathbf{B}_l = h\mathbf{D}_l + h^2\mathbf{K}_l\f$ of the
  /// linearised backward-Euler matrix \f$\mathbf{A} = \mathbf{M} - h\,\partial\mathbf{F}/
  /// \partial\mathbf{v} - h^2\,\partial\mathbf{F}/\partial\mathbf{x}\f$ has the form
  /// \f$a\,\mathbf{n}\mathbf{n}^T + b\,\mathbf{I}\f$: five scalars (n, a, b) per link.
  /// @{
  /// Scalars stored per link by prepare_implicit().
  static constexpr int implicit_block_size = 5;
  /// @brief Fills `blocks` (5 per link), the right-hand side
  /// \f$\mathbf{b} = h\mathbf{F} + h^2\,(\partial\mathbf{F}/\partial\mathbf{x})\,\mathbf{v}\f$
  /// and the diagonal of A (for a Jacobi preconditioner); rows of fixed nodes get b = 0, diag = 1.
  /// `form` must be symmetric or definite.
  void prepare_implicit(const SphereModel<Scalar>& model, Scalar h, JacobianForm form,
                        Scalar* blocks, PositionsRef rhs, PositionsRef diagonal) noexcept;
  /// @brief y = A p for the blocks of prepare_implicit(); rows of fixed nodes are zero.
  void apply_implicit(const SphereModel<Scalar>& model, const Scalar* blocks,
                      const ConstPositionsRef& p, PositionsRef y) noexcept;
  /// @}

  /// @name Assembled Jacobians (allocate; for analysis and the direct solvers)
  /// @{
  /// @brief \f$\partial\mathbf{F}/\partial\mathbf{x}\f$ (N/m), `3|V| x 3|V|`, at the model's state.
  [[nodiscard]] SparseMatrix stiffness_matrix(const SphereModel<Scalar>& model,
                                              JacobianForm form = JacobianForm::exact) const;
  /// @brief \f$\partial\mathbf{F}/\partial\mathbf{v}\f$ (N s/m), `3|V| x 3|V|`, drag included.
  [[nodiscard]] SparseMatrix damping_matrix(const SphereModel<Scalar>& model) const;
  /// @}

 private:
  void resize_scratch();

  void update_mobility(const SphereModel<Scalar>& model) noexcept;

  Options m_options;
  Index m_num_nodes{0};
  std::vector<std::uint8_t> m_asleep, m_immobile;
  std::vector<std::pair<Index, Index>> m_ranges;
  Scalar m_implicit_h{0};
  std::vector<Scalar> m_external;
  ScalarArray<Scalar> m_inverse_mass;
  std::vector<std::vector<Scalar>> m_scratch;
};

extern template class ForceModel<float>;
extern template class ForceModel<double>;

}  // namespace fsm

#include "fsm/impl/force_model-inl.hpp"
