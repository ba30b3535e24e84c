#pragma once

// The builder's one bridge between its TriangleMesh and CGAL's Surface_mesh (private; included
// only by the builder's CGAL translation units, never by a public header).

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <Eigen/Core>
#include <vector>

#include "fsm/error.hpp"
#include "fsm/triangle_mesh.hpp"

namespace fsm::build::cgal {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;

/// The vertices of `mesh` as CGAL points, each mapped by `map` (identity: as they are).
inline std::vector<Point> to_points(const TriangleMesh<double>& mesh,
                                    const Eigen::Matrix3d& map = Eigen::Matrix3d::Identity()) {
  std::vector<Point> points;
  points.reserve(std::size_t(mesh.num_vertices()));
  for (Index v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d p = map * mesh.vertices.row(v).transpose();
    points.emplace_back(p.x(), p.y(), p.z());
  }
  return points;
}

/// `mesh` as a Surface_mesh (vertex i and face i are the input's), its vertices mapped by `map`.
/// The caller has checked that the mesh is a closed manifold (inspect_mesh); a face CGAL refuses
/// is an fsm::Error, not a silent hole.
inline SurfaceMesh to_cgal(const TriangleMesh<double>& mesh,
                           const Eigen::Matrix3d& map = Eigen::Matrix3d::Identity()) {
  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> v;
  v.reserve(std::size_t(mesh.num_vertices()));
  for (const Point& p : to_points(mesh, map)) v.push_back(sm.add_vertex(p));
  for (Index f = 0; f < mesh.num_faces(); ++f)
    if (sm.add_face(v[std::size_t(mesh.faces(f, 0))], v[std::size_t(mesh.faces(f, 1))],
                    v[std::size_t(mesh.faces(f, 2))]) == SurfaceMesh::null_face())
      throw Error("", "", "face " + std::to_string(f) + " breaks the surface's manifoldness");
  return sm;
}

/// A TriangleMesh from a triangulated Surface_mesh without garbage; vertex i of the result is
/// vertex index i of `sm`, face i is face index i.
inline TriangleMesh<double> from_cgal(const SurfaceMesh& sm) {
  TriangleMesh<double> mesh;
  mesh.vertices.resize(Eigen::Index(sm.number_of_vertices()), 3);
  for (const auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    mesh.vertices.row(Eigen::Index(v.idx())) << p.x(), p.y(), p.z();
  }
  mesh.faces.resize(Eigen::Index(sm.number_of_faces()), 3);
  for (const auto f : sm.faces()) {
    int k = 0;
    for (const auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      if (k < 3) mesh.faces(Eigen::Index(f.idx()), k) = Index(v.idx());
      ++k;
    }
    if (k != 3) throw Error("", "", "a CGAL surface face is not a triangle");
  }
  return mesh;
}

}  // namespace fsm::build::cgal
