// The default data set (procedural uterus): parts and names, closed manifold outward surfaces
// without self-intersections, Table 1 sphere counts under the builder's Mesh_3 rule, body and
// fibroid in contact, tubes clear of ligaments and ovaries, attached parts penetrating, the scene
// file, determinism, and the committed data/uterus matching the generator.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Random.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/make_mesh_3.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "fsm/builder/uterus_generator.hpp"

namespace fsm::build {
namespace {

using V = Eigen::Vector3d;
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Surface = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

const std::vector<std::string> kNames{"body",        "fibroid",       "ovary_left",
                                      "ovary_right", "ligament_left", "ligament_right",
                                      "tube_left",   "tube_right"};

/// The default data set, generated once per test process.
const UterusMeshes& uterus() {
  static const UterusMeshes meshes = generate_uterus();
  return meshes;
}

const TriangleMesh<double>& part(const std::string& name) {
  const auto& u = uterus();
  for (std::size_t i = 0; i < u.names.size(); ++i)
    if (u.names[i] == name) return u.meshes[i];
  throw std::runtime_error("no part " + name);
}

V vertex(const TriangleMesh<double>& m, Index v) {
  return m.vertices.row(v).transpose();
}

Surface to_surface(const TriangleMesh<double>& m, double scale = 1.0) {
  Surface sm;
  std::vector<Surface::Vertex_index> v;
  for (Index i = 0; i < m.num_vertices(); ++i) {
    const V p = scale * vertex(m, i);
    v.push_back(sm.add_vertex(K::Point_3(p.x(), p.y(), p.z())));
  }
  for (Index f = 0; f < m.num_faces(); ++f)
    sm.add_face(v[std::size_t(m.faces(f, 0))], v[std::size_t(m.faces(f, 1))],
                v[std::size_t(m.faces(f, 2))]);
  return sm;
}

// ---- Distances -------------------------------------------------------------------------------

/// Distance from p to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
double point_triangle_distance(const V& p, const V& a, const V& b, const V& c) {
  const V ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.norm();
  const V bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const V cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

/// Distance from p to the surface m.
double point_mesh_distance(const V& p, const TriangleMesh<double>& m) {
  double best = std::numeric_limits<double>::infinity();
  for (Index f = 0; f < m.num_faces(); ++f)
    best =
        std::min(best, point_triangle_distance(p, vertex(m, m.faces(f, 0)),
                                               vertex(m, m.faces(f, 1)), vertex(m, m.faces(f, 2))));
  return best;
}

/// Smallest distance between two disjoint surfaces (vertex-to-triangle both ways: exact unless
/// two edges cross closer than any vertex, which for triangles of ~2 mm errs by far less than
/// the gaps tested here).
double surface_gap(const TriangleMesh<double>& a, const TriangleMesh<double>& b) {
  double best = std::numeric_limits<double>::infinity();
  for (Index v = 0; v < a.num_vertices(); ++v)
    best = std::min(best, point_mesh_distance(vertex(a, v), b));
  for (Index v = 0; v < b.num_vertices(); ++v)
    best = std::min(best, point_mesh_distance(vertex(b, v), a));
  return best;
}

// ---- The builder's tetrahedral rule ----------------------------------------------------------

using Domain = CGAL::Polyhedral_mesh_domain_3<Surface, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

/// The spheres (vertices of the Mesh_3 complex) a tetrahedral part of radius `r` (m) gets: the
/// surface as the builder sees it (OBJ in cm with 6 decimals, read in metres), mapped by the
/// metric's M^1/2 = I/r to unit size, meshed with cell_size = facet_size = 1, facet_distance =
/// 1/4, facet_angle = 25, cell_radius_edge_ratio = 2, ODT then exudation. Positions in metres.
std::vector<V> tetrahedral_spheres(const TriangleMesh<double>& surface, double r) {
  TriangleMesh<double> read = surface;
  for (Index v = 0; v < read.num_vertices(); ++v)
    for (int k = 0; k < 3; ++k) {
      std::ostringstream cm;
      cm << std::fixed << std::setprecision(6) << surface.vertices(v, k) * 100.0;
      read.vertices(v, k) = std::stod(cm.str()) * 0.01;
    }
  const Eigen::Matrix3d metric = Eigen::Matrix3d::Identity() / (r * r);
  const Eigen::Matrix3d to_unit =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(metric).operatorSqrt();
  TriangleMesh<double> unit = read;
  for (Index v = 0; v < unit.num_vertices(); ++v)
    unit.vertices.row(v) = (to_unit * vertex(read, v)).transpose();

  const Surface sm = to_surface(unit);
  const Domain domain(sm);
  namespace P = CGAL::parameters;
  const Criteria criteria(P::facet_angle = 25, P::facet_size = 1.0, P::facet_distance = 0.25,
                          P::cell_radius_edge_ratio = 2, P::cell_size = 1.0);
  CGAL::get_default_random() = CGAL::Random(0);
  const C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, P::odt(P::max_iteration_number = 20),
                                            P::no_perturb(), P::exude());
  std::set<Tr::Vertex_handle> used;
  std::vector<V> out;
  const Eigen::Matrix3d from_unit = to_unit.inverse();
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c)
    for (int k = 0; k < 4; ++k)
      if (used.insert(c->vertex(k)).second) {
        const auto& p = c->vertex(k)->point();
        out.push_back(from_unit *
                      V(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())));
      }
  return out;
}

