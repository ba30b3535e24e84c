#pragma once

// Definitions of ImplicitEulerIntegrator's members; included by fsm/implicit_euler_integrator.hpp.

#include <cmath>

namespace fsm {

template <typename Scalar>
void ImplicitEulerIntegrator<Scalar>::prepare(const SphereModel<Scalar>& model) {
  const Index n = model.num_nodes();
  m_blocks.assign(
      std::size_t(ForceModel<Scalar>::implicit_block_size) * std::size_t(model.num_links()),
      Scalar(0));
  for (Positions<Scalar>* w :
       {&m_rhs, &m_diag, &m_dv, &m_r, &m_z, &m_p, &m_q, &m_x_end, &m_dv_previous})
    w->setZero(n, 3);
  m_pblocks.assign(6 * std::size_t(n), Scalar(0));
  m_pinv.assign(
      std::is_same_v<Scalar, double> ? std::size_t(detail::simd::precondition_size(n)) : 0, 0.0);
  m_last_dt = m_previous_dt = Scalar(0);
}

template <typename Scalar>
void ImplicitEulerIntegrator<Scalar>::precondition() noexcept {
  if (m_options.preconditioner == Preconditioner::jacobi) {
    m_z = m_r.cwiseQuotient(m_diag);
    return;
  }
  const Index n = Index(m_r.rows());
  for (Index i = 0; i < n; ++i) {
    const Scalar* B = &m_pblocks[6 * std::size_t(i)];
    const Scalar rx = m_r(i, 0), ry = m_r(i, 1), rz = m_r(i, 2);
    m_z(i, 0) = B[0] * rx + B[3] * ry + B[4] * rz;
    m_z(i, 1) = B[3] * rx + B[1] * ry + B[5] * rz;
    m_z(i, 2) = B[4] * rx + B[5] * ry + B[2] * rz;
  }
}

template <typename Scalar>
void ImplicitEulerIntegrator<Scalar>::make_preconditioner(const SphereModel<Scalar>& model,
                                                          ForceModel<Scalar>& forces) noexcept {
  const Index n = model.num_nodes();
  const bool blocks = m_options.preconditioner == Preconditioner::block_jacobi;
  // The diagonal blocks (symmetric: 6 scalars).
  if (blocks) forces.implicit_diagonal_blocks(model, m_blocks.data(), m_pblocks.data());
  if constexpr (std::is_same_v<Scalar, double>) {
    if (m_simd.precondition) {
      m_simd.precondition(std::int32_t(n), blocks ? m_pblocks.data() : nullptr, m_diag.data(),
                          m_pinv.data());
      return;
    }
  }
  if (!blocks) return;  // Jacobi: m_diag itself
  // Inverted in place; a block that is not positive definite (a compressed link's indefinite
  // part) falls back to its diagonal.
  for (Index i = 0; i < n; ++i) {
    Scalar* B = &m_pblocks[6 * std::size_t(i)];
    const Scalar a = B[0], b = B[1], c = B[2], d = B[3], e = B[4], f = B[5];
    const Scalar c00 = b * c - f * f, c01 = e * f - d * c, c02 = d * f - b * e;
    const Scalar det = a * c00 + d * c01 + e * c02;
    if (det > Scalar(0) && a > Scalar(0) && a * b - d * d > Scalar(0) && std::isfinite(det)) {
      const Scalar s = Scalar(1) / det;
      B[0] = c00 * s;
      B[1] = (a * c - e * e) * s;
      B[2] = (a * b - d * d) * s;
      B[3] = c01 * s;
      B[4] = c02 * s;
      B[5] = (d * e - a * f) * s;
    } else {
      B[0] = Scalar(1) / m_diag(i, 0);
      B[1] = Scalar(1) / m_diag(i, 1);
      B[2] = Scalar(1) / m_diag(i, 2);
      B[3] = B[4] = B[5] = Scalar(0);
    }
  }
}

template <typename Scalar>
Scalar ImplicitEulerIntegrator<Scalar>::precondition_dot() noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    if (m_simd.update)
      return m_simd.update(std::int32_t(m_r.rows()), 0.0, nullptr, nullptr, nullptr, m_r.data(),
                           m_pinv.data(), m_z.data());
  }
  precondition();
  return m_r.cwiseProduct(m_z).sum();
}

