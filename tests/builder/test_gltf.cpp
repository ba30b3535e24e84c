// glTF 2.0 input (read_gltf through assimp): a multi-node GLB that the test writes itself builds
// the same model as an OBJ of the same geometry; node transforms are applied; bad files are named.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/mesh_io.hpp"
#include "fsm/model_file.hpp"
#include "../scratch_dir.hpp"
#include "shapes.hpp"

namespace fsm::build {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// A GLB under construction: meshes go into one binary buffer.
struct Glb {
  json doc = {{"asset", {{"version", "2.0"}}},
              {"scene", 0},
              {"scenes", {{{"nodes", json::array()}}}},
              {"nodes", json::array()},
              {"meshes", json::array()},
              {"accessors", json::array()},
              {"bufferViews", json::array()}};
  std::string bin;

  int view(const void* data, std::size_t bytes) {
    while (bin.size() % 4) bin.push_back('\0');
    doc["bufferViews"].push_back(
        {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}});
    bin.append(static_cast<const char*>(data), bytes);
    return int(doc["bufferViews"].size()) - 1;
  }
  // A mesh of float positions and uint32 indices; mode 4 = triangles, 0 = points.
  int mesh(const std::string& name, const std::vector<float>& xyz,
           const std::vector<std::uint32_t>& indices, int mode = 4) {
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (std::size_t i = 0; i < xyz.size(); ++i) {
      lo[i % 3] = std::min(lo[i % 3], xyz[i]);
      hi[i % 3] = std::max(hi[i % 3], xyz[i]);
    }
    doc["accessors"].push_back({{"bufferView", view(xyz.data(), xyz.size() * 4)},
                                {"componentType", 5126},
                                {"count", xyz.size() / 3},
                                {"type", "VEC3"},
                                {"min", {lo[0], lo[1], lo[2]}},
                                {"max", {hi[0], hi[1], hi[2]}}});
    const int positions = int(doc["accessors"].size()) - 1;
    doc["accessors"].push_back({{"bufferView", view(indices.data(), indices.size() * 4)},
                                {"componentType", 5125},
                                {"count", indices.size()},
                                {"type", "SCALAR"}});
    const int index = int(doc["accessors"].size()) - 1;
    doc["meshes"].push_back(
        {{"name", name},
         {"primitives",
          {{{"attributes", {{"POSITION", positions}}}, {"indices", index}, {"mode", mode}}}}});
    return int(doc["meshes"].size()) - 1;
  }
  int node(json n, bool root) {
    doc["nodes"].push_back(std::move(n));
    const int k = int(doc["nodes"].size()) - 1;
    if (root) doc["scenes"][0]["nodes"].push_back(k);
    return k;
  }
  void write(const fs::path& path) {
    while (bin.size() % 4) bin.push_back('\0');
    if (!bin.empty()) doc["buffers"] = {{{"byteLength", bin.size()}}};
    std::string text = doc.dump();
    while (text.size() % 4) text.push_back(' ');
    std::string out;
    auto u32 = [&](std::uint32_t v) {
      for (int k = 0; k < 4; ++k) out.push_back(char((v >> (8 * k)) & 0xff));
    };
    out += "glTF";
    u32(2);
    u32(std::uint32_t(12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size())));
    u32(std::uint32_t(text.size()));
    out += "JSON";
    out += text;
    if (!bin.empty()) {
      u32(std::uint32_t(bin.size()));
      out.append("BIN\0", 4);
      out += bin;
    }
    std::ofstream(path, std::ios::binary) << out;
  }
};

