#pragma once

// Definitions of Simulation's members; included at the bottom of fsm/simulation.hpp.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

namespace fsm {

inline const char* to_string(StepStatus status) noexcept {
  switch (status) {
    case StepStatus::ok:
      return "ok";
    case StepStatus::recovered:
      return "recovered";
    case StepStatus::diverged:
      return "diverged";
    case StepStatus::invalid_time_step:
      return "invalid_time_step";
    case StepStatus::invalid_input:
      return "invalid_input";
  }
  return "unknown";
}

template <typename Scalar>
Simulation<Scalar>::Simulation(SphereModel<Scalar> model, const Options& options)
    : Simulation(std::move(model), make_integrator<Scalar>(options.integrator), options) {}

template <typename Scalar>
Simulation<Scalar>::Simulation(SphereModel<Scalar> model,
                               std::unique_ptr<Integrator<Scalar>> integrator,
                               const Options& options)
    : m_model(std::move(model)), m_options(options), m_integrator(std::move(integrator)) {
  if (!m_integrator) throw Error("", "integrator", "is null");
  m_options.integrator = std::string(m_integrator->name());
  m_forces = ForceModel<Scalar>(m_model, m_options.forces);
  refresh();
}

template <typename Scalar>
void Simulation<Scalar>::refresh() {
  m_model.validate();
  m_thread_trial = ThreadTrial{};  // the threads' trials start again, on the pool
  m_forces.use_pool(true);
  const auto& d = m_options.divergence;
  if (!(d.energy_tolerance >= 0) || !(d.energy_floor_strain >= 0) || !(d.energy_gain_strain >= 0) ||
      !std::isfinite(d.energy_gain_strain) || d.max_substep_halvings < 0 ||
      d.max_substep_halvings > 20)
    throw Error("", "divergence policy",
                "tolerances must be non-negative, energy_gain_strain finite and "
                "max_substep_halvings in [0, 20]");
  m_fixed_nodes.clear();
  for (Index i = 0; i < m_model.num_nodes(); ++i)
    if (m_model.fixed()[i]) {
      m_model.velocities().row(i).setZero();
      m_fixed_nodes.push_back(i);
    }
  m_num_links = m_model.num_links();
  m_forces.set_options(m_options.forces);
  m_forces.refresh(m_model);
  m_integrator->prepare(m_model);
  m_integrator->reset();
  m_bound = fsm::spectral_bound(m_model, m_options.forces.damping);
  m_bound.damping_max += m_options.forces.drag;  // the drag damps every mode at rate gamma
  const auto k = m_model.stiffness();
  const auto l0 = m_model.rest_lengths();
  const Scalar strained = k.dot(l0.cwiseProduct(l0)) + m_forces.element_energy_scale();
  const Scalar s = d.energy_floor_strain, g = d.energy_gain_strain;
  m_energy_floor = Scalar(0.5) * s * s * strained;
  m_gain_limit = Scalar(0.5) * g * g * strained;
  // Sleeping bookkeeping (every region awake after a refresh).
  const Index nr = m_model.num_regions(), nn = m_model.num_nodes();
  const auto region = m_model.node_regions();
  m_region_start.assign(std::size_t(nr) + 1, 0);
  for (Index i = 0; i < nn; ++i) ++m_region_start[std::size_t(region[i]) + 1];
  for (Index r = 0; r < nr; ++r)
    m_region_start[std::size_t(r) + 1] += m_region_start[std::size_t(r)];
  m_region_nodes.assign(std::size_t(nn), 0);
  {
    std::vector<Index> fill(m_region_start.begin(), m_region_start.end() - 1);
    for (Index i = 0; i < nn; ++i) m_region_nodes[std::size_t(fill[std::size_t(region[i])]++)] = i;
  }
  std::vector<std::vector<Index>> border(static_cast<std::size_t>(nr));
  const auto links = m_model.links();
  for (Index l = 0; l < m_model.num_links(); ++l) {
    const Index a = links(l, 0), b = links(l, 1);
    if (region[a] != region[b]) {
      border[std::size_t(region[a])].push_back(b);
      border[std::size_t(region[b])].push_back(a);
    }
  }
  m_border_start.assign(1, 0);
  m_border_nodes.clear();
  for (auto& list : border) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    m_border_nodes.insert(m_border_nodes.end(), list.begin(), list.end());
    m_border_start.push_back(Index(m_border_nodes.size()));
  }
  m_region_asleep.assign(std::size_t(nr), 0);
  m_node_asleep.assign(std::size_t(nn), 0);
  m_quiet_time.assign(std::size_t(nr), Scalar(0));
  m_sleep_force.setZero(nn, 3);
  m_load.setZero(nn, 3);
  m_forces.set_asleep(m_node_asleep, m_model);
  const auto& sp = m_options.sleep;
  if (!(sp.sleep_speed >= 0) || !(sp.sleep_time >= 0) || !(sp.wake_speed >= 0) ||
      !(sp.wake_force >= 0))
    throw Error("", "sleep policy", "speeds and time must be non-negative");