template <typename Scalar>
Scalar ImplicitEulerIntegrator<Scalar>::update(Scalar alpha) noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    if (m_simd.update)
      return m_simd.update(std::int32_t(m_r.rows()), alpha, m_p.data(), m_q.data(), m_dv.data(),
                           m_r.data(), m_pinv.data(), m_z.data());
  }
  m_dv += alpha * m_p;
  m_r -= alpha * m_q;
  return precondition_dot();
}

template <typename Scalar>
void ImplicitEulerIntegrator<Scalar>::new_direction(Scalar beta) noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    if (m_simd.direction) {
      m_simd.direction(std::int64_t(m_p.size()), beta, m_z.data(), m_p.data());
      return;
    }
  }
  m_p = m_z + beta * m_p;
}

template <typename Scalar>
Scalar ImplicitEulerIntegrator<Scalar>::dot(const Positions<Scalar>& a,
                                            const Positions<Scalar>& b) const noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    if (m_simd.dot) return m_simd.dot(std::int64_t(a.size()), a.data(), b.data());
  }
  return a.cwiseProduct(b).sum();
}

template <typename Scalar>
Scalar ImplicitEulerIntegrator<Scalar>::curvature() noexcept {
  return dot(m_p, m_q);
}

template <typename Scalar>
Scalar ImplicitEulerIntegrator<Scalar>::scale_warm_start() noexcept {
  // s = b^T w / w^T A w minimises |s w - dv*|_A, the error's energy norm, so the start is never
  // further from the solution in that norm than zero is (Galerkin: |s w - dv*|_A <= |dv*|_A),
  // and CG only lowers it from there (both for A and P positive definite, as the default
  // JacobianForm::definite makes them). Unscaled, a warm start that carried a velocity change the
  // new system no longer wants kept it wherever the stopping test cannot see it (docs/physics.md,
  // section 5).
  const Scalar wq = dot(m_dv, m_q), bw = dot(m_dv, m_rhs);
  Scalar s = wq > Scalar(0) && std::isfinite(wq) ? bw / wq : Scalar(0);
  if (!std::isfinite(s)) s = Scalar(0);  // a NaN b^T w, or an overflow
  if (s != Scalar(1)) m_dv *= s;
  return s;
}

template <typename Scalar>
IntegratorResult ImplicitEulerIntegrator<Scalar>::step(SphereModel<Scalar>& model,
                                                       ForceModel<Scalar>& forces,
                                                       Scalar dt) noexcept {
  if (!detail::prepared_for(model, m_dv) ||
      m_blocks.size() !=
          std::size_t(ForceModel<Scalar>::implicit_block_size) * std::size_t(model.num_links()))
    return {false, 0};
  if (m_options.solver == Solver::conjugate_gradient) return solve_cg(model, forces, dt);
  return solve_assembled(model, forces, dt);
}

