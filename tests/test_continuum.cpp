// The continuum law (docs/physics.md section 11): tetrahedra in SphereModel; element forces are
// minus the gradient of the energy, match an independent single-element reference, balance
// momentum and torque, vanish for rigid motion; damping only dissipates; the implicit tangent is
// positive semi-definite; homogeneous deformations recover E, nu and mu exactly (patch test); an
// inverted element keeps finite forces that push it back; and a block squeezed between two
// frictionless instruments carries E A strain at every resolution (contact and law together).

#include <map>
#include <random>
#include <string>

#include "common.hpp"
#include "fsm/collision/contact.hpp"

namespace fsm::test {
namespace {

using V3 = Vector3<double>;
using M3 = Matrix3<double>;

Material<double> soft(double nu = 0.45, double E = 13150, double eta = 10.26) {
  Material<double> m = tissue<double>(E, eta);
  m.poisson_ratio = nu;
  return m;
}

/// A lattice block (cells x spacing) with the continuum law.
SphereModel<double> continuum_block(Eigen::Vector3i cells, double spacing,
                                    const Material<double>& mat = soft()) {
  SphereModel<double> m = block<double>(cells, spacing, mat);
  m.set_region_law(0, ForceLaw::continuum);
  return m;
}

Positions<double> affine(const SphereModel<double>& m, const M3& F) {
  Positions<double> x = m.rest_positions();
  for (Index i = 0; i < m.num_nodes(); ++i) x.row(i) = (F * x.row(i).transpose()).transpose();
  return x;
}

double block_volume(const SphereModel<double>& m) {
  double v = 0;
  const auto x = m.rest_positions();
  const auto t = m.tetrahedra();
  for (Index e = 0; e < m.num_tetrahedra(); ++e) {
    M3 D;
    for (int k = 0; k < 3; ++k) D.col(k) = (x.row(t(e, k + 1)) - x.row(t(e, 0))).transpose();
    v += D.determinant() / 6;
  }
  return v;
}

/// An implicit step's buffers for `m`, filled by prepare_implicit() at its state (definite form).
struct ImplicitBuffers {
  explicit ImplicitBuffers(const SphereModel<double>& m)
      : blocks(std::size_t(ForceModel<double>::implicit_block_size) * std::size_t(m.num_links())),
        rhs(m.num_nodes(), 3),
        diag(m.num_nodes(), 3) {}
  void prepare(ForceModel<double>& f, const SphereModel<double>& m, double h) {
    f.prepare_implicit(m, h, JacobianForm::definite, blocks.data(), rhs, diag);
  }
  std::vector<double> blocks;
  Positions<double> rhs, diag;
};

TEST(SphereModelTetrahedra, AreCheckedWhenAdded) {
  SphereModel<double> m;
  const Index a = m.add_region("a", soft()), b = m.add_region("b", soft());
  for (const V3& p : {V3(0, 0, 0), V3(1, 0, 0), V3(0, 1, 0), V3(0, 0, 1)})
    m.add_node(0.001 * p, 0.0005, 1e-4, a);
  m.add_node(V3(0.001, 0.001, 0.001), 0.0005, 1e-4, b);
  EXPECT_EQ(m.add_tetrahedron(0, 1, 2, 3), 0);
  EXPECT_EQ(m.num_tetrahedra(), 1);
  auto message = [&](Index p, Index q, Index r, Index s) {
    try {
      m.add_tetrahedron(p, q, r, s);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(0, 1, 2, 7).find("out of range"), std::string::npos);
  EXPECT_NE(message(0, 1, 1, 3).find("repeats"), std::string::npos);
  EXPECT_NE(message(1, 2, 3, 4).find("different regions"), std::string::npos);
  EXPECT_NE(message(0, 2, 1, 3).find("inverted or degenerate"), std::string::npos);
  EXPECT_EQ(m.num_tetrahedra(), 1);  // nothing added by the failures
  // The continuum law needs every node of its region in a tetrahedron.
  m.set_region_law(b, ForceLaw::continuum);
  EXPECT_THROW(m.validate(), Error);
  m.set_region_law(b, ForceLaw::links);
  m.set_region_law(a, ForceLaw::continuum);
  EXPECT_NO_THROW(m.validate());
  EXPECT_TRUE(m.has_continuum());
  EXPECT_THROW(m.set_region_law(7, ForceLaw::links), Error);
}

TEST(Continuum, InverseCubeRootSquaredMatchesLibm) {
  // Every volume ratio the law evaluates (J >= j_min = 0.2; strongly stretched up to 1e3) and
  // below: within 1e-15 of 1 / cbrt(x^2); exact at 1 (zero energy at rest) and at powers of 8.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> exponent(-3.0, 3.0);
  double worst = 0;
  for (int k = 0; k < 100000; ++k) {
    const double x = std::pow(10.0, exponent(rng));
    const double exact = 1.0 / std::cbrt(x * x);
    worst = std::max(worst, std::abs(detail::inverse_cbrt_squared(x) - exact) / exact);
  }
  EXPECT_LT(worst, 1e-15);
  EXPECT_EQ(detail::inverse_cbrt_squared(1.0), 1.0);
  EXPECT_EQ(detail::inverse_cbrt_squared(8.0), 0.25);
  EXPECT_EQ(detail::inverse_cbrt_squared(0.125), 4.0);
  EXPECT_NEAR(detail::inverse_cbrt_squared(0.2f), 1.0f / std::cbrt(0.04f), 1e-6f);
}

TEST(Continuum, LinksOfAContinuumRegionCarryNoForce) {
  SphereModel<double> m = continuum_block({2, 2, 2}, 0.005);
  ForceModel<double> f = no_gravity(m);
  EXPECT_EQ(f.num_elements(), m.num_tetrahedra());
  for (const auto carries : f.force_links()) EXPECT_EQ(carries, 0);
  // At rest: no force at all.
  Positions<double> out(m.num_nodes(), 3);
  f.evaluate(m, m.positions(), m.velocities(), out);
  EXPECT_LT(out.cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(f.elastic_energy(m, m.positions()), 0.0);
}

// Forces are minus the energy's gradient (central differences), for a deformed, jittered block in
// moderate strain, with the bilinear stiffening, and in an element pressed beyond J_min.
TEST(Continuum, ForcesAreMinusTheEnergyGradient) {
  std::mt19937 rng(7);
  for (const bool bilinear : {false, true}) {
    SphereModel<double> m = random_model<double>(rng, {2, 2, 2}, 0.25, bilinear);
    m.set_region_law(0, ForceLaw::continuum);
    m.velocities().setZero();
    ForceModel<double> f = no_gravity(m);
    const Positions<double> x = m.positions();
    Positions<double> g(m.num_nodes(), 3);
    f.evaluate(m, x, m.velocities(), g);
    double worst = 0, scale = g.cwiseAbs().maxCoeff();
    for (Index i = 0; i < m.num_nodes(); ++i)
      for (int c = 0; c < 3; ++c) {
        Positions<double> xp = x, xm = x;
        const double h = 1e-8;
        xp(i, c) += h;
        xm(i, c) -= h;
        const double fd = -(f.elastic_energy(m, xp) - f.elastic_energy(m, xm)) / (2 * h);
        worst = std::max(worst, std::abs(fd - g(i, c)));
      }
    EXPECT_LT(worst, 1e-5 * scale) << "bilinear " << bilinear;
  }
  // One element pressed flat (J = 0.05 < J_min) and one inverted (J < 0): finite, and the
  // gradient still holds (the extension of J^-2/3 is smooth).
  for (const double squash : {0.05, -0.3}) {
    SphereModel<double> m;
    const Index r = m.add_region("t", soft(0.45), ForceLaw::continuum);
    for (const V3& p : {V3(0, 0, 0), V3(1, 0, 0), V3(0, 1, 0), V3(0, 0, 1)})
      m.add_node(0.002 * p, 0.0005, 1e-4, r);
    m.add_tetrahedron(0, 1, 2, 3);
    m.positions()(3, 2) = 0.002 * squash;
    ForceModel<double> f = no_gravity(m);
    Positions<double> g(4, 3);
    f.evaluate(m, m.positions(), m.velocities(), g);
    ASSERT_TRUE(g.allFinite());
    EXPECT_GT(g(3, 2), 0) << "the flattened apex is pushed back up, J = " << squash;
    EXPECT_EQ(f.inverted_elements(m.positions()), squash < 0 ? 1 : 0);
    const Positions<double> x = m.positions();
    for (int c = 0; c < 3; ++c) {
      Positions<double> xp = x, xm = x;
      xp(3, c) += 1e-9;
      xm(3, c) -= 1e-9;
      const double fd = -(f.elastic_energy(m, xp) - f.elastic_energy(m, xm)) / 2e-9;
      EXPECT_TRUE(near(fd, g(3, c), 1e-5, 1e-6 * g.cwiseAbs().maxCoeff())) << squash << " " << c;
    }
  }
}

// A single element: every node's nodal volume ratio is the element's J, so the energy is
// V (C10 (I1 J^-2/3 - 3) + K/2 (J - 1)^2), written here from the textbook, independently of the
// library's code; its central-difference gradient must equal the library's forces.
TEST(Continuum, SingleElementMatchesTheTextbookNeoHookean) {
  const Material<double> mat = soft(0.49, 5000);
  SphereModel<double> m;
  const Index r = m.add_region("t", mat, ForceLaw::continuum);
  const V3 rest[4] = {V3(0, 0, 0), V3(0.003, 0, 0), V3(0.0005, 0.002, 0), V3(0.001, 0.001, 0.0025)};
  for (const V3& p : rest) m.add_node(p, 0.0005, 1e-4, r);
  m.add_tetrahedron(0, 1, 2, 3);
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 3e-4);
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < 3; ++c) m.positions()(i, c) += n(rng);
  const double mu = mat.youngs_modulus / (2 * (1 + mat.poisson_ratio));
  const double K = mat.youngs_modulus / (3 * (1 - 2 * mat.poisson_ratio));
  M3 Dm;
  for (int k = 0; k < 3; ++k) Dm.col(k) = rest[k + 1] - rest[0];
  const double V = Dm.determinant() / 6;
  auto textbook = [&](const Positions<double>& x) {
    M3 Ds;
    for (int k = 0; k < 3; ++k) Ds.col(k) = (x.row(k + 1) - x.row(0)).transpose();
    const M3 F = Ds * Dm.inverse();
    const double J = F.determinant();
    const double I1 = (F.transpose() * F).trace();
    return V * (mu / 2 * (I1 * std::pow(J, -2.0 / 3.0) - 3) + K / 2 * (J - 1) * (J - 1));
  };
  ForceModel<double> f = no_gravity(m);
  EXPECT_TRUE(near(f.elastic_energy(m, m.positions()), textbook(m.positions()), 1e-12));
  Positions<double> g(4, 3);
  f.evaluate(m, m.positions(), Positions<double>::Zero(4, 3), g);
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < 3; ++c) {
      Positions<double> xp = m.positions(), xm = m.positions();
      xp(i, c) += 1e-9;
      xm(i, c) -= 1e-9;
      const double fd = -(textbook(xp) - textbook(xm)) / 2e-9;
      EXPECT_TRUE(near(g(i, c), fd, 1e-6, 1e-7 * g.cwiseAbs().maxCoeff())) << i << " " << c;
    }
}

// Equal and opposite: the forces sum to zero and have no net torque, at any deformation and
// velocity; a rigid rotation (position and velocity) gives no force at all.
TEST(Continuum, ForcesBalanceAndRigidMotionIsFree) {
  std::mt19937 rng(11);
  SphereModel<double> m = random_model<double>(rng, {3, 2, 2}, 0.2);
  m.set_region_law(0, ForceLaw::continuum);
  ForceModel<double> f = no_gravity(m);
  Positions<double> g(m.num_nodes(), 3);
  f.evaluate(m, m.positions(), m.velocities(), g);
  const double scale = g.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0);
  EXPECT_LT(g.colwise().sum().norm(), 1e-10 * scale * double(m.num_nodes()));
  V3 torque = V3::Zero();
  for (Index i = 0; i < m.num_nodes(); ++i)
    torque += m.positions().row(i).transpose().cross(g.row(i).transpose());
  EXPECT_LT(torque.norm(), 1e-10 * scale * 0.03 * double(m.num_nodes()));
  // Rigid: rotate the rest shape by 40 degrees and spin it at 3 rad/s about the same axis.
  const M3 R = Eigen::AngleAxisd(0.7, V3(1, 2, 3).normalized()).toRotationMatrix();
  const V3 w = 3 * V3(1, 2, 3).normalized();
  Positions<double> x = affine(m, R), v(m.num_nodes(), 3);
  for (Index i = 0; i < m.num_nodes(); ++i)
    v.row(i) = w.cross(V3(x.row(i).transpose())).transpose();
  f.evaluate(m, x, v, g);
  EXPECT_LT(g.cwiseAbs().maxCoeff(), 1e-9 * scale);
}

