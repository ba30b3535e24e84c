// Tetrahedral filling under a metric tensor field: CGAL Mesh_3 Delaunay refinement.

#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Random.h>
#include <CGAL/make_mesh_3.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "cgal_mesh.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using K = cgal::Kernel;
using cgal::SurfaceMesh;
using cgal::to_cgal;
using Domain = CGAL::Polyhedral_mesh_domain_3<SurfaceMesh, K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

// Sizing field of a varying metric: its smallest size at the point (scaled by `factor`).
struct SizeField {
  const MetricField* metric;
  double factor;
  using FT = K::FT;
  using Point_3 = K::Point_3;
  using Index = Domain::Index;
  FT operator()(const Point_3& p, const int, const Index&) const {
    return factor * metric->size(Eigen::Vector3d(p.x(), p.y(), p.z()));
  }
};

template <typename... Criteria_args>
C3t3 run_mesh_3(const Domain& domain, const Criteria& criteria, const std::string& optimiser) {
  namespace P = CGAL::parameters;
  // Fixed seed: a tetrahedral part builds to the same mesh every time.
  CGAL::get_default_random() = CGAL::Random(0);
  if (optimiser == "none")
    return CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::no_exude());
  if (optimiser == "perturb")
    return CGAL::make_mesh_3<C3t3>(domain, criteria, P::perturb(), P::no_exude());
  if (optimiser == "exude")
    return CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::exude());
  if (optimiser == "lloyd")
    return CGAL::make_mesh_3<C3t3>(domain, criteria, P::lloyd(P::max_iteration_number = 20),
                                   P::no_perturb(), P::exude());
  if (optimiser == "odt_perturb")
    return CGAL::make_mesh_3<C3t3>(domain, criteria, P::odt(P::max_iteration_number = 20),
                                   P::perturb(), P::exude());
  return CGAL::make_mesh_3<C3t3>(domain, criteria, P::odt(P::max_iteration_number = 20),
                                 P::no_perturb(), P::exude());
}

}  // namespace

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
                              const std::string& optimiser, const std::string& part) {
  using namespace CGAL::parameters;
  TetraFilling out;
  out.optimiser = optimiser.empty() ? "odt" : optimiser;
  // Constant metric: work where it is the identity (x' = M^1/2 x) with unit sizes.
  Eigen::Matrix3d to_unit = Eigen::Matrix3d::Identity();
  if (metric.is_constant()) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(metric.metric(Eigen::Vector3d::Zero()));
    to_unit = es.operatorSqrt();
  }
  const SurfaceMesh sm = to_cgal(surface, to_unit);
  const Domain domain(sm);
  C3t3 c3t3;
  if (metric.is_constant()) {
    const Criteria criteria(facet_angle = 25, facet_size = 1.0, facet_distance = 0.25,
                            cell_radius_edge_ratio = 2, cell_size = 1.0);
    c3t3 = run_mesh_3(domain, criteria, out.optimiser);
  } else {
    const Criteria criteria(facet_angle = 25, facet_size = SizeField{&metric, 1.0},
                            facet_distance = SizeField{&metric, 0.25}, cell_radius_edge_ratio = 2,
                            cell_size = SizeField{&metric, 1.0});
    c3t3 = run_mesh_3(domain, criteria, out.optimiser);
  }

  const Eigen::Matrix3d from_unit = to_unit.inverse();
  std::unordered_map<Tr::Vertex_handle, Index> id;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::array<Index, 4>> tets;
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
