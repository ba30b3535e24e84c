#pragma once

/// @file simulation.hpp
/// @brief Simulation: a SphereModel, its forces and an integrator, stepped safely.

#include <memory>
#include <string>
#include <string_view>

#include "fsm/cutting.hpp"
#include "fsm/force_model.hpp"
#include "fsm/integrator.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/stability.hpp"

namespace fsm {

/// @brief How a step ended.
enum class StepStatus {
  ok,                 ///< Advanced by dt.
  recovered,          ///< Advanced by dt, but only after automatic sub-stepping.
  diverged,           ///< The step diverged and the state was rolled back to before it.
  invalid_time_step,  ///< dt was not positive and finite; nothing changed.
  /// Nothing was stepped: an external force is not finite, the model changed size since
  /// refresh(), or positions/velocities edited between steps are not finite (they were replaced
  /// by the last good state).
  invalid_input,
};

/// @brief Name of a StepStatus ("ok", "recovered", "diverged", "invalid_time_step",
/// "invalid_input").
[[nodiscard]] const char* to_string(StepStatus status) noexcept;

/// @brief What Simulation::step() reports.
template <typename Scalar>
struct StepReport {
  StepStatus status{StepStatus::ok};
  /// Integrator steps run, rejected attempts included: 1 for a step that passed at once; with
  /// halvings, the sub-steps run at every level tried (1 + 2 + ... + 2^k when the k-th halving
  /// passed and no solver broke down; a level stops at a sub-step whose solver broke down).
  int substeps{0};
  int solver_iterations{0};  ///< Summed linear-solver iterations (implicit schemes).
  /// Integrator steps (sub-steps, rejected ones included) with a linear solve (in any contact
  /// pass) that stopped at its iteration cap (ImplicitEulerIntegrator::Options::max_iterations)
  /// short of its tolerance. The step was still taken if the divergence checks passed; it is less
  /// accurate than asked.
  int unconverged_solves{0};
  /// Kinetic + elastic + gravitational energy after the step (J); NaN when not checked.
  Scalar energy{std::numeric_limits<Scalar>::quiet_NaN()};
  /// The energy the step ended with beyond what it started with plus the work done on it (J):
  /// negative when it removed energy, as an implicit step does; NaN when not checked (or when the
  /// step took a new reference after a cut).
  Scalar energy_gain{std::numeric_limits<Scalar>::quiet_NaN()};
  /// Sub-step levels run again because a level gained more energy than
  /// DivergencePolicy::energy_gain_strain allows (included in `substeps`).
  int energy_gain_retries{0};
  /// Continuum elements inverted (\f$J \le 0\f$) after an accepted step (0 without the law). The
  /// law's energy stays finite through inversion and pushes the element back; a step that cannot
  /// is rolled back as diverged.
  Index inverted_elements{0};
  /// Penalty contacts softened to the explicit step's limit (ForceModel::limit_contact_stiffness;
  /// always 0 with implicit Euler).
  Index softened_contacts{0};
  /// Links and tetrahedra the step tore (Material::tear_strain); Simulation::topology() lists
  /// them.
  TopologyChange torn{};
  /// @brief True if the model advanced by dt.
  [[nodiscard]] bool advanced() const noexcept {
    return status == StepStatus::ok || status == StepStatus::recovered;
  }
};

/// @brief The energy account of a simulation (J).
template <typename Scalar>
struct EnergyReport {
  Scalar kinetic{0};
  Scalar elastic{0};
  Scalar gravity{0};        ///< Relative to the rest configuration.
  Scalar external_work{0};  ///< Work of the external forces since the reference was taken.
  Scalar reference{0};      ///< Total energy when the reference was taken.
  [[nodiscard]] Scalar total() const noexcept { return kinetic + elastic + gravity; }
  /// The most energy the model may physically hold: reference + external work (damping only
  /// removes energy).
  [[nodiscard]] Scalar budget() const noexcept { return reference + external_work; }
};

/// @brief When a step counts as diverged, and what to do then.
template <typename Scalar>
struct DivergencePolicy {
  /// Check the energy after each step (one extra pass over the links and elements); non-finite
  /// states are always caught. The work of external forces and of contacts (ForceModel's penalty
  /// contacts, at their end-of-step forces) counts into the budget.
  bool check_energy{true};
  /// A step diverges when its energy exceeds budget + tolerance * |budget| + floor.
  Scalar energy_tolerance{Scalar(1)};
  /// Also hold each step to a budget of its own: the energy it started with plus the work done on
  /// it in the step (the same tolerance and floor). The cumulative budget alone grows slack as
  /// damping removes energy: after 16 s of probing, the bundled uterus held 3 mJ against a budget
  /// of 150 mJ, so a step that gave it fifty times its energy passed (docs/physics.md, section 7).
  bool check_step_energy{true};
  /// The floor is the energy of every link strained by this much (so a model at rest with a
  /// tiny budget does not trip on rounding).
  Scalar energy_floor_strain{Scalar(0.01)};
  /// After a divergence, retry with 2, 4, ... 2^k sub-steps (k = 0 turns this off).
  int max_substep_halvings{0};
  /// Implicit integrators only (backward Euler removes energy; it does not make any): a step that
  /// passes the checks above but ends with more energy than it started with plus the work done on
  /// it, by more than the energy of every link and element strained by this much, is retried as
  /// sub-steps like a divergence (with max_substep_halvings above 0). If the last level still gains
  /// that much, its result is kept when it passes the checks above; if every finer level fails
  /// them, the finest level that passed runs again (without the warm start it had) and stands if
  /// it passes them again (StepReport::energy_gain says how much a step gained). 0 turns this
  /// off. The default allows a quarter of the floor above: on the bundled uterus and the VHF
  /// pelvis, no accepted step of either law gained more than 0.13 of it, while the steps of a
  /// spurious runaway gained up to 19 floors in one step (docs/physics.md, section 7).
  Scalar energy_gain_strain{Scalar(0.005)};
};

/// @brief When regions (parts) sleep: held still and left out of the force loop until something
/// touches them.
///
/// A region falls asleep when every one of its nodes has moved slower than `sleep_speed` for
/// `sleep_time` (it is in equilibrium under whatever loads and contacts act on it); its velocities
/// are zeroed and its external forces remembered. It wakes before a step when the external force
/// on one of its nodes differs from the remembered one by more than `wake_force` (a new load, an
/// instrument touching it, a neighbouring part pressing harder), or when a node of another region
/// linked to it moves faster than `wake_speed`.
template <typename Scalar>
struct SleepPolicy {
  bool enabled{false};
  Scalar sleep_speed{Scalar(2e-4)};  ///< m/s
  Scalar sleep_time{Scalar(0.05)};   ///< s
  Scalar wake_speed{Scalar(2e-4)};   ///< m/s
  Scalar wake_force{Scalar(1e-4)};   ///< N
};

/// @brief A SphereModel stepped in time by an integrator under a ForceModel, with divergence
/// detection and rollback.
///
/// step(dt) allocates nothing and never throws. A step whose state is not finite, or whose
/// energy exceeds the physical budget (the reference energy plus the work of the external forces;
/// damping can only remove energy) by more than the policy allows, is undone: the model returns to
/// the state before the step and the report says `diverged`. With sub-stepping enabled the step
/// is first retried with smaller steps.
///
/// Edits to positions or velocities between steps are allowed: the simulation notices them,
/// checks them, sets fixed nodes' velocities back to zero (a fixed node moves only when its
/// position is edited) and takes a new energy reference. After editing masses, fixed flags or link
/// constants in place, or adding nodes or links, call refresh().
template <typename Scalar>
class Simulation {
 public:
  struct Options {
    /// Integrator registry name (see integrator_names()).
    std::string integrator{"implicit_euler"};
    typename ForceModel<Scalar>::Options forces{};
    DivergencePolicy<Scalar> divergence{};
    SleepPolicy<Scalar> sleep{};
    /// With forces.threads above 1: now and then, time 32 steps on the worker pool and 32 without
    /// it (ForceModel::use_pool; after a few untimed steps, at least 3 ms; plain steps only) and
    /// keep the one of lower median for the next 1,024 steps. A second core that
    /// is slow to reach can make the pool slower than one thread: on a 2-vCPU virtual machine
    /// whose vCPUs the host places far apart, one hand-over costs 0.6-0.8 us instead of 0.1 us
    /// and the uterus's implicit step took 205 us on two threads against 131 us on one
    /// (docs/benchmarks.md). Off by default: the pool and one thread sum in different orders, so
    /// such a run is reproducible only to rounding.
    bool adaptive_threads{false};
  };

