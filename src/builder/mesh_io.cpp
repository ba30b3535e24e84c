/// @file build/mesh_io.cpp
/// @brief Reading, writing, checking and repairing surface meshes with CGAL (GPL-3.0-or-later).
///
/// All CGAL code of the mesh IO lives in this one translation unit (it is expensive to compile).

#include "fsm/builder/mesh_io.hpp"

#include <CGAL/IO/polygon_soup_io.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/alpha_wrap_3.h>
#include <CGAL/box_intersection_d.h>

#include <boost/iterator/function_output_iterator.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>
#include <utility>
#include <vector>

#include "cgal_mesh.hpp"

namespace fsm::build {

namespace {

namespace PMP = CGAL::Polygon_mesh_processing;

using cgal::Kernel;
using cgal::Point;
using Surface = cgal::SurfaceMesh;
using cgal::to_points;
using Polygon = std::vector<std::size_t>;
using Triangle = std::array<std::size_t, 3>;

/// Self-intersecting face pairs are counted up to this many.
constexpr Index max_self_intersections = 1000;

// ---------------------------------------------------------------------------------------------
// Small helpers
// ---------------------------------------------------------------------------------------------

/// The extension of `path` without the dot, in lower case ("" when there is none).
std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty() && ext.front() == '.') ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

/// Throws fsm::Error naming `path` unless its extension is one of the four supported formats.
void check_extension(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == "obj" || ext == "off" || ext == "stl" || ext == "ply" || ext == "gltf" || ext == "glb")
    return;
  throw Error(path, "",
              (ext.empty() ? std::string("no file extension")
                           : "unknown mesh file extension '." + ext + "'") +
                  " (expected .obj, .off, .stl, .ply, .gltf or .glb)");
}

