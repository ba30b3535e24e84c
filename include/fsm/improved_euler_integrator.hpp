#pragma once

/// @file improved_euler_integrator.hpp
/// @brief The paper's scheme (eq. 10): one force evaluation per step.

#include "fsm/integrator.hpp"

namespace fsm {

/// @brief The "improved Euler" update the paper iterates (docs/physics.md section 10.2, eq. 10):
/// \f[ \mathbf{v}_{n+1} = \mathbf{v}_n + h\,\mathbf{M}^{-1}\mathbf{F}(\mathbf{x}_n, \mathbf{v}_n),
///     \qquad \mathbf{x}_{n+1} = \mathbf{x}_n + \tfrac{h}{2}(\mathbf{v}_n + \mathbf{v}_{n+1}). \f]
/// First order (the velocity update is forward Euler). Stable only with enough damping:
/// \f$\omega^2 h/2 < c < 2/h\f$ per mode (improved_euler_limit()); undamped it grows at every h.
template <typename Scalar>
class ImprovedEulerIntegrator final : public Integrator<Scalar> {
 public:
  [[nodiscard]] std::string_view name() const noexcept override { return "improved_euler"; }
  [[nodiscard]] std::unique_ptr<Integrator<Scalar>> clone() const override {
    return std::make_unique<ImprovedEulerIntegrator>(*this);
  }
  [[nodiscard]] int order() const noexcept override { return 1; }
  void prepare(const SphereModel<Scalar>& model) override { m_force.resize(model.num_nodes(), 3); }

  IntegratorResult step(SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                        Scalar dt) noexcept override {
    if (!detail::prepared_for(model, m_force)) return {false, 0};
    auto x = model.positions();
    auto v = model.velocities();
    forces.evaluate(model, x, v, m_force);
    const Scalar* w = forces.inverse_masses().data();
    Scalar* xp = x.data();
    Scalar* vp = v.data();
    const Scalar* F = m_force.data();
    const Scalar half = Scalar(0.5) * dt;
    for (Index i = 0; i < model.num_nodes(); ++i) {
      for (int c = 0; c < 3; ++c) {
        const std::ptrdiff_t k = 3 * std::ptrdiff_t(i) + c;
        const Scalar vn = vp[k] + dt * w[i] * F[k];
        xp[k] += half * (vp[k] + vn);
        vp[k] = vn;
      }
    }
    return {true, 0};
  }

  [[nodiscard]] Scalar stable_time_step(const SpectralBound<Scalar>& b) const noexcept override {
    return improved_euler_limit(b);
  }

 private:
  Positions<Scalar> m_force;
};

extern template class ImprovedEulerIntegrator<float>;
extern template class ImprovedEulerIntegrator<double>;

}  // namespace fsm
