// Tetrahedral filling under a metric: CGAL Mesh_3 Delaunay refinement, with the surface's sharp
// edges protected (Mesh_domain_with_polyline_features_3) when it has any.

#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/detect_features.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Random.h>
#include <CGAL/make_mesh_3.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>

#include "cgal_mesh.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using K = cgal::Kernel;
using cgal::SurfaceMesh;
using cgal::to_cgal;

// A smooth surface: the domain (and so the mesh) of the filling before feature protection.
using Domain = CGAL::Polyhedral_mesh_domain_3<SurfaceMesh, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

// A surface with sharp edges: they are detected as polylines, protected by balls of the edge
// size first, and become edges (their meeting points vertices) of the filling.
using FeatureDomain = CGAL::Polyhedral_mesh_domain_with_features_3<K, SurfaceMesh>;
using FeatureTr =
    CGAL::Mesh_triangulation_3<FeatureDomain, CGAL::Default, CGAL::Sequential_tag>::type;
using FeatureC3t3 = CGAL::Mesh_complex_3_in_triangulation_3<FeatureTr, FeatureDomain::Corner_index,
                                                            FeatureDomain::Curve_index>;
using FeatureCriteria = CGAL::Mesh_criteria_3<FeatureTr>;

// Sizing field of a varying metric: its smallest size at the point (scaled by `factor`).
struct SizeField {
  const MetricField* metric;
  double factor;
  using FT = K::FT;
  using Point_3 = K::Point_3;
  template <typename Index>
  FT operator()(const Point_3& p, const int, const Index&) const {
    return factor * metric->size(Eigen::Vector3d(p.x(), p.y(), p.z()));
  }
};

template <typename C3, typename D, typename Cr>
C3 run_mesh_3(const D& domain, const Cr& criteria, const std::string& optimiser) {
  namespace P = CGAL::parameters;
  // Fixed seed: a tetrahedral part builds to the same mesh every time. And no time limits: left
  // unset, make_mesh_3 gives perturb() and exude() the wall time the refinement took as their
  // limit, so a loaded machine stopped them earlier and the same scene built a different mesh
  // (fsm_build_cli failed under parallel ctest; 32 of 120 builds differed with a busy core).
  // 0 means none: they run until they cannot improve the mesh.
  CGAL::get_default_random() = CGAL::Random(0);
  const auto perturb = P::perturb(P::time_limit = 0);
  const auto exude = P::exude(P::time_limit = 0);
  if (optimiser == "none")
    return CGAL::make_mesh_3<C3>(domain, criteria, P::no_perturb(), P::no_exude());
  if (optimiser == "perturb")
    return CGAL::make_mesh_3<C3>(domain, criteria, perturb, P::no_exude());
  if (optimiser == "exude") return CGAL::make_mesh_3<C3>(domain, criteria, P::no_perturb(), exude);
  if (optimiser == "lloyd")
    return CGAL::make_mesh_3<C3>(domain, criteria, P::lloyd(P::max_iteration_number = 20),
                                 P::no_perturb(), exude);
  if (optimiser == "odt_perturb")
    return CGAL::make_mesh_3<C3>(domain, criteria, P::odt(P::max_iteration_number = 20), perturb,
                                 exude);
  return CGAL::make_mesh_3<C3>(domain, criteria, P::odt(P::max_iteration_number = 20),
                               P::no_perturb(), exude);
}

// Meshes `domain` with the builder's criteria (docs/builder.md), in the space where the metric is
// the identity when it is constant; `edges` adds the edge size of protected features.
template <typename C3, typename Cr, typename D>
C3 mesh(const D& domain, const MetricField& metric, const std::string& optimiser, bool edges) {
  using namespace CGAL::parameters;
  if (metric.is_constant()) {
    const Cr criteria = edges
                            ? Cr(edge_size = 1.0, facet_angle = 25, facet_size = 1.0,
                                 facet_distance = 0.25, cell_radius_edge_ratio = 2, cell_size = 1.0)
                            : Cr(facet_angle = 25, facet_size = 1.0, facet_distance = 0.25,
                                 cell_radius_edge_ratio = 2, cell_size = 1.0);
    return run_mesh_3<C3>(domain, criteria, optimiser);
  }
  const SizeField size{&metric, 1.0}, distance{&metric, 0.25};
  const Cr criteria =
      edges ? Cr(edge_size = size, facet_angle = 25, facet_size = size, facet_distance = distance,
                 cell_radius_edge_ratio = 2, cell_size = size)
            : Cr(facet_angle = 25, facet_size = size, facet_distance = distance,
                 cell_radius_edge_ratio = 2, cell_size = size);
  return run_mesh_3<C3>(domain, criteria, optimiser);
}

