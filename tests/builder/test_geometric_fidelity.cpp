// Geometric fidelity of the tetrahedral filling: sharp feature edges protected (a box keeps its
// corners, volume and face areas), and the build report's volume and area comparison with its
// warning above 1 %, which a smooth shape does not trigger.

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm/builder/metric_field.hpp"
#include "fsm/fsm.hpp"
#include "shapes.hpp"

namespace fsm::build {
namespace {

namespace fs = std::filesystem;
using V = Eigen::Vector3d;

// The validation's block (validation/scenes.py): [0, 20] x [0, 20] x [0, 10] mm, each face split
// into n x n quads, two triangles each, outward.
const V kBox(0.020, 0.020, 0.010);

TriangleMesh<double> box_mesh(const V& size, int n = 4) {
  std::vector<V> verts;
  std::map<std::array<long long, 3>, Index> index;
  std::vector<std::array<Index, 3>> faces;
  auto vertex = [&](const V& p) {
    const std::array<long long, 3> key{std::llround(p.x() * 1e9), std::llround(p.y() * 1e9),
                                       std::llround(p.z() * 1e9)};
    auto [it, inserted] = index.emplace(key, Index(verts.size()));
    if (inserted) verts.push_back(p);
    return it->second;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
          std::array<Index, 4> q;
          const int da[4] = {0, 1, 1, 0}, db[4] = {0, 0, 1, 1};
          for (int k = 0; k < 4; ++k) {
            V p = V::Zero();
            p[axis] = side * size[axis];
            p[u] = (a + da[k]) * size[u] / n;
            p[w] = (b + db[k]) * size[w] / n;
            q[std::size_t(k)] = vertex(p);
          }
          if (side == 0) std::swap(q[1], q[3]);  // (u, w, axis) is right-handed: face -axis
          faces.push_back({q[0], q[1], q[2]});
          faces.push_back({q[0], q[2], q[3]});
        }
    }
  TriangleMesh<double> m;
  m.vertices.resize(Index(verts.size()), 3);
  for (std::size_t i = 0; i < verts.size(); ++i) m.vertices.row(Index(i)) = verts[i].transpose();
  m.faces.resize(Index(faces.size()), 3);
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) m.faces(Index(i), k) = faces[i][std::size_t(k)];
  return m;
}

