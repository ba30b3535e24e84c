// Spectral bounds: exact for the two-sphere oscillator, and never below the true highest
// eigenfrequency of a random model (checked against a dense eigensolver).

#include <random>

#include "common.hpp"

namespace fsm::test {
namespace {

TEST(SpectralBound, ExactForTwoEqualSpheres) {
  const double m = 0.001, k = 500, kd = 0.05;
  const auto b = spectral_bound(two_spheres(m, k, kd));
  EXPECT_TRUE(near(b.omega_max, std::sqrt(2 * k / m), 1e-14));
  EXPECT_TRUE(near(b.damping_max, 2 * kd / m, 1e-14));
  EXPECT_TRUE(near(b.retardation_min, kd / k, 1e-14));
  // A fixed partner: the free sphere alone on a spring, omega^2 = k / m.
  SphereModel<double> fixed = two_spheres(m, k, kd);
  fixed.set_fixed(0);
  EXPECT_TRUE(near(spectral_bound(fixed).omega_max, std::sqrt(k / m), 1e-14));
}

// The bound must hold (it sets the explicit schemes' step). Block Gershgorin is loose by the
// spread of masses and directions: about 1.6 in omega^2 on these jittered lattices with masses
// varying by 2x; more than 2.5 would mean a wrong block norm.
TEST(SpectralBound, BoundsTheTrueHighestFrequencyOfRandomModels) {
  std::mt19937 rng(21);
  for (int trial = 0; trial < 5; ++trial) {
    SphereModel<double> model = random_model<double>(rng, {3, 3, 2}, 0.3, trial % 2 == 1);
    model.reset_to_rest();
    if (trial > 2) model.set_fixed(0);
    // The bound covers the stiffest regime of bilinear links, so compare with that regime.
    SphereModel<double> stiffest = model;
    stiffest.stiffness() = model.stiffness().cwiseMax(model.large_stiffness());
    stiffest.switch_strain().setConstant(std::numeric_limits<double>::infinity());
    const ForceModel<double> forces = no_gravity(stiffest);
    const Index n = model.num_nodes();
    // Rest stiffness: -dF/dx at rest (no pre-stress, so all forms agree).
    const Eigen::MatrixXd K =
        -Eigen::MatrixXd(forces.stiffness_matrix(stiffest, JacobianForm::exact));
    Eigen::VectorXd w(3 * n);
    for (Index i = 0; i < n; ++i)
      w.segment<3>(3 * i).setConstant(model.fixed()[i] ? 0.0 : 1.0 / std::sqrt(model.masses()[i]));
    const Eigen::MatrixXd A = w.asDiagonal() * K * w.asDiagonal();
    const double lmax = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A).eigenvalues().maxCoeff();
    const auto b = spectral_bound(model);
    EXPECT_GE(b.omega_max * b.omega_max, lmax * (1 - 1e-12));
    EXPECT_LE(b.omega_max * b.omega_max, 2.5 * lmax);
    RecordProperty("omega2_bound_over_true", std::to_string(b.omega_max * b.omega_max / lmax));
  }
}

TEST(StabilityLimits, ClosedFormsAtKnownPoints) {
  using SB = SpectralBound<double>;
  EXPECT_TRUE(near(symplectic_euler_limit(SB::oscillator(1000, 0)), 2e-3, 1e-14));
  EXPECT_EQ(improved_euler_limit(SB::oscillator(1000, 0)), 0.0);
  EXPECT_EQ(heun_limit(SB::oscillator(1000, 0)), 0.0);
  // Improved Euler: min(2c/w^2, 2/c).
  EXPECT_TRUE(near(improved_euler_limit(SB::oscillator(1000, 200)), 4e-4, 1e-14));
  EXPECT_TRUE(near(improved_euler_limit(SB::oscillator(1000, 1600)), 2.0 / 1600, 1e-14));
  // Heun on an overdamped real eigenvalue -a: |1 - ah + (ah)^2/2| <= 1 iff ah <= 2.
  const double c = 1e5, w = 10;  // eigenvalues ~ -c and -w^2/c
  EXPECT_TRUE(
      near(heun_limit(SB::oscillator(w, c)), 2.0 / (c / 2 + std::sqrt(c * c / 4 - w * w)), 1e-6));
}

}  // namespace
}  // namespace fsm::test
