#pragma once

/// @file heun_integrator.hpp
/// @brief Heun's method (the paper's eq. 9): explicit second-order Runge-Kutta.

#include "fsm/integrator.hpp"

namespace fsm {

namespace detail {

// Heun's two vector passes over the arrays' storage, 3 per node; the arrays do not overlap (the
// restrict parameters tell the compiler so, which it does not assume for Eigen's maps).
template <typename Scalar>
void heun_predict(const Scalar* FSM_RESTRICT x, const Scalar* FSM_RESTRICT v,
                  const Scalar* FSM_RESTRICT f1, const Scalar* FSM_RESTRICT w, Scalar dt, Index n,
                  Scalar* FSM_RESTRICT xp, Scalar* FSM_RESTRICT vp) noexcept {
  for (Index i = 0; i < n; ++i) {
    const Scalar hw = dt * w[i];
    const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
    xp[k] = x[k] + dt * v[k];
    xp[k + 1] = x[k + 1] + dt * v[k + 1];
    xp[k + 2] = x[k + 2] + dt * v[k + 2];
    vp[k] = v[k] + hw * f1[k];
    vp[k + 1] = v[k + 1] + hw * f1[k + 1];
    vp[k + 2] = v[k + 2] + hw * f1[k + 2];
  }
}

template <typename Scalar>
void heun_correct(const Scalar* FSM_RESTRICT vp, const Scalar* FSM_RESTRICT f1,
                  const Scalar* FSM_RESTRICT f2, const Scalar* FSM_RESTRICT w, Scalar dt, Index n,
                  Scalar* FSM_RESTRICT x, Scalar* FSM_RESTRICT v) noexcept {
  const Scalar half = Scalar(0.5) * dt;
  for (Index i = 0; i < n; ++i) {
    const Scalar hw = half * w[i];
    const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
    x[k] += half * (v[k] + vp[k]);
    x[k + 1] += half * (v[k + 1] + vp[k + 1]);
    x[k + 2] += half * (v[k + 2] + vp[k + 2]);
    v[k] += hw * (f1[k] + f2[k]);
    v[k + 1] += hw * (f1[k + 1] + f2[k + 1]);
    v[k + 2] += hw * (f1[k + 2] + f2[k + 2]);
  }
}

}  // namespace detail

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
    detail::heun_predict(x.data(), v.data(), m_f1.data(), w, dt, n, m_x.data(), m_v.data());
    forces.evaluate(model, m_x, m_v, m_f2);
    detail::heun_correct(m_v.data(), m_f1.data(), m_f2.data(), w, dt, n, x.data(), v.data());
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
