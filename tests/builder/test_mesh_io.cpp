// Surface mesh reading, writing, inspection and repair (fsm/builder/mesh_io.hpp): small meshes
// built in code with known answers, round trips through the four formats, errors that name the
// file, and the real Visible Human Female pelvis meshes from the shared data folder.

#include "fsm/builder/mesh_io.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <tuple>

namespace fsm::build {
namespace {

namespace fs = std::filesystem;
using Mesh = TriangleMesh<double>;
using V = Eigen::Vector3d;

// ---------------------------------------------------------------------------------------------
// Fixtures
// ---------------------------------------------------------------------------------------------

/// An axis-aligned cube [origin, origin + side]^3, 8 vertices, 12 outward triangles.
Mesh cube(double side = 1.0, const V& origin = V::Zero()) {
  Mesh m;
  m.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    m.vertices.row(i) = (origin + side * V(i & 1, (i >> 1) & 1, (i >> 2) & 1)).transpose();
  // Vertex i = (x, y, z) bits; each quad counter-clockwise seen from outside.
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  m.faces.resize(12, 3);
  for (int q = 0; q < 6; ++q) {
    m.faces.row(2 * q) << quads[q][0], quads[q][1], quads[q][2];
    m.faces.row(2 * q + 1) << quads[q][0], quads[q][2], quads[q][3];
  }
  return m;
}

/// The two meshes in one, vertices of `b` after those of `a`; with `weld`, exactly coincident
/// vertices become one.
Mesh combine(const Mesh& a, const Mesh& b, bool weld) {
  Mesh m;
  m.vertices.resize(a.vertices.rows() + b.vertices.rows(), 3);
  m.vertices << a.vertices, b.vertices;
  m.faces.resize(a.faces.rows() + b.faces.rows(), 3);
  m.faces << a.faces, (b.faces.array() + a.num_vertices()).matrix();
  if (!weld) return m;
  std::map<std::tuple<double, double, double>, Index> index;
  std::vector<Index> remap(std::size_t(m.num_vertices()));
  Mesh w;
  std::vector<V> kept;
  for (Index v = 0; v < m.num_vertices(); ++v) {
    const auto key = std::make_tuple(m.vertices(v, 0), m.vertices(v, 1), m.vertices(v, 2));
    const auto it = index.find(key);
    if (it != index.end()) {
      remap[std::size_t(v)] = it->second;
    } else {
      remap[std::size_t(v)] = index[key] = Index(kept.size());
      kept.push_back(m.vertices.row(v).transpose());
    }
  }
  w.vertices.resize(Index(kept.size()), 3);
  for (std::size_t i = 0; i < kept.size(); ++i) w.vertices.row(Index(i)) = kept[i].transpose();
  w.faces = m.faces;
  for (Index f = 0; f < w.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) w.faces(f, k) = remap[std::size_t(m.faces(f, k))];
  return w;
}

Mesh flipped(Mesh m) {
  m.faces.col(1).swap(m.faces.col(2));
  return m;
}

/// The mesh without face rows [first, first + count).
Mesh without_faces(const Mesh& m, Index first, Index count) {
  Mesh r;
  r.vertices = m.vertices;
  r.faces.resize(m.num_faces() - count, 3);
  for (Index f = 0, g = 0; f < m.num_faces(); ++f)
    if (f < first || f >= first + count) r.faces.row(g++) = m.faces.row(f);
  return r;
}

/// Generalised winding number of the closed surface `m` around `p` (1 inside, 0 outside).
double winding_number(const Mesh& m, const V& p) {
  double total = 0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    const V a = m.vertices.row(m.faces(f, 0)).transpose() - p;
    const V b = m.vertices.row(m.faces(f, 1)).transpose() - p;
    const V c = m.vertices.row(m.faces(f, 2)).transpose() - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double det = a.dot(b.cross(c));
    const double div = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    total += 2 * std::atan2(det, div);
  }
  return total / (4 * M_PI);
}

/// A fresh, empty folder for files written by one test.
fs::path scratch_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("fsm_test_mesh_io_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

bool has_defect(const MeshReport& r, const std::string& phrase) {
  for (const std::string& d : r.defects())
    if (d == phrase) return true;
  return false;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : "; ") + x;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Inspection of meshes built in code
// ---------------------------------------------------------------------------------------------

TEST(MeshIoInspect, ClosedCubeBoundsAVolumeWithExactVolumeAndArea) {
  // Dyadic coordinates: every product and sum is exact, so is the volume.
  const double side = 0.03125;
  const MeshReport r = inspect_mesh(cube(side, V(0.125, -0.25, 0.5)), "cube");
  EXPECT_EQ(r.file, "cube");
  EXPECT_EQ(r.vertices, 8);
  EXPECT_EQ(r.faces, 12);
  EXPECT_EQ(r.components, 1);
  EXPECT_EQ(r.boundary_edges, 0);
  EXPECT_EQ(r.non_manifold_edges, 0);
  EXPECT_EQ(r.non_manifold_vertices, 0);
  EXPECT_EQ(r.degenerate_faces, 0);
  EXPECT_EQ(r.self_intersections, 0);
  EXPECT_TRUE(r.outward_oriented);
  EXPECT_TRUE(r.closed());
  EXPECT_TRUE(r.manifold());
  EXPECT_TRUE(r.bounds_a_volume()) << joined(r.defects());
  EXPECT_TRUE(r.defects().empty()) << joined(r.defects());
  EXPECT_EQ(r.volume, side * side * side);
  EXPECT_EQ(r.area, 6 * side * side);

  // Not dyadic: right to rounding.
  const MeshReport s = inspect_mesh(cube(0.02, V(0.1, -0.3, 0.7)));
  EXPECT_TRUE(s.bounds_a_volume()) << joined(s.defects());
  EXPECT_NEAR(s.volume, 8e-6, 1e-13 * 8e-6);
  EXPECT_NEAR(s.area, 24e-4, 1e-13 * 24e-4);
}

TEST(MeshIoInspect, CubeWithOneSideRemovedHasFourBoundaryEdges) {
  const MeshReport r = inspect_mesh(without_faces(cube(), 0, 2));
  EXPECT_EQ(r.faces, 10);
  EXPECT_EQ(r.boundary_edges, 4);
  EXPECT_FALSE(r.closed());
  EXPECT_TRUE(r.manifold());
  EXPECT_EQ(r.components, 1);
  EXPECT_FALSE(r.outward_oriented);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_TRUE(has_defect(r, "4 boundary edges (open)")) << joined(r.defects());
}

TEST(MeshIoInspect, CubesSharingAnEdgeAreNonManifoldWithoutIntersections) {
  // Cube B sits diagonally next to cube A, touching it along the edge x = y = 1.
  const Mesh m = combine(cube(), cube(1.0, V(1, 1, 0)), true);
  ASSERT_EQ(m.num_vertices(), 14);
  const MeshReport r = inspect_mesh(m);
  EXPECT_EQ(r.non_manifold_edges, 1);     // four faces on the shared edge
  EXPECT_EQ(r.non_manifold_vertices, 2);  // its two ends
  EXPECT_FALSE(r.manifold());
  EXPECT_TRUE(r.closed());
  EXPECT_EQ(r.components, 1);          // joined through the shared edge
  EXPECT_EQ(r.self_intersections, 0);  // touching along an edge is not intersecting
  EXPECT_FALSE(r.outward_oriented);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_NEAR(r.volume, 2.0, 1e-12);
  EXPECT_TRUE(has_defect(r, "1 non-manifold edge")) << joined(r.defects());
  EXPECT_TRUE(has_defect(r, "2 non-manifold vertices")) << joined(r.defects());
  EXPECT_THROW(orient_outward(m), Error);
}

TEST(MeshIoInspect, CubesSharingAVertexHaveOneNonManifoldVertex) {
  const MeshReport r = inspect_mesh(combine(cube(), cube(1.0, V(1, 1, 1)), true));
  EXPECT_EQ(r.vertices, 15);
  EXPECT_EQ(r.non_manifold_edges, 0);
  EXPECT_EQ(r.non_manifold_vertices, 1);
  EXPECT_EQ(r.components, 2);
  EXPECT_EQ(r.self_intersections, 0);
  EXPECT_FALSE(r.bounds_a_volume());
}

TEST(MeshIoInspect, OverlappingCubesSelfIntersect) {
  const Mesh m = combine(cube(), cube(1.0, V(0.5, 0.5, 0.5)), false);
  const MeshReport r = inspect_mesh(m);
  EXPECT_TRUE(r.closed());
  EXPECT_TRUE(r.manifold());
  EXPECT_EQ(r.components, 2);
  EXPECT_GT(r.self_intersections, 0);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_TRUE(has_defect(r, std::to_string(r.self_intersections) + " self-intersecting face pairs"))
      << joined(r.defects());

  // The same count from the polygon-soup path, taken when the mesh cannot be a halfedge mesh:
  // add a far-away non-manifold "bow tie" (two triangles sharing one vertex only).
  Mesh bow_tie;
  bow_tie.vertices.resize(5, 3);
  bow_tie.vertices << 5, 5, 5, 6, 5, 5, 6, 6, 5, 4, 5, 5, 4, 4, 5;
  bow_tie.faces.resize(2, 3);
  bow_tie.faces << 0, 1, 2, 0, 3, 4;
  const MeshReport s = inspect_mesh(combine(m, bow_tie, false));
  EXPECT_EQ(s.non_manifold_vertices, 1);
  EXPECT_EQ(s.self_intersections, r.self_intersections);
}

TEST(MeshIoInspect, SelfIntersectionCountStopsAtOneThousand) {
  // 40 cubes, each shifted a little from the last: every pair intersects.
  Mesh m = cube();
  for (int i = 1; i < 40; ++i) m = combine(m, cube(1.0, V(0.013, 0.021, 0.017) * i), false);
  const auto start = std::chrono::steady_clock::now();
  const MeshReport r = inspect_mesh(m);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.self_intersections, 1000);
  EXPECT_TRUE(has_defect(r, "at least 1000 self-intersecting face pairs")) << joined(r.defects());
  EXPECT_LT(seconds, 5.0);
}

TEST(MeshIoInspect, FlippedCubeIsInwardAndOrientOutwardFixesIt) {
  const Mesh inward = flipped(cube(0.03));
  const MeshReport r = inspect_mesh(inward);
  EXPECT_TRUE(r.closed());
  EXPECT_TRUE(r.manifold());
  EXPECT_FALSE(r.outward_oriented);
  EXPECT_LT(r.volume, 0);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_TRUE(has_defect(r, "inward-oriented")) << joined(r.defects());

  const Mesh fixed = orient_outward(inward, "flipped cube");
  EXPECT_TRUE(fixed.vertices == inward.vertices);  // vertices kept, in order
  const MeshReport f = inspect_mesh(fixed);
  EXPECT_TRUE(f.outward_oriented);
  EXPECT_TRUE(f.bounds_a_volume()) << joined(f.defects());
  EXPECT_NEAR(f.volume, 2.7e-5, 1e-18);
}

TEST(MeshIoInspect, OrientOutwardFixesAMixedOrientationAndKeepsAGoodMesh) {
  // Flip half the faces: an inconsistently oriented closed cube.
  Mesh mixed = cube();
  for (Index f = 0; f < 6; ++f) std::swap(mixed.faces(f, 1), mixed.faces(f, 2));
  const MeshReport r = inspect_mesh(mixed);
  EXPECT_TRUE(r.closed());
  EXPECT_FALSE(r.outward_oriented);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_FALSE(r.defects().empty());
  const MeshReport f = inspect_mesh(orient_outward(mixed));
  EXPECT_TRUE(f.bounds_a_volume()) << joined(f.defects());
  EXPECT_NEAR(f.volume, 1.0, 1e-12);

  const Mesh good = cube();
  EXPECT_TRUE(orient_outward(good).faces == good.faces);
}

TEST(MeshIoInspect, OrientOutwardRefusesOpenMeshesNamingTheFile) {
  try {
    orient_outward(without_faces(cube(), 4, 2), "open.obj");
    FAIL() << "no error for an open mesh";
  } catch (const Error& e) {
    EXPECT_EQ(e.file(), "open.obj");
    EXPECT_NE(std::string(e.what()).find("open.obj"), std::string::npos);
    EXPECT_NE(e.reason().find("open"), std::string::npos) << e.what();
  }
}

TEST(MeshIoInspect, NestedCavityIsOutwardWhenInnerShellPointsIn) {
  // A hollow box: the outer shell outward, the inner shell (the cavity) inward.
  const Mesh hollow = combine(cube(3.0), flipped(cube(1.0, V(1, 1, 1))), false);
  const MeshReport r = inspect_mesh(hollow);
  EXPECT_EQ(r.components, 2);
  EXPECT_TRUE(r.outward_oriented);
  EXPECT_NEAR(r.volume, 26.0, 1e-12);
  // Both shells outward is wrong for a cavity.
  const MeshReport w = inspect_mesh(combine(cube(3.0), cube(1.0, V(1, 1, 1)), false));
  EXPECT_FALSE(w.outward_oriented);
  EXPECT_TRUE(has_defect(w, "not outward-oriented")) << joined(w.defects());
  // orient_outward turns the inner shell inward.
  const MeshReport o =
      inspect_mesh(orient_outward(combine(cube(3.0), cube(1.0, V(1, 1, 1)), false)));
  EXPECT_TRUE(o.bounds_a_volume()) << joined(o.defects());
  EXPECT_NEAR(o.volume, 26.0, 1e-12);
}

TEST(MeshIoInspect, DegenerateFacesAreCounted) {
  Mesh m = cube();
  m.vertices.conservativeResize(9, 3);
  m.vertices.row(8) << 0.5, 0, 0;  // on the edge from vertex 0 to vertex 1
  m.faces.conservativeResize(14, 3);
  m.faces.row(12) << 0, 8, 1;  // zero area, three distinct vertices
  m.faces.row(13) << 2, 2, 3;  // repeats a vertex
  const MeshReport r = inspect_mesh(m);
  EXPECT_EQ(r.degenerate_faces, 2);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_TRUE(has_defect(r, "2 degenerate faces")) << joined(r.defects());
  EXPECT_EQ(inspect_mesh(cube()).degenerate_faces, 0);
}

TEST(MeshIoInspect, EmptyAndInvalidMeshes) {
  const MeshReport r = inspect_mesh(Mesh{}, "nothing");
  EXPECT_EQ(r.faces, 0);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_TRUE(has_defect(r, "empty (no faces)"));

  Mesh bad = cube();
  bad.faces(3, 1) = 8;
  EXPECT_THROW(inspect_mesh(bad, "bad"), Error);
  bad = cube();
  bad.vertices(2, 0) = std::nan("");
  try {
    inspect_mesh(bad, "bad.obj");
    FAIL() << "no error for a NaN vertex";
  } catch (const Error& e) {
    EXPECT_EQ(e.file(), "bad.obj");
  }
}

// ---------------------------------------------------------------------------------------------
// Files
// ---------------------------------------------------------------------------------------------

TEST(MeshIoFiles, RoundTripsThroughAllFormatsKeepVerticesAndVolume) {
  const fs::path dir = scratch_dir("round_trip");
  const Mesh original = cube(0.0123, V(0.1, 0.2, -0.3));
  const double volume = original.volume();
  for (const std::string ext : {"obj", "off", "stl", "ply", "OBJ", "Stl"}) {
    SCOPED_TRACE(ext);
    const std::string path = (dir / ("cube." + ext)).string();
    write_mesh(path, original);
    const Mesh back = read_mesh(path);
    EXPECT_EQ(back.num_vertices(), 8);
    EXPECT_EQ(back.num_faces(), 12);
    const MeshReport r = inspect_mesh(back, path);
    EXPECT_TRUE(r.bounds_a_volume()) << joined(r.defects());
    // STL stores single precision: about 1e-8 m on coordinates of 0.3 m, 1e-6 of a 1 cm side.
    const double tol = (ext == "stl" || ext == "Stl") ? 1e-5 : 1e-12;
    EXPECT_NEAR(r.volume, volume, tol * volume);
  }
  fs::remove_all(dir);
}

TEST(MeshIoFiles, ReadsAsciiStlWeldsVerticesAndScales) {
  const fs::path dir = scratch_dir("ascii_stl");
  // A tetrahedron in millimetres, each facet with its own copies of the corners.
  const double p[4][3] = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}, {0, 0, 10}};
  const int t[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::string text = "solid tet\n";
  for (const auto& f : t) {
    text += "facet normal 0 0 0\n outer loop\n";
    for (int k = 0; k < 3; ++k)
      text += "  vertex " + std::to_string(p[f[k]][0]) + " " + std::to_string(p[f[k]][1]) + " " +
              std::to_string(p[f[k]][2]) + "\n";
    text += " endloop\nendfacet\n";
  }
  text += "endsolid tet\n";
  write_text(dir / "tet.stl", text);
  const Mesh m = read_mesh((dir / "tet.stl").string(), 1e-3);
  EXPECT_EQ(m.num_vertices(), 4);
  EXPECT_EQ(m.num_faces(), 4);
  const MeshReport r = inspect_mesh(m);
  EXPECT_TRUE(r.bounds_a_volume()) << joined(r.defects());
  EXPECT_NEAR(r.volume, 1e-6 / 6, 1e-18);  // (1 cm)^3 / 6
  fs::remove_all(dir);
}