// Viscous forces only take energy out: their power is negative for any velocity.
TEST(Continuum, DampingNeverAddsEnergy) {
  std::mt19937 rng(5);
  SphereModel<double> m = random_model<double>(rng, {2, 2, 2}, 0.25);
  m.set_region_law(0, ForceLaw::continuum);
  ForceModel<double> f = no_gravity(m);
  std::normal_distribution<double> n(0, 0.05);
  for (int trial = 0; trial < 20; ++trial) {
    Positions<double> v(m.num_nodes(), 3), with(m.num_nodes(), 3), without(m.num_nodes(), 3);
    for (Index i = 0; i < v.size(); ++i) v.data()[i] = n(rng);
    f.evaluate(m, m.positions(), v, with);
    f.evaluate(m, m.positions(), Positions<double>::Zero(m.num_nodes(), 3), without);
    const double power = (with - without).cwiseProduct(v).sum();
    EXPECT_LT(power, 0) << trial;
  }
  // The damping matrix is negative semi-definite (its eigenvalues <= 0).
  const Eigen::MatrixXd D = Eigen::MatrixXd(f.damping_matrix(m));
  EXPECT_TRUE(matrices_near(D, Eigen::MatrixXd(D.transpose()), 1e-12));
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D).eigenvalues();
  EXPECT_LT(ev.maxCoeff(), 1e-9 * ev.cwiseAbs().maxCoeff());
}