// The cells of a mesh complex as points (mapped back by `from_unit`) and vertex quadruples.
template <typename C3>
void cells_of(const C3& c3t3, const Eigen::Matrix3d& from_unit,
              std::vector<Eigen::Vector3d>& points, std::vector<std::array<Index, 4>>& tets) {
  std::unordered_map<typename C3::Triangulation::Vertex_handle, Index> id;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    std::array<Index, 4> t;
    for (int k = 0; k < 4; ++k) {
      const auto v = c->vertex(k);
      auto [it, inserted] = id.emplace(v, Index(points.size()));
      if (inserted) {
        const auto& p = v->point();
        points.push_back(from_unit * Eigen::Vector3d(CGAL::to_double(p.x()), CGAL::to_double(p.y()),
                                                     CGAL::to_double(p.z())));
      }
      t[std::size_t(k)] = it->second;
    }
    tets.push_back(t);
  }
}

// The sharp edges of `sm` (the normals of their two faces more than `angle_deg` apart) as
// polylines: chains of sharp edges between vertices where other than two of them meet, and closed
// loops (first point repeated last). Chains shorter than the element size `size(x)` at their
// midpoint (in the space of `sm`) are left out: a crease shorter than one element cannot be an
// edge of the filling, and protecting it only forces tiny elements around it. `edges` counts the
// sharp edges kept.
template <typename Size>
std::vector<std::vector<K::Point_3>> sharp_polylines(SurfaceMesh& sm, double angle_deg,
                                                     const Size& size, Index& edges) {
  using Vertex = SurfaceMesh::Vertex_index;
  using Edge = SurfaceMesh::Edge_index;
  auto sharp = sm.add_property_map<Edge, bool>("e:fsm_sharp", false).first;
  CGAL::Polygon_mesh_processing::detect_sharp_edges(sm, angle_deg, sharp);
  std::unordered_map<Vertex, std::vector<Vertex>> adj;
  for (const Edge e : sm.edges())
    if (sharp[e]) {
      const Vertex a = sm.vertex(e, 0), b = sm.vertex(e, 1);
      adj[a].push_back(b);
      adj[b].push_back(a);
    }
  std::vector<std::vector<Vertex>> chains;
  auto trace = [&](Vertex from, Vertex to) {
    std::vector<Vertex> c{from};
    Vertex a = from, b = to;
    for (;;) {
      sharp[sm.edge(sm.halfedge(a, b))] = false;  // visited
      c.push_back(b);
      const auto& next = adj[b];
      if (next.size() != 2 || b == from) break;
      const Vertex n = next[0] == a ? next[1] : next[0];
      a = b;
      b = n;
    }
    chains.push_back(std::move(c));
  };
  // Open chains from their ends first, then what is left: closed loops. Vertices in index order,
  // so the polylines (and the mesh) do not depend on hashing.
  std::vector<Vertex> ends;
  for (const auto& [v, nb] : adj) ends.push_back(v);
  std::sort(ends.begin(), ends.end());
  for (const bool loops : {false, true})
    for (const Vertex v : ends)
      if (loops == (adj[v].size() == 2))
        for (const Vertex w : adj[v])
          if (sharp[sm.edge(sm.halfedge(v, w))]) trace(v, w);
  sm.remove_property_map(sharp);
  auto point = [&](Vertex v) {
    const auto& p = sm.point(v);
    return Eigen::Vector3d(p.x(), p.y(), p.z());
  };
  std::vector<std::vector<K::Point_3>> lines;
  edges = 0;
  for (const auto& c : chains) {
    double length = 0;
    for (std::size_t i = 1; i < c.size(); ++i) length += (point(c[i]) - point(c[i - 1])).norm();
    if (length < size(point(c[c.size() / 2]))) continue;
    std::vector<K::Point_3> line;
    for (const Vertex v : c) line.push_back(sm.point(v));
    lines.push_back(std::move(line));
    edges += Index(c.size() - 1);
  }
  return lines;
}

}  // namespace