/// The Table 1 parts' spheres, computed once per process.
const std::map<std::string, std::vector<V>>& table1_spheres() {
  static const std::map<std::string, std::vector<V>> spheres{
      {"body", tetrahedral_spheres(part("body"), 0.005)},
      {"fibroid", tetrahedral_spheres(part("fibroid"), 0.003)},
      {"ovary_left", tetrahedral_spheres(part("ovary_left"), 0.004)}};
  return spheres;
}

// ---- Tests -----------------------------------------------------------------------------------

TEST(UterusGenerator, HasTheEightNamedParts) {
  const auto& u = uterus();
  EXPECT_EQ(u.names, kNames);
  ASSERT_EQ(u.meshes.size(), kNames.size());
  for (std::size_t i = 0; i < u.meshes.size(); ++i)
    EXPECT_NO_THROW(u.meshes[i].validate(u.names[i]));
}

// Every part is closed (each edge on exactly two faces, used once in each direction: also
// consistently oriented), vertex-manifold, one component, outward (positive volume) and free of
// self-intersections.
TEST(UterusGenerator, SurfacesAreClosedManifoldOutwardAndNotSelfIntersecting) {
  const auto& u = uterus();
  for (std::size_t i = 0; i < u.meshes.size(); ++i) {
    SCOPED_TRACE(u.names[i]);
    const auto& m = u.meshes[i];
    std::map<std::pair<Index, Index>, int> directed;
    for (Index f = 0; f < m.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) ++directed[{m.faces(f, k), m.faces(f, (k + 1) % 3)}];
    Index border = 0, non_manifold = 0;
    for (const auto& [edge, count] : directed) {
      if (count != 1) ++non_manifold;
      const auto twin = directed.find({edge.second, edge.first});
      if (twin == directed.end()) ++border;
    }
    EXPECT_EQ(border, 0);
    EXPECT_EQ(non_manifold, 0);

    std::vector<std::array<std::size_t, 3>> soup;
    std::vector<K::Point_3> points;
    for (Index v = 0; v < m.num_vertices(); ++v)
      points.emplace_back(m.vertices(v, 0), m.vertices(v, 1), m.vertices(v, 2));
    for (Index f = 0; f < m.num_faces(); ++f)
      soup.push_back(
          {std::size_t(m.faces(f, 0)), std::size_t(m.faces(f, 1)), std::size_t(m.faces(f, 2))});
    // Also false for a non-manifold vertex (two fans sharing a vertex).
    EXPECT_TRUE(PMP::is_polygon_soup_a_polygon_mesh(soup));

    Surface sm = to_surface(m);
    EXPECT_TRUE(CGAL::is_closed(sm));
    EXPECT_TRUE(sm.is_valid());
    EXPECT_FALSE(PMP::does_self_intersect(sm));
    const auto component = sm.add_property_map<Surface::Face_index, std::size_t>("f:cc").first;
    EXPECT_EQ(PMP::connected_components(sm, component), 1u);
    EXPECT_GT(m.volume(), 0.0);
    EXPECT_NEAR(PMP::volume(sm), m.volume(), 1e-12);
  }
}