// The implicit solve's tangent (definite form) is symmetric and negative semi-definite; at rest
// its volumetric part equals the exact Jacobian's (U' = 0 there) and both agree on the rigid
// modes (zero).
TEST(Continuum, TangentIsDefiniteAndExactJacobianIsTheForceDerivative) {
  std::mt19937 rng(9);
  SphereModel<double> m = random_model<double>(rng, {2, 2, 1}, 0.2);
  m.set_region_law(0, ForceLaw::continuum);
  ForceModel<double> f = no_gravity(m);
  const Eigen::MatrixXd T = Eigen::MatrixXd(f.stiffness_matrix(m, JacobianForm::definite));
  EXPECT_TRUE(matrices_near(T, Eigen::MatrixXd(T.transpose()), 1e-12));
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(T).eigenvalues();
  EXPECT_LT(ev.maxCoeff(), 1e-9 * ev.cwiseAbs().maxCoeff());
  // The exact Jacobian against a directional derivative of the forces.
  const Eigen::MatrixXd K = Eigen::MatrixXd(f.stiffness_matrix(m, JacobianForm::exact));
  std::normal_distribution<double> n(0, 1);
  Eigen::VectorXd d(3 * m.num_nodes());
  for (Index i = 0; i < d.size(); ++i) d[i] = n(rng);
  const double h = 1e-8;
  Positions<double> xp = m.positions(), xm = m.positions(), fp(m.num_nodes(), 3),
                    fm(m.num_nodes(), 3);
  const Positions<double> zero = Positions<double>::Zero(m.num_nodes(), 3);
  for (Index i = 0; i < m.num_nodes(); ++i)
    for (int c = 0; c < 3; ++c) {
      xp(i, c) += h * d[3 * i + c];
      xm(i, c) -= h * d[3 * i + c];
    }
  f.evaluate(m, xp, zero, fp);
  f.evaluate(m, xm, zero, fm);
  Eigen::VectorXd fd(3 * m.num_nodes());
  for (Index i = 0; i < m.num_nodes(); ++i)
    for (int c = 0; c < 3; ++c) fd[3 * i + c] = (fp(i, c) - fm(i, c)) / (2 * h);
  const Eigen::VectorXd Kd = K * d;
  EXPECT_LT((Kd - fd).norm(), 1e-5 * fd.norm());
}

// Homogeneous deformations of a block (a patch test): interior nodes feel no force, and the
// energy per unit volume is the continuum's, so E, nu and mu are what the material says at any
// resolution: uniaxial stress (lateral strain -nu eps) stores E eps^2 / 2 and is the minimum over
// lateral strains; simple shear stores mu gamma^2 / 2; a pure volume change K (dV/V)^2 / 2.
TEST(Continuum, HomogeneousStrainRecoversTheMaterialConstants) {
  for (const double nu : {0.3, 0.45, 0.49}) {
    const Material<double> mat = soft(nu);
    for (const double spacing : {0.005, 0.0025}) {
      SphereModel<double> m = continuum_block({4, 4, 4}, spacing * 4 / 4, mat);
      ForceModel<double> f = no_gravity(m);
      const double V = block_volume(m), E = mat.youngs_modulus, eps = 1e-4;
      auto energy = [&](const M3& F) { return f.elastic_energy(m, affine(m, F)) / V; };
      const M3 uni = V3(1 + eps, 1 - nu * eps, 1 - nu * eps).asDiagonal();
      EXPECT_TRUE(near(energy(uni), 0.5 * E * eps * eps, 2e-3)) << nu << " " << spacing;
      // Lateral strain -nu eps is the minimum: perturbing it either way costs energy.
      const double d = 0.2 * nu * eps;
      EXPECT_GT(energy(V3(1 + eps, 1 - nu * eps + d, 1 - nu * eps + d).asDiagonal()), energy(uni));
      EXPECT_GT(energy(V3(1 + eps, 1 - nu * eps - d, 1 - nu * eps - d).asDiagonal()), energy(uni));
      M3 shear = M3::Identity();
      shear(0, 1) = eps;
      EXPECT_TRUE(near(energy(shear), 0.5 * mat.shear_modulus() * eps * eps, 2e-3));
      const double s = std::cbrt(1 + eps);
      EXPECT_TRUE(near(energy(s * M3::Identity()), 0.5 * mat.bulk_modulus() * eps * eps, 2e-3));
      // Patch test: interior nodes in equilibrium under the homogeneous stretch.
      Positions<double> g(m.num_nodes(), 3);
      f.evaluate(m, affine(m, uni), Positions<double>::Zero(m.num_nodes(), 3), g);
      const double face = g.cwiseAbs().maxCoeff();
      const double extent = 4 * spacing;
      for (Index i = 0; i < m.num_nodes(); ++i) {
        const V3 p = m.rest_positions().row(i).transpose();
        const bool interior = (p.array() > 1e-9).all() && (p.array() < extent - 1e-9).all();
        if (interior) {
          EXPECT_LT(g.row(i).norm(), 1e-9 * face) << i;
        }
      }
    }
  }
}