TEST(MeshIoFiles, TriangulatesPolygonsIncludingNonConvexOnes) {
  const fs::path dir = scratch_dir("polygons");
  // A cube of quads, and an L-shaped prism whose hexagons start at a corner from which a fan
  // leaves the L: a plain fan folds a triangle over (area 4 instead of 3, and a
  // self-intersection) although its signed volume stays right.
  write_text(dir / "quads.obj",
             "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\n"
             "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n");
  const Mesh quads = read_mesh((dir / "quads.obj").string());
  EXPECT_EQ(quads.num_faces(), 12);
  EXPECT_TRUE(inspect_mesh(quads).bounds_a_volume()) << joined(inspect_mesh(quads).defects());
  EXPECT_NEAR(quads.volume(), 1.0, 1e-12);

  // L outline (counter-clockwise from +z): (2,1) (1,1) (1,2) (0,2) (0,0) (2,0); bottom z = 0
  // (seen from below, so reversed), top z = 1.
  const double l[6][2] = {{2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}, {2, 0}};
  std::string obj;
  for (int z = 0; z < 2; ++z)
    for (const auto& q : l)
      obj +=
          "v " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(z) + "\n";
  obj += "f 6 5 4 3 2 1\nf 7 8 9 10 11 12\n";
  for (int i = 0; i < 6; ++i) {
    const int a = i + 1, b = (i + 1) % 6 + 1;
    obj += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(b + 6) + " " +
           std::to_string(a + 6) + "\n";
  }
  write_text(dir / "l_prism.OBJ", obj);
  const Mesh prism = read_mesh((dir / "l_prism.OBJ").string());
  EXPECT_EQ(prism.num_faces(), 2 * 4 + 6 * 2);
  const MeshReport r = inspect_mesh(prism);
  EXPECT_TRUE(r.bounds_a_volume()) << joined(r.defects());
  EXPECT_NEAR(r.volume, 3.0, 1e-12);
  EXPECT_NEAR(r.area, 2 * 3.0 + 8.0, 1e-12);
  fs::remove_all(dir);
}