/// Throws fsm::Error naming `file` (and `part`) for a non-finite vertex or a face index out of
/// range.
void check_indices_and_coordinates(const TriangleMesh<double>& mesh, const std::string& file,
                                   const std::string& part = "") {
  for (Index v = 0; v < mesh.num_vertices(); ++v)
    if (!mesh.vertices.row(v).allFinite())
      throw Error(file, part, "vertex " + std::to_string(v) + " has a non-finite coordinate");
  for (Index f = 0; f < mesh.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      if (mesh.faces(f, k) < 0 || mesh.faces(f, k) >= mesh.num_vertices())
        throw Error(file, part,
                    "face " + std::to_string(f) + " has a vertex index out of range [0, " +
                        std::to_string(mesh.num_vertices()) + ")");
}

std::vector<Triangle> to_triangles(const TriangleMesh<double>& mesh) {
  std::vector<Triangle> triangles(std::size_t(mesh.num_faces()));
  for (Index f = 0; f < mesh.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      triangles[std::size_t(f)][std::size_t(k)] = std::size_t(mesh.faces(f, k));
  return triangles;
}

/// The three vertex indices of face `f` of `sm` in cyclic order, rotated to start at the smallest.
std::array<std::size_t, 3> canonical_face(const Surface& sm, Surface::Face_index f) {
  std::array<std::size_t, 3> v{};
  int k = 0;
  for (const auto u : CGAL::vertices_around_face(sm.halfedge(f), sm))
    if (k < 3) v[std::size_t(k++)] = u.idx();
  std::rotate(v.begin(), std::min_element(v.begin(), v.end()), v.end());
  return v;
}

/// Plain union-find over 0..n-1.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : m_parent(n) {
    std::iota(m_parent.begin(), m_parent.end(), std::size_t(0));
  }
  std::size_t find(std::size_t i) {
    while (m_parent[i] != i) i = m_parent[i] = m_parent[m_parent[i]];
    return i;
  }
  void unite(std::size_t a, std::size_t b) {
    a = find(a);
    b = find(b);
    if (a != b) m_parent[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::size_t> m_parent;
};

// ---------------------------------------------------------------------------------------------
// Combinatorics from the face array (works on any triangle soup, manifold or not)
// ---------------------------------------------------------------------------------------------

struct Combinatorics {
  Index components{0};
  Index boundary_edges{0};
  Index non_manifold_edges{0};
  Index non_manifold_vertices{0};
  /// Some edge on two faces is traversed in the same direction by both.
  bool inconsistent_orientation{false};
};

/// Counts components (faces joined through shared edges), boundary edges (one face),
/// non-manifold edges (three or more faces) and non-manifold vertices (the faces around the
/// vertex are not one fan: several fans, or a non-manifold edge at the vertex). Edges are
/// undirected vertex pairs; an edge from a face repeating a vertex (a, a) is ignored.
Combinatorics combinatorics(const FaceArray& faces, Index num_vertices) {
  Combinatorics c;
  const std::size_t nf = std::size_t(faces.rows());
  if (nf == 0) return c;

  struct HalfEdge {
    std::uint64_t key;  // (min << 32) | max
    std::size_t face;
    bool forward;  // traversed from min to max
  };
  std::vector<HalfEdge> edges;
  edges.reserve(3 * nf);
  for (std::size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const auto a = std::uint32_t(faces(Eigen::Index(f), k));
      const auto b = std::uint32_t(faces(Eigen::Index(f), (k + 1) % 3));
      if (a == b) continue;
      const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
      edges.push_back({(std::uint64_t(lo) << 32) | hi, f, a == lo});
    }
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.key != y.key ? x.key < y.key : x.face < y.face;
  });

  // The corner of vertex v in face f: 3 f + (first position of v in f).
  const auto corner = [&faces](std::size_t f, Index v) {
    for (int k = 0; k < 3; ++k)
      if (faces(Eigen::Index(f), k) == v) return 3 * f + std::size_t(k);
    return 3 * f;  // not reached
  };

  DisjointSets face_sets(nf);
  DisjointSets corner_sets(3 * nf);
  std::vector<char> on_non_manifold_edge(std::size_t(num_vertices), 0);
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    const std::size_t count = j - i;
    const auto lo = Index(edges[i].key >> 32), hi = Index(edges[i].key & 0xffffffffu);
    if (count == 1) ++c.boundary_edges;
    if (count >= 3) {
      ++c.non_manifold_edges;
      on_non_manifold_edge[std::size_t(lo)] = on_non_manifold_edge[std::size_t(hi)] = 1;
    }
    if (count == 2 && edges[i].forward == edges[i + 1].forward) c.inconsistent_orientation = true;
    for (std::size_t e = i + 1; e < j; ++e) {
      face_sets.unite(edges[i].face, edges[e].face);
      corner_sets.unite(corner(edges[i].face, lo), corner(edges[e].face, lo));
      corner_sets.unite(corner(edges[i].face, hi), corner(edges[e].face, hi));
    }
    i = j;
  }

  for (std::size_t f = 0; f < nf; ++f)
    if (face_sets.find(f) == f) ++c.components;

  // A vertex whose corners fall into more than one fan is non-manifold.
  std::vector<std::size_t> fan(std::size_t(num_vertices), SIZE_MAX);
  std::vector<char> non_manifold(on_non_manifold_edge);
  for (std::size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const Index v = faces(Eigen::Index(f), k);
      if (corner(f, v) != 3 * f + std::size_t(k)) continue;  // repeated vertex in f
      const std::size_t root = corner_sets.find(3 * f + std::size_t(k));
      std::size_t& seen = fan[std::size_t(v)];
      if (seen == SIZE_MAX)
        seen = root;
      else if (seen != root)
        non_manifold[std::size_t(v)] = 1;
    }
  c.non_manifold_vertices = Index(std::count(non_manifold.begin(), non_manifold.end(), char(1)));
  return c;
}

// ---------------------------------------------------------------------------------------------
// Self-intersections
// ---------------------------------------------------------------------------------------------

bool is_degenerate(const std::vector<Point>& points, const Triangle& t) {
  return t[0] == t[1] || t[1] == t[2] || t[2] == t[0] ||
         CGAL::collinear(points[t[0]], points[t[1]], points[t[2]]);
}

