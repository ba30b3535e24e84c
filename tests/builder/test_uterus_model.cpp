// The default data set through the builder: the paper's Table 1 sphere counts within 15 % per part
// (517 / 39 / 29 / 9 / 31, total 694), good elements, a model file round trip, and a model that
// steps.

#include <gtest/gtest.h>

#include <filesystem>
#include <map>

#include "fsm/builder/builder.hpp"
#include "fsm/fsm.hpp"

namespace fsm::build {
namespace {

TEST(UterusModel, TableOneCountsAndAWorkingModel) {
  BuildReport report;
  const TissueModel<double> model =
      build_model(std::string(FSM_SOURCE_DIR) + "/data/uterus/uterus.json", &report);
  const std::map<std::string, int> table1{
      {"body", 517},        {"fibroid", 39},       {"ovary_left", 29}, {"ovary_right", 29},
      {"ligament_left", 9}, {"ligament_right", 9}, {"tube_left", 31},  {"tube_right", 31}};
  ASSERT_EQ(model.parts.size(), table1.size());
  int total = 0;
  for (const Part& p : model.parts) {
    ASSERT_TRUE(table1.count(p.name)) << p.name;
    const int want = table1.at(p.name);
    EXPECT_NEAR(double(p.num_nodes), want, 0.15 * want) << p.name;
    total += p.num_nodes;
    RecordProperty(p.name, std::to_string(p.num_nodes));
  }
  EXPECT_NEAR(double(total), 694, 0.15 * 694);
  // Element quality of the tetrahedral parts (the paper: 97.9 % of the body's elements in [1, 3]).
  for (const auto& p : report.parts)
    if (p.topology == Topology::tetrahedral) {
      EXPECT_GT(p.quality.fraction_q_1_3, 0.95) << p.name;
    }
  // Table 1's radii and topologies.
  EXPECT_EQ(model.part("body").topology, Topology::tetrahedral);
  EXPECT_EQ(model.part("tube_left").topology, Topology::axis);
  EXPECT_DOUBLE_EQ(model.part("tube_left").radius, 0.0033);
  // A tetrahedral part keeps its filling's tetrahedra (the report's count), each on its own
  // spheres; the other parts have none.
  Index tets = 0;
  for (std::size_t k = 0; k < model.parts.size(); ++k) {
    const Part& p = model.parts[k];
    if (p.topology == Topology::tetrahedral) {
      EXPECT_EQ(p.num_tetrahedra, report.parts[k].quality.tetrahedra) << p.name;
      EXPECT_EQ(p.first_tetrahedron, tets) << p.name;
      const auto t = model.part_tetrahedra(p);
      EXPECT_GE(t.minCoeff(), p.first_node) << p.name;
      EXPECT_LT(t.maxCoeff(), p.first_node + p.num_nodes) << p.name;
      tets += p.num_tetrahedra;
    } else {
      EXPECT_EQ(p.num_tetrahedra, 0) << p.name;
    }
  }
  EXPECT_EQ(model.spheres.num_tetrahedra(), tets);
  EXPECT_GT(tets, 2000);
  // The model file keeps everything.
  const TissueModel<double> loaded = deserialize_model(serialize_model(model));
  EXPECT_EQ(loaded.spheres.num_links(), model.spheres.num_links());
  EXPECT_EQ(TetrahedronArray(loaded.spheres.tetrahedra()),
            TetrahedronArray(model.spheres.tetrahedra()));
  EXPECT_EQ(loaded.skin.num_vertices(), model.skin.num_vertices());
  // It steps under gravity at the haptic rate.
  Simulation<double> sim(model.spheres);
  for (int s = 0; s < 100; ++s) ASSERT_EQ(sim.step(1e-3).status, StepStatus::ok) << s;
  std::printf("%s", report.table().c_str());
}

}  // namespace
}  // namespace fsm::build
