// WorkerPool (detail/worker_pool.hpp): every thread of the pool runs its share of every job,
// including after its helpers went to sleep; the parallel link scatter on it gives the forces and
// the implicit step of one thread. Under ThreadSanitizer in CI (tools/dev.sh sanitize).

#include <algorithm>
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

// A share whose helper has not claimed it when the caller is done with its own runs on the caller
// (a descheduled or sleeping helper then costs no wait), and still exactly once. Helpers that
// sleep after every job (no spin) are usually slower to wake than the caller's empty share, but
// not always: where the scheduler runs a woken helper at once (a busy CI host ran 20 jobs with no
// share on the caller), so after 20 jobs they go on until one is seen, up to 2,000 (about half a
// second).
TEST(WorkerPool, TheCallerRunsSharesNoHelperHasClaimed) {
  WorkerPool pool(3, std::chrono::microseconds(0));
  const std::thread::id caller = std::this_thread::get_id();
  int on_caller = 0;
  for (int job = 0; job < 20 || (job < 2000 && on_caller == 0); ++job) {
    // The helpers fall asleep (the first jobs wait longer, as the test always did).
    std::this_thread::sleep_for(std::chrono::microseconds(job < 20 ? 2000 : 200));
    std::atomic<int> runs[3] = {0, 0, 0};
    std::atomic<int> stolen{0};
    auto fn = [&](int t, int) {
      runs[t].fetch_add(1);
      if (t > 0 && std::this_thread::get_id() == caller) stolen.fetch_add(1);
    };
    pool.run(fn);
    for (int t = 0; t < 3; ++t) EXPECT_EQ(runs[t].load(), 1) << "job " << job << " share " << t;
    on_caller += stolen.load();
  }
  EXPECT_GT(on_caller, 0);
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

// Checks a LinkPartition of links `ij` among T threads: the node bounds rise from 0 to n, the
// owned ranges and the bands between them cover the links once, in order, every owned link has
// both ends in its thread's nodes, and band_links counts the bands.
void expect_partition(const detail::LinkPartition& p, const std::vector<Index>& ij, Index n,
                      int T) {
  const auto L = Index(ij.size() / 2);
  ASSERT_EQ(p.threads(), T);
  ASSERT_EQ(p.nodes.size(), std::size_t(T) + 1);
  EXPECT_EQ(p.nodes.front(), 0);
  EXPECT_EQ(p.nodes.back(), n);
  EXPECT_EQ(p.owned.front().first, 0);
  EXPECT_EQ(p.owned.back().second, L);
  Index band = 0;
  for (int t = 0; t < T; ++t) {
    const auto k = std::size_t(t);
    EXPECT_LE(p.nodes[k], p.nodes[k + 1]);
    EXPECT_LE(p.owned[k].first, p.owned[k].second);
    if (t + 1 < T) {
      EXPECT_LE(p.owned[k].second, p.owned[k + 1].first);
      band += p.owned[k + 1].first - p.owned[k].second;
    }
    for (Index l = p.owned[k].first; l < p.owned[k].second; ++l)
      for (int e = 0; e < 2; ++e) {
        const Index v = ij[std::size_t(2 * l + e)];
        ASSERT_TRUE(v >= p.nodes[k] && v < p.nodes[k + 1])
            << "thread " << t << " link " << l << " node " << v;
      }
  }
  EXPECT_EQ(p.band_links, band);
}

// detail::partition_links: on any links (sorted by node as a lattice's, shuffled, or with empty
// stretches of nodes) and for 2-5 threads, a partition it accepts keeps each thread's links on
// its own nodes and covers every link once. Under the limit ForceModel uses (a longest path at
// most an eighth of the links above an even share), a lattice's sorted links are accepted on two
// threads with a band of one layer of nodes' links, and shuffled ones are refused (their
// partition would leave one thread every link).
TEST(WorkerPool, LinkPartitionKeepsEachThreadsLinksOnItsNodes) {
  std::mt19937 rng(3);
  for (const Eigen::Vector3i& cells :
       {Eigen::Vector3i(1, 1, 1), Eigen::Vector3i(6, 5, 4), Eigen::Vector3i(20, 18, 16)}) {
    const TetrahedralMesh<double> mesh =
        make_cube_lattice(Vector3<double>::Zero().eval(), cells, 0.01);
    SphereModel<double> model;
    add_tetrahedral_part(model, mesh, model.add_region("block", tissue<double>(3e3, 10.26)), 0.005);
    const Index n = model.num_nodes(), L = model.num_links();
    const std::vector<Index> sorted(model.links().data(), model.links().data() + 2 * L);
    std::vector<Index> shuffled = sorted;
    std::vector<Index> order(static_cast<std::size_t>(L));
    for (Index l = 0; l < L; ++l) order[std::size_t(l)] = l;
    std::shuffle(order.begin(), order.end(), rng);
    for (Index l = 0; l < L; ++l)
      for (int e = 0; e < 2; ++e)
        shuffled[std::size_t(2 * l + e)] = sorted[std::size_t(2 * order[std::size_t(l)] + e)];
    // The same links on nodes spread over 3 n, two of every three never touched.
    std::vector<Index> spread = sorted;
    for (Index& v : spread) v *= 3;
    for (int T = 2; T <= 5; ++T) {
      SCOPED_TRACE(testing::Message() << cells.transpose() << ", " << T << " threads");
      // Any band accepted: the partition is valid whatever the order.
      expect_partition(detail::partition_links(sorted.data(), L, n, T, L), sorted, n, T);
      expect_partition(detail::partition_links(shuffled.data(), L, n, T, L), shuffled, n, T);
      expect_partition(detail::partition_links(spread.data(), L, 3 * n, T, L), spread, 3 * n, T);
      if (cells[0] < 20) continue;
      EXPECT_EQ(detail::partition_links(shuffled.data(), L, n, T, L / 8).threads(), 0);
      const detail::LinkPartition p = detail::partition_links(sorted.data(), L, n, T, L / 8);
      if (T > 2 && p.threads() == 0) continue;  // (T - 1 bands: 6 % of the links each)
      expect_partition(p, sorted, n, T);
      // About one layer of nodes' links (21 x 19 of 6,783 nodes) per band.
      EXPECT_LE(p.band_links, (T - 1) * L * 21 * 19 / 6783 * 11 / 10);
      for (int t = 0; t < T; ++t)  // and each thread about its share
        EXPECT_GE(p.owned[std::size_t(t)].second - p.owned[std::size_t(t)].first, L / (2 * T));
    }
    EXPECT_EQ(detail::partition_links(sorted.data(), L, n, 1, L).threads(), 0);
  }
  // More threads than links: the spare threads own no link.
  for (const std::vector<Index>& ij : {std::vector<Index>{0, 1}, std::vector<Index>{0, 1, 3, 4}})
    for (int T = 2; T <= 5; ++T) {
      SCOPED_TRACE(testing::Message() << ij.size() / 2 << " links, " << T << " threads");
      const auto L = Index(ij.size() / 2);
      expect_partition(detail::partition_links(ij.data(), L, 5, T, L), ij, 5, T);
    }
}

// A jittered lattice block with random masses and velocities and the bilinear law, its bottom
// (z below 1e-9) fixed, from a fixed seed: the two-thread tests' model.
SphereModel<double> fixed_random_block(unsigned seed, Eigen::Vector3i cells) {
  std::mt19937 rng(seed);
  SphereModel<double> m = random_model<double>(rng, cells, 0.3, true);
  fix_below(m, 2);
  return m;
}

// The implicit step's system on two threads: the right-hand side, diag(A) and the per-node 3 x 3
// blocks of the block-Jacobi preconditioner (each thread sums its links' blocks, then its share of
// the nodes) are one thread's, to rounding. Drag, random velocities, jittered links, some nodes
// fixed (their links are out of the force ranges).
TEST(WorkerPool, TwoThreadsPrepareTheImplicitSystemOfOne) {
  // With one hardware thread ForceModel clamps threads to 1 and starts no pool: the comparison
  // would be one thread against itself and could not fail.
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  const SphereModel<double> model = fixed_random_block(11, {6, 5, 4});
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

// evaluate(), prepare_implicit() and apply_implicit() on two threads with the links partitioned
// (each thread adds its links straight into the outputs, then the band) and, on the same model
// with its nodes renumbered at random, with the per-thread buffers: both give one thread's forces,
// right-hand side, diagonal, per-node blocks and products A p to rounding, with the SIMD kernels
// (whose padded states each thread then makes for its own nodes) and the scalar loops, some nodes
// fixed (links with both ends fixed are out of the ranges), drag and external forces; on the link
// law and on the continuum law (its elements run after the links, on the states the threads
// padded; its product keeps the buffers).
TEST(WorkerPool, TwoThreadsEvaluateAndMultiplyLikeOneWithOrWithoutThePartition) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3i cells(14, 12, 13);
  TetrahedralMesh<double> mesh = make_cube_lattice(Vector3<double>::Zero().eval(), cells, 0.01);
  for (const bool renumbered : {false, true}) {
    SCOPED_TRACE(renumbered ? "nodes renumbered at random" : "lattice order");
    TetrahedralMesh<double> m = mesh;
    if (renumbered) {
      std::vector<Index> to(std::size_t(mesh.vertices.rows()));
      for (std::size_t i = 0; i < to.size(); ++i) to[i] = Index(i);
      std::shuffle(to.begin(), to.end(), rng);
      for (Index i = 0; i < mesh.vertices.rows(); ++i)
        m.vertices.row(to[std::size_t(i)]) = mesh.vertices.row(i);
      for (Index t = 0; t < mesh.tetrahedra.rows(); ++t)
        for (int c = 0; c < 4; ++c) m.tetrahedra(t, c) = to[std::size_t(mesh.tetrahedra(t, c))];
    }
    Material<double> mat = tissue<double>(3e3, 10.26);
    mat.large_strain_modulus = 2 * mat.youngs_modulus;
    mat.switch_strain = 0.05;
    SphereModel<double> model;
    add_tetrahedral_part(model, m, model.add_region("block", mat), 0.005);
    const Index n = model.num_nodes();
    for (Index i = 0; i < n; ++i) {
      if (model.positions()(i, 2) < 1e-9 && i % 3 != 0) model.set_fixed(i);
      for (int c = 0; c < 3; ++c) {
        model.positions()(i, c) += 0.001 * u(rng);
        model.velocities()(i, c) = 0.05 * u(rng);
      }
    }
    if (!renumbered) {  // the band between the threads' nodes is there to be run
      EXPECT_GT(detail::partition_links(model.links().data(), model.num_links(), n, 2,
                                        model.num_links() / 8)
                    .band_links,
                0);
    }
    for (const ForceLaw law : {ForceLaw::links, ForceLaw::continuum})
      for (const bool simd : {false, true}) {
        SCOPED_TRACE(simd ? "SIMD" : "scalar");
        SCOPED_TRACE(law == ForceLaw::links ? "link law" : "continuum law");
        model.set_region_law(0, law);
        Positions<double> f[2] = {Positions<double>(n, 3), Positions<double>(n, 3)};
        Positions<double> y[2] = {Positions<double>(n, 3), Positions<double>(n, 3)};
        Positions<double> rhs[2] = {Positions<double>(n, 3), Positions<double>(n, 3)};
        Positions<double> diagonal[2] = {Positions<double>(n, 3), Positions<double>(n, 3)};
        std::vector<double> node_blocks[2];
        Positions<double> p(n, 3);
        for (Index i = 0; i < n; ++i)
          for (int c = 0; c < 3; ++c) p(i, c) = u(rng);
        for (const int threads : {1, 2}) {
          ForceModel<double>::Options o;
          o.threads = threads;
          o.simd = simd;
          o.drag = 5;
          ForceModel<double> forces(model, o);
          forces.external_forces().row(n / 2) = Vector3<double>(0.1, -0.2, 0.3).transpose();
          if (threads == 2) {
            ASSERT_TRUE(forces.uses_pool());
            EXPECT_EQ(forces.links_partitioned(), !renumbered);
          }
          f[threads - 1].setConstant(std::nan(""));
          forces.evaluate(model, model.positions(), model.velocities(), f[threads - 1]);
          std::vector<double> blocks(
              std::size_t(ForceModel<double>::implicit_block_size * model.num_links()));
          const std::size_t k = std::size_t(threads - 1);
          rhs[k].setConstant(std::nan(""));
          diagonal[k].setConstant(std::nan(""));
          forces.prepare_implicit(model, 1e-3, JacobianForm::definite, blocks.data(), rhs[k],
                                  diagonal[k]);
          node_blocks[k].assign(6 * std::size_t(n), std::nan(""));
          forces.implicit_diagonal_blocks(model, blocks.data(), node_blocks[k].data());
          y[threads - 1].setConstant(std::nan(""));
          forces.apply_implicit(model, blocks.data(), p, y[threads - 1]);
        }
        ASSERT_TRUE(f[1].allFinite());
        EXPECT_GT(f[0].cwiseAbs().maxCoeff(), 0.0);
        EXPECT_LE((f[0] - f[1]).cwiseAbs().maxCoeff(), 1e-13 * f[0].cwiseAbs().maxCoeff());
        ASSERT_TRUE(rhs[1].allFinite() && diagonal[1].allFinite());
        EXPECT_LE((rhs[0] - rhs[1]).cwiseAbs().maxCoeff(), 1e-13 * rhs[0].cwiseAbs().maxCoeff());
        EXPECT_LE((diagonal[0] - diagonal[1]).cwiseAbs().maxCoeff(),
                  1e-13 * diagonal[0].cwiseAbs().maxCoeff());
        const Eigen::Map<const Eigen::ArrayXd> b1(node_blocks[0].data(), 6 * n);
        const Eigen::Map<const Eigen::ArrayXd> b2(node_blocks[1].data(), 6 * n);
        ASSERT_TRUE(b2.allFinite());
        EXPECT_LE((b1 - b2).abs().maxCoeff(), 1e-13 * b1.abs().maxCoeff());
        if (law == ForceLaw::links) {  // the links' n n^T (a continuum region's links carry none)
          EXPECT_GT(b1.reshaped(6, n).bottomRows(3).abs().maxCoeff(), 0.0);
        }
        ASSERT_TRUE(y[1].allFinite());
        EXPECT_LE((y[0] - y[1]).cwiseAbs().maxCoeff(), 1e-13 * y[0].cwiseAbs().maxCoeff());
        // The links' share of A p on the mobile nodes, beyond M (1 + h gamma) p: the comparison
        // sees them (fixed nodes' rows are zero).
        double links = 0;
        for (Index i = 0; i < n; ++i)
          if (!model.fixed()[i])
            links = std::max(
                links, (y[0].row(i) - 1.005 * model.masses()[i] * p.row(i)).cwiseAbs().maxCoeff());
        EXPECT_GT(links, 1e-3 * y[0].cwiseAbs().maxCoeff());
      }
  }
}

// Twenty implicit steps of `m` on `threads` threads (CG far below the comparisons' tolerance:
// the threads sum in different orders, which must not move CG's last iteration); returns where
// the nodes end, after checking that every step advanced and the model moved.
Positions<double> twenty_steps(SphereModel<double> m, int threads, double quality = 0.3,
                               int steps = 20, bool adaptive = false) {
  Simulation<double>::Options o;
  o.forces.threads = threads;
  o.forces.drag = 5;
  o.forces.element_tangent_quality = quality;
  o.adaptive_threads = adaptive;
  Simulation<double> sim(std::move(m), o);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = 1e-12;
  io.max_iterations = 1000;
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  for (int s = 0; s < steps; ++s) EXPECT_TRUE(sim.step(1e-3).advanced());
  EXPECT_GT((sim.model().positions() - sim.model().rest_positions()).norm(), 1e-6);
  return Positions<double>(sim.model().positions());
}

// Two threads (the link loops of the right-hand side, the diagonal and every CG product
// scattered on the pool) end where one thread does, to rounding: random masses, velocities and
// jittered links, bottom fixed; the model sags under gravity.
TEST(WorkerPool, TwoThreadsStepLikeOne) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  auto model = [] { return fixed_random_block(5, {5, 4, 6}); };
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

// Simulation::Options::adaptive_threads: 32 steps timed on the pool (after an untimed warm-up of
// at least 4 steps and 3 ms), as many without it, then the faster for 1,024 steps, then both
// again; whichever runs, the steps are one thread's, to rounding.
TEST(WorkerPool, AdaptiveThreadsTimeBothAndStepLikeOneThread) {
  // With one hardware thread ForceModel clamps threads to 1 and starts no pool: the comparison
  // would be one thread against itself and could not fail.
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  auto model = [] { return fixed_random_block(5, {4, 3, 4}); };
  Simulation<double>::Options o;
  o.forces.threads = 2;
  o.adaptive_threads = true;
  Simulation<double> sim(model(), o);
  std::vector<int> on;
  for (int s = 1; s <= 4000; ++s) {
    ASSERT_TRUE(sim.step(1e-3).advanced());
    on.push_back(sim.uses_pool() ? 1 : 0);
  }
  // The pool first, for at least 4 + 32 steps; then one thread, as long; then the pool again,
  // chosen or at the next trial (at most 1,024 steps later).
  const auto off = std::find(on.begin(), on.end(), 0);
  ASSERT_NE(off, on.end()) << "one thread was never timed";
  EXPECT_GE(off - on.begin(), 35);
  const auto back = std::find(off, on.end(), 1);
  ASSERT_NE(back, on.end()) << "the pool was never taken back";
  EXPECT_GE(back - off, 36);
  EXPECT_LE(back - off, 36 + 1024 + 400);  // (400: the warm-ups' 3 ms, generously)
  // Without the option the pool is never set aside.
  o.adaptive_threads = false;
  Simulation<double> fixed(model(), o);
  for (int s = 0; s < 40; ++s) ASSERT_TRUE(fixed.step(1e-3).advanced());
  EXPECT_TRUE(fixed.uses_pool());
  // Through both trials and into the choice (1,500 steps; the trials and their warm-ups take a
  // few hundred), the same end as one thread.
  EXPECT_TRUE(matrices_near(twenty_steps(model(), 1, 0.3, 1500),
                            twenty_steps(model(), 2, 0.3, 1500, true), 1e-9));
}

}  // namespace
}  // namespace fsm::test