class Gltf : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::scratch_dir("fsm_test_gltf");
    // A unit-radius icosphere quantised to 1/1024 (exact in float, and after the node transforms
    // below, so the GLB and the OBJ hold the very same numbers).
    ball = test::icosphere(1.0, 3);
    for (Index i = 0; i < ball.num_vertices(); ++i)
      for (int c = 0; c < 3; ++c)
        ball.vertices(i, c) = std::round(ball.vertices(i, c) * 1024) / 1024;
  }
  void TearDown() override { fs::remove_all(dir); }

  // organs.glb: "group" (translated by (0.25, -0.5, 1)) holding "ball" (scaled by 2: the local mesh
  // is half size), and a root "decoy" tetrahedron far away.
  fs::path organs() {
    Glb g;
    std::vector<float> xyz;
    std::vector<std::uint32_t> idx;
    for (Index i = 0; i < ball.num_vertices(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double offset = c == 0 ? 0.25 : c == 1 ? -0.5 : 1.0;
        xyz.push_back(float((ball.vertices(i, c) - offset) / 2));
      }
    for (Index f = 0; f < ball.num_faces(); ++f)
      for (int c = 0; c < 3; ++c) idx.push_back(std::uint32_t(ball.faces(f, c)));
    const int ball_mesh = g.mesh("ball_surface", xyz, idx);
    const int decoy_mesh = g.mesh("decoy_surface", {10, 10, 10, 11, 10, 10, 10, 11, 10, 10, 10, 11},
                                  {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3});
    const int child = g.node({{"name", "ball"}, {"mesh", ball_mesh}, {"scale", {2, 2, 2}}}, false);
    g.node({{"name", "group"}, {"translation", {0.25, -0.5, 1.0}}, {"children", {child}}}, true);
    g.node({{"name", "decoy"}, {"mesh", decoy_mesh}}, true);
    const fs::path path = dir / "organs.glb";
    g.write(path);
    return path;
  }

  std::string scene(const std::string& mesh) const {
    const std::string text = R"({"format": "fsm-scene", "version": 1, "name": "t", "units": "cm",
      "parts": [{"name": "ball", "mesh": )" +
                             mesh +
                             R"(, "topology": "tetrahedral", "radius": 0.4,
      "material": {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26}}],
      "fixed": [{"part": "ball", "box": {"min": [-2, -2, -2], "max": [2, 2, -0.5]}}]})";
    const fs::path path = dir / "scene.json";
    std::ofstream(path) << text;
    return path.string();
  }

  fs::path dir;
  TriangleMesh<double> ball;
};

TEST_F(Gltf, NodeTransformsAreAppliedInDouble) {
  const fs::path glb = organs();
  const TriangleMesh<double> m = read_mesh(glb.string(), 1.0, {"ball"});
  ASSERT_EQ(m.num_vertices(), ball.num_vertices());
  // The same points (welding keeps the order of first appearance, as for the OBJ).
  EXPECT_EQ((m.vertices - ball.vertices).cwiseAbs().maxCoeff(), 0.0);
  // The whole file: ball + decoy; the group node: its subtree, the ball.
  EXPECT_EQ(read_mesh(glb.string(), 1.0).num_faces(), ball.num_faces() + 4);
  EXPECT_EQ(read_mesh(glb.string(), 1.0, {"group"}).num_faces(), ball.num_faces());
  EXPECT_EQ(read_mesh(glb.string(), 0.01, {"decoy"}).vertices.maxCoeff(), 0.11);
}

TEST_F(Gltf, MultiNodeGlbBuildsTheSameModelAsAnObjOfTheSameGeometry) {
  const fs::path glb = organs();
  write_mesh((dir / "ball.obj").string(), ball);
  BuildReport from_glb_report;
  const TissueModel<double> from_glb =
      build_model(scene(R"({"file": "organs.glb", "nodes": ["ball"]})"), &from_glb_report);
  const TissueModel<double> from_obj = build_model(scene(R"("ball.obj")"));
  ASSERT_GT(from_glb.spheres.num_nodes(), 20);
  EXPECT_EQ(from_glb.spheres.num_nodes(), from_obj.spheres.num_nodes());
  EXPECT_EQ(from_glb.spheres.num_links(), from_obj.spheres.num_links());
  EXPECT_EQ(from_glb.spheres.num_tetrahedra(), from_obj.spheres.num_tetrahedra());
  EXPECT_TRUE(from_glb.spheres.rest_positions() == from_obj.spheres.rest_positions());
  EXPECT_TRUE(from_glb.spheres.links() == from_obj.spheres.links());
  EXPECT_TRUE(from_glb.skin.rest.vertices == from_obj.skin.rest.vertices);
  EXPECT_NE(from_glb_report.parts[0].meshes[0].file.find("organs.glb#ball"), std::string::npos);
}