  /// @brief Validates the model (fsm::Error on bad input) and prepares everything for stepping.
  explicit Simulation(SphereModel<Scalar> model, const Options& options = Options{});
  /// @brief The same with a configured integrator (options.integrator is ignored).
  Simulation(SphereModel<Scalar> model, std::unique_ptr<Integrator<Scalar>> integrator,
             const Options& options = Options{});

  /// @brief Advances by dt seconds. Never allocates, never throws.
  StepReport<Scalar> step(Scalar dt) noexcept;
  /// @brief Whether the steps now run on the worker pool (forces.threads above 1, and not set
  /// aside by Options::adaptive_threads).
  [[nodiscard]] bool uses_pool() const noexcept { return m_forces.uses_pool(); }

  /// @brief The model (positions and velocities may be edited between steps).
  [[nodiscard]] SphereModel<Scalar>& model() noexcept { return m_model; }
  [[nodiscard]] const SphereModel<Scalar>& model() const noexcept { return m_model; }
  /// @brief The forces (external forces, gravity, damping model, threads).
  [[nodiscard]] ForceModel<Scalar>& forces() noexcept { return m_forces; }
  [[nodiscard]] const ForceModel<Scalar>& forces() const noexcept { return m_forces; }
  /// @brief External force per node (N), `|V| x 3`, held until changed.
  Eigen::Map<Positions<Scalar>> external_forces() noexcept { return m_forces.external_forces(); }
  [[nodiscard]] Integrator<Scalar>& integrator() noexcept { return *m_integrator; }
  [[nodiscard]] const Options& options() const noexcept { return m_options; }

