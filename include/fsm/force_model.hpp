#pragma once

/// @file force_model.hpp
/// @brief ForceModel: every force on the spheres (links, gravity, external loads), their
/// energies and Jacobians. The `forces` argument of every integrator's step(model, forces, dt).

#include <Eigen/SparseCore>
#include <vector>

#include "fsm/detail/continuum.hpp"
#include "fsm/detail/parallel.hpp"
#include "fsm/detail/reserved_vector.hpp"
#include "fsm/detail/worker_pool.hpp"
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

/// @brief A penalty contact on one sphere, integrated by ForceModel (implicitly in implicit Euler).
///
/// collision::ContactSolver fills these (ForceModel::contacts()) from the instruments and parts;
/// they act through the step as the tangent plane at detection: the penetration is
/// \f$\delta(\mathbf{x}) = \delta_0 - \mathbf{n}\cdot(\Delta\mathbf{x}_i - \Delta\mathbf{x}_j)\f$
/// (displacements since detection; \f$j\f$ the other sphere of a part contact), the normal force
/// \f$f_n = \max(0, k\,s(\delta) - c\,s'(\delta)\,\mathbf{n}\cdot\mathbf{v}_{rel})\f$ never pulls,
/// and regularised Coulomb friction opposes the slip. The onset \f$s\f$ is \f$s(\delta) = \delta\f$
/// (the plain penalty) unless `onset` \f$\varepsilon > 0\f$: then \f$s = \delta^2 / 2\varepsilon\f$
/// below \f$\varepsilon\f$ and \f$\delta - \varepsilon/2\f$ beyond, continuous with its slope, so
/// that a contact that sits at its threshold (parts touching at rest) is barely stiff while it
/// barely touches. The damping ramps in with the slope. An instrument moving with
/// `surface_velocity` deepens the contact by \f$h\,\mathbf{n}\cdot\mathbf{v}_s\f$ over a step,
/// which implicit Euler takes into its solve (docs/physics.md section 8).
template <typename Scalar>
struct PenaltyContact {
  Index node{-1};        ///< The sphere pushed.
  Index other{-1};       ///< The other sphere of a part contact (pushed by -force), or -1.
  Index instrument{-1};  ///< The instrument, or -1 for a part contact.
  Vector3<Scalar> normal{Vector3<Scalar>::UnitZ()};  ///< Unit: the direction `node` is pushed.
  Vector3<Scalar> point{Vector3<Scalar>::Zero()};    ///< Contact point (m), for torques.
  Scalar depth{0};                                   ///< Penetration at detection (m).
  Scalar stiffness{0};                               ///< k (N/m).
  Scalar onset{0};     ///< \f$\varepsilon\f$ (m): the depth over which the law ramps in; 0 = none.
  Scalar damping{0};   ///< c (N s/m), along the normal.
  Scalar friction{0};  ///< Coulomb coefficient.
  Scalar friction_speed{Scalar(1e-3)};                        ///< Regularisation speed (m/s).
  Vector3<Scalar> surface_velocity{Vector3<Scalar>::Zero()};  ///< Instrument surface (m/s).
  Vector3<Scalar> node_start{Vector3<Scalar>::Zero()};        ///< `node`'s position at detection.
  Vector3<Scalar> other_start{Vector3<Scalar>::Zero()};       ///< `other`'s position at detection.
  /// Force on `node` (N) at the end of the last accepted step (ForceModel::finish_contacts), or
  /// at detection.
  Vector3<Scalar> force{Vector3<Scalar>::Zero()};
  /// Force on `node` (N) at the start of the step (ForceModel::start_contacts; zero when the
  /// step is implicit, which does not use it).
  Vector3<Scalar> start_force{Vector3<Scalar>::Zero()};
  /// Whether the last implicit step's last contact pass had this contact in its solve (it
  /// penetrated at the start, or at the end of an earlier pass: ForceModel::update_contact_set).
  bool in_solve{false};
  /// Once in an implicit step's solve, stays in it for the rest of the step, even when a contact
  /// pass ends with it outside (ForceModel::update_contact_set): its linear law then pulls for
  /// the rest of that step. collision::ContactSolver sets it on the face contact's vertices
  /// (ContactOptions::face_contact; their depth at detection is positive, so in practice they
  /// keep the step's first set) and, with face contact on, on the instrument contacts of the
  /// tetrahedral parts' nodes that are not face vertices (interior nodes, reached once the
  /// tissue folds past the surface; a near one of those may still join in a later pass).
  bool stays_in_solve{false};
  // The implicit step's linearisation (ForceModel::prepare_implicit): the penetration it was
  // linearised at and the blocks.
  Scalar solve_depth{0};
  Scalar normal_block{0}, tangent_block{0};
};

