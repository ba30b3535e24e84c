#pragma once

/// @file implicit_euler_integrator.hpp
/// @brief Linearised backward Euler (Baraff and Witkin 1998).

#include <Eigen/SparseCholesky>
#include <Eigen/SparseLU>
#include <type_traits>
#include <vector>

#include "fsm/detail/simd_solver.hpp"
#include "fsm/integrator.hpp"

namespace fsm {

/// @brief Backward Euler linearised once per step (D. Baraff and A. Witkin, "Large steps in cloth
/// simulation", SIGGRAPH 1998):
/// \f[ \Big(\mathbf{M} - h\frac{\partial\mathbf{F}}{\partial\mathbf{v}} - h^2\frac{\partial
///     \mathbf{F}}{\partial\mathbf{x}}\Big)\Delta\mathbf{v} = h\Big(\mathbf{F} + h\frac{\partial
///     \mathbf{F}}{\partial\mathbf{x}}\mathbf{v}\Big),\quad \mathbf{v}_{n+1} = \mathbf{v}_n +
///     \Delta\mathbf{v},\quad \mathbf{x}_{n+1} = \mathbf{x}_n + h\mathbf{v}_{n+1}. \f]
/// First order, stable at any step for the linearised system, and dissipative (it damps even an
/// undamped model, more so at larger h).
///
/// Solvers:
/// - `conjugate_gradient` (default): matrix-free CG (block-Jacobi or Jacobi preconditioned) on the
///   per-link blocks of ForceModel::prepare_implicit(), warm-started from the previous steps, rows
///   of fixed nodes filtered out. Allocates nothing per step (Eigen's own ConjugateGradient
///   allocates its work vectors on every solve, which a real-time step must not do). Needs a
///   symmetric Jacobian form.
/// - `eigen_ldlt`: Eigen::SimplicialLDLT on the assembled matrix (symmetric form). Exact solve;
///   allocates per step: for reference and offline use.
/// - `eigen_lu`: Eigen::SparseLU on the assembled matrix with the exact, non-symmetric Jacobian.
///   Allocates per step: for reference and offline use.
template <typename Scalar>
class ImplicitEulerIntegrator final : public Integrator<Scalar> {
 public:
  enum class Solver { conjugate_gradient, eigen_ldlt, eigen_lu };
  /// Preconditioner of the conjugate-gradient solver: the diagonal of A (`jacobi`) or its 3 x 3
  /// diagonal blocks (`block_jacobi`: exact for a contact's or a link's direction on a node; fewer
  /// iterations for the same cost per iteration, docs/benchmarks.md).
  enum class Preconditioner { jacobi, block_jacobi };