// The paper's Table 1 counts under the builder's rule for tetrahedral parts, within 15 %; the
// axis parts' counts from their length (volume of a capped tube: pi r^2 L + 4/3 pi r^3), at
// spacing = radius.
TEST(UterusGenerator, SphereCountsMatchTable1) {
  const auto& spheres = table1_spheres();
  const std::map<std::string, double> table{{"body", 517}, {"fibroid", 39}, {"ovary_left", 29}};
  for (const auto& [name, expected] : table) {
    const double n = double(spheres.at(name).size());
    std::cout << "[ counts   ] " << name << ": " << n << " spheres (Table 1: " << expected << ")\n";
    EXPECT_NEAR(n, expected, 0.15 * expected) << name;
  }
  const std::map<std::string, std::pair<double, double>> axis{{"ligament_left", {0.0025, 9}},
                                                              {"tube_left", {0.0033, 31}}};
  for (const auto& [name, spec] : axis) {
    const double r = spec.first;
    const double length = (part(name).volume() - 4.0 / 3.0 * M_PI * r * r * r) / (M_PI * r * r);
    const double n = length / r + 1;
    std::cout << "[ counts   ] " << name << ": axis " << length * 100 << " cm, ~" << n
              << " spheres (Table 1: " << spec.second << ")\n";
    EXPECT_NEAR(n, spec.second, 0.15 * spec.second) << name;
  }
}

// The scene's fixed regions select spheres: the body's cervical box, each ovary's lateral plane.
TEST(UterusGenerator, FixedRegionsSelectSpheres) {
  const UterusShape shape;
  const auto& spheres = table1_spheres();
  const double bottom = -shape.body_length / 2;
  Index in_box = 0;
  for (const V& p : spheres.at("body")) in_box += p.z() <= bottom + 0.01;
  EXPECT_GE(in_box, 3);
  Index lateral = 0;
  for (const V& p : spheres.at("ovary_left"))
    lateral += p.x() >= shape.ovary_offset + 0.6 * shape.ovary_size.x() / 2;
  EXPECT_GE(lateral, 1);
}

// The body is the pear minus the fibroid's ball: they touch over the fibroid's embedded cap,
// the fibroid bulges out, and no fibroid vertex lies deep inside the body.
TEST(UterusGenerator, BodyAndFibroidShareTheEmbeddedCap) {
  const auto& body = part("body");
  const auto& fibroid = part("fibroid");
  const Surface body_sm = to_surface(body);
  const CGAL::Side_of_triangle_mesh<Surface, K> inside_body(body_sm);
  Index touching = 0, bulging = 0, buried = 0;
  for (Index v = 0; v < fibroid.num_vertices(); ++v) {
    const V p = vertex(fibroid, v);
    const double d = point_mesh_distance(p, body);
    touching += d < 0.001;
    const auto side = inside_body(K::Point_3(p.x(), p.y(), p.z()));
    bulging += side == CGAL::ON_UNBOUNDED_SIDE && d > 0.003;
    buried += side == CGAL::ON_BOUNDED_SIDE && d > 0.0005;
  }
  EXPECT_GT(touching, 20);  // a cap's worth of vertices
  EXPECT_GT(bulging, 20);
  EXPECT_EQ(buried, 0);
  // Body vertices within 1 mm of fibroid vertices (the brief's contact test).
  Index close = 0;
  for (Index v = 0; v < body.num_vertices(); ++v)
    for (Index w = 0; w < fibroid.num_vertices(); ++w)
      if ((vertex(body, v) - vertex(fibroid, w)).norm() < 0.001) {
        ++close;
        break;
      }
  EXPECT_GT(close, 10);
}

// Tubes keep at least 3 mm from the ligaments and the ovaries (the brief allows closeness at the
// body end only; here the gap holds everywhere), and from the fibroid.
TEST(UterusGenerator, TubesKeepClearOfLigamentsAndOvaries) {
  for (const std::string side : {"left", "right"}) {
    SCOPED_TRACE(side);
    const auto& tube = part("tube_" + side);
    const double to_ligament = surface_gap(tube, part("ligament_" + side));
    const double to_ovary = surface_gap(tube, part("ovary_" + side));
    std::cout << "[ gaps     ] tube_" << side << ": ligament " << to_ligament * 1e3 << " mm, ovary "
              << to_ovary * 1e3 << " mm\n";
    EXPECT_GE(to_ligament, 0.003);
    EXPECT_GE(to_ovary, 0.003);
    EXPECT_GE(surface_gap(tube, part("fibroid")), 0.003);
  }
}

