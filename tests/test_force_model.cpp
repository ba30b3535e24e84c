// ForceModel: Newton's third law on random models, zero internal torque, gravity and external
// loads, assembled Jacobians against finite differences, the matrix-free implicit operator against
// the assembled matrix, and threads giving the same forces.

#include <cstdlib>
#include <random>
#include <string>

#include "common.hpp"
#include "fsm/detail/continuum.hpp"
#include "fsm/detail/simd_links.hpp"
#include "fsm/detail/simd_solver.hpp"
#include "fsm/detail/simd_tets.hpp"

namespace fsm::test {
namespace {

template <typename S>
Vector3<S> torque(const Positions<S>& x, const Positions<S>& f) {
  Vector3<S> t = Vector3<S>::Zero();
  for (Index i = 0; i < x.rows(); ++i) t += x.row(i).transpose().cross(f.row(i).transpose());
  return t;
}

template <typename Scalar>
class ForceModelTyped : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(ForceModelTyped, Scalars);

// Internal forces sum to zero. Float sums of ~1e3 terms carry ~1e-6 relative rounding.
TYPED_TEST(ForceModelTyped, InternalForcesSumToZeroAndHaveNoTorque) {
  using S = TypeParam;
  const double tol = std::is_same_v<S, float> ? 2e-5 : 1e-12;
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    for (bool bilinear : {false, true}) {
      SphereModel<S> model = random_model<S>(rng, {3, 4, 3}, S(0.3), bilinear);
      // Large random displacements so bilinear links switch and geometry is far from rest.
      std::uniform_real_distribution<double> u(-1, 1);
      for (Index i = 0; i < model.num_nodes(); ++i)
        for (int c = 0; c < 3; ++c) model.positions()(i, c) += S(0.002 * u(rng));
      ForceModel<S> forces = no_gravity(model, DampingModel::along_link);
      Positions<S> f(model.num_nodes(), 3);
      forces.evaluate(model, model.positions(), model.velocities(), f);
      const double scale = double(f.cwiseAbs().sum());
      ASSERT_GT(scale, 0);
      EXPECT_LT(double(f.colwise().sum().norm()), tol * scale);
      const double lever = double(model.positions().cwiseAbs().maxCoeff());
      EXPECT_LT(double(torque(Positions<S>(model.positions()), f).norm()),
                tol * scale * lever);  // central
    }
  }
}

// The paper's full relative-velocity damping sums to zero too, but twists: at rest positions (no
// elastic force) a rigid spin meets a damping torque.
TEST(ForceModel, FullRelativeVelocityDampingResistsRigidSpin) {
  std::mt19937 rng(6);
  SphereModel<double> model = random_model<double>(rng, {3, 3, 3}, 0.2);
  model.reset_to_rest();
  for (Index i = 0; i < model.num_nodes(); ++i) {
    model.velocities()(i, 0) = -model.positions()(i, 1);
    model.velocities()(i, 1) = model.positions()(i, 0);
  }
  Positions<double> f(model.num_nodes(), 3);
  no_gravity(model, DampingModel::along_link)
      .evaluate(model, model.positions(), model.velocities(), f);
  EXPECT_LT(f.norm(), 1e-12);  // rigid motion: no force along the links
  no_gravity(model, DampingModel::full_relative_velocity)
      .evaluate(model, model.positions(), model.velocities(), f);
  EXPECT_LT(f.colwise().sum().norm(), 1e-12 * f.cwiseAbs().sum());
  EXPECT_LT(torque(Positions<double>(model.positions()), f).z(), -1e-3 * f.cwiseAbs().sum() * 0.03);
}

TEST(ForceModel, GravityAndExternalForcesAreAdded) {
  SphereModel<double> model = two_spheres(0.002, 100.0, 0.0);
  ForceModel<double> forces(model);  // default gravity (0, 0, -9.81)
  forces.external_forces()(1, 0) = 0.5;
  Positions<double> f(2, 3);
  forces.evaluate(model, model.positions(), model.velocities(), f);
  EXPECT_TRUE(near(f(0, 2), -9.81 * 0.002, 1e-14));
  EXPECT_TRUE(near(f(1, 0), 0.5, 1e-14));
  forces.clear_external_forces();
  forces.evaluate(model, model.positions(), model.velocities(), f);
  EXPECT_EQ(f(1, 0), 0.0);
  // Fixed nodes get inverse mass 0.
  model.set_fixed(0);
  forces.refresh(model);
  EXPECT_EQ(forces.inverse_masses()[0], 0.0);
  EXPECT_TRUE(near(forces.inverse_masses()[1], 500.0, 1e-14));
}

TEST(ForceModel, SimdInstructionSetFollowsTheCpuAndTheCap) {
  // The kernels compiled for AVX-512VL where the CPU has it, unless FSM_SIMD=avx2 caps them (ctest
  // runs the Simd tests twice: ForceModel.SimdKernelsOnAvx2 with the cap), so that both sets of
  // kernels meet the scalar loops on an AVX-512 machine.
  const std::string isa = detail::simd::instruction_set();
  // A CPU without AVX2 and FMA, or a build without xsimd: no kernel to choose (the scalar loops
  // run, and have their own tests).
  if (isa == "none") GTEST_SKIP() << "no SIMD kernel for this CPU or build";
  const char* cap = std::getenv("FSM_SIMD");
  const bool capped = cap != nullptr && std::string(cap) == "avx2";
  const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                      __builtin_cpu_supports("avx512dq");
  EXPECT_EQ(isa, avx512 && !capped ? "avx2+fma (avx512vl)" : "avx2+fma");
}

// The SIMD link kernels (Options::simd, where the CPU has them) give the scalar loops' forces and
// energy: on a jittered lattice stretched and compressed past the bilinear switch, with random
// velocities, for both damping models, linear and bilinear links, one and two threads, with fixed
// nodes (so the loops see several link ranges) and a link of zero length.
TEST(ForceModel, SimdLinkKernelMatchesTheScalarLoop) {
  // Without AVX2+FMA (or without xsimd at build time) Options::simd runs the scalar loops, so
  // there is nothing to compare; the scalar loops have their own tests.
  if (std::string(detail::simd::instruction_set()) == "none")
    GTEST_SKIP() << "no SIMD link kernel for this CPU or build";
  std::mt19937 rng(21);
  std::normal_distribution<double> g(0.0, 1.0);
  for (const bool bilinear : {false, true})
    for (const DampingModel dm : {DampingModel::along_link, DampingModel::full_relative_velocity})
      for (const int threads : {1, 2}) {
        SCOPED_TRACE(testing::Message() << "bilinear " << bilinear << " damping " << int(dm)
                                        << " threads " << threads);
        SphereModel<double> model = random_model<double>(rng, {5, 4, 3}, 0.25, bilinear);
        for (Index i = 0; i < model.num_nodes(); ++i) {
          if (i % 7 == 3) model.set_fixed(i);
          for (int c = 0; c < 3; ++c) {
            model.positions()(i, c) *= 1.0 + 0.08 * g(rng);  // strains past the 5 % switch
            model.velocities()(i, c) = 0.05 * g(rng);
          }
        }
        // Coincident spheres: a link of zero length carries no along-link force.
        model.positions().row(model.links()(0, 1)) = model.positions().row(model.links()(0, 0));
        ForceModel<double>::Options o;
        o.damping = dm;
        o.threads = std::min(threads, detail::max_threads());
        o.simd = false;
        ForceModel<double> scalar(model, o);
        o.simd = true;
        ForceModel<double> simd(model, o);
        Positions<double> a(model.num_nodes(), 3), b(model.num_nodes(), 3);
        scalar.evaluate(model, model.positions(), model.velocities(), a);
        simd.evaluate(model, model.positions(), model.velocities(), b);
        ASSERT_TRUE(b.allFinite());
        EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 1e-14 * a.cwiseAbs().maxCoeff());
        EXPECT_GT(a.cwiseAbs().maxCoeff(), 0.0);
        // The energy kernel (the energy check's links), past the switch too.
        const double ea = scalar.elastic_energy(model, model.positions());
        const double eb = simd.elastic_energy(model, model.positions());
        EXPECT_GT(ea, 0.0);
        EXPECT_LE(std::abs(ea - eb), 1e-13 * ea);
      }
}