  m_topology.refresh(m_model);
  TopologyChange pieces;
  m_topology.count_pieces(m_model, m_forces.force_links(), pieces);

  m_saved_x.resize(m_model.num_nodes(), 3);
  m_saved_v.resize(m_model.num_nodes(), 3);
  save_state();
  reset_energy_reference();
}

template <typename Scalar>
void Simulation<Scalar>::apply_topology_change(TopologyChange& change) noexcept {
  if (!change.any()) return;
  m_forces.update_topology(m_model, m_topology.broken_links(), m_topology.removed_tetrahedra());
  m_topology.update_pieces(m_model, m_forces.force_links(), change);
  // The broken links' and elements' energy left the model (removing an element also changes its
  // nodes' volumes, so the continuum law's volumetric energy can rise as well as fall): the next
  // step's end energy becomes the reference.
  m_reference_stale = true;
}

template <typename Scalar>
TopologyChange Simulation<Scalar>::cut(const Blade<Scalar>& blade) noexcept {
  TopologyChange change;
  if (blade.problem() != nullptr) {
    change.rejected = true;
    return change;
  }
  change = m_topology.cut(m_model, blade);
  apply_topology_change(change);
  return change;
}

template <typename Scalar>
void Simulation<Scalar>::set_sleep_policy(const SleepPolicy<Scalar>& policy) {
  m_options.sleep = policy;
  refresh();
}

template <typename Scalar>
Index Simulation<Scalar>::num_asleep() const noexcept {
  return Index(std::count(m_region_asleep.begin(), m_region_asleep.end(), std::uint8_t(1)));
}

template <typename Scalar>
void Simulation<Scalar>::set_region_asleep(Index r, bool asleep) noexcept {
  m_region_asleep[std::size_t(r)] = asleep ? 1 : 0;
  m_quiet_time[std::size_t(r)] = Scalar(0);
  auto v = m_model.velocities();
  for (Index k = m_region_start[std::size_t(r)]; k < m_region_start[std::size_t(r) + 1]; ++k) {
    const Index i = m_region_nodes[std::size_t(k)];
    m_node_asleep[std::size_t(i)] = asleep ? 1 : 0;
    if (asleep) {
      v.row(i).setZero();
      m_sleep_force.row(i) = m_load.row(i);
    }
  }
}

// The load on each node: external forces plus the penalty contacts' and held nodes' last forces.
template <typename Scalar>
void Simulation<Scalar>::update_load() noexcept {
  m_load = m_forces.external_forces();  // same size: no allocation
  const PenaltyContact<Scalar>* c = m_forces.contacts();
  for (Index k = 0; k < m_forces.num_contacts(); ++k) {
    m_load.row(c[k].node) += c[k].force.transpose();
    if (c[k].other >= 0) m_load.row(c[k].other) -= c[k].force.transpose();
  }
  const HeldNode<Scalar>* held = m_forces.held();
  for (Index k = 0; k < m_forces.num_held(); ++k)
    m_load.row(held[k].node) += held[k].force.transpose();
}

// Before a step: wake asleep regions with a load on them or a moving neighbour. True if any woke.
template <typename Scalar>
bool Simulation<Scalar>::wake_regions() noexcept {
  bool changed = false;
  update_load();
  const auto v = m_model.velocities();
  const Scalar wake2 = m_options.sleep.wake_speed * m_options.sleep.wake_speed;
  for (Index r = 0; r < m_model.num_regions(); ++r) {
    if (!m_region_asleep[std::size_t(r)]) continue;
    bool wake = false;
    const Scalar tol2 = m_options.sleep.wake_force * m_options.sleep.wake_force;
    for (Index k = m_region_start[std::size_t(r)]; k < m_region_start[std::size_t(r) + 1] && !wake;
         ++k) {
      const Index i = m_region_nodes[std::size_t(k)];
      wake = (m_load.row(i) - m_sleep_force.row(i)).squaredNorm() > tol2;
    }
    for (Index k = m_border_start[std::size_t(r)]; k < m_border_start[std::size_t(r) + 1] && !wake;
         ++k)
      wake = v.row(m_border_nodes[std::size_t(k)]).squaredNorm() > wake2;
    if (wake) {
      set_region_asleep(r, false);
      changed = true;
    }
  }
  return changed;
}

