// Tetrahedral filling under a metric: the quality measure, the filling's geometry and quality,
// an anisotropic metric honoured exactly, a graded metric honoured in size.

#include <gtest/gtest.h>
#include <algorithm>
#include <cmath>

#include "fsm/builder/fillings.hpp"
#include "fsm/builder/metric_field.hpp"
#include "shapes.hpp"

namespace fsm::build {
namespace {

using V = Eigen::Vector3d;

// The regular tetrahedron inscribed in a cube: edges of length 2 sqrt 2.
const V ra(1, 1, 1), rb(1, -1, -1), rc(-1, 1, -1), rd(-1, -1, 1);

TEST(Quality, RegularTetrahedronIsOneAndScaleInvariant) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  EXPECT_NEAR(tetrahedron_quality(ra, rb, rc, rd, I), 1.0, 1e-12);
  EXPECT_NEAR(tetrahedron_quality(3 * ra, 3 * rb, 3 * rc, 3 * rd, I), 1.0, 1e-12);
  EXPECT_NEAR(tetrahedron_quality(ra, rb, rc, rd, 25 * I), 1.0, 1e-12);  // metric scale too
  EXPECT_NEAR(min_dihedral_angle(ra, rb, rc, rd), std::acos(1.0 / 3.0) * 180 / M_PI, 1e-9);
}

TEST(Quality, WorseShapesScoreHigherAndFlatIsInfinite) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const double squashed = tetrahedron_quality(ra, rb, rc, V(-1, -1, -0.5), I);
  EXPECT_GT(squashed, 1.0);
  EXPECT_GT(tetrahedron_quality(ra, rb, rc, V(-1, -1, -0.9), I), squashed);
  EXPECT_TRUE(std::isinf(tetrahedron_quality(V(0, 0, 0), V(1, 0, 0), V(0, 1, 0), V(1, 1, 0), I)));
}

// Two cells sharing a face are one piece; a cell hanging on it by a vertex only (and one by an
// edge only) is dropped with the vertices only it used, the rest renumbered in order; a second
// piece of comparable volume, joined to nothing, is kept.
TEST(HangingPieces, CellsJoinedByAVertexOrAnEdgeOnlyAreDropped) {
  std::vector<V> points = {V(0, 0, 0), V(1, 0, 0), V(0, 1, 0), V(0, 0, 1), V(1, 1, 1)};
  std::vector<std::array<Index, 4>> tets = {{0, 1, 2, 3}, {1, 2, 3, 4}};  // a face in common
  // By vertex 4 only: a small flat cell (volume 1e-4 of the piece's).
  points.insert(points.end(), {V(1.01, 1, 1), V(1, 1.01, 1), V(1.01, 1.01, 1.0006)});
  tets.push_back({4, 5, 6, 7});
  // By edge 0-1 only.
  points.insert(points.end(), {V(0.5, -0.01, 0), V(0.5, -0.01, -0.01)});
  tets.push_back({0, 1, 8, 9});
  // A separate piece of half the first one's volume.
  points.insert(points.end(), {V(5, 0, 0), V(6, 0, 0), V(5, 1, 0), V(5, 0, 1)});
  tets.push_back({10, 11, 12, 13});
  Index removed = 0;
  double volume = 0;
  detail::drop_hanging_pieces(points, tets, removed, volume);
  EXPECT_EQ(removed, 2);
  EXPECT_GT(volume, 0.0);
  EXPECT_LT(volume, 1e-3);
  ASSERT_EQ(tets.size(), 3u);
  ASSERT_EQ(points.size(), 9u);  // 5 + 4: the hanging cells' own vertices are gone
  EXPECT_EQ(tets[0], (std::array<Index, 4>{0, 1, 2, 3}));
  EXPECT_EQ(tets[1], (std::array<Index, 4>{1, 2, 3, 4}));
  EXPECT_EQ(tets[2], (std::array<Index, 4>{5, 6, 7, 8}));
  EXPECT_TRUE(points[5].isApprox(V(5, 0, 0)));
  // A filling that is one piece is left as it is.
  const auto before = tets;
  detail::drop_hanging_pieces(points, tets, removed, volume);
  EXPECT_EQ(removed, 0);
  EXPECT_EQ(tets, before);
}