/// Whether two non-degenerate triangles of a soup intersect other than in the vertices or edge
/// they share (by index). Same rules as CGAL::Polygon_mesh_processing::self_intersections:
/// sharing an edge, they intersect when coplanar and folded onto each other; sharing a vertex,
/// when the edge of one opposite the vertex meets the other; sharing all three, always.
bool soup_faces_intersect(const std::vector<Point>& points, const Triangle& t, const Triangle& u) {
  int shared = 0, ti = -1, uj = -1;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (t[std::size_t(i)] == u[std::size_t(j)]) {
        if (shared == 0) {
          ti = i;
          uj = j;
        }
        ++shared;
      }
  const auto& p = points;
  if (shared >= 3) return true;
  if (shared == 2) {
    // The vertex of each triangle that is not on the shared edge.
    std::size_t r = 0, s = 0;
    for (std::size_t i = 0; i < 3; ++i)
      if (std::find(u.begin(), u.end(), t[i]) == u.end()) r = t[i];
    for (std::size_t j = 0; j < 3; ++j)
      if (std::find(t.begin(), t.end(), u[j]) == t.end()) s = u[j];
    std::size_t a = 0, b = 0;
    int found = 0;
    for (std::size_t i = 0; i < 3; ++i)
      if (t[i] != r) (found++ == 0 ? a : b) = t[i];
    return CGAL::coplanar(p[a], p[b], p[r], p[s]) &&
           CGAL::coplanar_orientation(p[a], p[b], p[r], p[s]) == CGAL::POSITIVE;
  }
  const Kernel::Triangle_3 tt(p[t[0]], p[t[1]], p[t[2]]);
  const Kernel::Triangle_3 ut(p[u[0]], p[u[1]], p[u[2]]);
  if (shared == 1) {
    const Kernel::Segment_3 t_opposite(p[t[std::size_t(ti + 1) % 3]],
                                       p[t[std::size_t(ti + 2) % 3]]);
    const Kernel::Segment_3 u_opposite(p[u[std::size_t(uj + 1) % 3]],
                                       p[u[std::size_t(uj + 2) % 3]]);
    return CGAL::do_intersect(tt, u_opposite) || CGAL::do_intersect(ut, t_opposite);
  }
  return CGAL::do_intersect(tt, ut);
}

struct StopCounting {};

/// Intersecting pairs of non-degenerate faces of a triangle soup (box intersection, then
/// exact predicates), counting stops at `cap`. For soups that are not polygon meshes.
Index soup_self_intersections(const std::vector<Point>& points,
                              const std::vector<Triangle>& triangles, Index cap) {
  using Box =
      CGAL::Box_intersection_d::Box_with_info_d<double, 3, std::size_t,
                                                CGAL::Box_intersection_d::ID_FROM_BOX_ADDRESS>;
  std::vector<Box> boxes;
  boxes.reserve(triangles.size());
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const Triangle& t = triangles[f];
    if (is_degenerate(points, t)) continue;
    boxes.emplace_back(points[t[0]].bbox() + points[t[1]].bbox() + points[t[2]].bbox(), f);
  }
  std::vector<const Box*> box_pointers;
  box_pointers.reserve(boxes.size());
  for (const Box& b : boxes) box_pointers.push_back(&b);

  Index count = 0;
  const auto callback = [&](const Box* a, const Box* b) {
    if (!soup_faces_intersect(points, triangles[a->info()], triangles[b->info()])) return;
    if (++count >= cap) throw StopCounting{};
  };
  try {
    CGAL::box_self_intersection_d<CGAL::Sequential_tag>(box_pointers.begin(), box_pointers.end(),
                                                        callback, std::ptrdiff_t(2000));
  } catch (const StopCounting&) {
  }
  return std::min(count, cap);
}

/// Intersecting face pairs of a triangulated surface mesh with
/// CGAL::Polygon_mesh_processing::self_intersections (degenerate faces, which it reports paired
/// with themselves, are not counted); counting stops at `cap`.
Index mesh_self_intersections(const Surface& sm, Index degenerate_faces, Index cap) {
  using Face = Surface::Face_index;
  Index count = 0;
  const auto counter = [&count](const std::pair<Face, Face>& pair) {
    if (pair.first != pair.second) ++count;
  };
  PMP::self_intersections(
      sm, boost::make_function_output_iterator(counter),
      CGAL::parameters::maximum_number(unsigned(cap) + unsigned(degenerate_faces)));
  return std::min(count, cap);
}

// ---------------------------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------------------------