/// @brief A node held to a moving point (a grasper's jaw, collision::Grasper): a bilateral
/// spring-damper taken into the implicit solve, \f$\mathbf{F} = k(\mathbf{p}(t) - \mathbf{x}) +
/// c(\dot{\mathbf{p}} - \mathbf{v})\f$ with \f$\mathbf{p}(t) = \mathbf{p}_0 +
/// t\,\dot{\mathbf{p}}\f$, t the contact time (ForceModel::contact_time()). Unlike a PenaltyContact
/// it pulls as well as pushes (docs/physics.md section 12).
template <typename Scalar>
struct HeldNode {
  Index node{-1};                                   ///< The sphere held.
  Index instrument{-1};                             ///< Who holds it (for the wrench), or -1.
  Vector3<Scalar> target{Vector3<Scalar>::Zero()};  ///< \f$\mathbf{p}_0\f$ (m).
  Vector3<Scalar> target_velocity{Vector3<Scalar>::Zero()};  ///< \f$\dot{\mathbf{p}}\f$ (m/s).
  Scalar stiffness{0};                                       ///< k (N/m), > 0.
  Scalar damping{0};                                         ///< c (N s/m), >= 0.
  /// Force on the node (N) at the end of the last accepted step (ForceModel::finish_contacts).
  Vector3<Scalar> force{Vector3<Scalar>::Zero()};
  /// The force at the positions and velocities x, v (row-major `|V| x 3`) and contact time t.
  [[nodiscard]] Vector3<Scalar> force_at(const Scalar* x, const Scalar* v,
                                         Scalar t) const noexcept {
    const Scalar* xi = x + 3 * std::ptrdiff_t(node);
    const Scalar* vi = v + 3 * std::ptrdiff_t(node);
    const Vector3<Scalar> p = target + t * target_velocity;
    return stiffness * (p - Vector3<Scalar>(xi[0], xi[1], xi[2])) +
           damping * (target_velocity - Vector3<Scalar>(vi[0], vi[1], vi[2]));
  }
};