// The boundary faces of a tetrahedral mesh (faces of one tetrahedron only), as vertex triples.
std::vector<std::array<Index, 3>> boundary_faces(const TetrahedralMesh<double>& m) {
  std::map<std::array<Index, 3>, std::pair<int, std::array<Index, 3>>> count;
  static const int opp[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (Index t = 0; t < m.tetrahedra.rows(); ++t)
    for (const auto& o : opp) {
      std::array<Index, 3> f{m.tetrahedra(t, o[0]), m.tetrahedra(t, o[1]), m.tetrahedra(t, o[2])};
      std::array<Index, 3> key = f;
      std::sort(key.begin(), key.end());
      auto& [n, face] = count[key];
      ++n;
      face = f;
    }
  std::vector<std::array<Index, 3>> out;
  for (const auto& [key, v] : count)
    if (v.first == 1) out.push_back(v.second);
  return out;
}

// Area of the filling's boundary faces lying in the plane z = `z` (every vertex within `tol`).
double area_at_z(const TetrahedralMesh<double>& m, double z, double tol) {
  double a = 0;
  for (const auto& f : boundary_faces(m)) {
    const V p = m.vertices.row(f[0]).transpose(), q = m.vertices.row(f[1]).transpose(),
            r = m.vertices.row(f[2]).transpose();
    if (std::abs(p.z() - z) <= tol && std::abs(q.z() - z) <= tol && std::abs(r.z() - z) <= tol)
      a += 0.5 * (q - p).cross(r - p).norm();
  }
  return a;
}

// How many of the box's 8 corners are vertices of the filling (within `tol`).
int corners_kept(const TetrahedralMesh<double>& m, const V& size, double tol) {
  int kept = 0;
  for (int c = 0; c < 8; ++c) {
    const V corner((c & 1) * size.x(), ((c >> 1) & 1) * size.y(), ((c >> 2) & 1) * size.z());
    double best = std::numeric_limits<double>::infinity();
    for (Index v = 0; v < m.vertices.rows(); ++v)
      best = std::min(best, (m.vertices.row(v).transpose() - corner).norm());
    kept += best <= tol;
  }
  return kept;
}

class BoxFilling : public ::testing::TestWithParam<double> {};

// A 20 x 20 x 10 mm box at sphere radii of 1.5 and 2 mm: every corner is a vertex, the volume and
// the top face's covered area are within 1 % of the box's.
TEST_P(BoxFilling, KeepsCornersVolumeAndFaceArea) {
  const double r = GetParam();
  const auto surface = box_mesh(kBox);
  ASSERT_NEAR(surface.volume(), 4e-6, 1e-15);
  const auto metric = isotropic_metric(r);
  const TetraFilling fill = fill_tetrahedral(surface, *metric, "", "block");
  const auto& m = fill.mesh;
  ASSERT_NO_THROW(m.validate("block"));
  const double scale = kBox.norm();
  const int corners = corners_kept(m, kBox, 1e-6 * scale);
  const double volume = m.volume(), top = area_at_z(m, kBox.z(), 1e-6 * scale),
               bottom = area_at_z(m, 0, 1e-6 * scale);
  RecordProperty("corners", corners);
  RecordProperty("volume_mm3", std::to_string(volume * 1e9));
  RecordProperty("top_area_mm2", std::to_string(top * 1e6));
  std::printf(
      "r = %.1f mm: %d corners, volume %.1f mm^3, top %.1f mm^2, bottom %.1f mm^2, "
      "%d vertices, Q in [1,3] %.1f %%, min dihedral %.1f deg\n",
      r * 1e3, corners, volume * 1e9, top * 1e6, bottom * 1e6, int(m.vertices.rows()),
      100 * fill.quality.fraction_q_1_3, fill.quality.min_dihedral_deg);
  EXPECT_EQ(corners, 8);
  EXPECT_EQ(fill.feature_corners, 8);
  EXPECT_EQ(fill.feature_edges, 12 * 4);  // every box edge, in its 4 input segments
  EXPECT_EQ(fill.feature_angle_deg, 60);
  EXPECT_NEAR(volume, 4e-6, 0.01 * 4e-6);
  EXPECT_NEAR(top, 4e-4, 0.01 * 4e-4);
  EXPECT_NEAR(bottom, 4e-4, 0.01 * 4e-4);
  EXPECT_GT(fill.quality.fraction_q_1_3, 0.9);
}

INSTANTIATE_TEST_SUITE_P(Radii, BoxFilling, ::testing::Values(0.0015, 0.002),
                         [](const auto& param_info) {  // "r15" is 1.5 mm
                           return "r" + std::to_string(int(std::lround(param_info.param * 1e4)));
                         });

// Without protection (angle 0) the same box is chamfered: what the protection fixes.
TEST(BoxFilling, WithoutProtectionTheEdgesAreChamfered) {
  const auto surface = box_mesh(kBox);
  const TetraFilling fill = fill_tetrahedral(surface, *isotropic_metric(0.0015), "", "block", 0);
  EXPECT_EQ(fill.feature_edges, 0);
  EXPECT_LT(corners_kept(fill.mesh, kBox, 1e-6 * kBox.norm()), 8);
  EXPECT_LT(fill.mesh.volume(), 0.99 * 4e-6);
  EXPECT_LT(area_at_z(fill.mesh, kBox.z(), 1e-6 * kBox.norm()), 0.99 * 4e-4);
}

// A smooth surface has no sharp edge: it takes the filling's path without protection, and gives
// the same filling. (Not compared bit for bit: Mesh_3's result can vary slightly from run to run
// and with what the process meshed before, with or without protection.)
TEST(SmoothFilling, SphereIsFilledAsWithoutProtection) {
  const auto surface = test::icosphere(0.02, 4);
  const auto metric = isotropic_metric(0.002);
  const TetraFilling with = fill_tetrahedral(surface, *metric, "", "ball");
  const TetraFilling without = fill_tetrahedral(surface, *metric, "", "ball", 0);
  EXPECT_EQ(with.feature_angle_deg, 60);
  EXPECT_EQ(with.feature_edges, 0);
  EXPECT_EQ(with.feature_corners, 0);
  EXPECT_NEAR(double(with.mesh.vertices.rows()), double(without.mesh.vertices.rows()),
              0.01 * double(without.mesh.vertices.rows()));
  EXPECT_NEAR(with.mesh.volume(), without.mesh.volume(), 1e-3 * without.mesh.volume());
  EXPECT_NEAR(with.quality.q_mean, without.quality.q_mean, 0.01);
}

// ---- The build report ----------------------------------------------------------------------

// Scenes in mm around the box (written as OFF, in mm) and a ball, in a scratch folder.
class FidelityInReport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("fsm_fidelity_" +
           std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    TriangleMesh<double> box = box_mesh(kBox * 1e3);  // mm
    std::ofstream off(dir / "box.off");
    off.precision(17);
    off << "OFF\n" << box.num_vertices() << " " << box.num_faces() << " 0\n";
    for (Index v = 0; v < box.num_vertices(); ++v)
      off << box.vertices(v, 0) << " " << box.vertices(v, 1) << " " << box.vertices(v, 2) << "\n";
    for (Index f = 0; f < box.num_faces(); ++f)
      off << "3 " << box.faces(f, 0) << " " << box.faces(f, 1) << " " << box.faces(f, 2) << "\n";
    off.close();
    write_mesh((dir / "ball.obj").string(), test::icosphere(20, 4));  // mm
  }
  void TearDown() override { fs::remove_all(dir); }

  // One tetrahedral part in mm with the given mesh, radius and fixed regions.
  std::string scene(const std::string& mesh, double radius, const std::string& fixed) const {
    const std::string text =
        R"({"format": "fsm-scene", "version": 1, "name": "fidelity", "units": "mm",
        "parts": [{"name": "block", "mesh": ")" +
        mesh + R"(", "topology": "tetrahedral", "radius": )" + std::to_string(radius) +
        R"(, "material": {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26}}],
        "fixed": [)" +
        fixed + "]}";
    const std::string path = (dir / "scene.json").string();
    std::ofstream(path) << text;
    return path;
  }

  static bool any_warning_has(const BuildReport& r, const std::string& words) {
    for (const std::string& w : r.warnings())
      if (w.find(words) != std::string::npos) return true;
    return false;
  }

  fs::path dir;
};

// The validation's box, fixed at the bottom (a box, as validation/scenes.py writes it) and at the
// top (a half-space): the report gives the volume, the total area and each region's area, all
// within 1 %, with no warning; the corners are spheres of the model.
TEST_F(FidelityInReport, BoxReportsVolumeAndRegionAreas) {
  const std::string fixed =
      R"({"part": "block", "box": {"min": [-1, -1, -1], "max": [21, 21, 0.001]}},
         {"part": "block", "plane": {"point": [0, 0, 9.999], "normal": [0, 0, -1]}},
         {"part": "block", "vertices": [0]})";
  BuildReport report;
  const TissueModel<double> model = build_model(scene("box.off", 1.5, fixed), &report);
  ASSERT_EQ(report.parts.size(), 1u);
  const FidelityReport& f = report.parts[0].fidelity;
  EXPECT_NEAR(f.input_volume, 4e-6, 1e-15);
  EXPECT_NEAR(f.filled_volume, 4e-6, 0.01 * 4e-6);
  EXPECT_NEAR(f.volume_difference, f.filled_volume / f.input_volume - 1, 1e-15);
  EXPECT_NEAR(f.input_area, 1.6e-3, 1e-12);  // 2 x 400 + 4 x 200 mm^2
  EXPECT_NEAR(f.filled_area, 1.6e-3, 0.01 * 1.6e-3);
  EXPECT_EQ(f.feature_corners, 8);
  EXPECT_EQ(f.feature_angle_deg, 60);
  ASSERT_EQ(f.regions.size(), 2u);  // the vertices region is not geometric
  EXPECT_EQ(f.regions[0].region, "fixed region 0 (box)");
  EXPECT_EQ(f.regions[1].region, "fixed region 1 (plane)");
  // The bottom box reaches 1 um up the sides: 400 mm^2 plus 80 mm x 1 um.
  EXPECT_NEAR(f.regions[0].input_area, 400.08e-6, 1e-11);
  EXPECT_NEAR(f.regions[1].input_area, 400.08e-6, 1e-11);
  for (const RegionFidelity& r : f.regions) {
    EXPECT_NEAR(r.filled_area, r.input_area, 0.01 * r.input_area) << r.region;
    EXPECT_LE(std::abs(r.difference), 0.01) << r.region;
  }
  EXPECT_TRUE(report.warnings().empty()) << report.warnings().front();
  // The figures are in the JSON report (and so in the model file).
  const auto j = nlohmann::json::parse(report.json());
  const auto& jf = j["parts"][0]["fidelity"];
  EXPECT_NEAR(jf["filled_volume_m3"].get<double>(), f.filled_volume, 1e-18);
  EXPECT_NEAR(jf["input_volume_m3"].get<double>(), 4e-6, 1e-15);
  EXPECT_EQ(jf["regions"].size(), 2u);
  EXPECT_EQ(jf["regions"][1]["region"], "fixed region 1 (plane)");
  EXPECT_NEAR(jf["regions"][1]["filled_area_m2"].get<double>(), f.regions[1].filled_area, 1e-18);
  EXPECT_EQ(jf["tolerance"].get<double>(), 0.01);
  EXPECT_EQ(jf["feature_corners"].get<int>(), 8);
  EXPECT_EQ(nlohmann::json::parse(model.report_json)["parts"][0]["fidelity"], jf);
  // Every corner of the box is the centre of a sphere.
  const auto x = model.spheres.rest_positions();
  for (int c = 0; c < 8; ++c) {
    const V corner((c & 1) * kBox.x(), ((c >> 1) & 1) * kBox.y(), ((c >> 2) & 1) * kBox.z());
    double best = std::numeric_limits<double>::infinity();
    for (Index i = 0; i < x.rows(); ++i)
      best = std::min(best, (x.row(i).transpose() - corner).norm());
    EXPECT_LE(best, 1e-6 * kBox.norm()) << "corner " << c;
  }
  // A region enclosing the whole part holds the whole surface and the whole boundary.
  BuildReport all;
  (void)build_model(scene("box.off", 1.5, R"({"part": "block", "box": {"min": [-1, -1, -1],
                                                                       "max": [21, 21, 11]}})"),
                    &all);
  const FidelityReport& a = all.parts[0].fidelity;
  ASSERT_EQ(a.regions.size(), 1u);
  EXPECT_NEAR(a.regions[0].input_area, a.input_area, 1e-12);
  EXPECT_NEAR(a.regions[0].filled_area, a.filled_area, 1e-12);
}