// A tetrahedron that is regular after the metric's map is regular in the metric.
TEST(Quality, RegularInTheMetricMeansQOne) {
  const auto metric = anisotropic_metric(V(0.002, 0.004, 0.008), Eigen::Matrix3d::Identity());
  const Eigen::Matrix3d M = metric->metric(V::Zero());
  const Eigen::DiagonalMatrix<double, 3> stretch(0.002, 0.004, 0.008);  // M^-1/2
  EXPECT_NEAR(tetrahedron_quality(stretch * ra, stretch * rb, stretch * rc, stretch * rd, M), 1.0,
              1e-9);
  EXPECT_GT(tetrahedron_quality(ra, rb, rc, rd, M), 2.0);  // regular in space, not in the metric
  EXPECT_NEAR(metric->size(V::Zero()), 0.002, 1e-15);
}

TEST(Metric, BadParametersAreErrors) {
  EXPECT_THROW(isotropic_metric(0.0), Error);
  EXPECT_THROW(anisotropic_metric(V(1, -1, 1), Eigen::Matrix3d::Identity()), Error);
  Eigen::Matrix3d flat = Eigen::Matrix3d::Identity();
  flat.col(2) = flat.col(1);
  EXPECT_THROW(anisotropic_metric(V(1, 1, 1), flat), Error);
  EXPECT_THROW(graded_metric(0.001, 0.002, V(0, 0, 0), 0.0), Error);
  EXPECT_THROW(graded_metric(0.001, 0.002, V(0, 0, 0), 0.01, -0.001), Error);
  EXPECT_THROW(graded_metric(0.001, 0.002, V(0, 0, 0), 0.01, std::nan("")), Error);
}

// The graded size: h_min within the plateau radius of the centre, then linear over the distance,
// h_max beyond (the formula of graded_metric), in every direction; no plateau by default.
TEST(Metric, GradedSizeHasItsPlateauThenGrows) {
  const V c(0.01, -0.02, 0.003);
  const auto plain = graded_metric(0.001, 0.004, c, 0.006);
  const auto plateau = graded_metric(0.001, 0.004, c, 0.006, 0.003);
  for (const V dir : {V(1, 0, 0), V(0, -1, 0), V(1, 1, 1).normalized()}) {
    for (const double r : {0.0, 0.001, 0.003, 0.0045, 0.006, 0.009, 0.02}) {
      const V x = c + r * dir;
      EXPECT_NEAR(plain->size(x), 0.001 + 0.003 * std::min(1.0, r / 0.006), 1e-12) << r;
      EXPECT_NEAR(plateau->size(x), 0.001 + 0.003 * std::clamp((r - 0.003) / 0.006, 0.0, 1.0),
                  1e-12)
          << r;
    }
  }
  EXPECT_NE(plateau->describe().find("within 3 mm"), std::string::npos) << plateau->describe();
  EXPECT_EQ(plain->describe().find("within"), std::string::npos) << plain->describe();
}

// A ball of radius 2 cm with spheres of 5 mm: the filling covers the ball (every tetrahedron's
// circumradius within the size, up to the optimiser's moves), stays inside, and is good quality.
TEST(TetraFilling, IsotropicBall) {
  const double R = 0.02, r = 0.005;
  const auto surface = test::icosphere(R, 4);
  const auto metric = isotropic_metric(r);
  const auto fill = fill_tetrahedral(surface, *metric, "", "ball");
  const auto& m = fill.mesh;
  EXPECT_NO_THROW(m.validate("ball"));
  // Volume: the surface approximation (facet distance r/4) loses a thin shell.
  EXPECT_NEAR(m.volume(), 4.0 / 3.0 * M_PI * R * R * R, 0.06 * 4.0 / 3.0 * M_PI * R * R * R);
  EXPECT_LE(m.vertices.rowwise().norm().maxCoeff(), R * (1 + 1e-6));
  for (Index t = 0; t < m.tetrahedra.rows(); ++t) ASSERT_GT(m.signed_volume(t), 0);
  EXPECT_GT(fill.quality.fraction_q_1_3, 0.9);
  EXPECT_GT(fill.quality.min_dihedral_deg, 5.0);
  // Mean edge about 1.2 r for a circumradius bound of r.
  EXPECT_GT(fill.quality.mean_edge, 0.8 * r);
  EXPECT_LT(fill.quality.mean_edge, 1.8 * r);
  RecordProperty("vertices", std::to_string(m.vertices.rows()));
}

