// VolumeTerm: forces are the exact negative gradient of the energy, equal and opposite (no net
// force or torque), zero at rest; it adds exactly kappa to the bulk modulus and nothing to shear;
// its frequency bound bounds the true highest frequency; bad input is refused.

#include <random>

#include "common.hpp"
#include "fsm/volume_term.hpp"

namespace fsm::test {
namespace {

TetrahedralMesh<double> jittered_lattice(std::mt19937& rng, double jitter = 0.25) {
  const double h = 0.01;
  auto mesh = make_cube_lattice(Vector3<double>::Zero().eval(), Eigen::Vector3i(2, 2, 2), h);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Index i = 0; i < mesh.vertices.rows(); ++i)
    for (int c = 0; c < 3; ++c) mesh.vertices(i, c) += jitter * h * u(rng);
  return mesh;
}

Positions<double> deformed(std::mt19937& rng, const Positions<double>& rest, double amount) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Positions<double> x = rest;
  for (Index i = 0; i < x.rows(); ++i)
    for (int c = 0; c < 3; ++c) x(i, c) += amount * u(rng);
  return x;
}

TEST(VolumeTerm, ForcesAreTheNegativeGradientOfTheEnergy) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    const auto mesh = jittered_lattice(rng);
    const VolumeTerm<double> term(mesh.tetrahedra, mesh.vertices, 5e4);
    // Large deformation (20 % of the spacing), so the energy is far from quadratic.
    Positions<double> x = deformed(rng, mesh.vertices, 2e-3);
    Positions<double> f = Positions<double>::Zero(x.rows(), 3);
    term.add_forces(x, f);
    Positions<double> fd(x.rows(), 3);
    const double eps = 1e-7;  // m; central differences, error O(eps^2) relative to 1e-2 m
    for (Index i = 0; i < x.rows(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double x0 = x(i, c);
        x(i, c) = x0 + eps;
        const double ep = term.energy(x);
        x(i, c) = x0 - eps;
        const double em = term.energy(x);
        x(i, c) = x0;
        fd(i, c) = -(ep - em) / (2 * eps);
      }
    EXPECT_TRUE(matrices_near(f, fd, 1e-6));
  }
}

TEST(VolumeTerm, NoNetForceOrTorque) {
  std::mt19937 rng(11);
  const auto mesh = jittered_lattice(rng);
  const VolumeTerm<double> term(mesh.tetrahedra, mesh.vertices, 1e5);
  const Positions<double> x = deformed(rng, mesh.vertices, 3e-3);
  Positions<double> f = Positions<double>::Zero(x.rows(), 3);
  term.add_forces(x, f);
  Vector3<double> net = Vector3<double>::Zero(), torque = Vector3<double>::Zero();
  double scale = 0;
  for (Index i = 0; i < x.rows(); ++i) {
    net += f.row(i).transpose();
    torque += x.row(i).transpose().cross(f.row(i).transpose());
    scale += f.row(i).norm();
  }
  ASSERT_GT(scale, 0.0);  // the deformation changes volumes, so there are forces to cancel
  EXPECT_LT(net.norm(), 1e-12 * scale);
  EXPECT_LT(torque.norm(), 1e-12 * scale * 0.05);  // lever arms are at most ~0.05 m
}

TEST(VolumeTerm, ZeroAtRestAndUnderRigidMotion) {
  std::mt19937 rng(3);
  const auto mesh = jittered_lattice(rng);
  const VolumeTerm<double> term(mesh.tetrahedra, mesh.vertices, 1e5);
  Positions<double> f = Positions<double>::Zero(mesh.vertices.rows(), 3);
  term.add_forces(mesh.vertices, f);
  EXPECT_EQ(f.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(term.energy(mesh.vertices), 0.0);
  // A rotation by 0.7 rad about a tilted axis plus a translation keeps every volume.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  Positions<double> x = (mesh.vertices * R.transpose()).rowwise() + Eigen::RowVector3d(1, -2, 3);
  f.setZero();
  term.add_forces(x, f);
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-9);  // N; rounding of volumes ~1e-6 m^3 at 1e5 Pa
  EXPECT_LT(term.energy(x), 1e-15);
}

TEST(VolumeTerm, AddsExactlyKappaToTheBulkModulusAndNothingToShear) {
  std::mt19937 rng(5);
  const auto mesh = jittered_lattice(rng, 0.3);
  const double kappa = 2e4, eps = 1e-4;
  const VolumeTerm<double> term(mesh.tetrahedra, mesh.vertices, kappa);
  const double V = mesh.volume();
  // Uniform dilation: energy (9/2) kappa V eps^2 to first order (relative error ~ eps).
  const Positions<double> dil = mesh.vertices * (1 + eps);
  EXPECT_TRUE(near(term.energy(dil), 4.5 * kappa * V * eps * eps, 1e-3));
  // Simple shear keeps every volume exactly.
  Positions<double> sh = mesh.vertices;
  sh.col(0) += 0.05 * mesh.vertices.col(1);
  EXPECT_LT(term.energy(sh), 1e-12 * 4.5 * kappa * V * eps * eps);
}