// The implicit step's link blocks, right-hand sides and diagonals of two force models (scalar
// and SIMD loops) agree to rounding.
void expect_prepared_alike(const std::vector<double>& ba, const std::vector<double>& bb,
                           const Positions<double>& ra, const Positions<double>& rb,
                           const Positions<double>& da, const Positions<double>& db) {
  double worst = 0, scale = 0;
  for (std::size_t k = 0; k < ba.size(); ++k) {
    worst = std::max(worst, std::abs(ba[k] - bb[k]));
    scale = std::max(scale, std::abs(ba[k]));
  }
  EXPECT_LE(worst, 1e-13 * scale);
  EXPECT_LE((ra - rb).cwiseAbs().maxCoeff(), 1e-13 * ra.cwiseAbs().maxCoeff());
  EXPECT_LE((da - db).cwiseAbs().maxCoeff(), 1e-13 * da.cwiseAbs().maxCoeff());
}

// A model large enough (18,252 nodes) that the SIMD kernels' padded copies of the states are
// made on the pool's two threads, each its share of the nodes: the forces, then (at another
// state, so that a stale copy would show) the implicit step's blocks, right-hand side and
// diagonal, and the product A p give the scalar loops' results.
TEST(ForceModel, SimdKernelsOnALargeModelPadTheStatesOnThePool) {
  // Skipped where there is nothing to compare: without a SIMD kernel both models run the scalar
  // loops, and on one CPU no pool exists (ForceModel caps its threads at the CPUs it may use).
  if (std::string(detail::simd::instruction_set()) == "none")
    GTEST_SKIP() << "no SIMD link kernel for this CPU or build";
  if (detail::max_threads() < 2) GTEST_SKIP() << "one CPU: no pool";
  std::mt19937 rng(8);
  std::normal_distribution<double> g(0.0, 1.0);
  SphereModel<double> model = random_model<double>(rng, {26, 25, 25}, 0.25, true);
  ASSERT_GE(model.num_nodes(), 16384);
  const Index n = model.num_nodes();
  auto perturb = [&] {
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        model.positions()(i, c) *= 1.0 + 0.02 * g(rng);
        model.velocities()(i, c) = 0.05 * g(rng);
      }
  };
  perturb();
  ForceModel<double>::Options o;
  o.threads = 2;
  o.simd = false;
  ForceModel<double> scalar(model, o);
  o.simd = true;
  ForceModel<double> simd(model, o);
  ASSERT_TRUE(simd.uses_pool());
  Positions<double> a(n, 3), b(n, 3);
  scalar.evaluate(model, model.positions(), model.velocities(), a);
  simd.evaluate(model, model.positions(), model.velocities(), b);
  EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 1e-13 * a.cwiseAbs().maxCoeff());
  perturb();
  const std::size_t nb =
      std::size_t(ForceModel<double>::implicit_block_size) * std::size_t(model.num_links());
  std::vector<double> ba(nb, 7.0), bb(nb, -7.0);
  Positions<double> ra(n, 3), rb(n, 3), da(n, 3), db(n, 3), p(n, 3), ya(n, 3), yb(n, 3);
  scalar.prepare_implicit(model, 1e-3, JacobianForm::symmetric, ba.data(), ra, da);
  simd.prepare_implicit(model, 1e-3, JacobianForm::symmetric, bb.data(), rb, db);
  expect_prepared_alike(ba, bb, ra, rb, da, db);
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) p(i, c) = g(rng);
  scalar.apply_implicit(model, ba.data(), p, ya);
  simd.apply_implicit(model, ba.data(), p, yb);
  EXPECT_LE((ya - yb).cwiseAbs().maxCoeff(), 1e-13 * ya.cwiseAbs().maxCoeff());
}