/// @brief The force field of a SphereModel: Voigt links, the continuum law's elements, penalty
/// contacts, gravity and per-node external forces.
///
/// \f$\mathbf{F}(\mathbf{x},\mathbf{v}) = \sum_{\text{links}} \mathbf{F}_{\text{link}}
/// + \sum_{\text{elements}} \mathbf{F}_{\text{element}}
/// + \mathbf{M}\mathbf{g} + \mathbf{F}_{\text{ext}}\f$. Each region's ForceLaw decides which: a
/// region with the continuum law contributes its tetrahedra (docs/physics.md section 11) and its
/// links carry no force. Holds what the force evaluation needs
/// besides the model: options, the external forces, inverse masses (0 for fixed nodes) and
/// per-thread buffers. Everything is sized by refresh(); evaluate() and the other per-step
/// functions allocate nothing and never throw. With Options::threads above 1 they share one
/// worker pool and its buffers, const ones included (evaluate(), elastic_energy()): one caller at
/// a time.
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
    /// Threads for the link loops (forces, energy, the implicit step's blocks and products) and
    /// the continuum law's implicit products (at most the machine's hardware threads; the element
    /// forces and energy stay serial): more than 1 starts a
    /// persistent pool of threads - 1 helpers when the options are set (never inside a step); a
    /// helper spins for 2 ms after each loop, so at 1 kHz it keeps a second core busy while the
    /// simulation runs, and sleeps when it stops.
    int threads{1};
    /// Drag of the surroundings (1/s): a force \f$-\gamma m_i \mathbf{v}_i\f$ on every node, the
    /// mass-proportional damping that stands in for the tissue and fluid around an organ. It damps
    /// rigid motion (a tube swinging like a pendulum), which link damping cannot. 0 = none.
    Scalar drag{0};
    /// Run the link loops (the forces, and the implicit solve's link blocks and products) and the
    /// continuum law's element loops (forces, energy) on the SIMD kernels when the CPU has them
    /// (AVX2 with FMA, or AVX-512VL; double only: detail/simd_links.hpp, detail/simd_tets.hpp);
    /// false: the scalar loops, the reference. Both give the same results to rounding.
    bool simd{true};
    /// Continuum elements whose shape quality (6 sqrt(2) V / l_rms^3 at rest: 1 for a regular
    /// tetrahedron, 0 for a flat one) is below this get an exact-shape element tangent in the
    /// implicit solve instead of springs along their edges, which cannot resist a sliver's apex
    /// moving across its base (docs/physics.md section 11). 0 = none, above 1 = every element
    /// (each costs about five times its edge springs per solver iteration).
    Scalar element_tangent_quality{
        Scalar(detail::ContinuumTerm<Scalar>::default_element_tangent_quality)};
    /// Whether the implicit step watches each continuum element's volume for flutter (J swinging
    /// back and forth from one step to the next by more than 0.1 %, twice in a row) and gives an
    /// element found fluttering the element tangent from then on. The shape quality alone does
    /// not find every element whose edge springs let the step overshoot: on the VHF left adnexa
    /// one element of quality 0.47 kept about 50 elements swinging and took 2.4 times the solver
    /// iterations (docs/physics.md section 11). Off: the negative control.
    bool flutter_guard{true};
    /// How the continuum law measures the deviatoric strain: each tetrahedron's own F (element,
    /// the linear tetrahedron, the default) or F averaged over the tetrahedra at each face, edge
    /// or node (softer, closer to the continuum in bulk deformation at the same nodes, softer
    /// under a point load; the smoothed part runs scalar; docs/physics.md section 11).
    StrainSmoothing strain_smoothing{StrainSmoothing::element};
    /// With a smoothed strain: the share of the deviatoric energy kept on each element's own
    /// strain, in [0, 1] (it stabilises the smoothed strains' soft local modes).
    Scalar smoothing_element_share{Scalar(detail::ContinuumTerm<Scalar>::default_element_share)};
    /// Whether elastic_energy_keeping_forces() (Simulation's energy check at the end of an
    /// implicit step) takes the continuum elements' energy from a force evaluation at the end
    /// state, which the next step's first force evaluation then reuses instead of repeating it
    /// (the element strain only; smoothed strains evaluate the energy alone). The same forces and
    /// energies to the last bit; off evaluates both, as before (docs/physics.md section 11).
    bool reuse_end_forces{true};
  };

  ForceModel() = default;
  /// @brief Sized for `model`; see refresh().
  explicit ForceModel(const SphereModel<Scalar>& model, const Options& options = Options{});

  /// @brief Re-reads sizes, masses and fixed flags from the model (call after changing them).
  /// Keeps the external forces when the node count is unchanged, else clears them.
  void refresh(const SphereModel<Scalar>& model);
  /// @brief Re-reads which links and tetrahedra are intact (SphereModel::link_intact(),
  /// tetrahedron_intact()) after a cut or a tear. Real-time: no allocation (the capacity is
  /// reserved by refresh()); does nothing if the model changed size since refresh().
  void update_topology(const SphereModel<Scalar>& model) noexcept;
  /// @brief The same after a cut or a tear that broke `broken_links` and removed
  /// `removed_tetrahedra` (TopologyEditor's lists), updating the continuum term by what they
  /// remove rather than from scratch. No allocation.
  void update_topology(const SphereModel<Scalar>& model, const std::vector<Index>& broken_links,
                       const std::vector<Index>& removed_tetrahedra) noexcept;

  [[nodiscard]] const Options& options() const noexcept { return m_options; }
  /// @brief With Options::threads above 1: false sets the worker pool aside, so the loops run on
  /// the calling thread (as with one thread, to rounding), true takes it back. Allocates nothing;
  /// Simulation::Options::adaptive_threads switches it between steps.
  void use_pool(bool on) noexcept { m_pool.set_enabled(on); }
  /// @brief Whether the loops run on a pool (Options::threads above 1 and not set aside).
  [[nodiscard]] bool uses_pool() const noexcept { return m_pool.get() != nullptr; }
  /// @brief Whether the link loops on the pool share the links so that no two threads' links meet
  /// at a node (one dispatch, no per-thread buffers): evaluate(), prepare_implicit(), and
  /// apply_implicit() when there are no continuum elements.
  /// That takes links sorted by node over nodes numbered so that every link is short, as a
  /// lattice's edges are (the builder's parts are not: their Morton order's jumps make some links
  /// span most of a part, and the attachment links come last). The links between
  /// two threads' nodes (the band) then run on one thread, and the partition is used while a
  /// thread's links plus the band are at most an eighth of the links more than an even share.
  /// refresh() makes it for the pool's size and the model's; after set_options() with another
  /// thread count it waits for the next refresh(). Otherwise each thread sums into its own buffer.
  [[nodiscard]] bool links_partitioned() const noexcept {
    const detail::WorkerPool* pool = m_pool.get();
    return pool && m_partition.threads() == pool->size() &&
           m_partition.nodes.back() == m_num_nodes &&
           m_partition.owned.back().second == Index(m_force_link.size());
  }
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

  /// @name Penalty contacts (filled by collision::ContactSolver, integrated with the step)
  /// @{
  /// @brief Makes room for `capacity` contacts (allocates; ContactSolver calls it when sized).
  void reserve_contacts(Index capacity);
  [[nodiscard]] Index contact_capacity() const noexcept { return Index(m_contacts.size()); }
  /// @brief Forgets every contact (and resets the contact time).
  void clear_contacts() noexcept {
    m_num_contacts = 0;
    m_contact_time = Scalar(0);
    m_contacts_linearised = false;
  }
  /// @brief Adds a contact; false (nothing added) when the capacity is full.
  bool add_contact(const PenaltyContact<Scalar>& contact) noexcept;
  [[nodiscard]] Index num_contacts() const noexcept { return m_num_contacts; }
  [[nodiscard]] const PenaltyContact<Scalar>* contacts() const noexcept {
    return m_contacts.data();
  }
  /// @brief Time (s) since the contacts were detected: an instrument contact's surface has moved
  /// by this times its `surface_velocity` (Simulation advances it through each step).
  void set_contact_time(Scalar t) noexcept { m_contact_time = t; }
  [[nodiscard]] Scalar contact_time() const noexcept { return m_contact_time; }
  /// @brief The contacts' forces at the model's state and the contact time (the step's start),
  /// into each contact's `start_force` (zero with `start_forces` false: an implicit step, whose
  /// contact_work() does not use them); clears `in_solve`. Simulation::step calls it.
  void start_contacts(const SphereModel<Scalar>& model, bool start_forces = true) noexcept;
  /// @brief The contacts' forces at the model's state and the contact time, into each contact's
  /// `force`.
  void finish_contacts(const SphereModel<Scalar>& model) noexcept;
  /// @brief After a step that is rolled back: each contact's and held node's `force` back to what
  /// it was at start_contacts() (the end of the last accepted step, or detection), so that a
  /// ContactSolver::collect() or a wrench read after the rollback reports the restored state, not
  /// the rejected one. Simulation::step calls it.
  void reject_contacts() noexcept;
  /// @brief Caps each contact's stiffness for an explicit step of length h: at most
  /// \f$m/(2h^2)\f$ (m the sphere's mass, the reduced mass for a part contact), the damping scaled
  /// to keep its ratio. An explicit integrator cannot take a contact stiffer than its step allows;
  /// implicit Euler needs no cap. Returns how many contacts were softened.
  Index limit_contact_stiffness(const SphereModel<Scalar>& model, Scalar h) noexcept;
  /// @brief For the assembled implicit solvers: adds to `rhs` (`3|V|`, holding
  /// \f$h\mathbf{F} + h^2\mathbf{K}\mathbf{v}\f$ with evaluate()'s clamped contact forces), for
  /// each contact that penetrates at this state, \f$h\f$ times its linear law minus its clamped
  /// force and \f$h^2 k\,\mathbf{n}(\mathbf{n}\cdot\mathbf{v}_s)\f$ (the instrument's motion
  /// over the step), as prepare_implicit() does for the matrix-free solve; marks them `in_solve`.
  void add_contact_linearisation(const SphereModel<Scalar>& model, Scalar h, Scalar* rhs) noexcept;
  /// @brief Makes room for `capacity` held nodes (allocates; collision::Grasper calls it).
  void reserve_held(Index capacity);
  /// @brief Releases every held node.
  void clear_held() noexcept { m_num_held = 0; }
  /// @brief Holds a node; false (nothing added) when the capacity is full or the values are bad
  /// (node out of range, stiffness not positive, damping negative, a point not finite).
  bool add_held(const HeldNode<Scalar>& held) noexcept;
  [[nodiscard]] Index num_held() const noexcept { return m_num_held; }
  [[nodiscard]] const HeldNode<Scalar>* held() const noexcept { return m_held.data(); }
  /// @brief The work (J) the contacts did on the spheres' displacements from `x_before` to the
  /// model's positions over the last step: after an implicit step, the end-of-step force of the
  /// linear law of each contact the solve took (none for the others); after an explicit one, the
  /// mean of start_force and force (finish_contacts()).
  [[nodiscard]] Scalar contact_work(const SphereModel<Scalar>& model,
                                    const ConstPositionsRef& x_before) const noexcept;
  /// @}

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
  /// @brief The immobile nodes' indices, ascending.
  [[nodiscard]] const std::vector<Index>& immobile_nodes() const noexcept {
    return m_immobile_nodes;
  }
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

  /// @brief Elastic energy (J) at positions x: the links' \f$\sum_l \int f_e\,de\f$ and the
  /// elements' neo-Hookean energy.
  [[nodiscard]] Scalar elastic_energy(const SphereModel<Scalar>& model,
                                      const ConstPositionsRef& x) const noexcept;
  /// @brief elastic_energy() at the model's state, for a check at the end of a step: with
  /// Options::reuse_end_forces and continuum elements (element strain), the elements' energy comes
  /// from a force evaluation at the model's (x, v) (their flutter watch included), which the next
  /// prepare_implicit() uses instead of its own if reuse_kept_forces(true) is called first. No
  /// allocation.
  [[nodiscard]] Scalar elastic_energy_keeping_forces(const SphereModel<Scalar>& model) noexcept;
  /// @brief Whether the next prepare_implicit() may use the forces elastic_energy_keeping_forces()
  /// kept (the caller vouches that the model's positions and velocities are still those it was
  /// called at; they are used only if nothing has evaluated or changed the elements since); false
  /// drops them.
  void reuse_kept_forces(bool same_state) noexcept {
    if (same_state)
      m_kept_armed = m_kept;
    else
      drop_kept_forces();
  }
  /// @brief The continuum elements with \f$J \le 0\f$ at the state of the forces
  /// elastic_energy_keeping_forces() kept (as inverted_elements() counts them), or -1 if none are
  /// kept or the elements changed since.
  [[nodiscard]] Index kept_inverted_elements() const noexcept {
    return m_kept && m_kept_generation == m_continuum.generation() ? m_continuum.forces_inverted()
                                                                   : Index(-1);
  }
  /// @brief How many prepare_implicit() calls used kept forces instead of evaluating their own.
  [[nodiscard]] std::uint64_t kept_forces_reused() const noexcept { return m_kept_reused; }
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
  /// Contacts: those in the solve take their linear penalty law (exact: the law is linear in the
  /// positions and velocities where it pushes). Which are in the solve is decided at this state
  /// (those that penetrate), or, with `keep_contact_set`, kept as update_contact_set() left them.
  /// A re-solve of the same state (`keep_contact_set` after a prepare at the same h) recomputes
  /// only the contacts' part: the links' and elements' blocks, rhs and diagonal are kept.
  void prepare_implicit(const SphereModel<Scalar>& model, Scalar h, JacobianForm form,
                        Scalar* blocks, PositionsRef rhs, PositionsRef diagonal,
                        bool keep_contact_set = false) noexcept;
  /// @brief After a solve of a step of length h from the model's state: puts into the solve
  /// exactly the instrument contacts that penetrate at the end positions `x_end` (`3|V|`), plus
  /// those that did not penetrate at the start and joined an earlier pass of this step (near
  /// contacts: their damping stops the sphere short of the surface, and dropping them would let
  /// the next pass carry it in) and those marked PenaltyContact::stays_in_solve that were already
  /// in it, and returns whether that changed the set (part contacts keep the
  /// start's set: parts touching at rest sit at the threshold and would flip every step) (the
  /// step is then solved again with
  /// keep_contact_set, so that the contact law applied is the one of the end state: backward Euler
  /// on the piecewise-linear penalty, which neither pumps energy into a chattering contact nor lets
  /// a sphere pass in unopposed).
  bool update_contact_set(const SphereModel<Scalar>& model, const Scalar* x_end, Scalar h) noexcept;
  /// @brief The 3 x 3 diagonal blocks of A for the blocks of the last prepare_implicit()
  /// (block-Jacobi preconditioner), 6 scalars per node (xx, yy, zz, xy, xz, yz) into `out`
  /// (`6|V|`): mass with drag, the links' and elements' blocks on their nodes (kept by
  /// prepare_implicit(), which `blocks` must be the output of) and the contacts in the solve;
  /// fixed nodes get the identity. The continuum elements' volumetric part is exact too, summed
  /// over each node's pairs (docs/physics.md section 5). Serial; no allocation.
  void implicit_diagonal_blocks(const SphereModel<Scalar>& model, const Scalar* blocks,
                                Scalar* out) const noexcept;
  /// @brief y = A p for the blocks of prepare_implicit(); rows of fixed nodes are zero.
  void apply_implicit(const SphereModel<Scalar>& model, const Scalar* blocks,
                      const ConstPositionsRef& p, PositionsRef y) noexcept;
  /// @}

  /// @name Assembled Jacobians (allocate; for analysis and the direct solvers)
  /// @{
  /// @brief \f$\partial\mathbf{F}/\partial\mathbf{x}\f$ (N/m), `3|V| x 3|V|`, at the model's state.
  /// The continuum elements' part is their exact Jacobian for `exact` (by central differences of
  /// the exact forces, relative accuracy about 1e-7) and the positive semi-definite tangent the
  /// implicit solve uses otherwise.
  [[nodiscard]] SparseMatrix stiffness_matrix(const SphereModel<Scalar>& model,
                                              JacobianForm form = JacobianForm::exact) const;
  /// @brief \f$\partial\mathbf{F}/\partial\mathbf{v}\f$ (N s/m), `3|V| x 3|V|`, drag included.
  [[nodiscard]] SparseMatrix damping_matrix(const SphereModel<Scalar>& model) const;
  /// @}

  /// @brief A conservative stiffness (N/m) of each node against its own displacement: the
  /// Gershgorin row sum of the links' and elements' rest stiffness, `|V|` (for contact stiffness).
  [[nodiscard]] std::vector<Scalar> node_stiffness(const SphereModel<Scalar>& model) const;

  /// @brief Continuum elements that had the element tangent at the last evaluation (poorly shaped,
  /// strongly strained or fluttering ones, Options::element_tangent_quality and flutter_guard).
  [[nodiscard]] Index continuum_element_tangents() const noexcept {
    return Index(m_continuum.num_element_tangents());
  }
  /// @brief Whether the continuum law's implicit product runs on the node-pair SIMD kernels now:
  /// prepare_implicit() built the pairs and nothing has changed the elements since (else it runs
  /// on the scalar loops, the same product; docs/physics.md section 5). A diagnostic.
  [[nodiscard]] bool continuum_pair_product() const noexcept {
    return m_continuum.pair_product_ready();
  }
  /// @brief Continuum elements found fluttering in an implicit step (their J swinging back and
  /// forth from step to step), which keep the element tangent since (docs/physics.md section 11).
  [[nodiscard]] Index continuum_fluttered_elements() const noexcept {
    return Index(m_continuum.num_fluttered());
  }
  /// @brief Continuum elements with \f$J \le 0\f$ (inverted) at x.
  [[nodiscard]] Index inverted_elements(const ConstPositionsRef& x) const noexcept {
    return m_continuum.inverted(x.data());
  }
  /// @brief About E V summed over the continuum elements (J per unit strain squared).
  [[nodiscard]] Scalar element_energy_scale() const noexcept { return m_continuum.energy_scale(); }
  /// @brief Number of continuum elements (tetrahedra of continuum regions).
  [[nodiscard]] Index num_elements() const noexcept { return m_continuum.num_elements(); }
  /// @brief 1 for a link that carries force (0 inside a continuum region), `|L|`.
  [[nodiscard]] const std::vector<std::uint8_t>& force_links() const noexcept {
    return m_force_link;
  }

 private:
  void resize_scratch();
  // Options::simd is on and the padded copies are sized for n nodes (double only: see refresh()).
  [[nodiscard]] bool simd_ready(Index n) const noexcept;
  // Copies x (and v, unless null) into m_x4 (m_v4), four per node, for the SIMD kernels. On a
  // large model it runs on the pool: never call it from a pool job.
  void pad_states(const Scalar* x, const Scalar* v, Index n) noexcept;
  // The same for nodes [begin, end) on the calling thread (double only; nothing for float).
  void pad_state_rows(const Scalar* x, const Scalar* v, Index begin, Index end) noexcept;

  void update_mobility(const SphereModel<Scalar>& model) noexcept;
  // Forgets the kept forces; their evaluation's flutter watch is undone (a state that started no
  // step must not count as one).
  void drop_kept_forces() noexcept {
    if (m_kept && m_kept_watched) m_continuum.restore_watch();
    m_kept = m_kept_armed = m_kept_watched = false;
  }
  // The force links' energy at positions p (3 |V|).
  [[nodiscard]] Scalar link_energy(const SphereModel<Scalar>& model,
                                   const Scalar* p) const noexcept;
  // The force links' blocks in [begin, end) added to per-node blocks `out` (6 |V|: xx yy zz xy
  // xz yz).
  void add_link_node_blocks(const SphereModel<Scalar>& model, const Scalar* blocks, Index begin,
                            Index end, Scalar* out) const noexcept;
  // m_link_node_blocks for nodes [begin, end): M (1 + h gamma) on the diagonal plus the first `T`
  // buffers of m_block_scratch (T = 0: the mass alone).
  void init_link_node_blocks(const SphereModel<Scalar>& model, Scalar h, Index begin, Index end,
                             int T) noexcept;
  void update_ranges(const SphereModel<Scalar>& model) noexcept;

  Options m_options;
  Index m_num_nodes{0};
  std::vector<std::uint8_t> m_asleep, m_immobile;
  // The immobile ones' indices, and the active and force link ranges: refilled within the
  // capacity refresh() reserves (a copy keeps it: ReservedVector), so that update_mobility() and
  // update_ranges() never allocate.
  detail::ReservedVector<Index> m_immobile_nodes;
  detail::ReservedVector<std::pair<Index, Index>> m_ranges;
  Scalar m_implicit_h{0};
  std::vector<Scalar> m_external;
  std::vector<double> m_x4, m_v4;  // positions and velocities, 4 per node, for the SIMD kernel
  ScalarArray<Scalar> m_inverse_mass;
  std::vector<std::vector<Scalar>> m_scratch;        // one buffer of 3 |V| per pool thread
  std::vector<std::vector<Scalar>> m_node_scratch;   // one buffer of |V| per pool thread
  std::vector<std::vector<Scalar>> m_block_scratch;  // one buffer of 6 |V| per pool thread
  detail::PoolHandle m_pool;
  // The links shared among the pool's threads without a common node, made by refresh() for the
  // pool it had (evaluate() uses it while the pool's size matches; else the buffers).
  detail::LinkPartition m_partition;
  std::vector<PenaltyContact<Scalar>> m_contacts;
  Index m_num_contacts{0};
  std::vector<HeldNode<Scalar>> m_held;
  // The contacts' and held nodes' `force` at start_contacts(), for reject_contacts() (sized with
  // m_contacts and m_held).
  std::vector<Vector3<Scalar>> m_contact_forces_before, m_held_forces_before;
  Index m_num_held{0};
  Scalar m_contact_time{0};
  bool m_contacts_linearised{false};       // the last step was implicit (contact_work's accounting)
  std::vector<std::uint8_t> m_force_link;  // per link: carries force
  std::vector<std::uint8_t> m_continuum_link;  // per link: inside a continuum region
  detail::ReservedVector<std::pair<Index, Index>> m_force_ranges;  // force links, whatever moves
  detail::ContinuumTerm<Scalar> m_continuum;
  std::vector<Scalar> m_element_force;  // |V| x 3 scratch of prepare_implicit
  // prepare_implicit's rhs and diagonal before the contacts, for a re-solve of the same state.
  std::vector<Scalar> m_base_rhs, m_base_diagonal;
  // Per node, M (1 + h gamma) plus the force links' diagonal blocks (xx yy zz xy xz yz) at the
  // last prepare_implicit() (implicit_diagonal_blocks()).
  std::vector<Scalar> m_link_node_blocks;
  // elastic_energy_keeping_forces(): the elements' forces in m_element_force and their per-step
  // state are at a step's end state (m_kept, as of the continuum's generation), and the next
  // prepare_implicit() may use them (m_kept_armed).
  bool m_kept{false}, m_kept_armed{false}, m_kept_watched{false};
  std::uint64_t m_kept_generation{0}, m_kept_reused{0};
  Scalar m_base_h{-1};
};

extern template class ForceModel<float>;
extern template class ForceModel<double>;

}  // namespace fsm

#include "fsm/impl/force_model-inl.hpp"
