#pragma once

/// @file integrator.hpp
/// @brief The integrator concept: `step(model, forces, dt)`, shared by every time-stepping scheme
/// so a scene swaps schemes without other changes; make_integrator() picks one by name.

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "fsm/force_model.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/stability.hpp"

namespace fsm {

/// @brief What one integrator step reports.
struct IntegratorResult {
  bool ok{true};      ///< False when the scheme could not produce a state (solver breakdown).
  int iterations{0};  ///< Linear-solver iterations (implicit schemes), else 0.
  /// False when a linear solve (any contact pass's) stopped at its iteration cap short of its
  /// tolerance: the state was still produced when `ok` (a real-time budget takes the truncated
  /// solve), but it is less accurate.
  bool converged{true};
};

/// @brief Base of the time-stepping schemes.
///
/// An integrator advances the model's positions and velocities in place by `dt` seconds under
/// `forces`. Fixed nodes (inverse mass 0) never move. prepare() sizes the workspace (it may
/// allocate); step() allocates nothing and never throws, and returns `ok = false` without a
/// usable state only when its solver breaks down (Simulation then rolls back).
template <typename Scalar>
class Integrator {
 public:
  virtual ~Integrator() = default;
  /// @brief Registry name ("improved_euler", "heun", "symplectic_euler", "implicit_euler").
  [[nodiscard]] virtual std::string_view name() const noexcept = 0;
  /// @brief Global order of accuracy.
  [[nodiscard]] virtual int order() const noexcept = 0;
  /// @brief True when the step solves for the end-of-step forces (stiff contacts need no cap)
  /// and takes the contacts' linear laws into it (ForceModel::prepare_implicit() or
  /// add_contact_linearisation()), so it needs no start-of-step contact forces.
  [[nodiscard]] virtual bool implicit() const noexcept { return false; }
  /// @brief True when the step's first force evaluation is ForceModel::prepare_implicit() at the
  /// step's start state (so forces kept by ForceModel::elastic_energy_keeping_forces() serve it).
  [[nodiscard]] virtual bool prepares_implicit() const noexcept { return false; }
  /// @brief Sizes the workspace for `model`. Call again when the model's size changes.
  virtual void prepare(const SphereModel<Scalar>& model) = 0;
  /// @brief Advances by dt (s). Requires prepare() for this model's size; returns ok = false
  /// (and leaves the state alone) if it was not.
  virtual IntegratorResult step(SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                                Scalar dt) noexcept = 0;
  /// @brief Forgets state carried between steps (a warm start), e.g. after a rollback.
  virtual void reset() noexcept {}
  /// @brief A copy with the same options (the workspace must be prepared again).
  [[nodiscard]] virtual std::unique_ptr<Integrator> clone() const = 0;
  /// @brief Largest stable step (s) for the bounds (0: no step is stable; infinity: any is).
  [[nodiscard]] virtual Scalar stable_time_step(
      const SpectralBound<Scalar>& bound) const noexcept = 0;

 protected:
  Integrator() = default;
  Integrator(const Integrator&) = default;
  Integrator& operator=(const Integrator&) = default;
};

/// @brief Names accepted by make_integrator().
[[nodiscard]] std::vector<std::string> integrator_names();

/// @brief The integrator of that name with default options; fsm::Error listing the valid names
/// for anything else.
template <typename Scalar>
[[nodiscard]] std::unique_ptr<Integrator<Scalar>> make_integrator(std::string_view name);

extern template std::unique_ptr<Integrator<float>> make_integrator<float>(std::string_view);
extern template std::unique_ptr<Integrator<double>> make_integrator<double>(std::string_view);

namespace detail {
// True when the workspace `w` (3 scalars per node) was sized for this model.
template <typename Scalar>
bool prepared_for(const SphereModel<Scalar>& model, const Positions<Scalar>& w) noexcept {
  return w.rows() == model.num_nodes();
}
}  // namespace detail

}  // namespace fsm