// A smooth ball (r = 2 cm) at 2 mm: within 1 % in volume, area and at its fixed cap, so no
// warning; nothing protected.
TEST_F(FidelityInReport, SmoothBallHasNoWarning) {
  BuildReport report;
  (void)build_model(scene("ball.obj", 2.0, R"({"part": "block", "box": {"min": [-30, -30, -30],
                                                          "max": [30, 30, -15]}})"),
                    &report);
  const FidelityReport& f = report.parts[0].fidelity;
  RecordProperty("volume_difference", std::to_string(f.volume_difference));
  RecordProperty("area_difference", std::to_string(f.area_difference));
  EXPECT_EQ(f.feature_edges, 0);
  EXPECT_EQ(f.feature_corners, 0);
  EXPECT_LT(std::abs(f.volume_difference), 0.01);
  EXPECT_LT(std::abs(f.area_difference), 0.01);
  ASSERT_EQ(f.regions.size(), 1u);
  EXPECT_GT(f.regions[0].input_area, 0);
  EXPECT_LT(std::abs(f.regions[0].difference), 0.01);
  EXPECT_TRUE(report.warnings().empty()) << report.warnings().front();
}

// The same ball at 5 mm loses more than 1 % of its volume to the facets: warned about, naming
// the figures, in the report's warnings and its JSON.
TEST_F(FidelityInReport, CoarseFillingIsWarnedAbout) {
  BuildReport report;
  (void)build_model(scene("ball.obj", 5.0, R"({"part": "block", "box": {"min": [-30, -30, -30],
                                                          "max": [30, 30, -15]}})"),
                    &report);
  const FidelityReport& f = report.parts[0].fidelity;
  EXPECT_LT(f.volume_difference, -0.01);
  EXPECT_TRUE(any_warning_has(report,
                              "part 'block': the tetrahedral filling differs from its "
                              "surface by more than 1 %"));
  EXPECT_TRUE(any_warning_has(report, "cm^3"));
  EXPECT_TRUE(any_warning_has(report, "fixed region 0 (box): the filling's boundary covers"));
  const auto j = nlohmann::json::parse(report.json());
  bool in_json = false;
  for (const auto& w : j["warnings"])
    in_json = in_json || w.get<std::string>().find("differs from its surface") != std::string::npos;
  EXPECT_TRUE(in_json);
}

}  // namespace
}  // namespace fsm::build
