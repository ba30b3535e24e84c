#pragma once

/// @file symplectic_euler_integrator.hpp
/// @brief Semi-implicit (symplectic) Euler.

#include "fsm/integrator.hpp"

namespace fsm {

/// @brief Symplectic Euler: \f$\mathbf{v}_{n+1} = \mathbf{v}_n + h\,\mathbf{M}^{-1}
/// \mathbf{F}(\mathbf{x}_n, \mathbf{v}_n)\f$, \f$\mathbf{x}_{n+1} = \mathbf{x}_n +
/// h\,\mathbf{v}_{n+1}\f$. First order, one force evaluation, no secular energy drift without
/// damping; stable for \f$\omega h < 2\f$ undamped (symplectic_euler_limit() with damping).
template <typename Scalar>
class SymplecticEulerIntegrator final : public Integrator<Scalar> {
 public:
  [[nodiscard]] std::string_view name() const noexcept override { return "symplectic_euler"; }
  [[nodiscard]] std::unique_ptr<Integrator<Scalar>> clone() const override {
    return std::make_unique<SymplecticEulerIntegrator>(*this);
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
    for (Index i = 0; i < model.num_nodes(); ++i) {
      for (int c = 0; c < 3; ++c) {
        const std::ptrdiff_t k = 3 * std::ptrdiff_t(i) + c;
        vp[k] += dt * w[i] * F[k];
        xp[k] += dt * vp[k];
      }
    }
    return {true, 0};
  }

  [[nodiscard]] Scalar stable_time_step(const SpectralBound<Scalar>& b) const noexcept override {
    return symplectic_euler_limit(b);
  }

 private:
  Positions<Scalar> m_force;
};

extern template class SymplecticEulerIntegrator<float>;
extern template class SymplecticEulerIntegrator<double>;

}  // namespace fsm
