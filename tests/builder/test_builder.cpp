// The builder end to end on small scenes written at test time: parts filled and joined, anchors,
// the render surface bound (exact at rest), bad input named precisely, repairs on request,
// baselines.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

#include "fsm/builder/builder.hpp"
#include "fsm/fsm.hpp"
#include "shapes.hpp"

namespace fsm::build {
namespace {

namespace fs = std::filesystem;

// A scratch folder with a ball (r = 2 cm at the origin) and a capsule along x touching it.
class Scenes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("fsm_builder_" +
           std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    write_mesh((dir / "ball.obj").string(), test::icosphere(0.02, 4));
    TriangleMesh<double> capsule = test::capsule(0.003, 0.02);
    capsule.vertices.col(0).array() += 0.039;  // the left cap sits 4 mm inside the ball
    write_mesh((dir / "capsule.obj").string(), capsule);
    for (Index i = 0; i < capsule.num_vertices(); ++i) capsule.vertices(i, 1) += 0.1;
    write_mesh((dir / "far.obj").string(), capsule);  // 10 cm away from the ball
  }
  void TearDown() override { fs::remove_all(dir); }

  std::string scene(const std::string& parts, const std::string& rest) const {
    const std::string text = R"({"format": "fsm-scene", "version": 1, "name": "test", "units": "cm",
      "parts": [)" + parts + "]" +
                             rest + "}";
    const std::string path = (dir / "scene.json").string();
    std::ofstream(path) << text;
    return path;
  }