// After an accepted step: regions quiet for long enough, with no load, fall asleep.
template <typename Scalar>
bool Simulation<Scalar>::sleep_regions(Scalar dt) noexcept {
  bool changed = false;
  update_load();
  const auto v = m_model.velocities();
  const Scalar sleep2 = m_options.sleep.sleep_speed * m_options.sleep.sleep_speed;
  for (Index r = 0; r < m_model.num_regions(); ++r) {
    if (m_region_asleep[std::size_t(r)]) continue;
    bool quiet = true;
    for (Index k = m_region_start[std::size_t(r)]; k < m_region_start[std::size_t(r) + 1] && quiet;
         ++k) {
      const Index i = m_region_nodes[std::size_t(k)];
      quiet = v.row(i).squaredNorm() <= sleep2;
    }
    m_quiet_time[std::size_t(r)] = quiet ? m_quiet_time[std::size_t(r)] + dt : Scalar(0);
    if (quiet && m_quiet_time[std::size_t(r)] >= m_options.sleep.sleep_time) {
      set_region_asleep(r, true);
      changed = true;
    }
  }
  if (changed) m_forces.set_asleep(m_node_asleep, m_model);
  return changed;
}

template <typename Scalar>
void Simulation<Scalar>::set_integrator(std::unique_ptr<Integrator<Scalar>> integrator) {
  if (!integrator) throw Error("", "integrator", "is null");
  integrator->prepare(m_model);
  m_integrator = std::move(integrator);
  m_options.integrator = std::string(m_integrator->name());
}

template <typename Scalar>
void Simulation<Scalar>::set_integrator(std::string_view name) {
  set_integrator(make_integrator<Scalar>(name));
}

template <typename Scalar>
void Simulation<Scalar>::set_divergence_policy(const DivergencePolicy<Scalar>& policy) {
  m_options.divergence = policy;
  refresh();
}

template <typename Scalar>
void Simulation<Scalar>::set_force_options(const typename ForceModel<Scalar>::Options& options) {
  m_options.forces = options;
  refresh();
}

template <typename Scalar>
void Simulation<Scalar>::set_fixed(Index node, bool fixed) {
  m_model.set_fixed(node, fixed);
  m_fixed_nodes.erase(std::remove(m_fixed_nodes.begin(), m_fixed_nodes.end(), node),
                      m_fixed_nodes.end());
  if (fixed) m_fixed_nodes.push_back(node);
  m_forces.refresh(m_model);
  TopologyChange pieces;  // which pieces hold a fixed node changed
  m_topology.count_pieces(m_model, m_forces.force_links(), pieces);
  m_bound = fsm::spectral_bound(m_model, m_options.forces.damping);
  m_bound.damping_max += m_options.forces.drag;
  save_state();
  reset_energy_reference();
}

template <typename Scalar>
Scalar Simulation<Scalar>::total_energy() const noexcept {
  const auto x = m_model.positions();
  return m_forces.kinetic_energy(m_model, m_model.velocities()) +
         m_forces.elastic_energy(m_model, x) + m_forces.gravity_energy(m_model, x);
}

template <typename Scalar>
EnergyReport<Scalar> Simulation<Scalar>::energy() const noexcept {
  EnergyReport<Scalar> e;
  const auto x = m_model.positions();
  e.kinetic = m_forces.kinetic_energy(m_model, m_model.velocities());
  e.elastic = m_forces.elastic_energy(m_model, x);
  e.gravity = m_forces.gravity_energy(m_model, x);
  e.external_work = m_external_work;
  e.reference = m_energy_reference;
  return e;
}

template <typename Scalar>
void Simulation<Scalar>::reset_energy_reference() noexcept {
  m_energy_reference = total_energy();
  m_start_energy = m_energy_reference;
  m_external_work = Scalar(0);
  m_reference_stale = false;
}

template <typename Scalar>
void Simulation<Scalar>::reset() noexcept {
  m_model.reset_to_rest();
  m_forces.clear_external_forces();
  m_integrator->reset();
  m_time = Scalar(0);
  save_state();
  reset_energy_reference();
}

template <typename Scalar>
void Simulation<Scalar>::save_state() noexcept {
  m_saved_x = m_model.positions();
  m_saved_v = m_model.velocities();
  m_forces_kept = false;  // step() sets it again where the kept forces are at this state
}