TEST(MeshIoFiles, ReadDoesNotRepairTopology) {
  // A duplicated face and (once the coincident vertices 0 and 4 are welded) a reversed copy of a
  // face come through for inspect_mesh to report; read_mesh does not remove them.
  const fs::path dir = scratch_dir("no_repair");
  write_text(dir / "m.off",
             "OFF\n5 6 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n"
             "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n3 1 2 3\n3 4 1 2\n");
  const Mesh m = read_mesh((dir / "m.off").string());
  EXPECT_EQ(m.num_vertices(), 4);  // vertex 4 welded onto vertex 0
  EXPECT_EQ(m.num_faces(), 6);
  const MeshReport r = inspect_mesh(m);
  EXPECT_GT(r.non_manifold_edges, 0);
  EXPECT_EQ(r.self_intersections, 2);  // each copy with its original
  EXPECT_FALSE(r.bounds_a_volume());
  fs::remove_all(dir);
}

TEST(MeshIoFiles, ErrorsNameTheFile) {
  const fs::path dir = scratch_dir("errors");
  const auto expect_error = [](const std::string& path, const std::string& reason_part,
                               const auto& call) {
    try {
      call();
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_EQ(e.file(), path);
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(e.reason().find(reason_part), std::string::npos) << e.what();
    }
  };
  const std::string missing = (dir / "does_not_exist.obj").string();
  expect_error(missing, "not found", [&] { read_mesh(missing); });

  const std::string unknown = (dir / "mesh.xyz").string();
  write_text(unknown, "v 0 0 0\n");
  expect_error(unknown, "extension", [&] { read_mesh(unknown); });
  expect_error(unknown, "extension", [&] { write_mesh(unknown, cube()); });

  const std::string empty = (dir / "empty.obj").string();
  write_text(empty, "# nothing here\nv 0 0 0\n");
  expect_error(empty, "no faces", [&] { read_mesh(empty); });

  const std::string garbage = (dir / "garbage.off").string();
  write_text(garbage, "this is not an OFF file\n");
  expect_error(garbage, "", [&] { read_mesh(garbage); });

  // A binary STL with an infinite coordinate.
  const std::string infinite = (dir / "infinite.stl").string();
  {
    std::ofstream out(infinite, std::ios::binary);
    const std::string header(80, ' ');
    out.write(header.data(), 80);
    const std::uint32_t count = 1;
    out.write(reinterpret_cast<const char*>(&count), 4);
    const float facet[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, INFINITY, 1, 0};
    out.write(reinterpret_cast<const char*>(facet), sizeof facet);
    const std::uint16_t attribute = 0;
    out.write(reinterpret_cast<const char*>(&attribute), 2);
  }
  expect_error(infinite, "non-finite", [&] { read_mesh(infinite); });

  const std::string unwritable = (dir / "no_such_folder" / "cube.obj").string();
  expect_error(unwritable, "cannot write", [&] { write_mesh(unwritable, cube()); });
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// Alpha wrapping
// ---------------------------------------------------------------------------------------------

TEST(MeshIoAlphaWrap, TwoOverlappingOpenMeshesBecomeOneClosedOutwardSurface) {
  // Two 2 cm boxes, one open at the top, one open at the bottom, overlapping by 1 cm per axis.
  const double s = 0.02;
  const Mesh a = without_faces(cube(s), 2, 2);                       // top (z = 2 cm) removed
  const Mesh b = without_faces(cube(s, V(0.01, 0.01, 0.01)), 0, 2);  // bottom (z = 1 cm) removed
  ASSERT_EQ(inspect_mesh(a).boundary_edges, 4);
  ASSERT_EQ(inspect_mesh(b).boundary_edges, 4);
  const double alpha = 0.02, offset = 0.001;
  const Mesh w = alpha_wrap({a, b}, alpha, offset);
  const MeshReport r = inspect_mesh(w, "wrap");
  EXPECT_TRUE(r.closed());
  EXPECT_TRUE(r.manifold());
  EXPECT_TRUE(r.outward_oriented);
  EXPECT_EQ(r.components, 1);
  EXPECT_EQ(r.self_intersections, 0);
  EXPECT_TRUE(r.bounds_a_volume()) << joined(r.defects());
  // Every input vertex is inside the wrap.
  for (const Mesh* m : {&a, &b})
    for (Index v = 0; v < m->num_vertices(); ++v)
      EXPECT_NEAR(winding_number(w, m->vertices.row(v).transpose()), 1.0, 1e-6) << v;
  // At least the union of the two boxes (15 cm^3), at most their bounding box grown by the
  // offset; and far from the point-sized shell one gets when the wrap goes inside.
  const double union_volume = 2 * s * s * s - 0.01 * 0.01 * 0.01;
  const double box = std::pow(0.03 + 2 * offset, 3);
  EXPECT_GT(r.volume, union_volume);
  EXPECT_LT(r.volume, box);
}

TEST(MeshIoAlphaWrap, RejectsBadParametersAndEmptyInput) {
  EXPECT_THROW(alpha_wrap({cube()}, 0.0, 0.01), Error);
  EXPECT_THROW(alpha_wrap({cube()}, -1.0, 0.01), Error);
  EXPECT_THROW(alpha_wrap({cube()}, 0.1, 0.0), Error);
  EXPECT_THROW(alpha_wrap({cube()}, std::nan(""), 0.01), Error);
  EXPECT_THROW(alpha_wrap({}, 0.1, 0.01), Error);
  EXPECT_THROW(alpha_wrap({Mesh{}}, 0.1, 0.01), Error);
}

// ---------------------------------------------------------------------------------------------
// Real anatomy: the Visible Human Female pelvis (metres)
// ---------------------------------------------------------------------------------------------

const std::string vhf_dir = std::string(FSM_SHARED_DATA_DIR) + "/vhf-pelvis";

/// Skips the test (the project's rule) when the shared data folder is not there.
#define REQUIRE_VHF()             \
  if (!fs::is_directory(vhf_dir)) \
  GTEST_SKIP() << "the shared data folder " << vhf_dir << " does not exist"

void print_report(const MeshReport& r, double seconds) {
  std::printf(
      "%-40s V %5d F %5d comp %d bnd %3d nm-e %d nm-v %d degen %d si %4d out %d "
      "area %.3f cm^2 vol %.3f cm^3 (%.3f s) %s\n",
      fs::path(r.file).filename().string().c_str(), r.vertices, r.faces, r.components,
      r.boundary_edges, r.non_manifold_edges, r.non_manifold_vertices, r.degenerate_faces,
      r.self_intersections, int(r.outward_oriented), r.area * 1e4, r.volume * 1e6, seconds,
      joined(r.defects()).c_str());
}

MeshReport timed_inspection(const std::string& name) {
  const std::string path = vhf_dir + "/" + name;
  const auto start = std::chrono::steady_clock::now();
  const MeshReport r = inspect_mesh(read_mesh(path), path);
  print_report(r, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return r;
}

TEST(MeshIoVhfPelvis, LeftOvaryIsClosedAndManifold) {
  REQUIRE_VHF();
  const MeshReport r = timed_inspection("left_ovary.obj");
  EXPECT_EQ(r.vertices, 214);
  EXPECT_EQ(r.faces, 424);
  EXPECT_TRUE(r.closed());
  EXPECT_TRUE(r.manifold());
  EXPECT_EQ(r.components, 1);
  EXPECT_NEAR(r.volume * 1e6, 1.0, 0.1);  // about 1.0 cm^3
}

TEST(MeshIoVhfPelvis, OvarianLigamentIsOpenWithTenBoundaryEdges) {
  REQUIRE_VHF();
  const MeshReport r = timed_inspection("ovarian_ligament_L.obj");
  EXPECT_EQ(r.vertices, 110);
  EXPECT_EQ(r.faces, 208);
  EXPECT_EQ(r.boundary_edges, 10);
  EXPECT_FALSE(r.bounds_a_volume());
  EXPECT_TRUE(has_defect(r, "10 boundary edges (open)")) << joined(r.defects());
  EXPECT_THROW(orient_outward(read_mesh(vhf_dir + "/ovarian_ligament_L.obj"),
                              vhf_dir + "/ovarian_ligament_L.obj"),
               Error);
}

TEST(MeshIoVhfPelvis, BodyOfUterusIsOpenWithTwoComponents) {
  REQUIRE_VHF();
  const MeshReport r = timed_inspection("body_of_uterus.obj");
  EXPECT_EQ(r.vertices, 2823);
  EXPECT_FALSE(r.closed());
  EXPECT_EQ(r.components, 2);
  EXPECT_TRUE(has_defect(r, "2 components")) << joined(r.defects());
}

TEST(MeshIoVhfPelvis, InspectionOfEveryMeshIsFast) {
  REQUIRE_VHF();
  for (const auto& entry : fs::directory_iterator(vhf_dir)) {
    if (entry.path().extension() != ".obj") continue;
    const auto start = std::chrono::steady_clock::now();
    const MeshReport r = timed_inspection(entry.path().filename().string());
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_LT(seconds, 5.0) << r.file;
    EXPECT_GT(r.faces, 0);
  }
}

TEST(MeshIoVhfPelvis, AlphaWrapOfWallsAndCervixIsOnePlausibleUterus) {
  REQUIRE_VHF();
  std::vector<Mesh> parts;
  for (const char* name :
       {"anterior_wall_of_uterus.obj", "posterior_wall_of_uterus.obj", "cervix.obj"})
    parts.push_back(read_mesh(vhf_dir + "/" + name));
  const double alpha = 0.003, offset = 0.0003;  // 3 mm, 0.3 mm
  const auto start = std::chrono::steady_clock::now();
  const Mesh uterus = alpha_wrap(parts, alpha, offset);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const MeshReport r = inspect_mesh(uterus, "wrapped uterus");
  print_report(r, seconds);
  EXPECT_TRUE(r.bounds_a_volume()) << joined(r.defects());
  EXPECT_EQ(r.components, 1);
  // README: walls + cervix are about 19 cm^3; the wrap adds a thin offset shell.
  EXPECT_GT(r.volume * 1e6, 15.0);
  EXPECT_LT(r.volume * 1e6, 30.0);
  // Each part's vertices are inside (spot check).
  for (const Mesh& part : parts)
    for (Index v = 0; v < part.num_vertices(); v += 97)
      EXPECT_NEAR(winding_number(uterus, part.vertices.row(v).transpose()), 1.0, 1e-6);
}

}  // namespace
}  // namespace fsm::build