  static std::string tissue() {
    return R"("material": {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26})";
  }
  static std::string ball(const std::string& extra = "") {
    return R"({"name": "ball", "mesh": "ball.obj", "mesh_units": "m", "topology": "tetrahedral",
               "radius": 0.5, )" +
           tissue() + extra + "}";
  }
  static std::string tube() {
    return R"({"name": "tube", "mesh": "capsule.obj", "mesh_units": "m", "topology": "axis",
               "radius": 0.3, )" +
           tissue() + "}";
  }
  static std::string anchors() {
    return R"(, "attachments": [{"parts": ["ball", "tube"], "tolerance": 0.3}],
      "fixed": [{"part": "ball", "box": {"min": [-3, -3, -3], "max": [3, 3, -1.2]}}])";
  }

  void expect_error(const std::string& path, const std::string& part, const std::string& reason) {
    try {
      (void)build_model(path);
      ADD_FAILURE() << "no error; wanted '" << part << "': '" << reason << "'";
    } catch (const Error& e) {
      EXPECT_NE(e.part().find(part), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  }

  fs::path dir;
};

TEST_F(Scenes, BuildsJoinsAnchorsAndBindsTheSurface) {
  BuildReport report;
  const TissueModel<double> model = build_model(scene(ball() + "," + tube(), anchors()), &report);
  ASSERT_EQ(model.parts.size(), 2u);
  const Part& b = model.part("ball");
  const Part& t = model.part("tube");
  EXPECT_EQ(b.topology, Topology::tetrahedral);
  EXPECT_EQ(t.topology, Topology::axis);
  EXPECT_GT(b.num_nodes, 100);
  // A 4 cm capsule axis at 3 mm spacing: about 14 spheres.
  EXPECT_NEAR(double(t.num_nodes), 4.0 / 0.3 + 1, 3);
  EXPECT_GT(model.num_attachment_links, 0);
  EXPECT_GT(model.spheres.num_fixed(), 0);
  for (Index i = 0; i < model.spheres.num_nodes(); ++i)
    if (model.spheres.fixed()[i]) {
      EXPECT_GE(i, b.first_node);
      EXPECT_LT(i, b.first_node + b.num_nodes);
      EXPECT_LE(model.spheres.rest_positions()(i, 2), -0.012);
    }
  // Mass: rho V for each part (V of the surface it was filled from).
  EXPECT_NEAR(model.spheres.masses().segment(b.first_node, b.num_nodes).sum(),
              1050 * report.parts[0].volume, 1e-9);
  EXPECT_NEAR(model.spheres.masses().segment(t.first_node, t.num_nodes).sum(),
              1050 * report.parts[1].volume, 1e-9);
  // The skin reproduces the render surface at rest, for both kinds of binding.
  auto ws = model.skin.make_workspace();
  Positions<double> out(model.skin.num_vertices(), 3);
  model.skin.evaluate(model.spheres.rest_positions(), ws, out);
  EXPECT_LT((out - model.skin.rest.vertices).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(model.skin.surfaces.size(), 2u);
  // And it steps: the tube hangs from the ball under gravity.
  Simulation<double> sim(model.spheres);
  for (int s = 0; s < 50; ++s) ASSERT_EQ(sim.step(1e-3).status, StepStatus::ok);
  EXPECT_LT(sim.model().positions().middleRows(t.first_node, t.num_nodes).col(2).mean(),
            model.spheres.rest_positions().middleRows(t.first_node, t.num_nodes).col(2).mean());
  // The report.
  EXPECT_NE(report.table().find("ball"), std::string::npos);
  const auto j = nlohmann::json::parse(report.json());
  EXPECT_EQ(j["parts"][0]["name"], "ball");
  EXPECT_GT(j["parts"][0]["quality"]["fraction_q_1_3"].get<double>(), 0.9);
  EXPECT_EQ(j["spheres"].get<int>(), model.spheres.num_nodes());
  EXPECT_EQ(nlohmann::json::parse(model.report_json)["links"].get<int>(),
            model.spheres.num_links());
}

// Tear strains: a material's reaches its region, an attachment's its links; they survive the model
// file; a bad one is named.
TEST_F(Scenes, TearStrainsGoFromTheSceneToTheModel) {
  const std::string tearing_ball =
      R"({"name": "ball", "mesh": "ball.obj", "mesh_units": "m", "topology": "tetrahedral",
          "radius": 0.5, "material": {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26,
          "tear_strain": 0.8}})";
  const std::string path = scene(
      tearing_ball + "," + tube(),
      R"(, "attachments": [{"parts": ["ball", "tube"], "tolerance": 0.3, "tear_strain": 0.25}],
      "fixed": [{"part": "ball", "box": {"min": [-3, -3, -3], "max": [3, 3, -1.2]}}])");
  const TissueModel<double> model = deserialize_model(serialize_model(build_model(path)), "file");
  const SphereModel<double>& s = model.spheres;
  EXPECT_EQ(s.region(model.part("ball").region).material.tear_strain, 0.8);
  EXPECT_TRUE(std::isinf(s.region(model.part("tube").region).material.tear_strain));
  ASSERT_GT(model.num_attachment_links, 0);
  for (Index l = 0; l < s.num_links(); ++l) {
    const bool attachment = l >= model.first_attachment_link &&
                            l < model.first_attachment_link + model.num_attachment_links;
    if (attachment)
      EXPECT_EQ(s.tear_strain()[l], 0.25) << l;
    else
      EXPECT_TRUE(std::isinf(s.tear_strain()[l])) << l;
  }
  // The simulation's limits: the smallest of the link's own and its regions' materials'.
  Simulation<double> sim(s);
  const Index inside = model.part("ball").first_link;
  const Index tube_link = model.part("tube").first_link;
  EXPECT_EQ(sim.topology().tear_strains()[inside], 0.8);
  EXPECT_TRUE(std::isinf(sim.topology().tear_strains()[tube_link]));
  EXPECT_EQ(sim.topology().tear_strains()[model.first_attachment_link], 0.25);
  expect_error(scene(ball() + "," + tube(),
                     R"(, "attachments": [{"parts": ["ball", "tube"], "tolerance": 0.3,
                          "tear_strain": -1}])"),
               "attachment 0", "tear_strain");
}