namespace detail {

void drop_hanging_pieces(std::vector<Eigen::Vector3d>& points,
                         std::vector<std::array<Index, 4>>& tets, Index& removed_cells,
                         double& removed_volume) {
  removed_cells = 0;
  removed_volume = 0;
  const std::size_t nt = tets.size();
  std::vector<std::size_t> parent(nt);
  for (std::size_t t = 0; t < nt; ++t) parent[t] = t;
  auto find = [&](std::size_t t) {
    while (parent[t] != t) t = parent[t] = parent[parent[t]];
    return t;
  };
  std::map<std::array<Index, 3>, std::size_t> first_cell;  // face -> a cell that has it
  for (std::size_t t = 0; t < nt; ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<Index, 3> f{};
      for (int k = 0, j = 0; k < 4; ++k)
        if (k != skip) f[std::size_t(j++)] = tets[t][std::size_t(k)];
      std::sort(f.begin(), f.end());
      auto [it, inserted] = first_cell.emplace(f, t);
      if (!inserted) parent[find(t)] = find(it->second);
    }
  auto volume = [&](const std::array<Index, 4>& c) {
    const Eigen::Vector3d a = points[std::size_t(c[0])];
    return std::abs((points[std::size_t(c[1])] - a)
                        .cross(points[std::size_t(c[2])] - a)
                        .dot(points[std::size_t(c[3])] - a)) /
           6.0;
  };
  std::vector<double> component_volume(nt, 0.0);
  for (std::size_t t = 0; t < nt; ++t) component_volume[find(t)] += volume(tets[t]);
  const double largest = *std::max_element(component_volume.begin(), component_volume.end());
  std::vector<std::array<Index, 4>> kept;
  kept.reserve(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    if (component_volume[find(t)] >= kMinComponentShare * largest) {
      kept.push_back(tets[t]);
    } else {
      ++removed_cells;
      removed_volume += volume(tets[t]);
    }
  }
  if (removed_cells == 0) return;
  std::vector<Index> id(points.size(), -1);
  std::vector<Eigen::Vector3d> used;
  for (auto& c : kept)
    for (Index& v : c) {
      if (id[std::size_t(v)] < 0) {
        id[std::size_t(v)] = Index(used.size());
        used.push_back(points[std::size_t(v)]);
      }
      v = id[std::size_t(v)];
    }
  points = std::move(used);
  tets = std::move(kept);
}

}  // namespace detail

QualityStats measure_quality(const TetrahedralMesh<double>& mesh, const MetricField& metric) {
  QualityStats q;
  q.tetrahedra = Index(mesh.tetrahedra.rows());
  q.histogram.assign(6, 0);
  q.q_min = std::numeric_limits<double>::infinity();
  q.min_dihedral_deg = 180;
  double q_sum = 0, edge_sum = 0;
  Index in_1_3 = 0, edges = 0;
  for (Index t = 0; t < q.tetrahedra; ++t) {
    Eigen::Vector3d p[4];
    for (int k = 0; k < 4; ++k) p[k] = mesh.vertices.row(mesh.tetrahedra(t, k)).transpose();
    const Eigen::Vector3d centre = 0.25 * (p[0] + p[1] + p[2] + p[3]);
    const Eigen::Matrix3d M = metric.metric(centre);
    const double Q = tetrahedron_quality(p[0], p[1], p[2], p[3], M);
    // Dihedral angles in the metric's space, where a good element is regular.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(M);
    const Eigen::Matrix3d A = es.operatorSqrt();
    q.min_dihedral_deg =
        std::min(q.min_dihedral_deg, min_dihedral_angle(A * p[0], A * p[1], A * p[2], A * p[3]));
    q.q_min = std::min(q.q_min, Q);
    q.q_max = std::max(q.q_max, Q);
    q_sum += Q;
    in_1_3 += Q <= 3.0;
    const int bin = Q < 1.5 ? 0 : Q < 2 ? 1 : Q < 3 ? 2 : Q < 5 ? 3 : Q < 10 ? 4 : 5;
    ++q.histogram[std::size_t(bin)];
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        edge_sum += (p[a] - p[b]).norm();
        ++edges;
      }
  }
  if (q.tetrahedra > 0) {
    q.q_mean = q_sum / double(q.tetrahedra);
    q.fraction_q_1_3 = double(in_1_3) / double(q.tetrahedra);
    q.mean_edge = edge_sum / double(edges);
  }
  return q;
}