template <typename Scalar>
void Simulation<Scalar>::restore_state() noexcept {
  m_model.positions() = m_saved_x;
  m_model.velocities() = m_saved_v;
  m_forces_kept = false;
}

template <typename Scalar>
bool Simulation<Scalar>::state_matches_saved() const noexcept {
  const auto bytes = sizeof(Scalar) * 3 * std::size_t(m_model.num_nodes());
  return std::memcmp(m_model.positions().data(), m_saved_x.data(), bytes) == 0 &&
         std::memcmp(m_model.velocities().data(), m_saved_v.data(), bytes) == 0;
}

template <typename Scalar>
StepReport<Scalar> Simulation<Scalar>::step(Scalar dt) noexcept {
  if (!m_options.adaptive_threads || m_options.forces.threads < 2) return advance(dt);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const StepReport<Scalar> report = advance(dt);
  time_threads(std::chrono::duration<double>(Clock::now() - start).count(),
               report.status == StepStatus::ok);
  return report;
}

template <typename Scalar>
void Simulation<Scalar>::time_threads(double seconds, bool plain) noexcept {
  ThreadTrial& t = m_thread_trial;
  if (t.phase == 2) {
    if (++t.count >= ThreadTrial::period) {  // time both again
      t = ThreadTrial{};
      m_forces.use_pool(true);
    }
    return;
  }
  // Each trial's first steps are not timed: at least 4 of them and 3 ms, while helpers that slept
  // wake up, or, set aside, still spin (2 ms) on the other core.
  if (t.warm_steps < 4 || t.warm_seconds < 3e-3) {
    ++t.warm_steps;
    t.warm_seconds += seconds;
    return;
  }
  if (!plain) return;  // a step retried in halves, or not taken, is not compared
  t.seconds[t.phase][t.count++] = seconds;
  if (t.count < ThreadTrial::steps) return;
  t.count = t.warm_steps = 0;
  t.warm_seconds = 0;
  if (t.phase == 0) {
    t.phase = 1;
    m_forces.use_pool(false);
    return;
  }
  // The medians: a step that met a new contact or a busy core moves them little.
  auto median = [](double* a) {
    double* mid = a + ThreadTrial::steps / 2;
    std::nth_element(a, mid, a + ThreadTrial::steps);
    return *mid;
  };
  const double pool = median(t.seconds[0]), one = median(t.seconds[1]);
  t.phase = 2;
  m_forces.use_pool(pool <= one);
}