/// Splits polygons with more than three vertices into triangles: CGAL's
/// triangulate_hole_polyline (minimal area, no new vertices), a fan when that fails.
std::vector<Triangle> triangulate(const std::vector<Point>& points,
                                  const std::vector<Polygon>& polygons) {
  std::vector<Triangle> triangles;
  triangles.reserve(polygons.size());
  for (const Polygon& polygon : polygons) {
    const std::size_t n = polygon.size();
    if (n == 3) {
      triangles.push_back({polygon[0], polygon[1], polygon[2]});
      continue;
    }
    std::vector<CGAL::Triple<int, int, int>> pieces;
    Polygon sorted = polygon;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end()) {
      std::vector<Point> polyline;
      for (const std::size_t v : polygon) polyline.push_back(points[v]);
      PMP::triangulate_hole_polyline(polyline, std::back_inserter(pieces));
    }
    if (pieces.size() == n - 2) {
      // In a triangulation of a polygon, every triangle taken in the polygon's vertex order has
      // the polygon's orientation.
      for (const auto& piece : pieces) {
        std::array<int, 3> c{piece.first, piece.second, piece.third};
        std::sort(c.begin(), c.end());
        triangles.push_back(
            {polygon[std::size_t(c[0])], polygon[std::size_t(c[1])], polygon[std::size_t(c[2])]});
      }
    } else {
      for (std::size_t k = 1; k + 1 < n; ++k)
        triangles.push_back({polygon[0], polygon[k], polygon[k + 1]});
    }
  }
  return triangles;
}

}  // namespace

// -----------------------------------------------------------------------------------------------
// MeshReport
// -----------------------------------------------------------------------------------------------

std::vector<std::string> MeshReport::defects() const {
  std::vector<std::string> out;
  const auto counted = [&out](Index n, const char* one, const char* many,
                              const std::string& suffix = "") {
    if (n > 0) out.push_back(std::to_string(n) + " " + (n == 1 ? one : many) + suffix);
  };
  if (faces == 0) {
    out.emplace_back("empty (no faces)");
    return out;
  }
  counted(boundary_edges, "boundary edge", "boundary edges", " (open)");
  if (components > 1) out.push_back(std::to_string(components) + " components");
  counted(non_manifold_edges, "non-manifold edge", "non-manifold edges");
  counted(non_manifold_vertices, "non-manifold vertex", "non-manifold vertices");
  counted(degenerate_faces, "degenerate face", "degenerate faces");
  if (self_intersections >= max_self_intersections)
    out.push_back("at least " + std::to_string(self_intersections) +
                  " self-intersecting face pairs");
  else
    counted(self_intersections, "self-intersecting face pair", "self-intersecting face pairs");
  // Orientation is only meaningful for a closed manifold surface; "open" or "non-manifold"
  // already explain why an open or non-manifold mesh does not bound a volume.
  if (closed() && manifold() && !outward_oriented)
    out.emplace_back(volume < 0 ? "inward-oriented" : "not outward-oriented");
  return out;
}

// -----------------------------------------------------------------------------------------------
// read_mesh / write_mesh
// -----------------------------------------------------------------------------------------------

TriangleMesh<double> read_mesh(const std::string& path, double scale,
                               const std::vector<std::string>& nodes) {
  check_extension(path);
  const bool gltf = lower_extension(path) == "gltf" || lower_extension(path) == "glb";
  if (!gltf && !nodes.empty())
    throw Error(path, "", "nodes can only be chosen in a glTF file (.gltf, .glb)");
  if (!(std::isfinite(scale) && scale > 0))
    throw Error(path, "", "scale must be positive and finite, got " + std::to_string(scale));
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path, "", "file not found");
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(path, "", "not a regular file");

  // Our own strict parser (mesh_parse.cpp), not CGAL's readers: CGAL allocates what a header
  // declares before checking it against the file and cannot say which line is wrong.
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path, "", "cannot open the file for reading");
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw Error(path, "", "cannot read the file");
    bytes = std::move(s).str();
  }
  PolygonSoup soup =
      gltf ? read_gltf(bytes, path, nodes) : parse_mesh(bytes, *mesh_format(path), path);
  bytes = std::string();
  if (soup.polygons.empty())
    throw Error(path, "",
                "no faces: the file is empty or holds only vertices (" +
                    std::to_string(soup.points.size()) + " of them)");
  std::vector<Point> points;
  points.reserve(soup.points.size());
  for (const auto& p : soup.points) points.emplace_back(p[0], p[1], p[2]);
  std::vector<Polygon> polygons = std::move(soup.polygons);
  soup = PolygonSoup();

  // Weld coincident points and drop points no face uses. Deliberately not the rest of
  // repair_polygon_soup (removing degenerate or duplicated faces, splitting pinched polygons):
  // inspect_mesh() reports those instead of having them silently fixed here.
  PMP::merge_duplicate_points_in_polygon_soup(points, polygons);
  PMP::remove_isolated_points_in_polygon_soup(points, polygons);
  const std::vector<Triangle> triangles = triangulate(points, polygons);
  if (points.size() > std::size_t(std::numeric_limits<Index>::max()) ||
      triangles.size() > std::size_t(std::numeric_limits<Index>::max()))
    throw Error(path, "", "the mesh is too large");

  TriangleMesh<double> mesh;
  mesh.vertices.resize(Eigen::Index(points.size()), 3);
  for (std::size_t v = 0; v < points.size(); ++v)
    mesh.vertices.row(Eigen::Index(v)) << scale * points[v].x(), scale * points[v].y(),
        scale * points[v].z();
  if (!mesh.vertices.allFinite())
    throw Error(path, "", "a coordinate is not finite after scaling by " + std::to_string(scale));
  mesh.faces.resize(Eigen::Index(triangles.size()), 3);
  for (std::size_t f = 0; f < triangles.size(); ++f)
    for (std::size_t k = 0; k < 3; ++k)
      mesh.faces(Eigen::Index(f), Eigen::Index(k)) = Index(triangles[f][k]);
  return mesh;
}