TEST(VolumeTerm, BulkModulusForPoissonsRatio) {
  const double E = 13150;
  EXPECT_EQ(VolumeTerm<double>::bulk_modulus_for(E, 0.25), 0.0);
  // nu = 0.45 with mu = 2E/5: K = 2 mu (1 + nu) / (3 (1 - 2 nu)) = 2 * 0.4 * 1.45 / 0.3 E.
  EXPECT_TRUE(near(VolumeTerm<double>::bulk_modulus_for(E, 0.45),
                   (2 * 0.4 * 1.45 / 0.3 - 2.0 / 3.0) * E, 1e-12));
  EXPECT_THROW((void)VolumeTerm<double>::bulk_modulus_for(E, 0.5), Error);
  EXPECT_THROW((void)VolumeTerm<double>::bulk_modulus_for(E, 0.2), Error);
}

TEST(VolumeTerm, FrequencyBoundIsAbove) {
  std::mt19937 rng(9);
  const auto mesh = jittered_lattice(rng);
  const VolumeTerm<double> term(mesh.tetrahedra, mesh.vertices, 1e5);
  const Index n = Index(mesh.vertices.rows());
  std::uniform_real_distribution<double> u(0.5, 1.5);
  ScalarArray<double> m(n);
  for (Index i = 0; i < n; ++i) m[i] = 1e-4 * u(rng);
  Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1> fixed = decltype(fixed)::Zero(n);
  fixed[0] = 1;
  // Dense Hessian by differences of the forces at rest (the term is exactly quadratic there to
  // first order), mass-weighted, free nodes only.
  const double eps = 1e-8;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (Index j = 0; j < n; ++j)
    for (int c = 0; c < 3; ++c) {
      Positions<double> xp = mesh.vertices, xm = mesh.vertices;
      xp(j, c) += eps;
      xm(j, c) -= eps;
      Positions<double> fp = Positions<double>::Zero(n, 3), fm = fp;
      term.add_forces(xp, fp);
      term.add_forces(xm, fm);
      for (Index i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d)
          A(3 * i + d, 3 * j + c) =
              (fixed[i] || fixed[j]) ? 0.0
                                     : -(fp(i, d) - fm(i, d)) / (2 * eps) / std::sqrt(m[i] * m[j]);
    }
  const double w2 = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (A + A.transpose()))
                        .eigenvalues()
                        .maxCoeff();
  const double bound = term.omega_max_squared(m, fixed);
  EXPECT_GE(bound, w2 * (1 - 1e-6));
  EXPECT_LT(bound, 20 * w2);  // a bound that is useful, not just safe
}

TEST(VolumeTerm, RefusesBadInput) {
  std::mt19937 rng(1);
  const auto mesh = jittered_lattice(rng);
  TetrahedronArray bad = mesh.tetrahedra;
  bad(0, 1) = bad(0, 0);
  EXPECT_THROW(VolumeTerm<double>(bad, mesh.vertices, 1e4), Error);
  bad = mesh.tetrahedra;
  bad(0, 2) = Index(mesh.vertices.rows());
  EXPECT_THROW(VolumeTerm<double>(bad, mesh.vertices, 1e4), Error);
  EXPECT_THROW(VolumeTerm<double>(mesh.tetrahedra, mesh.vertices, -1.0), Error);
  Positions<double> flat = mesh.vertices;
  flat.col(2).setZero();
  EXPECT_THROW(VolumeTerm<double>(mesh.tetrahedra, flat, 1e4), Error);
}

TEST(VolumeTerm, FloatAgreesWithDouble) {
  std::mt19937 rng(2);
  const auto mesh = jittered_lattice(rng);
  const VolumeTerm<double> d(mesh.tetrahedra, mesh.vertices, 3e4);
  const Positions<float> restf = mesh.vertices.cast<float>();
  const VolumeTerm<float> s(mesh.tetrahedra, restf, 3e4f);
  const Positions<double> x = deformed(rng, mesh.vertices, 1e-3);
  Positions<double> fd = Positions<double>::Zero(x.rows(), 3);
  Positions<float> fs = Positions<float>::Zero(x.rows(), 3);
  d.add_forces(x, fd);
  s.add_forces(x.cast<float>(), fs);
  EXPECT_TRUE(matrices_near(fs.cast<double>(), fd, 1e-3));  // float rounding of 1e-3 m moves
}

}  // namespace
}  // namespace fsm::test
