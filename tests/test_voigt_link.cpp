// VoigtLink: the sign and direction of the force, energy consistency, the bilinear law, and the
// Jacobians against central finite differences.

#include <random>

#include "common.hpp"

namespace fsm::test {
namespace {

using V3 = Vector3<double>;

TEST(VoigtLink, StretchedLinkPullsTogetherCompressedPushesApart) {
  const auto law = VoigtLink<double>::linear(0.01, 100.0, 0.0);
  const V3 xi(0, 0, 0), vi = V3::Zero();
  // Stretched along +x: the force on i points toward j (+x).
  const V3 f_stretch = law.force(xi, V3(0.012, 0, 0), vi, V3::Zero());
  EXPECT_GT(f_stretch.x(), 0);
  EXPECT_TRUE(near(f_stretch.x(), 100.0 * 0.002, 1e-12));
  // Compressed: pushes i away from j (-x).
  const V3 f_comp = law.force(xi, V3(0.008, 0, 0), vi, V3::Zero());
  EXPECT_LT(f_comp.x(), 0);
  EXPECT_TRUE(near(f_comp.x(), -100.0 * 0.002, 1e-12));
}

TEST(VoigtLink, DashpotResistsSeparationAndIgnoresRotationAlongLink) {
  const auto law = VoigtLink<double>::linear(0.01, 100.0, 2.0);
  const V3 xi(0, 0, 0), xj(0.01, 0, 0);
  // j moving away at 0.1 m/s: the dashpot pulls i along (+x) with k_d * 0.1.
  EXPECT_TRUE(near(law.force(xi, xj, V3::Zero(), V3(0.1, 0, 0)).x(), 0.2, 1e-12));
  // Relative velocity across the link (rigid rotation): no force along the link model...
  EXPECT_TRUE(matrices_near(law.force(xi, xj, V3::Zero(), V3(0, 0.1, 0)), V3::Zero(), 1e-15));
  // ...but the paper's full relative-velocity damping does resist it.
  const V3 f = law.force(xi, xj, V3::Zero(), V3(0, 0.1, 0), DampingModel::full_relative_velocity);
  EXPECT_TRUE(near(f.y(), 0.2, 1e-12));
}

TEST(VoigtLink, ForceIsAlongTheLinkForTheDefaultModel) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto law = VoigtLink<double>::linear(0.01, 150.0, 1.5);
  for (int k = 0; k < 100; ++k) {
    const V3 xi(u(rng), u(rng), u(rng)), xj = xi + 0.012 * V3(u(rng), u(rng), u(rng));
    const V3 f =
        law.force(xi * 0.01, xj * 0.01, V3(u(rng), u(rng), u(rng)), V3(u(rng), u(rng), u(rng)));
    const V3 d = (xj - xi).normalized();
    EXPECT_LT(f.cross(d).norm(), 1e-12 * std::max(1.0, f.norm()));
  }
}

TEST(VoigtLink, CoincidentSpheresGiveZeroForceNotNaN) {
  const auto law = VoigtLink<double>::linear(0.01, 100.0, 1.0);
  const V3 x(0.1, 0.2, 0.3);
  const V3 f = law.force(x, x, V3(1, 0, 0), V3::Zero());
  EXPECT_TRUE(f.allFinite());
  EXPECT_EQ(f.norm(), 0.0);
  const auto J = law.jacobian(x, x, V3::Zero(), V3::Zero());
  EXPECT_TRUE(J.dx.allFinite() && J.dv.allFinite());
}

TEST(VoigtLink, BilinearLawIsContinuousAndSwitchesSlope) {
  const double l0 = 0.01, ks = 100, kl = 520, es = 0.1;
  const auto law = VoigtLink<double>::bilinear(l0, ks, 0.0, kl, es);
  const double s = es * l0;
  EXPECT_TRUE(near(law.elastic_force(s * (1 - 1e-9)), law.elastic_force(s * (1 + 1e-9)), 1e-7));
  EXPECT_TRUE(near(law.elastic_force(0.5 * s), ks * 0.5 * s, 1e-14));
  EXPECT_TRUE(near(law.elastic_force(2 * s), ks * s + kl * s, 1e-14));
  EXPECT_TRUE(near(law.elastic_force(-2 * s), -(ks * s + kl * s), 1e-14));  // symmetric
  EXPECT_EQ(law.tangent_stiffness(0.5 * s), ks);
  EXPECT_EQ(law.tangent_stiffness(-3 * s), kl);
}

TEST(VoigtLink, EnergyIsTheIntegralOfTheElasticForce) {
  for (const auto& law : {VoigtLink<double>::linear(0.01, 100, 0),
                          VoigtLink<double>::bilinear(0.01, 100, 0, 700, 0.05)}) {
    for (double e : {-0.004, -0.0007, -0.0001, 0.0002, 0.0006, 0.003}) {
      const double h = 1e-7;
      const double dE = (law.energy(e + h) - law.energy(e - h)) / (2 * h);
      EXPECT_TRUE(near(dE, law.elastic_force(e), 1e-6)) << "extension " << e;
    }
  }
}

// Jacobians against central differences of force() for random states, both damping models, both
// regimes of the bilinear law.
class VoigtJacobian : public ::testing::TestWithParam<DampingModel> {};

TEST_P(VoigtJacobian, MatchesFiniteDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  const DampingModel model = GetParam();
  for (int k = 0; k < 50; ++k) {
    const double l0 = 0.01;
    const auto law = (k % 2) ? VoigtLink<double>::linear(l0, 120.0, 0.7)
                             : VoigtLink<double>::bilinear(l0, 120.0, 0.7, 600.0, 0.05);
    const V3 xi = 0.01 * V3(u(rng), u(rng), u(rng));
    // Lengths from 0.6 l0 to 1.4 l0, away from the switch at 0.95 and 1.05 l0.
    double scale = 1.0 + 0.4 * u(rng);
    if (std::abs(std::abs(scale - 1.0) - 0.05) < 0.01) scale += 0.03;
    const V3 xj = xi + scale * l0 * V3(u(rng), u(rng), u(rng)).normalized();
    const V3 vi(u(rng), u(rng), u(rng)), vj(u(rng), u(rng), u(rng));
    const auto J = law.jacobian(xi, xj, vi, vj, model);
    Matrix3<double> dx, dv;
    const double hx = 1e-8, hv = 1e-6;
    for (int c = 0; c < 3; ++c) {
      V3 e = V3::Zero();
      e[c] = hx;
      dx.col(c) =
          (law.force(xi, xj + e, vi, vj, model) - law.force(xi, xj - e, vi, vj, model)) / (2 * hx);
      e[c] = hv;
      dv.col(c) =
          (law.force(xi, xj, vi, vj + e, model) - law.force(xi, xj, vi, vj - e, model)) / (2 * hv);
      // d/dx_i is the negative: the force depends on x_j - x_i only.
      e[c] = hx;
      const V3 dxi =
          (law.force(xi + e, xj, vi, vj, model) - law.force(xi - e, xj, vi, vj, model)) / (2 * hx);
      EXPECT_TRUE(matrices_near(dxi, (-J.dx.col(c)).eval(), 1e-5));
    }
    EXPECT_TRUE(matrices_near(J.dx, dx, 1e-5)) << "case " << k;
    EXPECT_TRUE(matrices_near(J.dv, dv, 1e-7)) << "case " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(BothDampingModels, VoigtJacobian,
                         ::testing::Values(DampingModel::along_link,
                                           DampingModel::full_relative_velocity));

}  // namespace
}  // namespace fsm::test