// The implicit solve's link loops on the SIMD kernels (the prepared blocks, right-hand side and
// Jacobi diagonal, and the product A p) give the scalar loops' results: three parts, the middle
// one on the continuum law (so the force links come in two ranges and the middle links get zero
// blocks), strained past the bilinear switch, both damping models and both Jacobian forms, one and
// two threads. The continuum part's edge springs go through the same apply kernel.
TEST(ForceModel, SimdImplicitLinkKernelsMatchTheScalarLoops) {
  // Without AVX2+FMA (or without xsimd at build time) Options::simd runs the scalar loops, so
  // there is nothing to compare; the scalar loops have their own tests.
  if (std::string(detail::simd::instruction_set()) == "none")
    GTEST_SKIP() << "no SIMD link kernel for this CPU or build";
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  for (const bool bilinear : {false, true})
    for (const DampingModel dm : {DampingModel::along_link, DampingModel::full_relative_velocity})
      for (const JacobianForm form : {JacobianForm::symmetric, JacobianForm::definite})
        for (const int threads : {1, 2}) {
          SCOPED_TRACE(testing::Message() << "bilinear " << bilinear << " damping " << int(dm)
                                          << " form " << int(form) << " threads " << threads);
          SphereModel<double> model;
          Material<double> mat = tissue<double>();
          if (bilinear) {
            mat.large_strain_modulus = 5 * mat.youngs_modulus;
            mat.switch_strain = 0.05;
          }
          for (int part = 0; part < 3; ++part) {
            const Index r = model.add_region("part" + std::to_string(part), mat);
            add_tetrahedral_part(model,
                                 make_cube_lattice(Vector3<double>(0.05 * part, 0, 0),
                                                   Eigen::Vector3i(3, 2, 2), 0.005),
                                 r, 0.0025);
          }
          model.set_region_law(1, ForceLaw::continuum);
          for (Index i = 0; i < model.num_nodes(); ++i) {
            if (i % 11 == 4) model.set_fixed(i);
            for (int c = 0; c < 3; ++c) {
              model.positions()(i, c) += 0.0004 * g(rng);
              model.velocities()(i, c) = 0.05 * g(rng);
            }
          }
          ForceModel<double>::Options o;
          o.damping = dm;
          o.drag = 2.0;
          o.threads = std::min(threads, detail::max_threads());
          o.simd = false;
          ForceModel<double> scalar(model, o);
          o.simd = true;
          ForceModel<double> simd(model, o);
          const Index n = model.num_nodes();
          const double h = 1e-3;
          const std::size_t nb =
              std::size_t(ForceModel<double>::implicit_block_size) * std::size_t(model.num_links());
          std::vector<double> ba(nb, 7.0), bb(nb, -7.0);  // every block must be written
          Positions<double> ra(n, 3), rb(n, 3), da(n, 3), db(n, 3), p(n, 3), ya(n, 3), yb(n, 3);
          scalar.prepare_implicit(model, h, form, ba.data(), ra, da);
          simd.prepare_implicit(model, h, form, bb.data(), rb, db);
          expect_prepared_alike(ba, bb, ra, rb, da, db);
          // The per-node 3 x 3 blocks of the block-Jacobi preconditioner.
          Eigen::ArrayXd pa(6 * n), pb(6 * n);
          scalar.implicit_diagonal_blocks(model, ba.data(), pa.data());
          simd.implicit_diagonal_blocks(model, bb.data(), pb.data());
          EXPECT_LE((pa - pb).abs().maxCoeff(), 1e-13 * pa.abs().maxCoeff());
          for (Index i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) p(i, c) = g(rng);
          scalar.apply_implicit(model, ba.data(), p, ya);
          simd.apply_implicit(model, ba.data(), p,
                              yb);  // the same blocks: only the product differs
          EXPECT_LE((ya - yb).cwiseAbs().maxCoeff(), 1e-13 * ya.cwiseAbs().maxCoeff());
        }
}

// The node-block kernel (the block-Jacobi preconditioner's link part) against the formula it
// replaces, to the last bit: per link a n n^T + b I added to both ends, the first node's summed
// over its run of links. Random blocks and runs of 1-5 links per first node, sub-ranges that cut
// runs, and guard values after the output that the kernel must not touch.
TEST(ForceModel, SimdLinkNodeBlocksMatchTheScalarLoop) {
  const auto kernel = detail::simd::link_node_blocks_kernel();
  // Without AVX2+FMA (or without xsimd at build time) there is no kernel and ForceModel runs its
  // scalar loop, which SimdImplicitLinkKernelsMatchTheScalarLoops compares with through the
  // preconditioner's blocks.
  if (!kernel) GTEST_SKIP() << "no SIMD link kernel for this CPU or build";
  std::mt19937 rng(8);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::int32_t n = 23;
  std::vector<std::int32_t> ij;
  for (std::int32_t i = 0; i < n && ij.size() < 2 * 40; ++i)
    for (std::int32_t k = 0, runs = 1 + std::int32_t(rng() % 5); k < runs; ++k) {
      ij.push_back(i);
      ij.push_back((i + 1 + std::int32_t(rng() % (n - 1))) % n);  // any other node
    }
  const auto links = std::int32_t(ij.size() / 2);
  std::vector<double> blocks(5 * std::size_t(links));
  for (std::size_t l = 0; l < std::size_t(links); ++l) {
    Eigen::Vector3d nv(g(rng), g(rng), g(rng));
    nv.normalize();
    const double v[5] = {nv[0], nv[1], nv[2], 1e3 * g(rng), std::abs(1e2 * g(rng))};
    std::copy(v, v + 5, blocks.begin() + std::ptrdiff_t(5 * l));
  }
  auto reference = [&](std::int32_t begin, std::int32_t end, double* out) {
    for (std::int32_t l = begin; l < end;) {
      const std::int32_t i = ij[std::size_t(2 * l)];
      double acc[6] = {0, 0, 0, 0, 0, 0};
      for (; l < end && ij[std::size_t(2 * l)] == i; ++l) {
        const double* B = blocks.data() + 5 * std::ptrdiff_t(l);
        const double al = B[3], be = B[4];
        const double d[6] = {al * B[0] * B[0] + be, al * B[1] * B[1] + be, al * B[2] * B[2] + be,
                             al * B[0] * B[1],      al * B[0] * B[2],      al * B[1] * B[2]};
        double* o = out + 6 * std::ptrdiff_t(ij[std::size_t(2 * l + 1)]);
        for (int c = 0; c < 6; ++c) {
          o[c] += d[c];
          acc[c] += d[c];
        }
      }
      for (int c = 0; c < 6; ++c) out[6 * std::ptrdiff_t(i) + c] += acc[c];
    }
  };
  const std::pair<std::int32_t, std::int32_t> ranges[] = {
      {0, links}, {0, 1}, {3, 4}, {2, links - 1}, {links / 2, links}, {5, 5}};
  for (const auto& [begin, end] : ranges) {
    SCOPED_TRACE(testing::Message() << "links [" << begin << ", " << end << ")");
    std::vector<double> a(6 * std::size_t(n) + 8), b;
    for (double& x : a) x = g(rng);
    b = a;
    reference(begin, end, a.data());
    kernel(ij.data(), blocks.data(), b.data(), begin, end);
    for (std::size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a[k], b[k]) << "entry " << k;
  }
}