void write_mesh(const std::string& path, const TriangleMesh<double>& mesh) {
  check_extension(path);
  if (lower_extension(path) == "gltf" || lower_extension(path) == "glb")
    throw Error(path, "", "glTF is read, not written (write .obj, .off, .stl or .ply)");
  check_indices_and_coordinates(mesh, path);
  if (mesh.num_faces() == 0) throw Error(path, "", "cannot write an empty mesh");
  const std::vector<Point> points = to_points(mesh);
  const std::vector<Triangle> triangles = to_triangles(mesh);
  bool ok = false;
  try {
    // OBJ and OFF are text: 17 digits keep doubles exact. STL (float) and PLY are binary.
    ok = CGAL::IO::write_polygon_soup(path, points, triangles,
                                      CGAL::parameters::stream_precision(17).verbose(false));
  } catch (const std::exception& e) {
    throw Error(path, "", std::string("cannot write the mesh: ") + e.what());
  }
  if (!ok) throw Error(path, "", "cannot write the mesh (is the folder there and writable?)");
}

// -----------------------------------------------------------------------------------------------
// inspect_mesh
// -----------------------------------------------------------------------------------------------

MeshReport inspect_mesh(const TriangleMesh<double>& mesh, const std::string& file) {
  check_indices_and_coordinates(mesh, file);
  MeshReport report;
  report.file = file;
  report.vertices = mesh.num_vertices();
  report.faces = mesh.num_faces();
  if (mesh.num_faces() == 0) return report;

  const Combinatorics comb = combinatorics(mesh.faces, mesh.num_vertices());
  report.components = comb.components;
  report.boundary_edges = comb.boundary_edges;
  report.non_manifold_edges = comb.non_manifold_edges;
  report.non_manifold_vertices = comb.non_manifold_vertices;

  const std::vector<Point> points = to_points(mesh);
  const std::vector<Triangle> triangles = to_triangles(mesh);

  // Area, and the signed volume about the bounding-box centre (the same value as about the
  // origin for a closed mesh, with less cancellation far from it).
  const Eigen::RowVector3d centre =
      0.5 * (mesh.vertices.colwise().minCoeff() + mesh.vertices.colwise().maxCoeff());
  double area = 0, volume = 0;
  for (Index f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = (mesh.vertices.row(mesh.faces(f, 0)) - centre).transpose();
    const Eigen::Vector3d b = (mesh.vertices.row(mesh.faces(f, 1)) - centre).transpose();
    const Eigen::Vector3d c = (mesh.vertices.row(mesh.faces(f, 2)) - centre).transpose();
    area += 0.5 * (b - a).cross(c - a).norm();
    volume += a.dot(b.cross(c));
    if (is_degenerate(points, triangles[std::size_t(f)])) ++report.degenerate_faces;
  }
  report.area = area;
  report.volume = volume / 6;

  if (PMP::is_polygon_soup_a_polygon_mesh(triangles)) {
    Surface sm;
    PMP::polygon_soup_to_polygon_mesh(points, triangles, sm);
    report.self_intersections =
        mesh_self_intersections(sm, report.degenerate_faces, max_self_intersections);
    if (CGAL::is_closed(sm) && report.volume > 0) {
      bool outward = PMP::is_outward_oriented(sm);
      // With several components (a nested cavity, separate lumps) also ask
      // orient_to_bound_a_volume whether it would flip any; it needs an intersection-free mesh.
      if (outward && report.components > 1 && report.self_intersections == 0) {
        Surface oriented = sm;
        PMP::orient_to_bound_a_volume(oriented);
        for (const auto f : sm.faces())
          if (canonical_face(sm, f) != canonical_face(oriented, f)) {
            outward = false;
            break;
          }
      }
      report.outward_oriented = outward;
    }
  } else {
    // Non-manifold, inconsistently oriented, or with faces repeating a vertex: no halfedge
    // structure is possible, so test the soup itself.
    report.self_intersections = soup_self_intersections(points, triangles, max_self_intersections);
    report.outward_oriented = false;
  }
  return report;
}