// Sizes (r, r, 3r): the same ball meshed with elements three times longer along z. In the metric
// the elements are isotropic: mean metric length of edges near the z direction equals that of
// edges near the x-y plane, while their physical lengths differ by about 3.
TEST(TetraFilling, ConstantAnisotropicMetricIsHonouredExactly) {
  const double R = 0.02, r = 0.004;
  const auto surface = test::icosphere(R, 4);
  const auto metric = anisotropic_metric(V(r, r, 3 * r), Eigen::Matrix3d::Identity());
  const auto fill = fill_tetrahedral(surface, *metric, "", "ball");
  const Eigen::Matrix3d M = metric->metric(V::Zero());
  double metric_z = 0, metric_xy = 0, phys_z = 0, phys_xy = 0;
  int nz = 0, nxy = 0;
  const auto& m = fill.mesh;
  for (Index t = 0; t < m.tetrahedra.rows(); ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const V e =
            (m.vertices.row(m.tetrahedra(t, a)) - m.vertices.row(m.tetrahedra(t, b))).transpose();
        const double ml = std::sqrt(e.dot(M * e)), c = std::abs(e.normalized().z());
        if (c > 0.9) {
          metric_z += ml;
          phys_z += e.norm();
          ++nz;
        } else if (c < 0.3) {
          metric_xy += ml;
          phys_xy += e.norm();
          ++nxy;
        }
      }
  ASSERT_GT(nz, 50);
  ASSERT_GT(nxy, 50);
  EXPECT_NEAR((metric_z / nz) / (metric_xy / nxy), 1.0, 0.15);
  EXPECT_GT((phys_z / nz) / (phys_xy / nxy), 2.3);
  EXPECT_GT(fill.quality.fraction_q_1_3, 0.9);  // quality in the metric
}

// A graded field: small elements near the centre, large far away (size honoured, isotropically).
TEST(TetraFilling, GradedMetricGradesTheSize) {
  const double R = 0.02;
  const auto surface = test::icosphere(R, 4);
  const auto metric = graded_metric(0.002, 0.008, V(R, 0, 0), 2 * R);
  const auto fill = fill_tetrahedral(surface, *metric, "", "ball");
  double near = 0, far = 0;
  int nn = 0, nf = 0;
  const auto& m = fill.mesh;
  for (Index t = 0; t < m.tetrahedra.rows(); ++t) {
    V c = V::Zero();
    for (int k = 0; k < 4; ++k) c += 0.25 * m.vertices.row(m.tetrahedra(t, k)).transpose();
    const double e =
        (m.vertices.row(m.tetrahedra(t, 0)) - m.vertices.row(m.tetrahedra(t, 1))).norm();
    if (c.x() > 0.01) {
      near += e;
      ++nn;
    } else if (c.x() < -0.01) {
      far += e;
      ++nf;
    }
  }
  ASSERT_GT(nn, 0);
  ASSERT_GT(nf, 0);
  EXPECT_GT((far / nf) / (near / nn), 1.6);
}

TEST(TetraFilling, EveryOptimiserGivesAValidMesh) {
  const auto surface = test::icosphere(0.015, 3);
  const auto metric = isotropic_metric(0.005);
  for (const std::string opt : {"none", "perturb", "exude", "lloyd", "odt"}) {
    const auto fill = fill_tetrahedral(surface, *metric, opt, "ball");
    EXPECT_NO_THROW(fill.mesh.validate("ball")) << opt;
    EXPECT_EQ(fill.optimiser, opt);
    EXPECT_GT(fill.quality.fraction_q_1_3, 0.7) << opt;
  }
}

}  // namespace
}  // namespace fsm::build