// The CG kernels (detail/simd_solver.hpp) against the scalar formulas they replace: the
// preconditioner from 3 x 3 blocks that are positive definite, indefinite, singular or not finite
// (those fall back to the diagonal) and from the diagonal alone; the update, z = P r, r^T z, the
// direction and the dot product; for 1 to 13 nodes and 67 (every remainder after the batches of
// four), with guard values after each array that no kernel may touch.
TEST(ForceModel, SimdSolverKernelsMatchTheScalarLoops) {
  namespace simd = detail::simd;
  // Without AVX2+FMA (or without xsimd at build time) there are no CG kernels to compare, and the
  // integrator runs its Eigen path, which the other integrator tests cover.
  if (simd::cg_update_kernel() == nullptr)
    GTEST_SKIP() << "no SIMD CG kernel for this CPU or build";
  std::mt19937 rng(9);
  std::normal_distribution<double> g(0.0, 1.0);
  constexpr double guard = 12345.0;
  std::vector<int> sizes{67};
  for (int n = 1; n <= 13; ++n) sizes.push_back(n);
  for (const int n : sizes)
    for (const bool blocks : {true, false}) {
      SCOPED_TRACE(testing::Message() << "n " << n << " blocks " << blocks);
      const auto n3 = std::size_t(3 * n);
      auto random = [&](std::size_t count) {
        std::vector<double> v(count + 4, guard);
        for (std::size_t k = 0; k < count; ++k) v[k] = g(rng);
        return v;
      };
      std::vector<double> B(6 * std::size_t(n)), diag = random(n3);
      for (std::size_t k = 0; k < n3; ++k) diag[k] = 1.0 + std::abs(diag[k]);
      for (int i = 0; i < n; ++i) {
        // A A^T + c I: definite for c > 0, indefinite for c well below 0; some singular (zero),
        // some with an infinite entry (a determinant that is not finite).
        Eigen::Matrix3d A = Eigen::Matrix3d::NullaryExpr([&] { return g(rng); });
        Eigen::Matrix3d K =
            A * A.transpose() + (i % 5 == 2 ? -4.0 : 0.5) * Eigen::Matrix3d::Identity();
        if (i % 7 == 3) K.setZero();
        if (i % 11 == 6) K(0, 0) = std::numeric_limits<double>::infinity();
        const double e[6] = {K(0, 0), K(1, 1), K(2, 2), K(0, 1), K(0, 2), K(1, 2)};
        std::copy(e, e + 6, B.begin() + 6 * i);
      }
      // The reference: each node's inverse block (xx yy zz xy xz yz), as the integrator's scalar
      // loop computes it for block-Jacobi (its Jacobi path divides by the diagonal where the kernel
      // multiplies by its inverse: within an ulp, which the iteration-count test below covers).
      std::vector<double> ref(6 * std::size_t(n));
      for (int i = 0; i < n; ++i) {
        double* o = &ref[6 * std::size_t(i)];
        const double* d = &diag[3 * std::size_t(i)];
        o[0] = 1 / d[0], o[1] = 1 / d[1], o[2] = 1 / d[2], o[3] = o[4] = o[5] = 0;
        if (!blocks) continue;
        const double* k = &B[6 * std::size_t(i)];
        const double a = k[0], b = k[1], c = k[2], x = k[3], y = k[4], f = k[5];
        const double c00 = b * c - f * f, c01 = y * f - x * c, c02 = x * f - b * y;
        const double det = a * c00 + x * c01 + y * c02;
        if (det > 0 && a > 0 && a * b - x * x > 0 && std::isfinite(det)) {
          o[0] = c00 / det, o[1] = (a * c - y * y) / det, o[2] = (a * b - x * x) / det;
          o[3] = c01 / det, o[4] = c02 / det, o[5] = (x * y - a * f) / det;
        }
      }
      const auto size = std::size_t(simd::precondition_size(n));
      std::vector<double> inv(size + 4, guard);
      simd::precondition_kernel()(n, blocks ? B.data() : nullptr, diag.data(), inv.data());
      for (int i = 0; i < n; ++i)
        for (int c = 0; c < 6; ++c) {
          const double got = inv[6 * std::size_t(i & ~3) + 4 * std::size_t(c) + std::size_t(i & 3)];
          const double want = ref[6 * std::size_t(i) + std::size_t(c)];
          EXPECT_LE(std::abs(got - want), 1e-12 * (std::abs(want) + 1e-300)) << i << " " << c;
        }
      EXPECT_EQ(inv[size], guard);
      // The update with alpha, and without p (z = P r only).
      const double alpha = 0.37;
      std::vector<double> p = random(n3), q = random(n3), dv = random(n3), r = random(n3),
                          z = random(n3);
      std::vector<double> dv_ref = dv, r_ref = r, z_ref(n3);
      double rz_ref = 0;
      for (std::size_t k = 0; k < n3; ++k) {
        dv_ref[k] += alpha * p[k];
        r_ref[k] -= alpha * q[k];
      }
      for (int i = 0; i < n; ++i) {
        const double* o = &ref[6 * std::size_t(i)];
        const double* ri = &r_ref[3 * std::size_t(i)];
        double* zi = &z_ref[3 * std::size_t(i)];
        zi[0] = o[0] * ri[0] + o[3] * ri[1] + o[4] * ri[2];
        zi[1] = o[3] * ri[0] + o[1] * ri[1] + o[5] * ri[2];
        zi[2] = o[4] * ri[0] + o[5] * ri[1] + o[2] * ri[2];
        rz_ref += ri[0] * zi[0] + ri[1] * zi[1] + ri[2] * zi[2];
      }
      double scale = 0;
      for (std::size_t k = 0; k < n3; ++k) scale += std::abs(r_ref[k] * z_ref[k]);
      const double rz = simd::cg_update_kernel()(n, alpha, p.data(), q.data(), dv.data(), r.data(),
                                                 inv.data(), z.data());
      EXPECT_LE(std::abs(rz - rz_ref), 1e-13 * scale);
      for (std::size_t k = 0; k < n3; ++k) {
        EXPECT_EQ(dv[k], dv_ref[k]) << k;
        EXPECT_EQ(r[k], r_ref[k]) << k;
        EXPECT_LE(std::abs(z[k] - z_ref[k]), 1e-12 * (std::abs(z_ref[k]) + 1e-300)) << k;
      }
      for (auto* v : {&dv, &r, &z}) EXPECT_EQ((*v)[n3], guard);
      std::fill(z.begin(), z.begin() + std::ptrdiff_t(n3), 0.0);
      const std::vector<double> r_before = r;
      EXPECT_LE(std::abs(simd::cg_update_kernel()(n, 0.0, nullptr, nullptr, nullptr, r.data(),
                                                  inv.data(), z.data()) -
                         rz_ref),
                1e-13 * scale);
      EXPECT_EQ(r, r_before);
      for (std::size_t k = 0; k < n3; ++k)
        EXPECT_LE(std::abs(z[k] - z_ref[k]), 1e-12 * (std::abs(z_ref[k]) + 1e-300)) << k;
      EXPECT_EQ(z[n3], guard);
      // The direction and the dot product.
      const double beta = -1.3;
      std::vector<double> p_ref = p;
      double pq_ref = 0, pq_scale = 0;
      for (std::size_t k = 0; k < n3; ++k) {
        p_ref[k] = z[k] + beta * p[k];
        pq_ref += p_ref[k] * q[k];
        pq_scale += std::abs(p_ref[k] * q[k]);
      }
      simd::cg_direction_kernel()(std::int64_t(n3), beta, z.data(), p.data());
      EXPECT_EQ(p, p_ref);
      EXPECT_LE(std::abs(simd::dot_kernel()(std::int64_t(n3), p.data(), q.data()) - pq_ref),
                1e-13 * pq_scale);
    }
}