// Reproducible builds: the same scene gives the same bytes, whatever the heap looked like before
// (the medial axis's contraction picks edges in address order, deterministic_arena.hpp), the stored
// report has no wall times and names meshes relative to the scene; progress only grows.
TEST_F(Scenes, SameSceneGivesTheSameBytes) {
  const std::string path = scene(ball() + "," + tube(), anchors());
  std::vector<double> fractions;
  HybridTopologyBuilder first(load_scene(path));
  first.set_progress(
      [&](const std::string&, const std::string&, double f) { fractions.push_back(f); });
  const std::string a = serialize_model(first.build());
  ASSERT_GT(fractions.size(), 4u);
  EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
  EXPECT_EQ(fractions.back(), 1.0);
  for (int round = 0; round < 3; ++round) {
    // A different heap each time: blocks of several sizes kept alive across the build.
    std::vector<std::unique_ptr<char[]>> clutter;
    for (int k = 0; k < 1000 * (round + 1); ++k)
      clutter.emplace_back(new char[std::size_t(16 + 48 * ((k * 7919 + round) % 37))]);
    for (std::size_t k = 0; k < clutter.size(); k += 3) clutter[k].reset();
    const std::string b = serialize_model(build_model(path));
    ASSERT_EQ(a.size(), b.size()) << "round " << round;
    EXPECT_TRUE(a == b) << "round " << round;
  }
  const TissueModel<double> model = deserialize_model(a, "built");
  const auto stored = nlohmann::json::parse(model.report_json);
  EXPECT_FALSE(stored.contains("seconds"));
  EXPECT_FALSE(stored["parts"][0].contains("seconds"));
  EXPECT_EQ(stored["parts"][1]["meshes"][0]["file"], "capsule.obj");
}

// The graded metric's plateau radius is a length in the scene's units, like its other lengths;
// a negative one is refused naming the part.
TEST_F(Scenes, GradedMetricPlateauIsInTheScenesUnits) {
  const std::string graded =
      R"(, "metric": {"type": "graded", "size_min": 0.1, "size_max": 0.5, "centre": [1, 0, 0],
          "distance": 0.8, "plateau_radius": 0.4})";
  const Scene s = load_scene(scene(ball(graded), ""));  // "units": "cm"
  ASSERT_EQ(s.parts.size(), 1u);
  const auto& metric = *s.parts[0].metric;
  EXPECT_NE(metric.describe().find("within 4 mm"), std::string::npos) << metric.describe();
  EXPECT_NEAR(metric.size(Eigen::Vector3d(0.01 + 0.004, 0, 0)), 0.001, 1e-12);
  EXPECT_NEAR(metric.size(Eigen::Vector3d(0.01 + 0.008, 0, 0)), 0.001 + 0.004 * 0.5, 1e-12);
  EXPECT_NEAR(metric.size(Eigen::Vector3d(0.01 - 0.02, 0, 0)), 0.005, 1e-12);
  const std::string negative =
      R"(, "metric": {"type": "graded", "size_min": 0.1, "size_max": 0.5, "centre": [1, 0, 0],
          "distance": 0.8, "plateau_radius": -0.4})";
  expect_error(scene(ball(negative), ""), "part 'ball'", "plateau_radius must be non-negative");
}