// Equal-and-opposite frictionless instruments squeeze a free block (no gravity, no fixed node):
// uniaxial stress, so the force must be E A (compression) at small strain. The penalty contact's
// stiffness follows the tissue's, so the force and the penetration share must hold at 5 mm and at
// 2.5 mm spacing alike: no softening as the spheres get smaller.
TEST(Continuum, SqueezedBlockCarriesEAStrainAtEveryResolution) {
  using namespace fsm::collision;
  const double side = 0.02, strain = 0.01;
  const Material<double> mat = soft(0.45, 13150, 10.26);
  std::vector<double> forces;
  for (const int cells : {4, 8}) {
    SphereModel<double> m = continuum_block({cells, cells, cells}, side / cells, mat);
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    o.forces.drag = 50;  // settles the free block's rigid modes
    Simulation<double> sim(m, o);
    ContactSolver<double> contacts(sim.model(), sim.forces());
    Instrument<double> plate;
    plate.shape = CylinderShape<double>{0.02, 0.005};  // radius 20 mm, half height 5 mm, axis z
    plate.friction = 0;
    plate.pose.position = V3(0.01, 0.01, side + 0.005);
    const Index top = contacts.add_instrument(plate);
    plate.pose.position = V3(0.01, 0.01, -0.005);
    const Index bottom = contacts.add_instrument(plate);
    const int ramp = 200, hold = 600;
    for (int s = 0; s < ramp + hold; ++s) {
      const double squeeze = 0.5 * strain * side * std::min(1.0, double(s + 1) / ramp);
      contacts.instrument(top).pose.position.z() = side + 0.005 - squeeze;
      contacts.instrument(bottom).pose.position.z() = -0.005 + squeeze;
      contacts.compute(sim.model(), sim.forces());
      const StepReport<double> r = sim.step(1e-3);
      ASSERT_TRUE(r.advanced()) << s;
      ASSERT_EQ(r.inverted_elements, 0);
      contacts.collect(sim.forces());
    }
    const double F = contacts.wrench(top).force.z();
    EXPECT_TRUE(near(F, -contacts.wrench(bottom).force.z(), 1e-3)) << "balance, " << cells;
    // The block's height change against the plates' travel: the contact's share is small.
    double zmax = -1, zmin = 1;
    for (Index i = 0; i < sim.model().num_nodes(); ++i) {
      zmax = std::max(zmax, sim.model().positions()(i, 2));
      zmin = std::min(zmin, sim.model().positions()(i, 2));
    }
    const double compressed = side - (zmax - zmin);
    EXPECT_TRUE(near(compressed, strain * side, 0.03)) << cells;
    // Uniaxial stress at the compressed strain: F = E A_current eps (nearly; neo-Hookean at 1%).
    const double expected = mat.youngs_modulus * side * side * compressed / side;
    EXPECT_TRUE(near(F, expected, 0.03)) << cells << " spheres per side";
    forces.push_back(F);
  }
  EXPECT_TRUE(near(forces[0], forces[1], 0.02)) << "resolution changed the force";
}

// The matrix-free operator, right-hand side and diagonal blocks of the continuum law equal the
// assembled tangent's (definite form), with edge springs only, with the element tangent on the
// poorly shaped elements (the default) and with it on every element; every one of them is positive
// semi-definite and free of rigid translation, and its block-Jacobi blocks positive definite.
TEST(Continuum, MatrixFreeTangentMatchesAssembledForEveryTangentChoice) {
  for (const double quality : {0.0, 0.3, 2.0}) {
    std::mt19937 rng(21);
    SphereModel<double> m = random_model<double>(rng, {3, 2, 2}, 0.35);
    m.set_region_law(0, ForceLaw::continuum);
    m.set_fixed(0);
    ForceModel<double> f = no_gravity(m);
    auto o = f.options();
    o.element_tangent_quality = quality;
    o.drag = 2.0;
    f.set_options(o);
    const Index n = m.num_nodes();
    const double h = 1e-3;
    ImplicitBuffers step(m);
    step.prepare(f, m, h);
    Positions<double> y(n, 3), p(n, 3);
    const Index element_tangents = f.continuum_element_tangents();
    if (quality > 1) {
      EXPECT_EQ(element_tangents, m.num_tetrahedra());
    } else if (quality == 0) {
      EXPECT_LT(element_tangents, m.num_tetrahedra());  // only strained ones
    }
    const Eigen::MatrixXd K = Eigen::MatrixXd(f.stiffness_matrix(m, JacobianForm::definite));
    const Eigen::MatrixXd D = Eigen::MatrixXd(f.damping_matrix(m));
    Eigen::MatrixXd A = -h * D - h * h * K;
    for (Index i = 0; i < n; ++i)
      A.block<3, 3>(3 * i, 3 * i) += m.masses()[i] * Eigen::Matrix3d::Identity();
    std::uniform_real_distribution<double> u(-1, 1);
    for (Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) p(i, c) = m.fixed()[i] ? 0.0 : u(rng);
    f.apply_implicit(m, step.blocks.data(), p, y);
    Eigen::VectorXd Ap = A * Eigen::Map<const Eigen::VectorXd>(p.data(), 3 * n);
    Ap.segment<3>(0).setZero();  // the fixed node's row
    EXPECT_TRUE(matrices_near(Eigen::Map<const Eigen::VectorXd>(y.data(), 3 * n), Ap, 1e-10))
        << "quality " << quality;
    Positions<double> F(n, 3);
    f.evaluate(m, m.positions(), m.velocities(), F);
    Eigen::VectorXd b = h * Eigen::Map<const Eigen::VectorXd>(F.data(), 3 * n) +
                        h * h * K * Eigen::Map<const Eigen::VectorXd>(m.velocities().data(), 3 * n);
    b.segment<3>(0).setZero();
    EXPECT_TRUE(matrices_near(Eigen::Map<const Eigen::VectorXd>(step.rhs.data(), 3 * n), b, 1e-10))
        << "quality " << quality;
    // The block-Jacobi blocks are A's diagonal blocks (the volumetric part's too, summed over
    // the node pairs), positive definite and at least the mass.
    std::vector<double> pb(6 * std::size_t(n));
    f.implicit_diagonal_blocks(m, step.blocks.data(), pb.data());
    for (Index i = 1; i < n; ++i) {
      const double* B = &pb[6 * std::size_t(i)];
      Eigen::Matrix3d Bi;
      Bi << B[0], B[3], B[4], B[3], B[1], B[5], B[4], B[5], B[2];
      EXPECT_TRUE(matrices_near(Bi, Eigen::Matrix3d(A.block<3, 3>(3 * i, 3 * i)), 1e-10))
          << i << " " << quality;
      EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(Bi).eigenvalues().minCoeff(),
                m.masses()[i] * (1 - 1e-12))
          << i << " " << quality;
    }
    const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(-K).eigenvalues();
    EXPECT_GT(ev.minCoeff(), -1e-9 * ev.cwiseAbs().maxCoeff()) << "quality " << quality;
    Eigen::VectorXd shift(3 * n);
    for (Index i = 0; i < n; ++i) shift.segment<3>(3 * i) = V3(0.3, -0.2, 0.5);
    EXPECT_LT((K * shift).norm(), 1e-9 * K.norm() * shift.norm()) << "quality " << quality;
  }
}

/// Node i's 3 x 3 block of the block-Jacobi blocks `pb` (6 per node: xx, yy, zz, xy, xz, yz).
M3 stored_block(const std::vector<double>& pb, Index i) {
  const double* B = &pb[6 * std::size_t(i)];
  M3 Bi;
  Bi << B[0], B[3], B[4], B[3], B[1], B[5], B[4], B[5], B[2];
  return Bi;
}