// -----------------------------------------------------------------------------------------------
// orient_outward
// -----------------------------------------------------------------------------------------------

TriangleMesh<double> orient_outward(const TriangleMesh<double>& mesh, const std::string& file) {
  check_indices_and_coordinates(mesh, file);
  if (mesh.num_faces() == 0) throw Error(file, "", "cannot orient an empty mesh");
  const Combinatorics comb = combinatorics(mesh.faces, mesh.num_vertices());
  const std::string why = "cannot orient the mesh to bound a volume: ";
  if (comb.boundary_edges > 0)
    throw Error(file, "",
                why + "it is open (" + std::to_string(comb.boundary_edges) + " boundary edges)");
  if (comb.non_manifold_edges > 0 || comb.non_manifold_vertices > 0)
    throw Error(file, "",
                why + "it is non-manifold (" + std::to_string(comb.non_manifold_edges) +
                    " non-manifold edges, " + std::to_string(comb.non_manifold_vertices) +
                    " non-manifold vertices)");

  std::vector<Point> points = to_points(mesh);
  std::vector<Polygon> polygons;
  polygons.reserve(std::size_t(mesh.num_faces()));
  for (const Triangle& t : to_triangles(mesh)) {
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0])
      throw Error(file, "", why + "a face repeats a vertex");
    polygons.push_back({t[0], t[1], t[2]});
  }
  if (!PMP::orient_polygon_soup(points, polygons))
    throw Error(file, "", why + "its faces cannot be oriented consistently (non-orientable)");
  if (!PMP::is_polygon_soup_a_polygon_mesh(polygons))
    throw Error(file, "", why + "it is not a valid polygon mesh after orientation");

  Surface sm;
  PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);
  if (!CGAL::is_closed(sm)) throw Error(file, "", why + "it is not closed");
  PMP::orient_to_bound_a_volume(sm);
  // The soup keeps the vertex and face order, so vertex i (and face i) is the input's.
  return cgal::from_cgal(sm);
}

// -----------------------------------------------------------------------------------------------
// alpha_wrap
// -----------------------------------------------------------------------------------------------

TriangleMesh<double> alpha_wrap(const std::vector<TriangleMesh<double>>& meshes, double alpha,
                                double offset) {
  if (!(std::isfinite(alpha) && alpha > 0))
    throw Error("", "alpha", "must be a positive length in metres, got " + std::to_string(alpha));
  if (!(std::isfinite(offset) && offset > 0))
    throw Error("", "offset", "must be a positive length in metres, got " + std::to_string(offset));

  std::vector<Point> points;
  std::vector<Triangle> triangles;
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const TriangleMesh<double>& mesh = meshes[m];
    check_indices_and_coordinates(mesh, "", "alpha_wrap input mesh " + std::to_string(m));
    const std::size_t first = points.size();
    const std::vector<Point> p = to_points(mesh);
    points.insert(points.end(), p.begin(), p.end());
    for (Triangle t : to_triangles(mesh)) {
      for (std::size_t& v : t) v += first;
      triangles.push_back(t);
    }
  }
  if (triangles.empty()) throw Error("", "alpha_wrap", "no input triangles to wrap");

  Surface wrap;
  CGAL::alpha_wrap_3(points, triangles, alpha, offset, wrap);
  if (wrap.number_of_faces() == 0) throw Error("", "alpha_wrap", "the wrap is empty");
  if (wrap.has_garbage()) wrap.collect_garbage();
  if (!CGAL::is_closed(wrap)) throw Error("", "alpha_wrap", "the wrap is not closed");
  PMP::orient_to_bound_a_volume(wrap);
  return cgal::from_cgal(wrap);
}

}  // namespace fsm::build
