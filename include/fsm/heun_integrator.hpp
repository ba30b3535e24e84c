#pragma once

/// @file heun_integrator.hpp
/// @brief Heun's method (the paper's eq. 9): explicit second-order Runge-Kutta.

#include "fsm/integrator.hpp"

namespace fsm {

/// @brief Heun's method on \f$\mathbf{z} = (\mathbf{x}, \mathbf{v})\f$ (docs/physics.md
/// section 10.2, eq. 9): \f$\mathbf{z}_{n+1} = \mathbf{z}_n + \tfrac{h}{2}[\mathbf{f}(\mathbf{z}_n)
/// + \mathbf{f}(\mathbf{z}_n + h\mathbf{f}(\mathbf{z}_n))]\f$, two force evaluations per step: \f[
/// \tilde{\mathbf{x}} = \mathbf{x} + h\mathbf{v},\quad \tilde{\mathbf{v}} = \mathbf{v} +
///     h\mathbf{a}_1,\quad \mathbf{x}_{n+1} = \mathbf{x} + \tfrac{h}{2}(\mathbf{v} +
///     \tilde{\mathbf{v}}),\quad \mathbf{v}_{n+1} = \mathbf{v} + \tfrac{h}{2}(\mathbf{a}_1 +
///     \tilde{\mathbf{a}}). \f]
/// Second order. Its amplification for an undamped oscillator is
/// \f$\sqrt{1 + (\omega h)^4/4} > 1\f$: it needs damping to be stable at all (heun_limit()).
template <typename Scalar>
class HeunIntegrator final : public Integrator<Scalar> {
 public:
  [[nodiscard]] std::string_view name() const noexcept override { return "heun"; }
  [[nodiscard]] std::unique_ptr<Integrator<Scalar>> clone() const override {
    return std::make_unique<HeunIntegrator>(*this);
  }
  [[nodiscard]] int order() const noexcept override { return 2; }
  void prepare(const SphereModel<Scalar>& model) override {
    const Index n = model.num_nodes();
    m_f1.resize(n, 3);
    m_f2.resize(n, 3);
    m_x.resize(n, 3);
    m_v.resize(n, 3);
  }

  IntegratorResult step(SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                        Scalar dt) noexcept override {
    if (!detail::prepared_for(model, m_f1)) return {false, 0};
    auto x = model.positions();
    auto v = model.velocities();
    const Scalar* w = forces.inverse_masses().data();
    const Index n = model.num_nodes();
    forces.evaluate(model, x, v, m_f1);
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        m_x(i, c) = x(i, c) + dt * v(i, c);
        m_v(i, c) = v(i, c) + dt * w[i] * m_f1(i, c);
      }
    forces.evaluate(model, m_x, m_v, m_f2);
    const Scalar half = Scalar(0.5) * dt;
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        x(i, c) += half * (v(i, c) + m_v(i, c));
        v(i, c) += half * w[i] * (m_f1(i, c) + m_f2(i, c));
      }
    return {true, 0};
  }

  [[nodiscard]] Scalar stable_time_step(const SpectralBound<Scalar>& b) const noexcept override {
    return heun_limit(b);
  }

 private:
  Positions<Scalar> m_f1, m_f2, m_x, m_v;
};

extern template class HeunIntegrator<float>;
extern template class HeunIntegrator<double>;

}  // namespace fsm