  struct Options {
    Solver solver{Solver::conjugate_gradient};
    Preconditioner preconditioner{Preconditioner::block_jacobi};
    /// Jacobian form for the symmetric solvers (eigen_lu always uses the exact one).
    JacobianForm jacobian{JacobianForm::definite};
    /// CG stops when \f$|\mathbf{r}|_{P^{-1}} \le\f$ tolerance \f$\cdot|\mathbf{b}|_{P^{-1}}\f$,
    /// the norms weighted by the preconditioner (\f$|\mathbf{r}|_{P^{-1}}^2 = \mathbf{r}^T
    /// P^{-1}\mathbf{r}\f$): close to the error's energy norm as far as P matches the system, so
    /// each node's velocity error weighs by its kinetic energy rather than its momentum, and
    /// stiff rows (contacts, held nodes) cannot hide light nodes' errors. Where
    /// \f$\mathbf{r}^T P^{-1}\mathbf{r}\f$ is not positive (a preconditioner that is not
    /// positive definite, possible with JacobianForm::symmetric) the plain test
    /// \f$|\mathbf{r}| \le\f$ tolerance \f$\cdot|\mathbf{b}|\f$ applies.
    Scalar tolerance{std::is_same_v<Scalar, float> ? Scalar(1e-4) : Scalar(1e-6)};
    /// CG also stops once the velocity change is solved to about this speed (m/s):
    /// \f$|\mathbf{r}|_{P^{-1}}^2 \le\f$ velocity_tolerance\f$^2 \sum_i m_i\f$ over the
    /// nodes that move (for the plain test, \f$|\mathbf{r}| \le\f$ velocity_tolerance
    /// \f$\sqrt{\sum_i m_i^2}\f$): with P = M that is a velocity error of this mass-weighted
    /// RMS. As far as P matches A it is about that; block-Jacobi's P holds M and more, so in smooth
    /// modes it accepts up to about \f$\sqrt{P_{ii}/m_i}\f$ times as much (about 2 for tissue
    /// at h = 1 ms), and the RMS is over the whole model, so a small moving region may carry
    /// more. The relative test alone asks the same fraction of a right-hand side that vanishes as
    /// the tissue comes to rest, where the forces' own round-off is all that is left of it: on
    /// the bundled uterus held still CG then took 15 iterations a step instead of 4 while moving
    /// (docs/benchmarks.md). The floor decides whenever the step's velocity change is below
    /// about velocity_tolerance / tolerance: at the real-time 1e-3, only near rest; at the default
    /// 1e-6, in any step that changes the velocities by less than about 1 mm/s. One default for
    /// both precisions (float's own round-off lies above it, so there it rarely decides). 0 (or a
    /// negative value or NaN) turns the floor off; a very large value turns CG off (the step
    /// keeps its warm start, scaled as extrapolate_warm_start says).
    Scalar velocity_tolerance{Scalar(1e-9)};
    /// CG iteration cap; reaching it is not a failure (the partial solution is used and the
    /// iteration count reported), a breakdown is.
    int max_iterations{200};
    /// Solves per step when contacts are present: the first with the contacts that penetrate at
    /// the start, each further one (warm-started) with those that penetrate at the end of the
    /// previous solve, until the set no longer changes (ForceModel::update_contact_set). 1 keeps
    /// the start's set (cheaper; a sphere entering the tool then meets it only in the next step,
    /// and a chattering contact can gain energy).
    int max_contact_passes{3};
    /// CG's starting guess: the velocity change extrapolated linearly from the last two steps'
    /// (`2 dv_n-1 - dv_n-2`, when both had this step's length), else the last step's scaled to
    /// this step's length. The solution is the same to the tolerance; the motion of
    /// tissue under a steady or slowly changing load is smooth, so a step then starts nearer it:
    /// 4.1 instead of 6.2 iterations on the bundled uterus with a probe pressing, 5.5 instead of
    /// 10.0 on the VHF pelvis (docs/benchmarks.md; measured 2026-11-26, before the scaling below).
    /// Quadratic extrapolation amplified the solver's own error and needed more iterations than
    /// none. Either guess w is then scaled along itself to the least error in the system's energy
    /// norm, s = b^T w / w^T A w (two dot products and one scaling), so no solve starts further
    /// from the solution in that norm than zero (A positive definite, as JacobianForm::definite
    /// makes it): unscaled, a guess that carried motion the new system no longer has kept it
    /// wherever the stopping test could not see it, and the error grew from step to step
    /// (docs/physics.md, section 5).
    bool extrapolate_warm_start{true};
  };

  ImplicitEulerIntegrator() = default;
  explicit ImplicitEulerIntegrator(const Options& options) : m_options(options) {}

  [[nodiscard]] std::string_view name() const noexcept override { return "implicit_euler"; }
  [[nodiscard]] std::unique_ptr<Integrator<Scalar>> clone() const override {
    return std::make_unique<ImplicitEulerIntegrator>(*this);
  }
  [[nodiscard]] int order() const noexcept override { return 1; }
  [[nodiscard]] bool implicit() const noexcept override { return true; }
  /// The matrix-free solve (conjugate_gradient) starts with prepare_implicit(); the direct
  /// solvers evaluate the forces themselves.
  [[nodiscard]] bool prepares_implicit() const noexcept override {
    return m_options.solver == Solver::conjugate_gradient;
  }
  [[nodiscard]] const Options& options() const noexcept { return m_options; }
  void set_options(const Options& options) { m_options = options; }
  /// Whether the last CG solve ran its vector work on the SIMD kernels (detail/simd_solver.hpp:
  /// doubles, ForceModel::Options::simd, a CPU with AVX2 and FMA).
  [[nodiscard]] bool used_simd_kernels() const noexcept { return m_simd.update != nullptr; }