TEST_F(Gltf, BadFilesAreNamed) {
  const fs::path glb = organs();
  auto expect = [](const std::function<void()>& f, const std::string& where,
                   const std::vector<std::string>& reasons) {
    try {
      f();
      ADD_FAILURE() << "no error, wanted " << reasons.front();
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(where), std::string::npos) << e.what();
      for (const std::string& r : reasons)
        EXPECT_NE(std::string(e.what()).find(r), std::string::npos) << e.what();
    }
  };
  // A node that does not exist: the message lists those that do.
  expect([&] { (void)read_mesh(glb.string(), 1.0, {"uterus"}); }, "organs.glb",
         {"node 'uterus'", "no such node", "'group'", "'ball'", "'decoy'"});
  // Nodes for a format without nodes.
  write_mesh((dir / "ball.obj").string(), ball);
  expect([&] { (void)read_mesh((dir / "ball.obj").string(), 1.0, {"ball"}); }, "ball.obj",
         {"only be chosen in a glTF"});
  // No mesh at all.
  {
    Glb g;
    g.node({{"name", "empty"}}, true);
    g.doc.erase("meshes");
    g.write(dir / "empty.glb");
    expect([&] { (void)read_mesh((dir / "empty.glb").string()); }, "empty.glb", {"no mesh"});
  }
  // Points, not triangles.
  {
    Glb g;
    g.node(
        {{"name", "cloud"}, {"mesh", g.mesh("cloud", {0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}, 0)}},
        true);
    g.write(dir / "points.glb");
    expect([&] { (void)read_mesh((dir / "points.glb").string()); }, "points.glb",
           {"node 'cloud'", "point or line primitives"});
  }
  // A required extension that re-encodes the geometry and that this build does not decode.
  {
    Glb g;
    g.node({{"name", "n"}, {"mesh", g.mesh("m", {0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2})}}, true);
    g.doc["extensionsUsed"] = {"EXT_meshopt_compression"};
    g.doc["extensionsRequired"] = {"EXT_meshopt_compression"};
    g.write(dir / "meshopt.glb");
    expect([&] { (void)read_mesh((dir / "meshopt.glb").string()); }, "meshopt.glb",
           {"EXT_meshopt_compression", "cannot read"});
  }
  // Draco-compressed with a corrupt compressed buffer: assimp's reason, never a crash.
  {
    Glb g;
    const char junk[16] = "not draco data!";
    const int v = g.view(junk, sizeof junk);
    g.doc["accessors"] = {{{"componentType", 5126}, {"count", 3}, {"type", "VEC3"}},
                          {{"componentType", 5125}, {"count", 3}, {"type", "SCALAR"}}};
    g.doc["meshes"] = {{{"primitives",
                         {{{"attributes", {{"POSITION", 0}}},
                           {"indices", 1},
                           {"extensions",
                            {{"KHR_draco_mesh_compression",
                              {{"bufferView", v}, {"attributes", {{"POSITION", 0}}}}}}}}}}}};
    g.node({{"name", "squashed"}, {"mesh", 0}}, true);
    g.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
    g.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    g.write(dir / "draco.glb");
    expect([&] { (void)read_mesh((dir / "draco.glb").string()); }, "draco.glb", {"Draco"});
  }
  // Truncated framing and malformed JSON.
  std::ofstream(dir / "short.glb", std::ios::binary) << "glTF";
  expect([&] { (void)read_mesh((dir / "short.glb").string()); }, "short.glb", {"GLB"});
  std::ofstream(dir / "bad.gltf") << "{\"asset\": ";
  expect([&] { (void)read_mesh((dir / "bad.gltf").string()); }, "bad.gltf", {"malformed"});
  // The scene names the nodes and refuses an empty list.
  expect([&] { (void)build_model(scene(R"({"file": "organs.glb", "nodes": []})")); }, "ball",
         {"'nodes'"});
}

}  // namespace
}  // namespace fsm::build