/// Node i's diagonal block of the matrix-free product A, probed column by column.
M3 probed_block(ForceModel<double>& f, const SphereModel<double>& m, const ImplicitBuffers& step,
                Index i) {
  Positions<double> y(m.num_nodes(), 3), p = Positions<double>::Zero(m.num_nodes(), 3);
  M3 probed;
  for (int c = 0; c < 3; ++c) {
    p.setZero();
    p(i, c) = 1;
    f.apply_implicit(m, step.blocks.data(), p, y);
    probed.col(c) = y.row(i).transpose();
  }
  return probed;
}

// The block-Jacobi blocks are the diagonal blocks of the operator the matrix-free product applies.
// On a single element a stretched element, which gets the element tangent, checks that tangent's
// blocks: with Q from tangent_rotation()'s two Newton steps short of orthogonal at a
// 2.5-fold stretch, a block with I in place of Q Q^T puts the node's block 3 % off.
TEST(Continuum, BlockJacobiBlocksAreTheProductsDiagonalBlocks) {
  for (const double stretch : {1.0, 2.5}) {
    SphereModel<double> m;
    const Index r = m.add_region("t", soft(0.45), ForceLaw::continuum);
    const V3 rest[4] = {V3(0, 0, 0), V3(0.003, 0, 0), V3(0.0005, 0.002, 0),
                        V3(0.001, 0.001, 0.0025)};
    for (const V3& p : rest) m.add_node(p, 0.0005, 1e-4, r);
    m.add_tetrahedron(0, 1, 2, 3);
    M3 F = M3::Identity();
    F(0, 0) = stretch;
    F(1, 0) = 0.2 * (stretch - 1);
    m.positions() = affine(m, F);
    ForceModel<double> f = no_gravity(m);
    const Index n = m.num_nodes();
    const double h = 1e-3;
    ImplicitBuffers step(m);
    step.prepare(f, m, h);
    EXPECT_EQ(f.continuum_element_tangents(), stretch > 1 ? 1 : 0);
    std::vector<double> pb(6 * std::size_t(n));
    f.implicit_diagonal_blocks(m, step.blocks.data(), pb.data());
    for (Index i = 0; i < n; ++i)
      EXPECT_TRUE(matrices_near(stored_block(pb, i), probed_block(f, m, step, i), 1e-12))
          << "stretch " << stretch << " node " << i;
  }
}

// On a mesh too: the volumetric part's blocks are the exact sums over each node's pairs
// (sum_a c_a G_ab G_ab^T, G_ab = d v_a / d x_b). Before 2026-11-29 they were a per-element
// stand-in that dropped the cross terms between the elements sharing a node pair (the uterus took
// 4.58 CG iterations a step with it, 4.08 with the exact blocks).
// Both the SIMD pair kernels and the scalar loops, on one and two threads, with an element
// tangent among them (one element stretched far) and nodes fixed (their rows are not probed).
TEST(Continuum, BlockJacobiBlocksAreTheProductsDiagonalBlocksOnAMesh) {
  for (const bool simd : {true, false})
    for (const int threads : {1, 2}) {
      SphereModel<double> m = continuum_block({3, 2, 2}, 0.004);
      std::mt19937 rng(7);
      std::uniform_real_distribution<double> u(-1, 1);
      Positions<double> x = affine(m, M3::Identity());
      for (Index i = 0; i < m.num_nodes(); ++i)
        for (int c = 0; c < 3; ++c) x(i, c) += 4e-4 * u(rng);
      x(m.num_nodes() - 1, 0) += 0.006;  // a corner pulled far out: its element's tangent
      m.positions() = x;
      typename ForceModel<double>::Options o;
      o.gravity.setZero();
      o.threads = threads;
      o.simd = simd;
      ForceModel<double> f(m, o);
      const Index n = m.num_nodes();
      ImplicitBuffers step(m);
      step.prepare(f, m, 1e-3);
      EXPECT_GT(f.continuum_element_tangents(), 0);
      // (Both paths: the SIMD one on the pair kernels where the CPU has them.)
      EXPECT_EQ(f.continuum_pair_product(), simd && detail::simd::pair_spread_kernel() != nullptr);
      std::vector<double> pb(6 * std::size_t(n));
      f.implicit_diagonal_blocks(m, step.blocks.data(), pb.data());
      int probed_nodes = 0;
      for (Index i = 0; i < n; ++i) {
        if (m.fixed()[i]) continue;
        ++probed_nodes;
        EXPECT_TRUE(matrices_near(stored_block(pb, i), probed_block(f, m, step, i), 1e-12))
            << "simd " << simd << " threads " << threads << " node " << i;
      }
      EXPECT_GT(probed_nodes, 20);
    }
}

// Springs along a sliver's edges cannot resist its apex moving across its base; a light node
// held only by a sliver (what Mesh_3 leaves where a surface pinches) then flies off in the
// linearised step. The element tangent holds it: the block sags under gravity without a diverged
// step, and the apex stays by its base.
TEST(Continuum, LightNodeOnASliverStaysStable) {
  const double s = 0.003;
  // (quality, flutter guard): edge springs alone; the element tangent by shape; by flutter alone.
  for (const auto& [quality, guard] : {std::pair(0.0, false), {0.3, false}, {0.0, true}}) {
    SphereModel<double> m = continuum_block({3, 3, 2}, s, soft(0.45));
    // Three top nodes around a corner and an apex 0.05 s above their centroid: quality ~0.05.
    Index a = -1, b = -1, c = -1;
    for (Index i = 0; i < m.num_nodes(); ++i) {
      const V3 x = m.rest_positions().row(i).transpose();
      if (std::abs(x.z() - 2 * s) > 1e-9) continue;
      if ((x - V3(s, s, 2 * s)).norm() < 1e-9) a = i;
      if ((x - V3(2 * s, s, 2 * s)).norm() < 1e-9) b = i;
      if ((x - V3(s, 2 * s, 2 * s)).norm() < 1e-9) c = i;
    }
    for (Index i = 0; i < m.num_nodes(); ++i)
      if (std::abs(m.rest_positions()(i, 2)) < 1e-9) m.set_fixed(i);
    ASSERT_TRUE(a >= 0 && b >= 0 && c >= 0);
    const V3 centroid =
        (m.rest_positions().row(a) + m.rest_positions().row(b) + m.rest_positions().row(c))
            .transpose() /
        3.0;
    const Index d = m.add_node(centroid + V3(0, 0, 0.05 * s), 0.0005, 1e-8, 0);
    m.add_tetrahedron(a, b, c, d);
    Simulation<double>::Options o;
    o.forces.element_tangent_quality = quality;
    o.forces.flutter_guard = guard;
    Simulation<double> sim(m, o);
    int diverged = 0;
    for (int k = 0; k < 300; ++k) diverged += !sim.step(1e-3).advanced();
    {  // The energy check's kept forces change nothing here either (flutter, rejected steps).
      o.forces.reuse_end_forces = false;
      Simulation<double> plain(m, o);
      for (int k = 0; k < 300; ++k) (void)plain.step(1e-3);
      EXPECT_EQ((plain.model().positions() - sim.model().positions()).cwiseAbs().maxCoeff(), 0.0);
      EXPECT_EQ(plain.forces().continuum_fluttered_elements(),
                sim.forces().continuum_fluttered_elements());
    }
    const double lift = sim.model().positions()(d, 2) - sim.model().positions()(a, 2);
    std::printf(
        "quality %.1f, flutter guard %d: %d of 300 steps diverged, lift %.3g mm, %d "
        "elements found fluttering\n",
        quality, int(guard), diverged, lift * 1e3,
        int(sim.forces().continuum_fluttered_elements()));
    if (quality > 0 || guard) {
      EXPECT_EQ(diverged, 0);
      EXPECT_TRUE(sim.model().positions().allFinite());
      EXPECT_LT(std::abs(lift), s) << "the apex left its base";
    } else {
      // The negative control: edge springs alone lose the apex.
      EXPECT_TRUE(diverged > 0 || std::abs(lift) > s) << "edge springs held the sliver";
    }
  }
}