// The implicit solve on the CG kernels gives the scalar path's velocities and iteration counts
// (both preconditioners), over steps of a strained random model with fixed nodes.
TEST(ForceModel, SimdConjugateGradientMatchesTheScalarSolve) {
  // Without AVX2+FMA (or without xsimd at build time) both runs would take the Eigen path: there
  // is nothing to compare, and the integrator tests cover that path.
  if (detail::simd::cg_update_kernel() == nullptr)
    GTEST_SKIP() << "no SIMD CG kernel for this CPU or build";
  using IE = ImplicitEulerIntegrator<double>;
  std::mt19937 rng(31);
  std::normal_distribution<double> g(0.0, 1.0);
  SphereModel<double> start = random_model<double>(rng, {5, 4, 3}, 0.25, true);
  for (Index i = 0; i < start.num_nodes(); ++i) {
    if (i % 9 == 2) start.set_fixed(i);
    for (int c = 0; c < 3; ++c) start.positions()(i, c) *= 1.0 + 0.05 * g(rng);
  }
  for (const IE::Preconditioner pc :
       {IE::Preconditioner::block_jacobi, IE::Preconditioner::jacobi}) {
    SCOPED_TRACE(testing::Message() << "preconditioner " << int(pc));
    auto run = [&](bool use_simd, std::vector<int>& iterations) {
      SphereModel<double> model = start;
      ForceModel<double>::Options fo;
      fo.simd = use_simd;
      ForceModel<double> forces(model, fo);
      IE::Options o;
      o.preconditioner = pc;
      o.tolerance = 1e-8;
      IE ie(o);
      ie.prepare(model);
      for (int s = 0; s < 5; ++s) {
        const IntegratorResult res = ie.step(model, forces, 1e-3);
        EXPECT_TRUE(res.ok);
        EXPECT_EQ(ie.used_simd_kernels(), use_simd);  // the path under test did run
        iterations.push_back(res.iterations);
      }
      return Positions<double>(model.velocities());
    };
    std::vector<int> it_scalar, it_simd;
    const Positions<double> a = run(false, it_scalar), b = run(true, it_simd);
    EXPECT_GT(it_scalar.front(), 3);
    EXPECT_EQ(it_scalar, it_simd);
    EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 1e-9 * a.cwiseAbs().maxCoeff());
    EXPECT_GT(a.cwiseAbs().maxCoeff(), 0.0);
  }
}

// The edge kernels on their own, against their formulas computed here: every count of edges from
// 0 to 13 (so the 8-edge, 4-edge and single-edge loops all run), a zero-length edge among them,
// edges sharing their first node (the kernels sum a run of them in registers) and not.
TEST(ForceModel, SimdEdgeKernelsMatchTheirFormulas) {
  // Without AVX2+FMA (or without xsimd at build time) there are no kernels and the continuum term
  // runs its scalar loops, which SimdElementKernelsMatchTheScalarLoops and the continuum tests
  // cover.
  const auto dashpots = detail::simd::edge_dashpot_kernel();
  const auto scatter = detail::simd::edge_scatter_kernel();
  if (dashpots == nullptr || scatter == nullptr)
    GTEST_SKIP() << "no SIMD edge kernel for this CPU or build";
  std::mt19937 rng(41);
  std::normal_distribution<double> g(0.0, 1.0);
  const int nodes = 9;
  std::vector<double> x4(4 * nodes), v4(4 * nodes);
  for (double& a : x4) a = 0.01 * g(rng);
  for (double& a : v4) a = 0.1 * g(rng);
  for (int c = 0; c < 4; ++c) x4[4 * 8 + c] = x4[4 * 7 + c];  // nodes 7 and 8 coincide
  for (int count = 0; count <= 13; ++count) {
    SCOPED_TRACE(testing::Message() << count << " edges");
    std::vector<std::int32_t> ij;
    std::vector<double> tau, k, w;
    for (int e = 0; e < count; ++e) {
      const int i = e % 5 == 4 ? 7 : e / 3;  // runs of three edges at node e / 3
      const int j = e % 5 == 4 ? 8 : (e / 3 + 1 + e % 3) % nodes;
      ij.push_back(i);
      ij.push_back(j);
      tau.push_back(0.01 * (1 + e));
      k.push_back(100.0 + 10.0 * e);
      w.push_back(1e-6 * (1 + e));
    }
    std::vector<double> blocks(5 * std::size_t(count), 7.0), rate(std::size_t(count), 0.0);
    std::vector<double> f(3 * nodes, 0.0), rhs(3 * nodes, 0.0);
    std::vector<double> f_ref(3 * nodes, 0.0), rhs_ref(3 * nodes, 0.0);
    dashpots(ij.data(), tau.data(), k.data(), x4.data(), v4.data(), blocks.data(), rate.data(),
             f.data(), 0, count);
    scatter(ij.data(), blocks.data(), rate.data(), w.data(), rhs.data(), 0, count);
    double largest = 0, largest_rhs = 0;
    for (int e = 0; e < count; ++e) {
      const int i = ij[2 * std::size_t(e)], j = ij[2 * std::size_t(e) + 1];
      Vector3<double> d, u;
      for (int c = 0; c < 3; ++c) {
        d[c] = x4[4 * std::size_t(j) + std::size_t(c)] - x4[4 * std::size_t(i) + std::size_t(c)];
        u[c] = v4[4 * std::size_t(j) + std::size_t(c)] - v4[4 * std::size_t(i) + std::size_t(c)];
      }
      const double l = d.norm();
      const Vector3<double> n = l > 0 ? Vector3<double>(d / l) : Vector3<double>::Zero();
      const double r = n.dot(u);
      const double* blk = &blocks[5 * std::size_t(e)];
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(blk[c], n[c], 1e-15);
      EXPECT_EQ(blk[3], 7.0);  // the entries it does not own are left alone
      EXPECT_EQ(blk[4], 7.0);
      EXPECT_NEAR(rate[std::size_t(e)], r, 1e-15 * (1 + std::abs(r)));
      if (e % 5 == 4) {
        EXPECT_EQ(rate[std::size_t(e)], 0.0);  // the zero-length edge
      }
      for (int c = 0; c < 3; ++c) {
        const double F = tau[std::size_t(e)] * k[std::size_t(e)] * r * n[c];
        f_ref[3 * std::size_t(i) + std::size_t(c)] += F;
        f_ref[3 * std::size_t(j) + std::size_t(c)] -= F;
        const double R = w[std::size_t(e)] * r * n[c];
        rhs_ref[3 * std::size_t(i) + std::size_t(c)] += R;
        rhs_ref[3 * std::size_t(j) + std::size_t(c)] -= R;
        largest = std::max(largest, std::abs(F));
        largest_rhs = std::max(largest_rhs, std::abs(R));
      }
    }
    for (std::size_t a = 0; a < f.size(); ++a) {
      EXPECT_NEAR(f[a], f_ref[a], 1e-13 * (1 + largest));
      EXPECT_NEAR(rhs[a], rhs_ref[a], 1e-13 * largest_rhs);
    }
    if (count > 0) {
      EXPECT_GT(largest, 0.0);
    }
  }
}