  /// @brief Swaps the integrator (nothing else changes).
  void set_integrator(std::unique_ptr<Integrator<Scalar>> integrator);
  /// @brief Swaps the integrator by registry name.
  void set_integrator(std::string_view name);
  /// @brief Changes the divergence policy.
  void set_divergence_policy(const DivergencePolicy<Scalar>& policy);
  /// @brief Changes gravity, damping model or thread count.
  void set_force_options(const typename ForceModel<Scalar>::Options& options);

  /// @brief Fixes or frees a node (its velocity is zeroed when fixed).
  void set_fixed(Index node, bool fixed = true);
  /// @brief Re-validates the model and re-derives everything from it (inverse masses, bounds,
  /// workspaces, energy reference). Call after editing model arrays other than positions and
  /// velocities. Not real-time safe.
  void refresh();

  /// @name Cutting and tearing (docs/physics.md section 12)
  /// @{
  /// @brief Cuts the links and tetrahedra the blade swept through at the current positions
  /// (between steps; the servo loop calls it before the step it belongs to). No allocation, never
  /// throws: an invalid blade (Blade::validate()) is reported as `rejected` and changes nothing.
  /// The energy reference restarts with the next step (a cut releases the energy its links held;
  /// that step is checked for finite values only).
  TopologyChange cut(const Blade<Scalar>& blade) noexcept;
  /// @brief The cutting and tearing state: tear strains per link (writable; then
  /// topology().refresh_tearing(model())), the links and tetrahedra of the last cut or tear.
  [[nodiscard]] TopologyEditor<Scalar>& topology() noexcept { return m_topology; }
  [[nodiscard]] const TopologyEditor<Scalar>& topology() const noexcept { return m_topology; }
  /// @}
  /// @brief Changes the sleep policy (turning it off wakes every region).
  void set_sleep_policy(const SleepPolicy<Scalar>& policy);
  /// @brief True while region r sleeps.
  [[nodiscard]] bool asleep(Index region) const {
    return m_region_asleep.at(std::size_t(region)) != 0;
  }
  /// @brief How many regions sleep now.
  [[nodiscard]] Index num_asleep() const noexcept;

