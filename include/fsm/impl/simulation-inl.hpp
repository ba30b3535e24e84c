#pragma once

// Definitions of Simulation's members; included at the bottom of fsm/simulation.hpp.

#include <algorithm>
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
  const auto& d = m_options.divergence;
  if (!(d.energy_tolerance >= 0) || !(d.energy_floor_strain >= 0) || d.max_substep_halvings < 0 ||
      d.max_substep_halvings > 20)
    throw Error("", "divergence policy",
                "tolerances must be non-negative and max_substep_halvings in [0, 20]");
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
  const auto k = m_model.stiffness();
  const auto l0 = m_model.rest_lengths();
  const Scalar s = d.energy_floor_strain;
  m_energy_floor = Scalar(0.5) * s * s * k.dot(l0.cwiseProduct(l0));
  m_saved_x.resize(m_model.num_nodes(), 3);
  m_saved_v.resize(m_model.num_nodes(), 3);
  save_state();
  reset_energy_reference();
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
  m_bound = fsm::spectral_bound(m_model, m_options.forces.damping);
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
  m_external_work = Scalar(0);
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
}

template <typename Scalar>
void Simulation<Scalar>::restore_state() noexcept {
  m_model.positions() = m_saved_x;
  m_model.velocities() = m_saved_v;
}

template <typename Scalar>
bool Simulation<Scalar>::state_matches_saved() const noexcept {
  const auto bytes = sizeof(Scalar) * 3 * std::size_t(m_model.num_nodes());
  return std::memcmp(m_model.positions().data(), m_saved_x.data(), bytes) == 0 &&
         std::memcmp(m_model.velocities().data(), m_saved_v.data(), bytes) == 0;
}

template <typename Scalar>
StepReport<Scalar> Simulation<Scalar>::step(Scalar dt) noexcept {
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
      !ext.allFinite()) {
    report.status = StepStatus::invalid_input;
    return report;
  }
  // Between steps the caller may have moved nodes or changed velocities: check the edit, keep fixed
  // nodes still, and start a new energy reference (that energy did not come through the forces).
  if (!state_matches_saved()) {
    if (!x.allFinite() || !v.allFinite()) {
      restore_state();
      report.status = StepStatus::invalid_input;
      return report;
    }
    for (const Index i : m_fixed_nodes) v.row(i).setZero();
    save_state();
    if (policy.check_energy) reset_energy_reference();
  }
  for (int level = 0; level <= policy.max_substep_halvings; ++level) {
    const int n = 1 << level;
    const Scalar h = dt / Scalar(n);
    bool good = true;
    int iterations = 0;
    for (int s = 0; s < n && good; ++s) {
      const IntegratorResult r = m_integrator->step(m_model, m_forces, h);
      iterations += r.iterations;
      good = r.ok;
    }
    good = good && x.allFinite() && v.allFinite();
    Scalar work(0), energy = std::numeric_limits<Scalar>::quiet_NaN();
    if (good && policy.check_energy) {
      // External forces are constant over the step, so their work is exact.
      work = ext.cwiseProduct(x - m_saved_x).sum();
      energy = total_energy();
      const Scalar budget = m_energy_reference + m_external_work + work;
      good = std::isfinite(energy) &&
             energy <= budget + policy.energy_tolerance * std::abs(budget) + m_energy_floor;
    }
    report.substeps += n;
    report.solver_iterations += iterations;
    if (good) {
      m_external_work += work;
      m_time += dt;
      save_state();
      report.status = level == 0 ? StepStatus::ok : StepStatus::recovered;
      report.energy = energy;
      return report;
    }
    restore_state();
    m_integrator->reset();  // its warm start came from the rejected state
  }
  report.status = StepStatus::diverged;
  return report;
}

}  // namespace fsm