TEST_F(Scenes, BadScenesAreNamed) {
  expect_error(
      scene(ball() + "," + tube(),
            R"(, "fixed": [{"part": "ball", "box": {"min": [-3, -3, -3], "max": [3, 3, -1.2]}}])"),
      "part 'tube'", "neither fixed nor attached");
  expect_error(scene(ball() + "," + tube(),
                     R"(, "attachments": [{"parts": ["ball", "tube"], "tolerance": 0.3}])"),
               "part 'ball'", "attached only to parts that are not fixed");
  expect_error(
      scene(ball(),
            R"(, "fixed": [{"part": "ball", "box": {"min": [5, 5, 5], "max": [6, 6, 6]}}])"),
      "fixed region 0", "selects no sphere");
  const std::string far =
      R"({"name": "far", "mesh": "far.obj", "mesh_units": "m", "topology": "axis",
               "radius": 0.3, )" +
      tissue() + "}";
  expect_error(
      scene(ball() + "," + far, R"(, "attachments": [{"parts": ["ball", "far"], "tolerance": 0.3}],
      "fixed": [{"part": "ball", "vertices": [0]}, {"part": "far", "chain_end": "last"}])"),
      "attachment 'ball'-'far'", "no spheres within");
  expect_error(scene(ball(R"(, "colour": "red")"), ""), "part 'ball'", "unknown key 'colour'");
  expect_error(
      scene(
          R"({"name": "ball", "mesh": "missing.obj", "topology": "tetrahedral", "radius": 0.5, )" +
              tissue() + "}",
          ""),
      "part 'ball'", "does not exist");
  expect_error(
      scene(R"({"name": "ball", "mesh": "ball.obj", "topology": "cubic", "radius": 0.5, )" +
                tissue() + "}",
            ""),
      "part 'ball'", "unknown topology 'cubic'");
  expect_error(
      scene(R"({"name": "ball", "mesh": "ball.obj", "topology": "tetrahedral", "radius": -1, )" +
                tissue() + "}",
            ""),
      "part 'ball'", "radius");
  expect_error(
      scene(
          R"({"name": "ball", "mesh": "ball.obj", "topology": "tetrahedral", "radius": 0.5, "material": {"density": 1050, "youngs_modulus": -5}})",
          ""),
      "part 'ball'", "youngs_modulus");
  expect_error(
      scene(ball(), R"(, "attachments": [{"parts": ["ball", "liver"], "tolerance": 0.3}])"),
      "attachment 0", "names part 'liver'");
  {
    const std::string path = (dir / "newer.json").string();
    std::ofstream(path) << R"({"format": "fsm-scene", "version": 2, "parts": []})";
    expect_error(path, "scene", "newer than this builder");
  }
}

// An open mesh is refused naming the file and the defect; with an alpha wrap it builds. An inward
// mesh is refused with a hint; with "orient" it builds.
// The resource budget: a scene's limits below what it asks for are refused before the filling,
// with the estimate; raising them (as --max-spheres does) builds the same scene; the estimate is
// in the report and within a small factor of what was built.
TEST_F(Scenes, ResourceBudgetRefusesThenAllowsWhenRaised) {
  const std::string path =
      scene(ball() + "," + tube(), anchors() + R"(, "limits": {"spheres": 20})");
  Scene s = load_scene(path);
  EXPECT_EQ(s.limits.spheres, 20);
  try {
    HybridTopologyBuilder(s).build();
    ADD_FAILURE() << "built past the limit";
  } catch (const Error& e) {
    EXPECT_EQ(e.part(), "ball");
    EXPECT_NE(e.reason().find("the tetrahedral filling would need about"), std::string::npos)
        << e.what();
    EXPECT_NE(e.reason().find("more than the limit of 20"), std::string::npos) << e.what();
  }
  HybridTopologyBuilder raised(s);
  BuildLimits more = s.limits;
  more.spheres = 1e5;
  raised.set_limits(more);
  const TissueModel<double> m = raised.build();
  const PartReport& ball_report = raised.report().parts.front();
  EXPECT_GT(ball_report.estimate.spheres, 0.8 * double(ball_report.spheres));
  EXPECT_LT(ball_report.estimate.spheres, 3.0 * double(ball_report.spheres));
  EXPECT_NE(ball_report.estimate.basis.find("at element size 5 mm"), std::string::npos)
      << ball_report.estimate.basis;
  EXPECT_GT(ball_report.estimate.memory_bytes, 0);
  EXPECT_THROW(raised.set_limits(BuildLimits{0, 1, 1}), Error);
  // Memory and elements are limits too.
  HybridTopologyBuilder tight(s);
  tight.set_limits(BuildLimits{1e5, 1e5, 1e3});
  try {
    tight.build();
    ADD_FAILURE() << "built past the memory limit";
  } catch (const Error& e) {
    EXPECT_NE(e.reason().find("bytes of memory"), std::string::npos) << e.what();
    EXPECT_NE(e.reason().find("memory_gb"), std::string::npos) << e.what();
  }
}