// Ligaments reach a few mm into the body and the ovary; tubes start inside the body; ovaries
// are separate from the body.
TEST(UterusGenerator, AttachedPartsPenetrate) {
  const Surface body_sm = to_surface(part("body"));
  const CGAL::Side_of_triangle_mesh<Surface, K> inside_body(body_sm);
  const auto depth_inside = [](const TriangleMesh<double>& m, const TriangleMesh<double>& host,
                               const CGAL::Side_of_triangle_mesh<Surface, K>& inside) {
    double deepest = 0;
    for (Index v = 0; v < m.num_vertices(); ++v) {
      const V p = vertex(m, v);
      if (inside(K::Point_3(p.x(), p.y(), p.z())) == CGAL::ON_BOUNDED_SIDE)
        deepest = std::max(deepest, point_mesh_distance(p, host));
    }
    return deepest;
  };
  for (const std::string side : {"left", "right"}) {
    SCOPED_TRACE(side);
    const auto& ovary = part("ovary_" + side);
    const Surface ovary_sm = to_surface(ovary);
    const CGAL::Side_of_triangle_mesh<Surface, K> inside_ovary(ovary_sm);
    const auto& ligament = part("ligament_" + side);
    EXPECT_GE(depth_inside(ligament, part("body"), inside_body), 0.002);
    EXPECT_GE(depth_inside(ligament, ovary, inside_ovary), 0.002);
    EXPECT_GE(depth_inside(part("tube_" + side), part("body"), inside_body), 0.002);
    EXPECT_GE(surface_gap(ovary, part("body")), 0.005);
  }
}

TEST(UterusGenerator, IsDeterministic) {
  const UterusMeshes again = generate_uterus();
  const auto& u = uterus();
  ASSERT_EQ(again.names, u.names);
  for (std::size_t i = 0; i < u.meshes.size(); ++i) {
    SCOPED_TRACE(u.names[i]);
    EXPECT_TRUE(again.meshes[i].vertices == u.meshes[i].vertices);
    EXPECT_TRUE(again.meshes[i].faces == u.meshes[i].faces);
  }
}

TEST(UterusGenerator, RejectsImpossibleShapes) {
  UterusShape shape;
  shape.fibroid_protrusion = 1.5;
  EXPECT_THROW(generate_uterus(shape), Error);
  shape = UterusShape{};
  shape.body_width = -0.05;
  EXPECT_THROW(generate_uterus(shape), Error);
  shape = UterusShape{};
  shape.tube_length = 0.5;  // longer than the path around the ovary
  EXPECT_THROW(generate_uterus(shape), Error);
}