// The energy check at the end of an implicit step evaluates the elements' forces at the end state
// and the next step reuses them (ForceModel::Options::reuse_end_forces): the same run to the last
// bit as evaluating both, through what invalidates the kept forces (an edit of the state between
// steps, a region falling asleep and waking, a cut), and the reuse does happen.
TEST(Continuum, EndOfStepForcesAreReusedExactly) {
  // A block fixed at its base, with the reuse on or off.
  auto simulation = [](Eigen::Vector3i cells, bool reuse) {
    SphereModel<double> m = continuum_block(cells, 0.003);
    fix_below(m, 2);
    Simulation<double>::Options o;
    o.forces.reuse_end_forces = reuse;
    return Simulation<double>(m, o);
  };
  auto run = [&](bool reuse, std::vector<StepReport<double>>& reports,
                 std::vector<Positions<double>>& states) {
    Simulation<double> sim = simulation({4, 3, 3}, reuse);
    const Index top = sim.model().num_nodes() - 1;
    bool slept = false;
    for (int k = 0; k < 240; ++k) {
      if (k == 20) sim.model().velocities().row(top) += V3(0.05, 0, 0).transpose();  // an edit
      if (k == 40) {  // a cut through the middle
        Blade<double> b;
        b.start_a = V3(0.006, -0.001, 0.01);
        b.start_b = V3(0.006, 0.01, 0.01);
        b.end_a = V3(0.006, -0.001, 0.004);
        b.end_b = V3(0.006, 0.01, 0.004);
        EXPECT_TRUE(sim.cut(b).any());
      }
      if (k == 80) {  // then it may sleep, and a load wakes it
        SleepPolicy<double> p;
        p.enabled = true;
        p.sleep_speed = 2e-3;
        p.sleep_time = 0.02;
        sim.set_sleep_policy(p);
      }
      if (k == 200) sim.external_forces().row(top) = V3(0, 0, -0.02).transpose();
      reports.push_back(sim.step(1e-3));
      states.push_back(sim.model().positions());
      slept = slept || sim.asleep(0);
    }
    EXPECT_TRUE(slept) << "the block never fell asleep: the test misses that case";
    // The last step's check kept its forces (with the reuse on).
    EXPECT_EQ(sim.forces().kept_inverted_elements() >= 0, reuse);
    return sim.forces().kept_forces_reused();
  };
  std::vector<StepReport<double>> ra, rb;
  std::vector<Positions<double>> xa, xb;
  const std::uint64_t reused = run(true, ra, xa);
  EXPECT_EQ(run(false, rb, xb), 0u);
  // Reused wherever the state was the checked one: not after the edit, the cut, or sleep.
  EXPECT_GT(reused, 150u);
  EXPECT_LT(reused, 239u);
  ASSERT_EQ(ra.size(), rb.size());
  for (std::size_t k = 0; k < ra.size(); ++k) {
    ASSERT_EQ(ra[k].status, rb[k].status) << "step " << k;
    EXPECT_EQ(ra[k].solver_iterations, rb[k].solver_iterations) << "step " << k;
    EXPECT_EQ(ra[k].inverted_elements, rb[k].inverted_elements) << "step " << k;
    if (std::isnan(ra[k].energy)) {
      EXPECT_TRUE(std::isnan(rb[k].energy)) << "step " << k;
    } else {
      EXPECT_EQ(ra[k].energy, rb[k].energy) << "step " << k;
    }
    ASSERT_EQ((xa[k] - xb[k]).cwiseAbs().maxCoeff(), 0.0) << "step " << k;
  }
  // A direct solver evaluates its own forces: nothing is kept for it, and nothing changes.
  std::vector<Positions<double>> direct;
  for (const bool reuse : {true, false}) {
    Simulation<double> sim = simulation({2, 2, 2}, reuse);
    ImplicitEulerIntegrator<double>::Options io;
    io.solver = ImplicitEulerIntegrator<double>::Solver::eigen_ldlt;
    sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
    for (int k = 0; k < 10; ++k) ASSERT_TRUE(sim.step(1e-3).advanced());
    EXPECT_EQ(sim.forces().kept_forces_reused(), 0u);
    EXPECT_EQ(sim.forces().kept_inverted_elements(), -1) << "a check kept forces no step uses";
    direct.push_back(sim.model().positions());
  }
  EXPECT_EQ((direct[0] - direct[1]).cwiseAbs().maxCoeff(), 0.0);
}

// An element strained past element_tangent_strain (0.5) gets the element tangent for the step, and
// a well-shaped one at rest or moderately strained does not.
TEST(Continuum, StrainedElementsGetTheElementTangent) {
  SphereModel<double> m = continuum_block({2, 2, 2}, 0.005);
  ForceModel<double> f = no_gravity(m);
  Positions<double> F(m.num_nodes(), 3);
  const Positions<double> zero = Positions<double>::Zero(m.num_nodes(), 3);
  f.evaluate(m, m.positions(), zero, F);
  EXPECT_EQ(f.continuum_element_tangents(), 0);
  // An isochoric stretch of 2 (I1bar - 3 = 2): every element; of 1.3 (0.23): none; a volume
  // change of 2.5 (|J - 1| = 1.5): every element.
  auto isochoric = [](double l) {
    M3 G = M3::Identity() / std::sqrt(l);
    G(0, 0) = l;
    return G;
  };
  f.evaluate(m, affine(m, isochoric(2.0)), zero, F);
  EXPECT_EQ(f.continuum_element_tangents(), m.num_tetrahedra());
  f.evaluate(m, affine(m, M3(std::cbrt(2.5) * M3::Identity())), zero, F);
  EXPECT_EQ(f.continuum_element_tangents(), m.num_tetrahedra());
  f.evaluate(m, affine(m, isochoric(1.3)), zero, F);
  EXPECT_EQ(f.continuum_element_tangents(), 0);
}