template <typename Scalar>
IntegratorResult ImplicitEulerIntegrator<Scalar>::solve_cg(SphereModel<Scalar>& model,
                                                           ForceModel<Scalar>& forces,
                                                           Scalar dt) noexcept {
  const JacobianForm form =
      m_options.jacobian == JacobianForm::exact ? JacobianForm::symmetric : m_options.jacobian;
  const Index n = model.num_nodes();

  // Warm start: the previous step's velocity change, scaled to this step size, or extrapolated
  // from the two before (Options::extrapolate_warm_start). m_q is CG's scratch, free until the
  // solve.
  const bool extrapolate =
      m_options.extrapolate_warm_start && m_last_dt == dt && m_previous_dt == dt;
  if (m_last_dt > Scalar(0) && m_last_dt != dt) m_dv *= dt / m_last_dt;
  if (extrapolate) {  // dv = 2 dv - dv_previous, dv_previous = the old dv, in one pass
    Scalar* dv = m_dv.data();
    Scalar* previous = m_dv_previous.data();
    for (Index k = 0; k < 3 * n; ++k) {
      const Scalar d = dv[k];
      dv[k] = Scalar(2) * d - previous[k];
      previous[k] = d;
    }
  } else {
    m_dv_previous = m_dv;
  }
  m_previous_dt = m_last_dt > Scalar(0) ? dt : Scalar(0);
  for (const Index i : forces.immobile_nodes()) m_dv.row(i).setZero();
  if (!detail::all_finite(m_dv.data(), m_dv.size())) m_dv.setZero();
  // The velocity floor over the nodes that move (off at 0, a negative value or NaN).
  m_floor2 = m_plain_floor = Scalar(0);
  if (const Scalar vt = m_options.velocity_tolerance; vt > Scalar(0)) {
    const auto mass = model.masses();
    Scalar sum = mass.sum(), sum2 = mass.squaredNorm();
    for (const Index i : forces.immobile_nodes()) {
      sum -= mass[i];
      sum2 -= mass[i] * mass[i];
    }
    m_floor2 = vt * vt * std::max(sum, Scalar(0));
    m_plain_floor = vt * std::sqrt(std::max(sum2, Scalar(0)));
  }

  m_simd = {};
  if constexpr (std::is_same_v<Scalar, double>) {
    if (forces.options().simd && m_pinv.size() == std::size_t(detail::simd::precondition_size(n)))
      m_simd = {detail::simd::precondition_kernel(), detail::simd::cg_update_kernel(),
                detail::simd::cg_direction_kernel(), detail::simd::dot_kernel()};
    if (!(m_simd.precondition && m_simd.update && m_simd.direction && m_simd.dot)) m_simd = {};
  }

  // Contacts: solve with those penetrating at the start, then again (warm-started) with those
  // penetrating at the end while that set changes, at most max_contact_passes solves.
  int total = 0;
  bool converged = true;
  for (int pass = 0;; ++pass) {
    forces.prepare_implicit(model, dt, form, m_blocks.data(), m_rhs, m_diag, pass > 0);
    make_preconditioner(model, forces);
    const IntegratorResult r = solve_cg_pass(model, forces);
    total += r.iterations;
    converged = converged && r.converged;
    if (!r.ok) return {false, total, converged};
    if (forces.num_contacts() == 0 || pass + 1 >= m_options.max_contact_passes) break;
    m_x_end = model.positions() + dt * (model.velocities() + m_dv);
    if (!forces.update_contact_set(model, m_x_end.data(), dt)) break;
  }
  m_last_dt = dt;
  auto x = model.positions();
  auto v = model.velocities();
  v += m_dv;
  x += dt * v;
  return {true, total, converged};
}

template <typename Scalar>
IntegratorResult ImplicitEulerIntegrator<Scalar>::solve_cg_pass(
    const SphereModel<Scalar>& model, ForceModel<Scalar>& forces) noexcept {
  const Scalar bnorm = m_rhs.norm();
  if (!std::isfinite(bnorm)) {  // NaN or infinite forces: no solution to apply
    reset();
    return {false, 0};
  }
  // The stopping test weighs the residual by the preconditioner: |r|_P^-1 <= tol |b|_P^-1
  // (Options::tolerance), each node's error by its kinetic energy rather than its momentum; the
  // plain |r| let a light node's velocity be far off while stiff rows dominated |b|
  // (docs/physics.md). A preconditioner that is not positive definite (the symmetric Jacobian
  // form's compressed links can make a diagonal negative) falls back to the plain test wherever
  // r^T P^-1 r is not positive.
  const Scalar plain_target = std::max(m_options.tolerance * bnorm, m_plain_floor);
  m_r = m_rhs;
  const Scalar bz = precondition_dot();
  const bool weighted = bz > Scalar(0) && std::isfinite(bz);
  const Scalar target2 =
      weighted ? std::max(m_options.tolerance * m_options.tolerance * bz, m_floor2) : Scalar(0);
  forces.apply_implicit(model, m_blocks.data(), m_dv, m_q);
  m_r = m_rhs - scale_warm_start() * m_q;  // A (s w) = s A w
  Scalar rz = precondition_dot();
  // (Written so that a NaN residual goes into CG and fails there.)
  auto converged = [&](Scalar r_z) {
    return weighted && r_z > Scalar(0) ? r_z <= target2 : m_r.norm() <= plain_target;
  };
  int it = 0;
  bool ok = true, reached = true;
  if (!converged(rz) || !std::isfinite(rz)) {
    m_p = m_z;
    for (it = 1; it <= m_options.max_iterations; ++it) {
      forces.apply_implicit(model, m_blocks.data(), m_p, m_q);
      const Scalar pq = curvature();
      if (!(pq > Scalar(0)) || !std::isfinite(pq)) {  // not positive definite, or NaN
        ok = false;
        break;
      }
      const Scalar alpha = rz / pq;
      const Scalar rz_new = update(alpha);
      if (converged(rz_new)) break;
      new_direction(rz_new / rz);
      rz = rz_new;
    }
    reached = it <= m_options.max_iterations;  // else the loop ran out at its cap
    it = std::min(it, m_options.max_iterations);
  }
  if (!ok || !detail::all_finite(m_dv.data(), m_dv.size())) {
    reset();
    return {false, it, reached};
  }
  return {true, it, reached};
}