/// Reads an OBJ written by write_uterus_scene (v and f lines only), in the file's units.
TriangleMesh<double> read_obj(const std::string& path) {
  std::ifstream in(path);
  std::vector<V> v;
  std::vector<std::array<Index, 3>> f;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "v") {
      V p;
      s >> p.x() >> p.y() >> p.z();
      v.push_back(p);
    } else if (tag == "f") {
      std::array<Index, 3> t;
      s >> t[0] >> t[1] >> t[2];
      f.push_back({t[0] - 1, t[1] - 1, t[2] - 1});
    }
  }
  TriangleMesh<double> m;
  m.vertices.resize(Index(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(Index(i)) = v[i].transpose();
  m.faces.resize(Index(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i) m.faces.row(Index(i)) << f[i][0], f[i][1], f[i][2];
  return m;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

std::string temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fsm_test_uterus_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir.string();
}

// The scene: Table 1 topologies and radii, the paper's material, the attachments and fixed
// regions, every part attached to a fixed part or fixed; the OBJ files in cm.
TEST(UterusGenerator, WritesTheScene) {
  const std::string dir = temp_dir("scene");
  const std::string path = write_uterus_scene(dir);
  EXPECT_EQ(std::filesystem::path(path).filename(), "uterus.json");
  const nlohmann::json scene = read_json(path);
  EXPECT_EQ(scene["format"], "fsm-scene");
  EXPECT_EQ(scene["version"], 1);
  EXPECT_EQ(scene["units"], "cm");
  EXPECT_EQ(scene["mesh_units"], "cm");

  const std::map<std::string, std::pair<std::string, double>> table{
      {"body", {"tetrahedral", 0.50}},       {"fibroid", {"tetrahedral", 0.30}},
      {"ovary_left", {"tetrahedral", 0.40}}, {"ovary_right", {"tetrahedral", 0.40}},
      {"ligament_left", {"axis", 0.25}},     {"ligament_right", {"axis", 0.25}},
      {"tube_left", {"axis", 0.33}},         {"tube_right", {"axis", 0.33}}};
  ASSERT_EQ(scene["parts"].size(), table.size());
  for (const auto& p : scene["parts"]) {
    const std::string name = p["name"];
    SCOPED_TRACE(name);
    ASSERT_TRUE(table.count(name));
    EXPECT_EQ(p["topology"], table.at(name).first);
    EXPECT_DOUBLE_EQ(p["radius"].get<double>(), table.at(name).second);
    EXPECT_EQ(p["material"]["density"], 1050);
    EXPECT_EQ(p["material"]["youngs_modulus"], 13150);
    EXPECT_EQ(p["material"]["large_strain_modulus"], 68380);
    EXPECT_DOUBLE_EQ(p["material"]["switch_strain"].get<double>(), 0.1);
    EXPECT_DOUBLE_EQ(p["material"]["viscosity"].get<double>(), 10.26);
    const std::string mesh_path =
        (std::filesystem::path(dir) / p["mesh"].get<std::string>()).string();
    ASSERT_TRUE(std::filesystem::exists(mesh_path));
    const TriangleMesh<double> cm = read_obj(mesh_path);
    const TriangleMesh<double>& m = part(name);
    EXPECT_EQ(cm.num_vertices(), m.num_vertices());
    EXPECT_TRUE(cm.faces == m.faces);
    EXPECT_NEAR(cm.volume() * 1e-6, m.volume(), 1e-6 * m.volume());  // cm^3 -> m^3
  }

  // Attachments, and every part attached (transitively) to a fixed part.
  const std::set<std::set<std::string>> expected_pairs{{"body", "fibroid"},
                                                       {"body", "ligament_left"},
                                                       {"body", "ligament_right"},
                                                       {"ovary_left", "ligament_left"},
                                                       {"ovary_right", "ligament_right"},
                                                       {"body", "tube_left"},
                                                       {"body", "tube_right"}};
  std::set<std::set<std::string>> pairs;
  std::map<std::string, std::set<std::string>> linked;
  for (const auto& a : scene["attachments"]) {
    EXPECT_DOUBLE_EQ(a["tolerance"].get<double>(), 0.3);
    const std::string x = a["parts"][0], y = a["parts"][1];
    pairs.insert({x, y});
    linked[x].insert(y);
    linked[y].insert(x);
  }
  EXPECT_EQ(pairs, expected_pairs);
  std::set<std::string> fixed;
  for (const auto& f : scene["fixed"]) fixed.insert(f["part"].get<std::string>());
  EXPECT_EQ(fixed, (std::set<std::string>{"body", "ovary_left", "ovary_right"}));
  std::set<std::string> reached = fixed;
  for (bool grew = true; grew;) {
    grew = false;
    for (const auto& [a, bs] : linked)
      if (reached.count(a))
        for (const auto& b : bs) grew |= reached.insert(b).second;
  }
  EXPECT_EQ(reached.size(), table.size());
  std::filesystem::remove_all(dir);
}

// data/uterus is what make-uterus writes: the same scene, and meshes with the same counts and
// volumes (to 0.5 %: a different compiler may round differently inside the mesher).
TEST(UterusGenerator, CommittedDataSetIsCurrent) {
  const std::filesystem::path data = std::filesystem::path(FSM_SOURCE_DIR) / "data" / "uterus";
  ASSERT_TRUE(std::filesystem::exists(data / "uterus.json")) << data;
  const std::string dir = temp_dir("data");
  const std::string path = write_uterus_scene(dir);
  EXPECT_EQ(read_json((data / "uterus.json").string()), read_json(path))
      << "regenerate data/uterus (see data/uterus/README.md)";
  for (const auto& name : kNames) {
    SCOPED_TRACE(name);
    const TriangleMesh<double> committed = read_obj((data / (name + ".obj")).string());
    const TriangleMesh<double> fresh =
        read_obj((std::filesystem::path(dir) / (name + ".obj")).string());
    EXPECT_NEAR(double(committed.num_faces()), double(fresh.num_faces()),
                0.05 * double(fresh.num_faces()));
    EXPECT_NEAR(committed.volume(), fresh.volume(), 0.005 * fresh.volume());
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fsm::build