  void prepare(const SphereModel<Scalar>& model) override;
  IntegratorResult step(SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                        Scalar dt) noexcept override;
  /// Drops the warm start (the next solve starts from zero).
  void reset() noexcept override {
    m_dv.setZero();
    m_last_dt = m_previous_dt = Scalar(0);
  }
  [[nodiscard]] Scalar stable_time_step(const SpectralBound<Scalar>&) const noexcept override {
    return std::numeric_limits<Scalar>::infinity();
  }

 private:
  IntegratorResult solve_cg(SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                            Scalar dt) noexcept;
  // One CG solve of the prepared system into m_dv (warm-started from it).
  IntegratorResult solve_cg_pass(const SphereModel<Scalar>& model,
                                 ForceModel<Scalar>& forces) noexcept;
  IntegratorResult solve_assembled(SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                                   Scalar dt) noexcept;

  Options m_options;
  // The velocity floor's targets for this step (Options::velocity_tolerance): squared, for the
  // weighted test; plain, for the unweighted one.
  Scalar m_floor2{0}, m_plain_floor{0};
  std::vector<Scalar> m_blocks;
  // The preconditioner P^-1 of the prepared system (m_pblocks or m_pinv; its inputs m_diag and,
  // for block-Jacobi, m_pblocks).
  void make_preconditioner(const SphereModel<Scalar>& model, ForceModel<Scalar>& forces) noexcept;
  // z = P^-1 r for the chosen preconditioner (the scalar path).
  void precondition() noexcept;
  // CG's vector work, on the SIMD kernels where there are (doubles, ForceModel::Options::simd,
  // a CPU with AVX2 and FMA), else on Eigen's expressions: z = P^-1 r and r^T z; the update
  // dv += alpha p, r -= alpha q, then z and r^T z; the direction p = z + beta p; p^T q.
  Scalar precondition_dot() noexcept;
  Scalar update(Scalar alpha) noexcept;
  void new_direction(Scalar beta) noexcept;
  Scalar curvature() noexcept;
  // a^T b, on the SIMD dot kernel where there is one.
  Scalar dot(const Positions<Scalar>& a, const Positions<Scalar>& b) const noexcept;
  // Scales the warm start m_dv, whose product A m_dv is in m_q, by the factor s that minimises the
  // error's energy norm along it (0 when A is not positive along it), and returns s.
  Scalar scale_warm_start() noexcept;

  Positions<Scalar> m_rhs, m_diag, m_dv, m_r, m_z, m_p, m_q, m_x_end;
  // The velocity change of the step before the last (the warm start's extrapolation) and the
  // step length it is scaled to (0: none).
  Positions<Scalar> m_dv_previous;
  Scalar m_previous_dt{0};
  // Block-Jacobi: 6 per node (xx yy zz xy xz yz), the diagonal blocks, inverted in place on the
  // scalar path (on the SIMD path their inverse goes to m_pinv).
  std::vector<Scalar> m_pblocks;
  // The SIMD path (set per solve; all null otherwise) and its preconditioner, grouped by four
  // nodes (detail/simd_solver.hpp).
  struct SimdKernels {
    detail::simd::PreconditionKernel precondition{};
    detail::simd::CgUpdateKernel update{};
    detail::simd::CgDirectionKernel direction{};
    detail::simd::DotKernel dot{};
  } m_simd;
  std::vector<double> m_pinv;
  Scalar m_last_dt{0};
};

extern template class ImplicitEulerIntegrator<float>;
extern template class ImplicitEulerIntegrator<double>;

}  // namespace fsm

#include "fsm/impl/implicit_euler_integrator-inl.hpp"