// The continuum law's element kernels (Options::simd, where the CPU has them) give the scalar
// loops' forces, energy, element tangents, implicit right-hand side, diagonal and diagonal blocks,
// and product (the edge dashpots' forces and the right-hand side's edge springs on the edge
// kernels included): a lattice of 29 elements per part (so the last batch of four is partly
// filled), linear and bilinear, squeezed, stretched past the switch and with one element pushed
// through its base (J below j_min, inverted), random velocities, one element cut out, one and two
// threads; with the element strain and with node-smoothed strains (the element share on the
// kernel).
TEST(ForceModel, SimdElementKernelsMatchTheScalarLoops) {
  // Without AVX2+FMA (or without xsimd at build time) Options::simd runs the scalar loops, so
  // there is nothing to compare; the scalar loops have their own tests.
  if (detail::simd::tet_force_kernel() == nullptr)
    GTEST_SKIP() << "no SIMD element kernel for this CPU or build";
  std::mt19937 rng(8);
  std::normal_distribution<double> g(0.0, 1.0);
  for (const StrainSmoothing smoothing : {StrainSmoothing::element, StrainSmoothing::node})
    for (const bool bilinear : {false, true})
      for (const bool cut : {false, true})
        for (const int threads : {1, 2}) {
          SCOPED_TRACE(testing::Message() << "smoothing " << to_string(smoothing) << " bilinear "
                                          << bilinear << " cut " << cut << " threads " << threads);
          SphereModel<double> model;
          Material<double> mat = tissue<double>();
          if (bilinear) {
            mat.large_strain_modulus = 5 * mat.youngs_modulus;
            mat.switch_strain = 0.05;
          }
          const Index r = model.add_region("block", mat);
          add_tetrahedral_part(
              model, make_cube_lattice(Vector3<double>(0, 0, 0), Eigen::Vector3i(3, 3, 1), 0.005),
              r, 0.0025);
          model.set_region_law(r, ForceLaw::continuum);
          ASSERT_NE(model.num_tetrahedra() % 4, 0) << model.num_tetrahedra();
          for (Index i = 0; i < model.num_nodes(); ++i) {
            auto x = model.positions().row(i);
            x.x() *= x.x() > 0.007 ? 1.5 : 0.8;  // stretched past the switch, and squeezed
            for (int c = 0; c < 3; ++c) {
              model.positions()(i, c) += 0.0004 * g(rng);
              model.velocities()(i, c) = 0.05 * g(rng);
            }
          }
          // One element's first corner through its base: J < 0.
          const auto t0 = model.tetrahedra().row(0);
          const Vector3<double> base = (model.positions().row(t0(1)) +
                                        model.positions().row(t0(2)) + model.positions().row(t0(3)))
                                           .transpose() /
                                       3.0;
          model.positions().row(t0(0)) =
              (base + 0.5 * (base - model.positions().row(t0(0)).transpose())).transpose();
          ForceModel<double>::Options o;
          o.threads = std::min(threads, detail::max_threads());
          o.strain_smoothing = smoothing;
          o.simd = false;
          ForceModel<double> scalar(model, o);
          o.simd = true;
          ForceModel<double> simd(model, o);
          ASSERT_GE(scalar.inverted_elements(model.positions()), 1);
          if (cut) {
            model.tetrahedron_intact()[5] = 0;
            scalar.update_topology(model);
            simd.update_topology(model);
          }
          const Index n = model.num_nodes();
          Positions<double> a(n, 3), b(n, 3);
          scalar.evaluate(model, model.positions(), model.velocities(), a);
          simd.evaluate(model, model.positions(), model.velocities(), b);
          ASSERT_TRUE(b.allFinite());
          EXPECT_GT(a.cwiseAbs().maxCoeff(), 0.0);
          EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 1e-13 * a.cwiseAbs().maxCoeff());
          EXPECT_EQ(scalar.continuum_element_tangents(), simd.continuum_element_tangents());
          {
            // The elements' pressures, signed, which the forces' scatter kernel hands back (only
            // their size reaches the forces and the tangent).
            detail::ContinuumTerm<double> ts, tk;
            for (detail::ContinuumTerm<double>* term : {&ts, &tk}) {
              term->refresh(model);
              term->set_simd(term == &tk);
              term->set_smoothing(smoothing);
              std::vector<double> f(3 * std::size_t(model.num_nodes()), 0.0);
              term->add_forces(model.positions().data(), model.velocities().data(), f.data());
            }
            ASSERT_EQ(ts.num_elements(), tk.num_elements());
            double largest = 0, worst = 0;
            int compressed = 0, stretched = 0;
            for (std::size_t t = 0; t < std::size_t(ts.num_elements()); ++t) {
              largest = std::max(largest, std::abs(ts.pressure(t)));
              worst = std::max(worst, std::abs(ts.pressure(t) - tk.pressure(t)));
              compressed += ts.pressure(t) < 0 ? 1 : 0;
              stretched += ts.pressure(t) > 0 ? 1 : 0;
            }
            EXPECT_GT(compressed, 0);
            EXPECT_GT(stretched, 0);
            EXPECT_LE(worst, 1e-13 * largest);
          }
          const double ea = scalar.elastic_energy(model, model.positions());
          const double eb = simd.elastic_energy(model, model.positions());
          EXPECT_GT(ea, 0.0);
          EXPECT_LE(std::abs(ea - eb), 1e-13 * ea);
          // The implicit solve's preparation reads the kernel's volume gradients and flags.
          const double h = 1e-3;
          std::vector<double> blocks(std::size_t(ForceModel<double>::implicit_block_size) *
                                     std::size_t(model.num_links()));
          Positions<double> ra(n, 3), rb(n, 3), da(n, 3), db(n, 3);
          scalar.prepare_implicit(model, h, JacobianForm::definite, blocks.data(), ra, da);
          simd.prepare_implicit(model, h, JacobianForm::definite, blocks.data(), rb, db);
          EXPECT_LE((ra - rb).cwiseAbs().maxCoeff(), 1e-13 * ra.cwiseAbs().maxCoeff());
          EXPECT_LE((da - db).cwiseAbs().maxCoeff(), 1e-13 * da.cwiseAbs().maxCoeff());
          // The block-Jacobi blocks: the edges' on the links' node-block kernel, the volumetric
          // ones on the node-pair kernels.
          Eigen::ArrayXd pa(6 * n), pb(6 * n);
          scalar.implicit_diagonal_blocks(model, blocks.data(), pa.data());
          simd.implicit_diagonal_blocks(model, blocks.data(), pb.data());
          EXPECT_LE((pa - pb).abs().maxCoeff(), 1e-13 * pa.abs().maxCoeff());
          // The product A p: the edge springs and the volumetric passes on the kernels.
          Positions<double> p(n, 3), ya(n, 3), yb(n, 3);
          for (Index i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) p(i, c) = g(rng);
          scalar.apply_implicit(model, blocks.data(), p, ya);
          simd.apply_implicit(model, blocks.data(), p, yb);
          EXPECT_LE((ya - yb).cwiseAbs().maxCoeff(), 1e-13 * ya.cwiseAbs().maxCoeff());
        }
}

