// The baselines the paper compares against (docs/physics.md section 10.4): grid (hexahedral)
// filling and unequal-radius (greedy medial-ball) packing; and a Delaunay tetrahedralisation of
// sphere centres.

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "cgal_mesh.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using K = cgal::Kernel;
using cgal::SurfaceMesh;
using cgal::to_cgal;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

K::Point_3 pt(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}

}  // namespace

GridFilling fill_grid(const TriangleMesh<double>& surface, double spacing, int neighbours,
                      const std::string& part) {
  if (!(spacing > 0)) throw Error("", "part '" + part + "'", "grid spacing must be positive");
  SurfaceMesh sm = to_cgal(surface);
  Tree tree(faces(sm).first, faces(sm).second, sm);
  CGAL::Side_of_triangle_mesh<SurfaceMesh, K> inside(tree);
  const Eigen::Vector3d lo = surface.vertices.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = surface.vertices.colwise().maxCoeff().transpose();
  // Cells centred in the box, so the grid sits symmetrically in the part.
  const Eigen::Vector3i n =
      ((hi - lo) / spacing).array().floor().cast<int>().matrix() + Eigen::Vector3i::Ones();
  const Eigen::Vector3d start =
      0.5 * (lo + hi) - 0.5 * spacing * (n - Eigen::Vector3i::Ones()).cast<double>();
  GridFilling out;
  out.spacing = spacing;
  std::unordered_map<std::int64_t, Index> id;
  auto key = [&](int i, int j, int k) { return (std::int64_t(k) * n.y() + j) * n.x() + i; };
  std::vector<Eigen::Vector3d> pts;
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const Eigen::Vector3d p = start + spacing * Eigen::Vector3d(i, j, k);
        if (inside(pt(p)) == CGAL::ON_BOUNDED_SIDE) {
          id[key(i, j, k)] = Index(pts.size());
          pts.push_back(p);
        }
      }
  if (pts.empty())
    throw Error("", "part '" + part + "'",
                "no grid point falls inside the part; reduce the spacing");
  out.centres.resize(Index(pts.size()), 3);
  for (std::size_t q = 0; q < pts.size(); ++q) out.centres.row(Index(q)) = pts[q].transpose();
  // Half of the neighbour offsets, so each pair appears once.
  std::vector<std::pair<Eigen::Vector3i, std::uint8_t>> offsets;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const Eigen::Vector3i d(dx, dy, dz);
        const int nonzero = (d.array() != 0).count();
        if (nonzero == 0) continue;
        // Keep d if its first non-zero component is positive.
        const int first = dx != 0 ? dx : dy != 0 ? dy : dz;
        if (first < 0) continue;
        if ((neighbours == 6 && nonzero > 1) || (neighbours == 18 && nonzero > 2)) continue;
        offsets.emplace_back(d, std::uint8_t(nonzero - 1));
      }
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        auto a = id.find(key(i, j, k));
        if (a == id.end()) continue;
        for (const auto& [d, kind] : offsets) {
          const Eigen::Vector3i c = Eigen::Vector3i(i, j, k) + d;
          if ((c.array() < 0).any() || (c.array() >= n.array()).any()) continue;
          auto b = id.find(key(c.x(), c.y(), c.z()));
          if (b == id.end()) continue;
          out.links.emplace_back(a->second, b->second);
          out.link_kind.push_back(kind);
        }
      }
  return out;
}