TEST_F(Scenes, RepairsOnlyWhenAsked) {
  TriangleMesh<double> open = test::icosphere(0.02, 3);
  open.faces.conservativeResize(open.faces.rows() - 5, 3);
  write_mesh((dir / "open.obj").string(), open);
  const std::string part =
      R"({"name": "ball", "mesh": "open.obj", "mesh_units": "m", "topology": "tetrahedral", "radius": 0.5, )" +
      tissue();
  const std::string fixed =
      R"(, "fixed": [{"part": "ball", "box": {"min": [-3, -3, -3], "max": [3, 3, -1.2]}}])";
  expect_error(scene(part + "}", fixed), "ball", "boundary edges");
  const auto wrapped = build_model(
      scene(part + R"(, "repair": {"alpha_wrap": {"alpha": 0.4, "offset": 0.05}}})", fixed));
  EXPECT_GT(wrapped.spheres.num_nodes(), 50);

  TriangleMesh<double> inward = test::icosphere(0.02, 3);
  inward.faces.col(1).swap(inward.faces.col(2));
  write_mesh((dir / "inward.obj").string(), inward);
  const std::string part2 =
      R"({"name": "ball", "mesh": "inward.obj", "mesh_units": "m", "topology": "tetrahedral", "radius": 0.5, )" +
      tissue();
  expect_error(scene(part2 + "}", fixed), "ball", "orient");
  EXPECT_GT(
      build_model(scene(part2 + R"(, "repair": {"orient": true}})", fixed)).spheres.num_nodes(),
      50);
}

TEST_F(Scenes, GridAndPackingBaselines) {
  const std::string fixed =
      R"(, "fixed": [{"part": "ball", "box": {"min": [-3, -3, -3], "max": [3, 3, -1.0]}}])";
  auto grid = [&](int n) {
    return R"({"name": "ball", "mesh": "ball.obj", "mesh_units": "m", "topology": "grid", "radius": 0.25,
               "grid": {"neighbours": )" +
           std::to_string(n) + "}, " + tissue() + "}";
  };
  BuildReport r6, r18, r26;
  const auto g6 = build_model(scene(grid(6), fixed), &r6);
  const auto g18 = build_model(scene(grid(18), fixed), &r18);
  const auto g26 = build_model(scene(grid(26), fixed), &r26);
  // Spacing 5 mm in a 2 cm ball: the same nodes, more links per node with more neighbours.
  EXPECT_EQ(g6.spheres.num_nodes(), g18.spheres.num_nodes());
  EXPECT_LT(g6.spheres.num_links(), g18.spheres.num_links());
  EXPECT_LT(g18.spheres.num_links(), g26.spheres.num_links());
  EXPECT_NEAR(double(g6.spheres.num_nodes()), 4.0 / 3.0 * M_PI * 8e-6 / 1.25e-7, 0.15 * 268);
  // Interior nodes of the 6-grid have 6 links, and the axis links have k = E s.
  EXPECT_NEAR(g6.spheres.stiffness().maxCoeff(), 13150 * 0.005, 1e-9);
  EXPECT_NEAR(g18.spheres.stiffness().maxCoeff(), 0.4 * 13150 * 0.005, 1e-9);
  const auto pk = build_model(scene(
      R"({"name": "ball", "mesh": "ball.obj", "mesh_units": "m", "topology": "packing", "radius": 0.5, )" +
          tissue() + "}",
      fixed));
  EXPECT_GT(pk.spheres.num_nodes(), 5);
  EXPECT_GE(pk.spheres.radii().minCoeff(), 0.0025 - 1e-12);  // radius_min = radius / 2
  EXPECT_LE(pk.spheres.radii().maxCoeff(), 0.02);
  EXPECT_NEAR(pk.spheres.total_mass(), 1050 * 4.0 / 3.0 * M_PI * 8e-6,
              0.03 * 1050 * 4.0 / 3.0 * M_PI * 8e-6);
  // The baselines bind their render surface too, exactly at rest.
  auto ws = g6.skin.make_workspace();
  Positions<double> out(g6.skin.num_vertices(), 3);
  g6.skin.evaluate(g6.spheres.rest_positions(), ws, out);
  EXPECT_LT((out - g6.skin.rest.vertices).cwiseAbs().maxCoeff(), 1e-14);
}

}  // namespace
}  // namespace fsm::build