// The assembled dF/dx and dF/dv against central differences of evaluate().
TEST(ForceModel, AssembledJacobiansMatchFiniteDifferences) {
  std::mt19937 rng(9);
  for (DampingModel dm : {DampingModel::along_link, DampingModel::full_relative_velocity}) {
    SphereModel<double> model = random_model<double>(rng, {2, 2, 2}, 0.3, true);
    ForceModel<double> forces = no_gravity(model, dm);
    auto opt = forces.options();
    opt.drag = 3.0;  // the drag's Jacobian is part of dF/dv
    forces.set_options(opt);
    const Index n = model.num_nodes();
    const Eigen::MatrixXd K = Eigen::MatrixXd(forces.stiffness_matrix(model, JacobianForm::exact));
    const Eigen::MatrixXd D = Eigen::MatrixXd(forces.damping_matrix(model));
    Eigen::MatrixXd Kfd(3 * n, 3 * n), Dfd(3 * n, 3 * n);
    Positions<double> fp(n, 3), fm(n, 3);
    for (Index k = 0; k < 3 * n; ++k) {
      const double hx = 1e-8, hv = 1e-6;
      Positions<double> x = model.positions(), v = model.velocities();
      x(k / 3, k % 3) += hx;
      forces.evaluate(model, x, v, fp);
      x(k / 3, k % 3) -= 2 * hx;
      forces.evaluate(model, x, v, fm);
      Kfd.col(k) = Eigen::Map<const Eigen::VectorXd>((fp - fm).eval().data(), 3 * n) / (2 * hx);
      x = model.positions();
      v(k / 3, k % 3) += hv;
      forces.evaluate(model, x, v, fp);
      v(k / 3, k % 3) -= 2 * hv;
      forces.evaluate(model, x, v, fm);
      Dfd.col(k) = Eigen::Map<const Eigen::VectorXd>((fp - fm).eval().data(), 3 * n) / (2 * hv);
    }
    EXPECT_TRUE(matrices_near(K, Kfd, 1e-5));
    EXPECT_TRUE(matrices_near(D, Dfd, 1e-7));
    // The symmetric form drops only the non-symmetric damping term k_d/l n (P u)^T: it is
    // symmetric, and with the spheres at rest relative to each other (u = 0) it equals the
    // finite-difference-checked exact form.
    const Eigen::MatrixXd Ks =
        Eigen::MatrixXd(forces.stiffness_matrix(model, JacobianForm::symmetric));
    EXPECT_TRUE(matrices_near(Ks, Ks.transpose().eval(), 1e-14));
    {
      SphereModel<double> still = model;
      still.velocities().setZero();
      EXPECT_TRUE(matrices_near(
          Eigen::MatrixXd(forces.stiffness_matrix(still, JacobianForm::symmetric)),
          Eigen::MatrixXd(forces.stiffness_matrix(still, JacobianForm::exact)), 1e-13));
    }
    // The definite form makes -K positive semi-definite.
    const Eigen::MatrixXd Kd =
        Eigen::MatrixXd(forces.stiffness_matrix(model, JacobianForm::definite));
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(-Kd).eigenvalues().minCoeff(),
              -1e-9 * Kd.cwiseAbs().maxCoeff());
  }
}

// The matrix-free operator and right-hand side equal the assembled A = M - hD - h^2 K and
// b = h F + h^2 K v (rows and columns of fixed nodes removed).
TEST(ForceModel, MatrixFreeImplicitOperatorMatchesAssembledMatrix) {
  std::mt19937 rng(13);
  for (DampingModel dm : {DampingModel::along_link, DampingModel::full_relative_velocity}) {
    SphereModel<double> model = random_model<double>(rng, {3, 2, 2}, 0.3, false);
    model.set_fixed(0);
    model.set_fixed(5);
    ForceModel<double> forces = no_gravity(model, dm);
    auto opt = forces.options();
    opt.drag = 3.0;
    forces.set_options(opt);
    forces.external_forces()(3, 1) = 0.01;
    const Index n = model.num_nodes();
    const double h = 2e-3;
    std::vector<double> blocks(5 * std::size_t(model.num_links()));
    Positions<double> rhs(n, 3), diag(n, 3), y(n, 3), p(n, 3);
    forces.prepare_implicit(model, h, JacobianForm::symmetric, blocks.data(), rhs, diag);

    const Eigen::MatrixXd K =
        Eigen::MatrixXd(forces.stiffness_matrix(model, JacobianForm::symmetric));
    const Eigen::MatrixXd D = Eigen::MatrixXd(forces.damping_matrix(model));
    Eigen::MatrixXd A = -h * D - h * h * K;
    for (Index i = 0; i < n; ++i)
      A.block<3, 3>(3 * i, 3 * i) += model.masses()[i] * Eigen::Matrix3d::Identity();
    Positions<double> F(n, 3);
    forces.evaluate(model, model.positions(), model.velocities(), F);
    Eigen::VectorXd b =
        h * Eigen::Map<const Eigen::VectorXd>(F.data(), 3 * n) +
        h * h * K * Eigen::Map<const Eigen::VectorXd>(model.velocities().data(), 3 * n);
    std::uniform_real_distribution<double> u(-1, 1);
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) p(i, c) = model.fixed()[i] ? 0.0 : u(rng);
    forces.apply_implicit(model, blocks.data(), p, y);
    Eigen::VectorXd Ap = A * Eigen::Map<const Eigen::VectorXd>(p.data(), 3 * n);
    for (Index i = 0; i < n; ++i)
      if (model.fixed()[i]) {
        Ap.segment<3>(3 * i).setZero();
        b.segment<3>(3 * i).setZero();
      }
    EXPECT_TRUE(matrices_near(Eigen::Map<const Eigen::VectorXd>(y.data(), 3 * n), Ap, 1e-12));
    EXPECT_TRUE(matrices_near(Eigen::Map<const Eigen::VectorXd>(rhs.data(), 3 * n), b, 1e-12));
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c)
        EXPECT_TRUE(near(diag(i, c), model.fixed()[i] ? 1.0 : A(3 * i + c, 3 * i + c), 1e-12));
    // The block-Jacobi blocks are A's 3 x 3 diagonal blocks (identity on fixed nodes).
    std::vector<double> pb(6 * std::size_t(n));
    forces.implicit_diagonal_blocks(model, blocks.data(), pb.data());
    for (Index i = 0; i < n; ++i) {
      const Eigen::Matrix3d Ai = model.fixed()[i] ? Eigen::Matrix3d::Identity().eval()
                                                  : A.block<3, 3>(3 * i, 3 * i).eval();
      const double* B = &pb[6 * std::size_t(i)];
      Eigen::Matrix3d Bi;
      Bi << B[0], B[3], B[4], B[3], B[1], B[5], B[4], B[5], B[2];
      EXPECT_TRUE(matrices_near(Bi, Ai, 1e-12)) << "node " << i;
    }
  }
}

