#pragma once

// Preconditioners of the implicit step's matrix A = M + h D + h^2 K, for the scale issue's
// choice of CG preconditioner (docs/benchmarks.md): PCG from zero to |r| <= tol |b| for a random
// b, counting iterations, with Jacobi, 3 x 3 block-Jacobi (A's own blocks: the integrator's
// default; on the continuum law a per-element stand-in for the volumetric part's before
// 2026-11-29, exact since), incomplete
// Cholesky (Eigen, IC with shift) and a sparse Cholesky factored at rest (no contacts) or at the
// state of A: Eigen's SimplicialLLT (AMD ordering) and, when the build found SuiteSparse,
// CHOLMOD's supernodal factor (FSM_BENCH_CHOLMOD). It times each factor and one application (two
// triangular solves) and the assembled product A p. Given groups of nodes (bench_model_step: the
// model's parts), it also counts the iterations with each group solved exactly and block-Jacobi
// elsewhere: which part the iterations come from. Used by bench_contact
// (BM_UterusPreconditioners) and bench_model_step --preconditioners.

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <chrono>
#include <memory>
#include <utility>
#include <vector>
#ifdef FSM_BENCH_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

#include "fsm/fsm.hpp"

namespace fsm::bench {

/// The implicit Euler step's matrix at the simulation's state (with its contacts, if the force
/// model holds any), fixed nodes' rows and columns replaced by the identity, as the integrator's
/// matrix-free product sees it.
inline Eigen::SparseMatrix<double> implicit_matrix(const Simulation<double>& sim, double h) {
  using Sparse = Eigen::SparseMatrix<double>;
  const auto& forces = sim.forces();
  const auto& model = sim.model();
  const Index n = model.num_nodes();
  const Sparse K = forces.stiffness_matrix(model, JacobianForm::definite);
  const Sparse D = forces.damping_matrix(model);
  const auto& fixed = forces.immobile();
  Sparse A = -h * D - (h * h) * K;
  A.prune([&](Index r, Index c, const double&) {
    return !fixed[std::size_t(r / 3)] && !fixed[std::size_t(c / 3)];
  });
  std::vector<Eigen::Triplet<double>> diag;
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      diag.emplace_back(
          3 * i + c, 3 * i + c,
          fixed[std::size_t(i)] ? 1.0 : model.masses()[i] * (1 + h * forces.options().drag));
  Sparse M(3 * n, 3 * n);
  M.setFromTriplets(diag.begin(), diag.end());
  A += M;
  A.makeCompressed();
  return A;
}

struct PreconditionerStudy {
  int it_jacobi{0}, it_block_jacobi{0}, it_incomplete_cholesky{0};
  int it_cholesky_rest{0}, it_cholesky_now{0}, it_cholmod_now{-1};  // -1: not built
  double dofs{0}, nnz_A{0}, nnz_L{0};
  double product_us{0};                       ///< one assembled product A p
  double factor_us{0}, cholesky_apply_us{0};  ///< SimplicialLLT at A's state
  double cholmod_factor_us{-1}, cholmod_apply_us{-1};
  double incomplete_cholesky_apply_us{0};
  /// Iterations with the factor (CHOLMOD's if built, else Eigen's) of the matrix `lag` steps
  /// before A's state: what an asynchronous refactor that lags by that much gives.
  std::vector<std::pair<int, int>> it_cholesky_lagged;
  /// Iterations with each group of nodes solved exactly (its diagonal block of A factored by
  /// SimplicialLLT) and block-Jacobi elsewhere, one count per grouping given.
  std::vector<int> it_groups;
};

/// PCG iterations from zero to |r| <= tol |b| (b random, seeded) for each preconditioner of A,
/// with `A_rest` the same matrix at rest for the factor at rest; times from `repeats` runs.
inline PreconditionerStudy study_preconditioners(
    const Eigen::SparseMatrix<double>& A_rest, const Eigen::SparseMatrix<double>& A, double tol,
    const std::vector<std::pair<int, Eigen::SparseMatrix<double>>>& lagged = {}, int repeats = 50,
    const std::vector<std::vector<std::vector<Index>>>& groupings = {}) {
  using Sparse = Eigen::SparseMatrix<double>;
  using Vec = Eigen::VectorXd;
  using Clock = std::chrono::steady_clock;
  auto us = [](Clock::time_point a, Clock::time_point b, int n) {
    return std::chrono::duration<double, std::micro>(b - a).count() / n;
  };
  PreconditionerStudy s;
  std::srand(7);
  const Vec b = Vec::Random(A.rows());
  auto pcg = [&](const auto& apply_inverse) {
    Vec x = Vec::Zero(A.rows()), r = b, z = apply_inverse(r), p = z, q;
    double rz = r.dot(z);
    int it = 1;
    for (; it < 2000; ++it) {
      q = A * p;
      const double alpha = rz / p.dot(q);
      x += alpha * p;
      r -= alpha * q;
      if (r.norm() <= tol * b.norm()) break;
      z = apply_inverse(r);
      const double rz_new = r.dot(z);
      p = z + (rz_new / rz) * p;
      rz = rz_new;
    }
    return it;
  };
  const Vec d = A.diagonal();
  s.it_jacobi = pcg([&](const Vec& r) -> Vec { return r.cwiseQuotient(d); });
  std::vector<Eigen::Matrix3d> blocks(std::size_t(A.rows() / 3));
  for (std::size_t i = 0; i < blocks.size(); ++i)
    blocks[i] = Eigen::Matrix3d(A.block(3 * Index(i), 3 * Index(i), 3, 3)).inverse();
  s.it_block_jacobi = pcg([&](const Vec& r) -> Vec {
    Vec z(r.size());
    for (std::size_t i = 0; i < blocks.size(); ++i)
      z.segment<3>(3 * Index(i)) = blocks[i] * r.segment<3>(3 * Index(i));
    return z;
  });
  const Eigen::IncompleteCholesky<double> ic(A);
  s.it_incomplete_cholesky = pcg([&](const Vec& r) -> Vec { return ic.solve(r); });
  const Eigen::SimplicialLLT<Sparse> rest(A_rest);
  s.it_cholesky_rest = pcg([&](const Vec& r) -> Vec { return rest.solve(r); });
  const auto t0 = Clock::now();
  const Eigen::SimplicialLLT<Sparse> now(A);
  const auto t1 = Clock::now();
  s.factor_us = us(t0, t1, 1);
  s.it_cholesky_now = pcg([&](const Vec& r) -> Vec { return now.solve(r); });
  Vec y;
  auto time_it = [&](const auto& f) {
    const auto a = Clock::now();
    for (int k = 0; k < repeats; ++k) {
      y = f();
      asm volatile("" : : "r"(y.data()) : "memory");
    }
    return us(a, Clock::now(), repeats);
  };
  s.cholesky_apply_us = time_it([&] { return Vec(now.solve(b)); });
  s.product_us = time_it([&] { return Vec(A * b); });
  s.incomplete_cholesky_apply_us = time_it([&] { return Vec(ic.solve(b)); });
#ifdef FSM_BENCH_CHOLMOD
  {
    Eigen::CholmodSupernodalLLT<Sparse> cm;
    const auto c0 = Clock::now();
    cm.compute(A);
    const auto c1 = Clock::now();
    s.cholmod_factor_us = us(c0, c1, 1);
    s.it_cholmod_now = pcg([&](const Vec& r) -> Vec { return cm.solve(r); });
    s.cholmod_apply_us = time_it([&] { return Vec(cm.solve(b)); });
  }
#endif
  for (const auto& [lag, A_lag] : lagged) {
#ifdef FSM_BENCH_CHOLMOD
    Eigen::CholmodSupernodalLLT<Sparse> f(A_lag);
#else
    const Eigen::SimplicialLLT<Sparse> f(A_lag);
#endif
    s.it_cholesky_lagged.emplace_back(lag, pcg([&](const Vec& r) -> Vec { return f.solve(r); }));
  }
  for (const auto& groups : groupings) {
    // Dofs of each group; a factor of A restricted to them; block-Jacobi for the others.
    std::vector<std::vector<Index>> dofs;
    std::vector<std::unique_ptr<Eigen::SimplicialLLT<Sparse>>> factors;
    std::vector<char> grouped(blocks.size(), 0);
    for (const auto& g : groups) {
      if (g.empty()) continue;
      std::vector<Index> gd;
      for (Index i : g) {
        grouped[std::size_t(i)] = 1;
        for (int c = 0; c < 3; ++c) gd.push_back(3 * i + c);
      }
      std::vector<Index> where(std::size_t(A.rows()), -1);
      for (std::size_t k = 0; k < gd.size(); ++k) where[std::size_t(gd[k])] = Index(k);
      std::vector<Eigen::Triplet<double>> t;
      for (Index col : gd)
        for (Sparse::InnerIterator it(A, col); it; ++it)
          if (where[std::size_t(it.row())] >= 0)
            t.emplace_back(where[std::size_t(it.row())], where[std::size_t(col)], it.value());
      Sparse S(Index(gd.size()), Index(gd.size()));
      S.setFromTriplets(t.begin(), t.end());
      factors.push_back(std::make_unique<Eigen::SimplicialLLT<Sparse>>(S));
      dofs.push_back(std::move(gd));
    }
    s.it_groups.push_back(pcg([&](const Vec& r) -> Vec {
      Vec z(r.size());
      for (std::size_t i = 0; i < blocks.size(); ++i)
        if (!grouped[i]) z.segment<3>(3 * Index(i)) = blocks[i] * r.segment<3>(3 * Index(i));
      for (std::size_t g = 0; g < dofs.size(); ++g) {
        Vec rg(Index(dofs[g].size()));
        for (std::size_t k = 0; k < dofs[g].size(); ++k) rg[Index(k)] = r[dofs[g][k]];
        const Vec zg = factors[g]->solve(rg);
        for (std::size_t k = 0; k < dofs[g].size(); ++k) z[dofs[g][k]] = zg[Index(k)];
      }
      return z;
    }));
  }
  s.dofs = double(A.rows());
  s.nnz_A = double(A.nonZeros());
  s.nnz_L = double(now.matrixL().nestedExpression().nonZeros());
  return s;
}

}  // namespace fsm::bench