  /// @brief Bounds on the model's highest eigenfrequency and damping (at rest).
  [[nodiscard]] const SpectralBound<Scalar>& spectral_bound() const noexcept { return m_bound; }
  /// @brief The current integrator's largest stable step for this model (s).
  [[nodiscard]] Scalar stable_time_step() const noexcept {
    return m_integrator->stable_time_step(m_bound);
  }
  /// @brief Energy account at the current state.
  [[nodiscard]] EnergyReport<Scalar> energy() const noexcept;
  /// @brief The energy a step may gain before it is retried finer (J):
  /// DivergencePolicy::energy_gain_strain as the energy of every link and element strained that
  /// much; 0 when off.
  [[nodiscard]] Scalar energy_gain_limit() const noexcept { return m_gain_limit; }
  /// @brief Takes the current energy as the new reference (external work restarts at 0).
  void reset_energy_reference() noexcept;
  /// @brief Simulated time (s) since construction or reset().
  [[nodiscard]] Scalar time() const noexcept { return m_time; }
  /// @brief Back to rest, zero velocity, zero external force, time 0.
  void reset() noexcept;

 private:
  StepReport<Scalar> advance(Scalar dt) noexcept;          // step() without the thread trials
  void time_threads(double seconds, bool plain) noexcept;  // Options::adaptive_threads
  [[nodiscard]] Scalar total_energy() const noexcept;
  void save_state() noexcept;
  void restore_state() noexcept;
  [[nodiscard]] bool state_matches_saved() const noexcept;
  bool wake_regions() noexcept;
  void update_load() noexcept;
  bool sleep_regions(Scalar dt) noexcept;  // true if a region fell asleep
  void set_region_asleep(Index region, bool asleep) noexcept;
  void apply_topology_change(TopologyChange& change) noexcept;

  SphereModel<Scalar> m_model;
  Options m_options;
  ForceModel<Scalar> m_forces;
  std::unique_ptr<Integrator<Scalar>> m_integrator;
  SpectralBound<Scalar> m_bound;
  TopologyEditor<Scalar> m_topology;
  std::vector<Index> m_fixed_nodes;
  Index m_num_links{0};
  // Sleeping: nodes per region (CSR), nodes of other regions linked to each region (CSR).
  std::vector<Index> m_region_start, m_region_nodes, m_border_start, m_border_nodes;
  std::vector<std::uint8_t> m_region_asleep, m_node_asleep;
  std::vector<Scalar> m_quiet_time;
  Positions<Scalar> m_sleep_force;  // load (external + contact) when its region fell asleep
  Positions<Scalar> m_load;         // external forces plus the penalty contacts' forces, per node
  Positions<Scalar> m_saved_x, m_saved_v;
  // The force model kept the elements' forces at the saved state (the last step's energy check).
  bool m_forces_kept{false};
  Scalar m_energy_reference{0};
  // A cut or a tear removed energy since the reference was taken: the next accepted step takes
  // its end energy as the new reference instead of checking it (a full energy pass on every cut
  // would cost more than the cut itself).
  bool m_reference_stale{false};
  Scalar m_external_work{0};
  // The energy at the start of the next step (DivergencePolicy::check_step_energy).
  Scalar m_start_energy{0};
  Scalar m_energy_floor{0};
  // DivergencePolicy::energy_gain_strain as an energy (J); 0: off.
  Scalar m_gain_limit{0};
  Scalar m_time{0};
  // Options::adaptive_threads: phase 0 times steps on the pool, 1 without, 2 runs the faster for
  // `period` steps; `count` timed steps into a trial (after its untimed warm-up), or steps into
  // phase 2.
  struct ThreadTrial {
    static constexpr int steps = 32, period = 1024;
    int phase{0};
    int count{0};
    int warm_steps{0};
    double warm_seconds{0};
    double seconds[2][steps]{};
  };
  ThreadTrial m_thread_trial;
};

extern template class Simulation<float>;
extern template class Simulation<double>;

}  // namespace fsm

#include "fsm/impl/simulation-inl.hpp"