// A contact re-solve (keep_contact_set at the same h) reuses the links' part of rhs and diagonal
// and recomputes the contacts': it must equal a full prepare with the same contact set.
TEST(ForceModel, ContactResolveReusesBlocksAndMatchesAFullPrepare) {
  std::mt19937 rng(21);
  SphereModel<double> model = random_model<double>(rng, {3, 2, 2}, 0.3, false);
  model.set_fixed(0);
  ForceModel<double> forces = no_gravity(model, DampingModel::along_link);
  auto opt = forces.options();
  opt.drag = 3.0;
  forces.set_options(opt);
  forces.reserve_contacts(4);
  PenaltyContact<double> tool;  // instrument contact on node 2, penetrating 0.1 mm at the start
  tool.node = 2;
  tool.instrument = 0;
  tool.normal = Vector3<double>(0.3, -0.2, 1.0).normalized();
  tool.depth = 1e-4;
  tool.stiffness = 50;
  tool.damping = 0.1;
  tool.friction = 0.3;
  tool.node_start = model.positions().row(2).transpose();
  PenaltyContact<double> part = tool;  // part contact between nodes 3 and 4
  part.node = 3;
  part.other = 4;
  part.instrument = -1;
  part.node_start = model.positions().row(3).transpose();
  part.other_start = model.positions().row(4).transpose();
  ASSERT_TRUE(forces.add_contact(tool));
  ASSERT_TRUE(forces.add_contact(part));
  ForceModel<double> fresh = forces;
  const Index n = model.num_nodes();
  const double h = 2e-3;
  std::vector<double> blocks(5 * std::size_t(model.num_links()));
  Positions<double> rhs(n, 3), diag(n, 3), rhs2(n, 3), diag2(n, 3);
  // End positions that take node 2 out of the tool: the set changes.
  Positions<double> x_end = model.positions();
  x_end.row(2) += 1e-3 * tool.normal.transpose();
  forces.start_contacts(model);
  forces.prepare_implicit(model, h, JacobianForm::symmetric, blocks.data(), rhs, diag);
  EXPECT_TRUE(forces.contacts()[0].in_solve);
  ASSERT_TRUE(forces.update_contact_set(model, x_end.data(), h));
  EXPECT_FALSE(forces.contacts()[0].in_solve);
  forces.prepare_implicit(model, h, JacobianForm::symmetric, blocks.data(), rhs, diag, true);
  // The same set, prepared in full: a first prepare at another h stores nothing reusable at h.
  fresh.start_contacts(model);
  fresh.prepare_implicit(model, 2 * h, JacobianForm::symmetric, blocks.data(), rhs2, diag2);
  ASSERT_TRUE(fresh.update_contact_set(model, x_end.data(), h));
  fresh.prepare_implicit(model, h, JacobianForm::symmetric, blocks.data(), rhs2, diag2, true);
  EXPECT_TRUE(matrices_near(rhs, rhs2, 1e-14));
  EXPECT_TRUE(matrices_near(diag, diag2, 1e-14));
}

// Drag: a free model moving rigidly slows as exp(-gamma t) (links stay unstrained, so nothing else
// acts), under symplectic and implicit Euler alike to their first-order accuracy.
TEST(ForceModel, DragDecaysRigidMotionExponentially) {
  for (const std::string name : {"symplectic_euler", "implicit_euler"}) {
    SphereModel<double> model = block<double>({2, 2, 2}, 0.005);
    model.velocities().col(0).setConstant(0.1);
    Simulation<double>::Options o;
    o.integrator = name;
    o.forces.gravity.setZero();
    o.forces.drag = 5.0;
    Simulation<double> sim(model, o);
    const double dt = 1e-4;
    for (int s = 0; s < 2000; ++s) ASSERT_TRUE(sim.step(dt).advanced());  // 0.2 s
    EXPECT_TRUE(near(sim.model().velocities().col(0).mean(), 0.1 * std::exp(-5.0 * 0.2), 2e-3))
        << name;
  }
  ForceModel<double>::Options bad;
  bad.drag = -1;
  EXPECT_THROW(ForceModel<double>(block<double>({1, 1, 1}, 0.005), bad), Error);
}

TEST(ForceModel, TwoThreadsGiveTheSameForcesAndEnergyAsOne) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  std::mt19937 rng(17);
  SphereModel<double> model = random_model<double>(rng, {6, 5, 7}, 0.3, true);
  ForceModel<double> one = no_gravity(model, DampingModel::along_link, 1);
  ForceModel<double> two = no_gravity(model, DampingModel::along_link, 2);
  Positions<double> f1(model.num_nodes(), 3), f2(model.num_nodes(), 3);
  one.evaluate(model, model.positions(), model.velocities(), f1);
  two.evaluate(model, model.positions(), model.velocities(), f2);
  EXPECT_TRUE(matrices_near(f1, f2, 1e-13));
  // The energy too: each thread sums its share of the links (a bilinear law).
  const double e1 = one.elastic_energy(model, model.positions());
  EXPECT_GT(e1, 0.0);
  EXPECT_NEAR(two.elastic_energy(model, model.positions()), e1, 1e-12 * e1);
}

TEST(ForceModel, EnergiesAreZeroAtRestAndPositiveWhenStrained) {
  SphereModel<double> model = two_spheres(0.002, 100.0, 0.0);
  const ForceModel<double> forces(model);
  EXPECT_EQ(forces.elastic_energy(model, model.positions()), 0.0);
  EXPECT_EQ(forces.gravity_energy(model, model.positions()), 0.0);
  model.positions()(1, 0) += 0.001;
  EXPECT_TRUE(near(forces.elastic_energy(model, model.positions()), 0.5 * 100 * 1e-6, 1e-9));
  model.positions().col(2).array() -= 0.01;  // both sink 1 cm: lose 2 m g h, no strain change
  EXPECT_TRUE(near(forces.elastic_energy(model, model.positions()), 0.5 * 100 * 1e-6, 1e-9));
  EXPECT_TRUE(
      near(forces.gravity_energy(model, model.positions()), -2 * 0.002 * 9.81 * 0.01, 1e-12));
}

}  // namespace
}  // namespace fsm::test
