// WorkerPool (detail/worker_pool.hpp): every thread of the pool runs its share of every job,
// including after its helpers went to sleep; the parallel link scatter on it gives the forces and
// the implicit step of one thread. Under ThreadSanitizer in CI (tools/dev.sh sanitize).

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <random>
#include <thread>
#include <vector>

#include "common.hpp"
#include "fsm/detail/parallel.hpp"
#include "fsm/detail/worker_pool.hpp"
#include "fsm/implicit_euler_integrator.hpp"

namespace fsm::test {
namespace {

using detail::WorkerPool;

TEST(WorkerPool, EveryThreadRunsItsShareOfEveryJob) {
  for (int threads : {1, 2, 3, 4}) {
    WorkerPool pool(threads);
    ASSERT_EQ(pool.size(), threads);
    std::vector<long> hits(std::size_t(threads), 0);
    long total = 0;
    for (int job = 0; job < 200; ++job) {
      auto fn = [&](int t, int n) {
        ASSERT_EQ(n, threads);
        hits[std::size_t(t)] += job;  // each thread writes its own slot only
      };
      pool.run(fn);
      total += job;
    }
    for (int t = 0; t < threads; ++t) EXPECT_EQ(hits[std::size_t(t)], total) << t;
  }
}

// Helpers sleep after the spin time; a job then wakes them, and the pool can be destroyed while
// they sleep (no hang).
TEST(WorkerPool, WakesSleepingHelpersAndStopsWhileTheySleep) {
  WorkerPool pool(3, std::chrono::microseconds(100));
  std::atomic<int> ran{0};
  auto fn = [&](int, int) { ran.fetch_add(1); };
  for (int round = 0; round < 5; ++round) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // far past the spin: asleep
    pool.run(fn);
    EXPECT_EQ(ran.load(), 3 * (round + 1));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
}

// Many jobs with helpers that sleep between every two of them (no spin): a lost wake-up would
// hang run(), so the jobs run on another thread and the test fails if they do not finish.
TEST(WorkerPool, NoWakeUpIsLostWhenHelpersSleepBetweenJobs) {
  auto jobs = std::async(std::launch::async, [] {
    WorkerPool pool(3, std::chrono::microseconds(0));
    std::atomic<long> ran{0};
    auto fn = [&](int, int) { ran.fetch_add(1, std::memory_order_relaxed); };
    for (int job = 0; job < 20000; ++job) pool.run(fn);
    return ran.load();
  });
  if (jobs.wait_for(std::chrono::seconds(120)) != std::future_status::ready) {
    ADD_FAILURE() << "a job never finished: a helper missed its wake-up";
    std::fflush(nullptr);
    std::_Exit(1);  // the pool's threads are stuck; nothing can be joined
  }
  EXPECT_EQ(jobs.get(), 3L * 20000);
}

// A pool copied with what holds it is a pool of its own, of the same size.
TEST(WorkerPool, HandleCopiesMakeTheirOwnPool) {
  detail::PoolHandle a(2);
  const detail::PoolHandle b = a;
  EXPECT_EQ(b.threads(), 2);
  EXPECT_NE(a.get(), b.get());
  detail::PoolHandle c;
  EXPECT_EQ(c.threads(), 1);
  EXPECT_EQ(c.get(), nullptr);
}

// The implicit step's system on two threads: the right-hand side, diag(A) and the per-node 3 x 3
// blocks of the block-Jacobi preconditioner (each thread sums its links' blocks, then its share of
// the nodes) are one thread's, to rounding. Drag, random velocities, jittered links, some nodes
// fixed (their links are out of the force ranges).
TEST(WorkerPool, TwoThreadsPrepareTheImplicitSystemOfOne) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  std::mt19937 rng(11);
  SphereModel<double> model = random_model<double>(rng, {6, 5, 4}, 0.3, true);
  fix_below(model, 1);
  const Index n = model.num_nodes();
  struct System {
    Positions<double> rhs, diagonal;
    std::vector<double> blocks;
  };
  auto prepare = [&](int threads) {
    ForceModel<double>::Options o;
    o.threads = threads;
    o.drag = 5;
    ForceModel<double> forces(model, o);
    std::vector<double> link_blocks(
        std::size_t(ForceModel<double>::implicit_block_size * model.num_links()));
    System s{Positions<double>(n, 3), Positions<double>(n, 3),
             std::vector<double>(6 * std::size_t(n))};
    forces.prepare_implicit(model, 1e-3, JacobianForm::definite, link_blocks.data(), s.rhs,
                            s.diagonal);
    forces.implicit_diagonal_blocks(model, link_blocks.data(), s.blocks.data());
    return s;
  };
  const System one = prepare(1), two = prepare(2);
  EXPECT_GT(one.rhs.norm(), 0.0);
  EXPECT_TRUE(matrices_near(one.rhs, two.rhs, 1e-13));
  EXPECT_TRUE(matrices_near(one.diagonal, two.diagonal, 1e-13));
  const Eigen::Map<const Eigen::ArrayXd> b1(one.blocks.data(), Index(one.blocks.size()));
  const Eigen::Map<const Eigen::ArrayXd> b2(two.blocks.data(), Index(two.blocks.size()));
  EXPECT_GT(b1.abs().maxCoeff(), 0.0);
  EXPECT_LE((b1 - b2).abs().maxCoeff(), 1e-13 * b1.abs().maxCoeff());
  // Off-diagonal entries are there: the links' n n^T, not only the mass.
  EXPECT_GT(b1.reshaped(6, n).bottomRows(3).abs().maxCoeff(), 0.0);
}

// Twenty implicit steps of `m` on `threads` threads (CG far below the comparisons' tolerance:
// the threads sum in different orders, which must not move CG's last iteration); returns where
// the nodes end, after checking that every step advanced and the model moved.
Positions<double> twenty_steps(SphereModel<double> m, int threads, double quality = 0.3) {
  Simulation<double>::Options o;
  o.forces.threads = threads;
  o.forces.drag = 5;
  o.forces.element_tangent_quality = quality;
  Simulation<double> sim(std::move(m), o);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = 1e-12;
  io.max_iterations = 1000;
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  for (int s = 0; s < 20; ++s) EXPECT_TRUE(sim.step(1e-3).advanced());
  EXPECT_GT((sim.model().positions() - sim.model().rest_positions()).norm(), 1e-6);
  return Positions<double>(sim.model().positions());
}

// Two threads (the link loops of the right-hand side, the diagonal and every CG product
// scattered on the pool) end where one thread does, to rounding: random masses, velocities and
// jittered links, bottom fixed; the model sags under gravity.
TEST(WorkerPool, TwoThreadsStepLikeOne) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  auto model = [] {
    std::mt19937 rng(5);
    SphereModel<double> m = random_model<double>(rng, {5, 4, 6}, 0.3, true);
    fix_below(m, 2);
    return m;
  };
  EXPECT_TRUE(matrices_near(twenty_steps(model(), 1), twenty_steps(model(), 2), 1e-9));
}

// The continuum law on two threads: its edge springs, element tangents and both volumetric
// passes of every CG product on the pool (ForceModel::apply_implicit) step like one thread, to
// rounding. Jittered nodes and random velocities strain the elements; with an element-tangent
// quality of 1 every element takes the element tangent, so the dense share is split too.
TEST(WorkerPool, TwoThreadsStepTheContinuumLawLikeOne) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  auto model = [] {
    std::mt19937 rng(7);
    SphereModel<double> m = random_model<double>(rng, {4, 3, 5}, 0.3, true);
    m.set_region_law(0, ForceLaw::continuum);
    fix_below(m, 2, 0.003);
    return m;
  };
  for (const double quality : {0.3, 1.0})
    EXPECT_TRUE(
        matrices_near(twenty_steps(model(), 1, quality), twenty_steps(model(), 2, quality), 1e-9))
        << "element tangent quality " << quality;
}

}  // namespace
}  // namespace fsm::test