PackingFilling fill_packing(const TriangleMesh<double>& surface, double radius_min,
                            double radius_max, const std::string& part) {
  if (!(radius_min > 0))
    throw Error("", "part '" + part + "'", "packing radius_min must be positive");
  SurfaceMesh sm = to_cgal(surface);
  Tree tree(faces(sm).first, faces(sm).second, sm);
  tree.accelerate_distance_queries();
  CGAL::Side_of_triangle_mesh<SurfaceMesh, K> inside(tree);
  // Candidate centres on a grid of half the smallest radius, with their distance to the surface
  // (the radius of the largest ball centred there).
  const double h = 0.5 * radius_min;
  const Eigen::Vector3d lo = surface.vertices.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = surface.vertices.colwise().maxCoeff().transpose();
  const Eigen::Vector3i n =
      ((hi - lo) / h).array().ceil().cast<int>().matrix() + Eigen::Vector3i::Ones();
  std::vector<std::pair<double, Eigen::Vector3d>> candidates;
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const Eigen::Vector3d p = lo + h * Eigen::Vector3d(i, j, k);
        if (inside(pt(p)) != CGAL::ON_BOUNDED_SIDE) continue;
        const double d = std::sqrt(CGAL::to_double(tree.squared_distance(pt(p))));
        if (d >= radius_min) candidates.emplace_back(d, p);
      }
  // Deepest first; each ball is the largest centred there (its distance to the surface), capped
  // at radius_max so a part is not swallowed by one ball.
  std::sort(candidates.begin(), candidates.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  // Greedy: the next ball whose centre no earlier ball covers, until balls get too small.
  std::vector<Eigen::Vector3d> c;
  std::vector<double> r;
  for (const auto& [d, p] : candidates) {
    bool covered = false;
    for (std::size_t q = 0; q < c.size() && !covered; ++q) covered = (p - c[q]).norm() < r[q];
    if (covered) continue;
    c.push_back(p);
    r.push_back(std::min(d, radius_max));
  }
  if (c.empty())
    throw Error("", "part '" + part + "'", "no ball of radius_min fits inside the part");
  PackingFilling out;
  out.centres.resize(Index(c.size()), 3);
  out.radii.resize(Index(c.size()));
  for (std::size_t q = 0; q < c.size(); ++q) {
    out.centres.row(Index(q)) = c[q].transpose();
    out.radii[Index(q)] = r[q];
  }
  for (std::size_t a = 0; a < c.size(); ++a)
    for (std::size_t b = a + 1; b < c.size(); ++b)
      if ((c[a] - c[b]).norm() < r[a] + r[b]) out.links.emplace_back(Index(a), Index(b));
  return out;
}

TetrahedralMesh<double> tetrahedralise(const Positions<double>& points) {
  using Vb = CGAL::Triangulation_vertex_base_with_info_3<Index, K>;
  using Tds = CGAL::Triangulation_data_structure_3<Vb>;
  using Delaunay = CGAL::Delaunay_triangulation_3<K, Tds>;
  std::vector<std::pair<K::Point_3, Index>> input;
  for (Index i = 0; i < Index(points.rows()); ++i)
    input.emplace_back(pt(points.row(i).transpose()), i);
  Delaunay dt(input.begin(), input.end());
  TetrahedralMesh<double> out;
  out.vertices = points;
  std::vector<std::array<Index, 4>> tets;
  // Points on a grid are co-spherical in groups of eight, so the Delaunay tetrahedralisation has
  // flat elements; drop them (they would give meaningless barycentric coordinates).
  double scale = 0;
  for (Index i = 1; i < Index(points.rows()); ++i)
    scale = std::max(scale, (points.row(i) - points.row(0)).norm());
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c) {
    const auto& a = c->vertex(0)->point();
    const double v = std::abs(CGAL::to_double(
        CGAL::volume(a, c->vertex(1)->point(), c->vertex(2)->point(), c->vertex(3)->point())));
    if (v <= 1e-12 * scale * scale * scale) continue;
    tets.push_back(
        {c->vertex(0)->info(), c->vertex(1)->info(), c->vertex(2)->info(), c->vertex(3)->info()});
  }
  if (tets.empty()) {
    throw Error("", "tetrahedralise", "fewer than four non-coplanar sphere centres");
  }
  out.tetrahedra.resize(Index(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t)
    for (int k = 0; k < 4; ++k) out.tetrahedra(Index(t), k) = tets[t][std::size_t(k)];
  return out;
}

}  // namespace fsm::build