// The flutter guard (ContinuumTerm::flutter_change): an element whose J swings back and forth by
// more than 0.1 % over three implicit steps (two reversals) keeps the element tangent; a steady
// change, a small swing, a re-solve of the same step and a guard that is off mark nothing.
TEST(Continuum, FlutteringElementsGetTheElementTangent) {
  const SphereModel<double> rest = continuum_block({2, 2, 2}, 0.005);
  // The block's force model, without gravity, and an implicit step's buffers for it.
  struct Prepared {
    static ForceModel<double>::Options options(bool guard) {
      ForceModel<double>::Options o;
      o.gravity.setZero();
      o.flutter_guard = guard;
      return o;
    }
    Prepared(const SphereModel<double>& m, bool guard)
        : f(m, options(guard)),
          blocks(std::size_t(ForceModel<double>::implicit_block_size) * std::size_t(m.num_links())),
          rhs(m.num_nodes(), 3),
          diag(m.num_nodes(), 3) {}
    void prepare(const SphereModel<double>& m, bool resolve = false) {
      f.prepare_implicit(m, 1e-3, JacobianForm::definite, blocks.data(), rhs, diag, resolve);
    }
    ForceModel<double> f;
    std::vector<double> blocks;
    Positions<double> rhs, diag;
  };
  auto run = [&](const std::vector<double>& js, bool guard, int passes = 1) {
    SphereModel<double> m = rest;
    Prepared p(m, guard);
    for (const double j : js) {
      m.positions() = affine(m, M3(std::cbrt(j) * M3::Identity()));
      for (int pass = 0; pass < passes; ++pass) p.prepare(m, pass > 0);
    }
    return std::pair{p.f.continuum_fluttered_elements(), p.f.continuum_element_tangents()};
  };
  const Index all = rest.num_tetrahedra();
  EXPECT_EQ(run({1.0, 1.01, 1.0}, true).first, 0) << "one reversal is a bounce, not flutter";
  EXPECT_EQ(run({1.0, 1.01, 1.0, 1.01}, true), std::pair(all, all));
  EXPECT_EQ(run({1.0, 1.01, 1.0, 1.01}, true, 2), std::pair(all, all)) << "re-solves";
  EXPECT_EQ(run({1.0, 1.01, 1.02, 1.03, 1.04}, true).first, 0) << "a steady change";
  EXPECT_EQ(run({1.0, 1.0005, 1.0, 1.0005, 1.0}, true).first, 0) << "a swing below 0.1 %";
  EXPECT_EQ(run({1.0, 1.01, 1.0, 1.01, 1.0}, false), std::pair(Index(0), Index(0)));
  // Marked elements keep the element tangent when the swing stops.
  EXPECT_EQ(run({1.0, 1.01, 1.0, 1.01, 1.01, 1.01}, true), std::pair(all, all));
  // The energy check's kept forces (elastic_energy_keeping_forces) watch their state only if it
  // starts a step: kept and used, each state counts once; kept at a state that is then dropped
  // (a rejected step, an edit), it leaves no trace.
  auto kept = [&](const std::vector<double>& js, bool use) {
    SphereModel<double> m = rest;
    Prepared p(m, true);
    for (const double j : js) {
      m.positions() = affine(m, M3(std::cbrt(j) * M3::Identity()));
      (void)p.f.elastic_energy_keeping_forces(m);
      p.f.reuse_kept_forces(use);
      if (!use) m.positions() = rest.positions();  // rolled back to J = 1
      p.prepare(m);
    }
    return std::pair{p.f.continuum_fluttered_elements(), p.f.kept_forces_reused()};
  };
  EXPECT_EQ(kept({1.0, 1.01, 1.0, 1.01}, true), std::pair(all, std::uint64_t(4)));
  EXPECT_EQ(kept({1.01, 1.01, 1.01, 1.01, 1.01}, false), std::pair(Index(0), std::uint64_t(0)))
      << "the rejected states were watched";
}

// --- Smoothed strains (StrainSmoothing, docs/physics.md section 11) ---

ForceModel<double> smoothed(const SphereModel<double>& m, StrainSmoothing s, double share) {
  ForceModel<double>::Options o;
  o.gravity.setZero();
  o.strain_smoothing = s;
  o.smoothing_element_share = share;
  return ForceModel<double>(m, o);
}

// The smoothed law's energy written independently of the library: each element's F; per face,
// edge or node of the mesh the rest-volume average of the F of the intact elements there, on a
// domain of 1/4, 1/6 or 1/4 of their volume; the element's own F for the remaining share; the
// nodal volumetric part as in the element law.
double textbook_smoothed_energy(const SphereModel<double>& m, const Positions<double>& x,
                                StrainSmoothing s, double share) {
  const Material<double>& mat = m.region(0).material;
  const double mu = mat.youngs_modulus / (2 * (1 + mat.poisson_ratio));
  const double K = mat.youngs_modulus / (3 * (1 - 2 * mat.poisson_ratio));
  auto W = [&](const M3& F) {
    return mu / 2 * ((F.transpose() * F).trace() * std::pow(F.determinant(), -2.0 / 3.0) - 3);
  };
  const auto T = m.tetrahedra();
  const auto X = m.rest_positions();
  const auto intact = m.tetrahedron_intact();
  std::map<std::vector<Index>, std::pair<M3, double>> domains;  // key -> (sum V F, sum V)
  std::map<Index, std::pair<double, double>> nodal;             // node -> (v, V)
  double e = 0;
  for (Index t = 0; t < m.num_tetrahedra(); ++t) {
    if (!intact[t]) continue;
    M3 Dm, Ds;
    for (int k = 0; k < 3; ++k) {
      Dm.col(k) = (X.row(T(t, k + 1)) - X.row(T(t, 0))).transpose();
      Ds.col(k) = (x.row(T(t, k + 1)) - x.row(T(t, 0))).transpose();
    }
    const double V = Dm.determinant() / 6;
    const M3 F = Ds * Dm.inverse();
    e += share * V * W(F);
    std::vector<std::vector<Index>> keys;
    const Index id[4] = {T(t, 0), T(t, 1), T(t, 2), T(t, 3)};
    for (int a = 0; a < 4; ++a) {
      nodal[id[a]].first += Ds.determinant() / 24;
      nodal[id[a]].second += V / 4;
      if (s == StrainSmoothing::node) keys.push_back({id[a]});
      for (int b = a + 1; b < 4; ++b) {
        if (s == StrainSmoothing::edge) keys.push_back({id[a], id[b]});
        for (int c = b + 1; c < 4; ++c)
          if (s == StrainSmoothing::face) keys.push_back({id[a], id[b], id[c]});
      }
    }
    for (auto& k : keys) std::sort(k.begin(), k.end());
    for (auto& k : keys) {
      auto& d = domains.try_emplace(k, M3::Zero(), 0.0).first->second;
      d.first += V * F;
      d.second += V;
    }
  }
  const double fraction = s == StrainSmoothing::edge ? 1.0 / 6 : 1.0 / 4;
  for (const auto& [key, d] : domains)
    e += (1 - share) * fraction * d.second * W(d.first / d.second);
  for (const auto& [a, vV] : nodal) e += K / 2 * vV.second * std::pow(vV.first / vV.second - 1, 2);
  return e;
}