template <typename Scalar>
IntegratorResult ImplicitEulerIntegrator<Scalar>::solve_assembled(SphereModel<Scalar>& model,
                                                                  ForceModel<Scalar>& forces,
                                                                  Scalar dt) noexcept {
  // Reference path: assembles and factorises, so it allocates; any exception (bad_alloc) is a
  // failed step, never an escaping throw.
  try {
    using Sparse = Eigen::SparseMatrix<Scalar>;
    using Vec = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
    const Index n = model.num_nodes();
    const bool lu = m_options.solver == Solver::eigen_lu;
    const JacobianForm form = lu                                          ? JacobianForm::exact
                              : m_options.jacobian == JacobianForm::exact ? JacobianForm::symmetric
                                                                          : m_options.jacobian;
    const Sparse K = forces.stiffness_matrix(model, form);
    const Sparse D = forces.damping_matrix(model);
    forces.evaluate(model, model.positions(), model.velocities(), m_q);
    const auto& fixed = forces.immobile();  // fixed or asleep
    const auto mass = model.masses();

    Sparse A = -dt * D - (dt * dt) * K;
    A.prune([&](Index r, Index c, const Scalar&) {
      return !fixed[std::size_t(r / 3)] && !fixed[std::size_t(c / 3)];
    });
    std::vector<Eigen::Triplet<Scalar>> diag;
    diag.reserve(3 * std::size_t(n));
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c)
        diag.emplace_back(3 * i + c, 3 * i + c, fixed[std::size_t(i)] ? 1 : mass[i]);
    Sparse Mm(3 * n, 3 * n);
    Mm.setFromTriplets(diag.begin(), diag.end());
    A += Mm;
    A.makeCompressed();

    const Eigen::Map<const Vec> vflat(model.velocities().data(), 3 * n);
    const Eigen::Map<const Vec> fflat(m_q.data(), 3 * n);
    Vec b = dt * fflat + (dt * dt) * (K * vflat);
    forces.add_contact_linearisation(model, dt, b.data());
    for (Index i = 0; i < n; ++i)
      if (fixed[std::size_t(i)]) b.template segment<3>(3 * i).setZero();

    Vec dv;
    if (lu) {
      Eigen::SparseLU<Sparse> solver;
      solver.compute(A);
      if (solver.info() != Eigen::Success) return {false, 0};
      dv = solver.solve(b);
    } else {
      Eigen::SimplicialLDLT<Sparse> solver;
      solver.compute(A);
      if (solver.info() != Eigen::Success) return {false, 0};
      dv = solver.solve(b);
    }
    if (!detail::all_finite(dv.data(), dv.size())) return {false, 0};
    auto x = model.positions();
    auto v = model.velocities();
    Eigen::Map<Vec>(v.data(), 3 * n) += dv;
    x += dt * v;
    return {true, 1};
  } catch (...) {
    return {false, 0};
  }
}

}  // namespace fsm