template <typename Scalar>
StepReport<Scalar> Simulation<Scalar>::advance(Scalar dt) noexcept {
  StepReport<Scalar> report;
  if (!(dt > Scalar(0)) || !std::isfinite(dt)) {
    report.status = StepStatus::invalid_time_step;
    return report;
  }
  const DivergencePolicy<Scalar>& policy = m_options.divergence;
  auto x = m_model.positions();
  auto v = m_model.velocities();
  const auto ext = m_forces.external_forces();
  if (m_model.num_nodes() != Index(m_saved_x.rows()) || m_model.num_links() != m_num_links ||
      !detail::all_finite(ext.data(), ext.size())) {
    report.status = StepStatus::invalid_input;
    return report;
  }
  // Between steps the caller may have moved nodes or changed velocities: check the edit, keep fixed
  // nodes still, and start a new energy reference (that energy did not come through the forces).
  if (!state_matches_saved()) {
    if (!detail::all_finite(x.data(), x.size()) || !detail::all_finite(v.data(), v.size())) {
      restore_state();
      report.status = StepStatus::invalid_input;
      return report;
    }
    for (const Index i : m_fixed_nodes) v.row(i).setZero();
    for (Index i = 0; i < m_model.num_nodes(); ++i)
      if (m_node_asleep[std::size_t(i)]) v.row(i).setZero();
    save_state();
    if (policy.check_energy) reset_energy_reference();
  }
  if (m_options.sleep.enabled && wake_regions()) m_forces.set_asleep(m_node_asleep, m_model);
  // The elements' forces kept by the last step's energy check are at this very state unless it
  // was edited (save_state() above) or changed since (ForceModel checks its own side).
  m_forces.reuse_kept_forces(m_forces_kept);
  const bool keep_forces = m_integrator->prepares_implicit();
  if (!m_integrator->implicit())
    report.softened_contacts = m_forces.limit_contact_stiffness(m_model, dt);
  const Scalar contact_time = m_forces.contact_time();
  // (An implicit step's contact work does not use the start forces: contact_work().)
  m_forces.start_contacts(m_model, !m_integrator->implicit());
  // The finest level that passed the checks and was retried only for its gain
  // (DivergencePolicy::energy_gain_strain): if every finer level fails the checks, it runs again
  // with its gain allowed (`last_try`), so that the limit does not itself roll back a step the
  // checks accepted.
  int fallback = -1;
  bool last_try = false;
  for (int level = 0; level <= policy.max_substep_halvings; ++level) {
    const int n = 1 << level;
    const Scalar h = dt / Scalar(n);
    bool good = true;
    int iterations = 0, unconverged = 0, s = 0;  // s: the sub-steps that ran
    for (; s < n && good; ++s) {
      // The instruments' surfaces move through the step: contact time at this substep's start.
      m_forces.set_contact_time(contact_time + Scalar(s) * h);
      const IntegratorResult r = m_integrator->step(m_model, m_forces, h);
      iterations += r.iterations;
      unconverged += r.converged ? 0 : 1;
      good = r.ok;
    }
    m_forces.set_contact_time(contact_time + dt);
    good = good && detail::all_finite(x.data(), x.size()) && detail::all_finite(v.data(), v.size());
    if (good) m_forces.finish_contacts(m_model);
    Scalar work(0), energy = std::numeric_limits<Scalar>::quiet_NaN(),
                    gain = std::numeric_limits<Scalar>::quiet_NaN();
    if (good && policy.check_energy) {
      // External forces are constant over the step, so their work is exact; the contacts' is
      // taken at their end-of-step force, an upper bound for a contact that pushes harder as it
      // is pressed.
      work = ext.cwiseProduct(x - m_saved_x).sum() + m_forces.contact_work(m_model, m_saved_x);
      // The elements' energy from a force evaluation at the end state, which the next implicit
      // step reuses (ForceModel::Options::reuse_end_forces).
      energy = keep_forces ? m_forces.kinetic_energy(m_model, v) +
                                 m_forces.elastic_energy_keeping_forces(m_model) +
                                 m_forces.gravity_energy(m_model, x)
                           : total_energy();
      if (m_reference_stale) {  // after a cut or a tear: this energy is the new reference
        good = std::isfinite(energy);
        if (good) {
          m_energy_reference = energy;
          m_external_work = -work;  // added back below: the reference already holds it
          m_reference_stale = false;
        }
      } else {
        auto within = [&](Scalar budget) {
          return energy <= budget + policy.energy_tolerance * std::abs(budget) + m_energy_floor;
        };
        good = std::isfinite(energy) && within(m_energy_reference + m_external_work + work) &&
               (!policy.check_step_energy || within(m_start_energy + work));
        gain = energy - (m_start_energy + work);
        // A level that gained energy a backward-Euler step cannot make: retried finer while
        // there is a finer level; the last level's result stands on the checks above.
        if (good && !last_try && m_gain_limit > Scalar(0) && m_integrator->implicit() &&
            gain > m_gain_limit && level < policy.max_substep_halvings) {
          good = false;
          fallback = level;
          ++report.energy_gain_retries;
        }
      }
    }
    report.substeps += s;
    report.solver_iterations += iterations;
    report.unconverged_solves += unconverged;
    if (good) {
      m_external_work += work;
      if (policy.check_energy) m_start_energy = energy;
      m_time += dt;
      // A region falling asleep zeroes its velocities: the kept forces are then not at this state.
      bool kept = keep_forces && policy.check_energy;
      if (m_options.sleep.enabled && sleep_regions(dt)) kept = false;
      if (m_topology.tears()) {
        report.torn = m_topology.tear(m_model);
        apply_topology_change(report.torn);
        kept = false;
      }
      save_state();
      m_forces_kept = kept;
      report.status = level == 0 ? StepStatus::ok : StepStatus::recovered;
      report.energy = energy;
      report.energy_gain = gain;
      // From the kept evaluation unless the elements changed since (then -1).
      const Index inverted = m_forces.kept_inverted_elements();
      report.inverted_elements = inverted >= 0 ? inverted : m_forces.inverted_elements(x);
      return report;
    }
    restore_state();
    m_integrator->reset();              // its warm start came from the rejected state
    m_forces.reuse_kept_forces(false);  // kept at the rejected state: never a step's start
    m_forces.reject_contacts();         // finished at the rejected state: back to the restored
    if (last_try) break;
    if (level == policy.max_substep_halvings && fallback >= 0) {
      last_try = true;
      level = fallback - 1;  // the loop's increment makes it `fallback`
    }
  }
  m_forces.set_contact_time(contact_time);
  report.status = StepStatus::diverged;
  return report;
}

}  // namespace fsm
