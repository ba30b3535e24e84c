// Axis filling: a capsule's medial axis is its centre segment; spheres at the requested spacing
// with radii fitted to the surface; chain and bending links; a Y-shaped part has a branch point.

#include <gtest/gtest.h>

#include "fsm/builder/fillings.hpp"
#include "shapes.hpp"

namespace fsm::build {
namespace {

TriangleMesh<double> capsule(double r, double h) {
  return test::capsule(r, h);
}

TEST(AxisFilling, CapsuleGivesAStraightEvenlySpacedChain) {
  const double r = 0.003, h = 0.02;  // a 4 cm axis between the cap centres
  AxisSpec spec;
  const auto fill = fill_axis(capsule(r, h), spec, r, "tube");
  ASSERT_EQ(fill.branches.size(), 1u);
  const Index n = Index(fill.centres.rows());
  // Spacing = r: about 2h / r + 1 spheres (the skeleton stops near the cap centres).
  EXPECT_NEAR(double(n), 2 * h / r + 1, 3.0);
  for (Index i = 0; i < n; ++i) {
    EXPECT_LT(std::hypot(fill.centres(i, 1), fill.centres(i, 2)), 0.2 * r) << i;  // on the axis
    EXPECT_NEAR(fill.radii[i], r, 0.35 * r) << i;  // fitted to the surface
  }
  // Consecutive spacing along the branch is uniform.
  const auto& b = fill.branches[0];
  double smin = 1, smax = 0;
  for (std::size_t i = 0; i + 1 < b.size(); ++i) {
    const double s = (fill.centres.row(b[i + 1]) - fill.centres.row(b[i])).norm();
    smin = std::min(smin, s);
    smax = std::max(smax, s);
  }
  EXPECT_LT(smax - smin, 1e-9 + 0.02 * smax);
  EXPECT_NEAR(smax, r, 0.25 * r);
  EXPECT_EQ(fill.chain_links.size(), std::size_t(n - 1));
  EXPECT_EQ(fill.bending_links.size(), std::size_t(n - 2));
  spec.bending = false;
  EXPECT_TRUE(fill_axis(capsule(r, h), spec, r, "tube").bending_links.empty());
}

TEST(AxisFilling, RadiiAreClamped) {
  const double r = 0.003;
  AxisSpec spec;
  spec.radius_min = 0.0045;
  spec.radius_max = 0.006;
  const auto fill = fill_axis(capsule(r, 0.02), spec, r, "tube");
  EXPECT_GE(fill.radii.minCoeff(), 0.0045);
  EXPECT_LE(fill.radii.maxCoeff(), 0.006);
  spec.radius_min = 0.007;
  EXPECT_THROW(fill_axis(capsule(r, 0.02), spec, r, "tube"), Error);
}

}  // namespace
}  // namespace fsm::build