// Each smoothing, with and without the element's share: the energy equals the independent one and
// the forces are minus its gradient, on a randomly deformed mesh and after a cut.
TEST(Continuum, SmoothedStrainsMatchAnIndependentReference) {
  for (const StrainSmoothing s :
       {StrainSmoothing::face, StrainSmoothing::edge, StrainSmoothing::node}) {
    for (const double share : {0.0, 0.1}) {
      for (const bool cut : {false, true}) {
        std::mt19937 rng(21);
        SphereModel<double> m = random_model<double>(rng, {2, 2, 1}, 0.2);
        m.set_region_law(0, ForceLaw::continuum);
        m.velocities().setZero();
        if (cut)  // two elements out: their neighbours' domains lose them
          for (const Index t : {Index(1), Index(5)}) m.tetrahedron_intact()[t] = 0;
        ForceModel<double> f = smoothed(m, s, share);
        f.update_topology(m);
        const Positions<double> x = m.positions();
        const std::string what =
            std::string(to_string(s)) + " share " + std::to_string(share) + +(cut ? " cut" : "");
        const double e = textbook_smoothed_energy(m, x, s, share);
        ASSERT_GT(e, 0) << what;
        EXPECT_TRUE(near(f.elastic_energy(m, x), e, 1e-10)) << what;
        Positions<double> g(m.num_nodes(), 3);
        f.evaluate(m, x, m.velocities(), g);
        const double scale = g.cwiseAbs().maxCoeff();
        double worst = 0;
        for (Index i = 0; i < m.num_nodes(); ++i)
          for (int c = 0; c < 3; ++c) {
            Positions<double> xp = x, xm = x;
            xp(i, c) += 1e-9;
            xm(i, c) -= 1e-9;
            const double fd = -(textbook_smoothed_energy(m, xp, s, share) -
                                textbook_smoothed_energy(m, xm, s, share)) /
                              2e-9;
            worst = std::max(worst, std::abs(fd - g(i, c)));
          }
        EXPECT_LT(worst, 1e-6 * scale) << what;
        // It is not the element law's energy (the test would not see a smoothing left out).
        ForceModel<double> plain = no_gravity(m);
        plain.update_topology(m);
        EXPECT_GT(std::abs(plain.elastic_energy(m, x) - e), 1e-3 * e) << what;
      }
    }
  }
}

// The smoothed strains keep the law's invariants: forces sum to zero with no torque, a rigid
// rotation costs nothing, and a homogeneous strain is reproduced exactly (every domain's average
// of equal F is that F): E and mu come back and the interior nodes are in equilibrium.
TEST(Continuum, SmoothedStrainsBalanceAndPassThePatchTest) {
  for (const StrainSmoothing s :
       {StrainSmoothing::face, StrainSmoothing::edge, StrainSmoothing::node}) {
    std::mt19937 rng(11);
    SphereModel<double> m = random_model<double>(rng, {3, 2, 2}, 0.2);
    m.set_region_law(0, ForceLaw::continuum);
    ForceModel<double> f = smoothed(m, s, 0.1);
    Positions<double> g(m.num_nodes(), 3);
    f.evaluate(m, m.positions(), m.velocities(), g);
    const double scale = g.cwiseAbs().maxCoeff();
    ASSERT_GT(scale, 0);
    EXPECT_LT(g.colwise().sum().norm(), 1e-10 * scale * double(m.num_nodes())) << to_string(s);
    V3 torque = V3::Zero();
    for (Index i = 0; i < m.num_nodes(); ++i)
      torque += m.positions().row(i).transpose().cross(g.row(i).transpose());
    EXPECT_LT(torque.norm(), 1e-10 * scale * 0.03 * double(m.num_nodes())) << to_string(s);
    const M3 R = Eigen::AngleAxisd(0.7, V3(1, 2, 3).normalized()).toRotationMatrix();
    f.evaluate(m, affine(m, R), Positions<double>::Zero(m.num_nodes(), 3), g);
    EXPECT_LT(g.cwiseAbs().maxCoeff(), 1e-9 * scale) << to_string(s);

    const Material<double> mat = soft(0.45);
    SphereModel<double> b = continuum_block({4, 4, 4}, 0.0025, mat);
    ForceModel<double> fb = smoothed(b, s, 0.1);
    const double V = block_volume(b), E = mat.youngs_modulus, eps = 1e-4, nu = 0.45;
    const M3 uni = V3(1 + eps, 1 - nu * eps, 1 - nu * eps).asDiagonal();
    EXPECT_TRUE(near(fb.elastic_energy(b, affine(b, uni)) / V, 0.5 * E * eps * eps, 2e-3));
    M3 shear = M3::Identity();
    shear(0, 1) = eps;
    EXPECT_TRUE(near(fb.elastic_energy(b, affine(b, shear)) / V,
                     0.5 * mat.shear_modulus() * eps * eps, 2e-3));
    Positions<double> gb(b.num_nodes(), 3);
    fb.evaluate(b, affine(b, uni), Positions<double>::Zero(b.num_nodes(), 3), gb);
    const double face = gb.cwiseAbs().maxCoeff();
    for (Index i = 0; i < b.num_nodes(); ++i) {
      const V3 p = b.rest_positions().row(i).transpose();
      if ((p.array() > 1e-9).all() && (p.array() < 0.01 - 1e-9).all()) {
        EXPECT_LT(gb.row(i).norm(), 1e-9 * face) << to_string(s) << " " << i;
      }
    }
  }
}

// The option is checked: a share outside [0, 1] is an fsm::Error at set_options(), never in a
// step.
TEST(Continuum, SmoothingShareIsChecked) {
  SphereModel<double> m = continuum_block({1, 1, 1}, 0.005);
  ForceModel<double> f = no_gravity(m);
  ForceModel<double>::Options o = f.options();
  o.strain_smoothing = StrainSmoothing::node;
  for (const double bad : {-0.1, 1.5, std::nan("")}) {
    o.smoothing_element_share = bad;
    EXPECT_THROW(f.set_options(o), Error) << bad;
  }
}

}  // namespace
}  // namespace fsm::test
