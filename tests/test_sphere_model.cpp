// SphereModel: construction, bad input named precisely, the strong guarantee, mass rules, cast.

#include "common.hpp"

namespace fsm::test {
namespace {

using V3 = Vector3<double>;

// Runs f, expects fsm::Error whose part and message contain the given fragments.
template <typename F>
void expect_error(F&& f, const std::string& part, const std::string& reason) {
  try {
    f();
    ADD_FAILURE() << "no fsm::Error (wanted '" << part << "': '" << reason << "')";
  } catch (const Error& e) {
    EXPECT_NE(e.part().find(part), std::string::npos) << "part: " << e.part();
    EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
  }
}

SphereModel<double> small_model() {
  SphereModel<double> m;
  const Index r = m.add_region("body", tissue<double>());
  m.add_node(V3(0, 0, 0), 0.005, 0.001, r);
  m.add_node(V3(0.01, 0, 0), 0.005, 0.001, r);
  m.add_node(V3(0, 0.01, 0), 0.005, 0.001, r);
  m.add_link(0, 1, 100.0, 0.1);
  return m;
}

TEST(SphereModel, BuildsStructureOfArrays) {
  SphereModel<double> m = small_model();
  EXPECT_EQ(m.num_nodes(), 3);
  EXPECT_EQ(m.num_links(), 1);
  EXPECT_EQ(m.positions().rows(), 3);
  EXPECT_EQ(m.positions().cols(), 3);
  EXPECT_TRUE(near(m.rest_lengths()[0], 0.01, 1e-15));
  // Row-major: a node's coordinates are adjacent in memory.
  EXPECT_EQ(&m.positions()(1, 0) + 1, &m.positions()(1, 1));
  m.positions()(2, 2) = 0.5;  // the map writes through
  EXPECT_EQ(m.positions()(2, 2), 0.5);
  m.reset_to_rest();
  EXPECT_EQ(m.positions()(2, 2), 0.0);
  EXPECT_NO_THROW(m.validate());
}

TEST(SphereModel, BadNodesAreNamed) {
  SphereModel<double> m = small_model();
  expect_error([&] { m.add_node(V3(0, 0, 0), -0.001, 0.001, 0); }, "node 3 (region 'body')",
               "radius");
  expect_error([&] { m.add_node(V3(0, 0, 0), 0.0, 0.001, 0); }, "node 3", "radius");
  expect_error([&] { m.add_node(V3(0, 0, 0), 0.001, 0.0, 0); }, "node 3", "mass");
  expect_error([&] { m.add_node(V3(std::nan(""), 0, 0), 0.001, 0.001, 0); }, "node 3",
               "not finite");
  expect_error([&] { m.add_node(V3(0, 0, 0), 0.001, 0.001, 4); }, "node 3", "region index 4");
  EXPECT_EQ(m.num_nodes(), 3);  // nothing half-added
  EXPECT_NO_THROW(m.validate());
}

TEST(SphereModel, BadLinksAreNamed) {
  SphereModel<double> m = small_model();
  expect_error([&] { m.add_link(1, 1, 10.0, 0.0); }, "link 1 (nodes 1-1)", "itself");
  expect_error([&] { m.add_link(0, 7, 10.0, 0.0); }, "link 1", "out of range");
  expect_error([&] { m.add_link(0, 2, -10.0, 0.0); }, "link 1 (nodes 0-2)", "stiffness");
  expect_error([&] { m.add_link(0, 2, 0.0, 0.0); }, "link 1", "stiffness");
  expect_error([&] { m.add_link(0, 2, 10.0, -1.0); }, "link 1", "damping");
  expect_error([&] { m.add_link(0, 2, VoigtLink<double>::linear(0.0, 10, 0)); }, "link 1",
               "rest length");
  expect_error(
      [&] { m.add_link(0, 2, VoigtLink<double>::bilinear(0.01, 10, 0, 50, std::nan(""))); },
      "link 1", "switch strain");
  EXPECT_EQ(m.num_links(), 1);
  // A duplicate is caught by validate() (in either orientation).
  m.add_link(1, 0, 10.0, 0.0);
  expect_error([&] { m.validate(); }, "link 1 (nodes 1-0)", "duplicates");
}

TEST(SphereModel, ValidateCatchesValuesWrittenInPlace) {
  SphereModel<double> m = small_model();
  m.radii()[2] = -1;
  expect_error([&] { m.validate(); }, "node 2", "radius");
  m = small_model();
  m.velocities()(1, 0) = std::numeric_limits<double>::infinity();
  expect_error([&] { m.validate(); }, "node 1", "velocity");
  m = small_model();
  m.links()(0, 1) = 9;
  expect_error([&] { m.validate(); }, "link 0", "out of range");
  m = small_model();
  m.stiffness()[0] = std::nan("");
  expect_error([&] { m.validate(); }, "link 0", "stiffness");
}

TEST(SphereModel, RegionsAreUniqueAndLookedUpByName) {
  SphereModel<double> m = small_model();
  expect_error([&] { m.add_region("body", tissue<double>()); }, "region 'body'", "exists");
  expect_error([&] { m.add_region("", tissue<double>()); }, "region 1", "empty");
  Material<double> bad = tissue<double>();
  bad.youngs_modulus = -1;
  expect_error([&] { m.add_region("ovary", bad); }, "region 'ovary'", "youngs_modulus");
  EXPECT_EQ(m.region_index("body"), 0);
  expect_error([&] { (void)m.region_index("fibroid"); }, "region 'fibroid'", "'body'");
}

TEST(SphereModel, SetLinkKeepsTheOldLawOnBadInput) {
  SphereModel<double> m = small_model();
  const auto before = m.link(0);
  expect_error([&] { m.set_link(0, VoigtLink<double>::linear(0.01, -1, 0)); }, "link 0",
               "stiffness");
  EXPECT_EQ(m.link(0).stiffness, before.stiffness);
  m.set_link(0, VoigtLink<double>::bilinear(0.01, 100, 0.1, 500, 0.05));
  EXPECT_TRUE(m.has_bilinear_links());
}

TEST(SphereModel, FixingANodeZeroesItsVelocity) {
  SphereModel<double> m = small_model();
  m.velocities().row(1) << 1, 2, 3;
  m.set_fixed(1);
  EXPECT_EQ(m.num_fixed(), 1);
  EXPECT_EQ(m.velocities().row(1).norm(), 0.0);
  expect_error([&] { m.set_fixed(3); }, "node 3", "out of range");
}

TEST(SphereModel, EqualShareMassRule) {
  SphereModel<double> m = small_model();
  m.distribute_region_mass(0, 3e-6);  // rho V / N = 1050 * 3e-6 / 3
  for (Index i = 0; i < 3; ++i) EXPECT_TRUE(near(m.masses()[i], 1050 * 1e-6, 1e-14));
  EXPECT_TRUE(near(m.total_mass(), 1050 * 3e-6, 1e-14));
  expect_error([&] { m.distribute_region_mass(0, -1.0); }, "region 'body'", "volume");
}

TEST(SphereModel, CastsToFloatAndBack) {
  const SphereModel<double> m = small_model();
  const SphereModel<float> f = m.cast<float>();
  EXPECT_EQ(f.num_nodes(), 3);
  EXPECT_EQ(f.num_links(), 1);
  EXPECT_EQ(f.region(0).name, "body");
  EXPECT_TRUE(near(f.stiffness()[0], 100.0, 1e-7));
  EXPECT_NO_THROW(f.validate());
  EXPECT_TRUE(std::isinf(f.switch_strain()[0]));
}

}  // namespace
}  // namespace fsm::test