TetraFilling fill_tetrahedral(const TriangleMesh<double>& surface, const MetricField& metric,
                              const std::string& optimiser, const std::string& part,
                              double feature_angle_deg) {
  TetraFilling out;
  out.optimiser = optimiser.empty() ? "odt" : optimiser;
  out.feature_angle_deg = feature_angle_deg;
  // Constant metric: work where it is the identity (x' = M^1/2 x) with unit sizes.
  Eigen::Matrix3d to_unit = Eigen::Matrix3d::Identity();
  if (metric.is_constant()) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(metric.metric(Eigen::Vector3d::Zero()));
    to_unit = es.operatorSqrt();
  }
  SurfaceMesh sm = to_cgal(surface, to_unit);
  // Sharp edges, measured where the filling is built (for an isotropic metric, as in space).
  std::vector<std::vector<K::Point_3>> features;
  if (feature_angle_deg > 0) {
    if (metric.is_constant())
      features = sharp_polylines(
          sm, feature_angle_deg, [](const Eigen::Vector3d&) { return 1.0; }, out.feature_edges);
    else
      features = sharp_polylines(
          sm, feature_angle_deg, [&](const Eigen::Vector3d& x) { return metric.size(x); },
          out.feature_edges);
  }
  const Eigen::Matrix3d from_unit = to_unit.inverse();
  std::vector<Eigen::Vector3d> points;
  std::vector<std::array<Index, 4>> tets;
  if (features.empty()) {
    // No sharp edge: exactly the filling without feature protection.
    const Domain domain(sm);
    const C3t3 c3t3 = mesh<C3t3, Criteria>(domain, metric, out.optimiser, false);
    cells_of(c3t3, from_unit, points, tets);
  } else {
    FeatureDomain domain(sm);
    domain.add_features(features.begin(), features.end());
    const FeatureC3t3 c3t3 =
        mesh<FeatureC3t3, FeatureCriteria>(domain, metric, out.optimiser, true);
    out.feature_corners = Index(c3t3.number_of_corners());
    cells_of(c3t3, from_unit, points, tets);
  }
  if (!tets.empty())
    detail::drop_hanging_pieces(points, tets, out.dropped_cells, out.dropped_volume);
  if (tets.empty())
    throw Error("", "part '" + part + "'",
                "the tetrahedral filling produced no element (the part is smaller than its sphere "
                "radius, or its surface does not bound a volume)");
  // Vertices in a spatially coherent order (sorted along a Morton-like key), which keeps the force
  // loop's memory access local; tetrahedra positively oriented.
  std::vector<Index> order(points.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = Index(i);
  Eigen::Vector3d lo = points[0], hi = points[0];
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  auto key = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d u = ((p - lo).array() / (hi - lo).array().max(1e-12)).matrix();
    std::uint64_t k = 0;
    const auto q = (u * 1023.0).cast<std::uint64_t>();
    for (int b = 9; b >= 0; --b)
      for (int c = 0; c < 3; ++c) k = (k << 1) | ((q[c] >> b) & 1u);
    return k;
  };
  std::sort(order.begin(), order.end(), [&](Index a, Index b) {
    return key(points[std::size_t(a)]) < key(points[std::size_t(b)]);
  });
  std::vector<Index> rank(points.size());
  for (std::size_t i = 0; i < order.size(); ++i) rank[std::size_t(order[i])] = Index(i);
  out.mesh.vertices.resize(Index(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    out.mesh.vertices.row(rank[i]) = points[i].transpose();
  out.mesh.tetrahedra.resize(Index(tets.size()), 4);
  for (std::size_t t = 0; t < tets.size(); ++t)
    for (int k = 0; k < 4; ++k)
      out.mesh.tetrahedra(Index(t), k) = rank[std::size_t(tets[t][std::size_t(k)])];
  for (Index t = 0; t < Index(tets.size()); ++t)
    if (out.mesh.signed_volume(t) < 0)
      std::swap(out.mesh.tetrahedra(t, 2), out.mesh.tetrahedra(t, 3));
  out.quality = measure_quality(out.mesh, metric);
  return out;
}

}  // namespace fsm::build
