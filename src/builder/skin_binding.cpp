// Binding render-surface vertices to the spheres (no CGAL): barycentric coordinates in the
// containing or nearest tetrahedron; chain parameter and rest offset for axis parts.

#include "skin_binding.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace fsm::build::detail {

namespace {

// Barycentric coordinates of p in tetrahedron (a, b, c, d).
Eigen::Vector4d barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                            const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                            const Eigen::Vector3d& d) {
  Eigen::Matrix3d T;
  T << b - a, c - a, d - a;
  const Eigen::Vector3d w = T.fullPivLu().solve(p - a);
  return {1.0 - w.sum(), w[0], w[1], w[2]};
}

}  // namespace

void bind_barycentric(const TetrahedralMesh<double>& mesh, Index first_node,
                      const Positions<double>& points,
                      Eigen::Ref<Eigen::Matrix<Index, -1, 4, Eigen::RowMajor>> nodes,
                      Eigen::Ref<Eigen::Matrix<double, -1, 4, Eigen::RowMajor>> weights) {
  // A uniform grid over the tetrahedra's bounding boxes; cells about one mean edge wide.
  const Index nt = Index(mesh.tetrahedra.rows());
  Eigen::Vector3d lo = mesh.vertices.colwise().minCoeff().transpose();
  Eigen::Vector3d hi = mesh.vertices.colwise().maxCoeff().transpose();
  double edge = 0;
  for (Index t = 0; t < nt; ++t)
    edge += (mesh.vertices.row(mesh.tetrahedra(t, 0)) - mesh.vertices.row(mesh.tetrahedra(t, 1)))
                .norm();
  edge = std::max(edge / double(std::max<Index>(nt, 1)), 1e-9);
  const Eigen::Vector3i dims = (((hi - lo) / edge).array().ceil().cast<int>() + 1).max(1).matrix();
  // (An explicit return type: returning the Eigen expression would dangle.)
  auto cell_of = [&](const Eigen::Vector3d& p) -> Eigen::Vector3i {
    const Eigen::Vector3i c = ((p - lo) / edge).array().floor().cast<int>().matrix();
    return c.cwiseMax(0).cwiseMin(dims - Eigen::Vector3i::Ones());
  };
  auto flat = [&](const Eigen::Vector3i& c) {
    return (std::int64_t(c.z()) * dims.y() + c.y()) * dims.x() + c.x();
  };
  std::unordered_map<std::int64_t, std::vector<Index>> grid;
  for (Index t = 0; t < nt; ++t) {
    Eigen::Vector3d a = mesh.vertices.row(mesh.tetrahedra(t, 0)).transpose(), b = a;
    for (int k = 1; k < 4; ++k) {
      a = a.cwiseMin(mesh.vertices.row(mesh.tetrahedra(t, k)).transpose());
      b = b.cwiseMax(mesh.vertices.row(mesh.tetrahedra(t, k)).transpose());
    }
    const Eigen::Vector3i ca = cell_of(a), cb = cell_of(b);
    for (int z = ca.z(); z <= cb.z(); ++z)
      for (int y = ca.y(); y <= cb.y(); ++y)
        for (int x = ca.x(); x <= cb.x(); ++x) grid[flat({x, y, z})].push_back(t);
  }
  for (Index v = 0; v < Index(points.rows()); ++v) {
    const Eigen::Vector3d p = points.row(v).transpose();
    const Eigen::Vector3i c = cell_of(p);
    // Search growing shells of cells; the best tetrahedron maximises its smallest barycentric
    // coordinate (>= 0 inside). Stop once one contains p, or a shell beyond the first hit is done.
    double best = -std::numeric_limits<double>::infinity();
    Index best_t = -1;
    Eigen::Vector4d best_w;
    const int max_shell = dims.maxCoeff();
    int found_at = -1;
    for (int s = 0; s <= max_shell; ++s) {
      for (int z = c.z() - s; z <= c.z() + s; ++z)
        for (int y = c.y() - s; y <= c.y() + s; ++y)
          for (int x = c.x() - s; x <= c.x() + s; ++x) {
            if (std::max({std::abs(x - c.x()), std::abs(y - c.y()), std::abs(z - c.z())}) != s)
              continue;
            if (x < 0 || y < 0 || z < 0 || x >= dims.x() || y >= dims.y() || z >= dims.z())
              continue;
            auto it = grid.find(flat({x, y, z}));
            if (it == grid.end()) continue;
            for (Index t : it->second) {
              if (std::abs(mesh.signed_volume(t)) < 1e-9 * edge * edge * edge) continue;  // flat
              const Eigen::Vector4d w =
                  barycentric(p, mesh.vertices.row(mesh.tetrahedra(t, 0)).transpose(),
                              mesh.vertices.row(mesh.tetrahedra(t, 1)).transpose(),
                              mesh.vertices.row(mesh.tetrahedra(t, 2)).transpose(),
                              mesh.vertices.row(mesh.tetrahedra(t, 3)).transpose());
              if (w.minCoeff() > best) {
                best = w.minCoeff();
                best_t = t;
                best_w = w;
              }
            }
          }
      if (best_t >= 0 && found_at < 0) found_at = s;
      if (best >= 0 || (found_at >= 0 && s >= found_at + 1)) break;
    }
    for (int k = 0; k < 4; ++k) {
      nodes(v, k) = first_node + mesh.tetrahedra(best_t, k);
      weights(v, k) = best_w[k];
    }
  }
}

ChainBinding bind_chain(const Positions<double>& centres,
                        const std::vector<std::vector<Index>>& branches, Index first_node,
                        const Positions<double>& points) {
  ChainBinding out;
  // Chain-node table: one entry per (branch, position), so a junction node gets one tangent per
  // branch through it.
  std::vector<std::vector<Index>> entry(branches.size());
  std::vector<std::array<Index, 3>> table;
  std::vector<Eigen::Vector3d> tangents;
  for (std::size_t b = 0; b < branches.size(); ++b) {
    const auto& br = branches[b];
    for (std::size_t i = 0; i < br.size(); ++i) {
      const Index prev = br[i == 0 ? i : i - 1], next = br[i + 1 < br.size() ? i + 1 : i];
      Eigen::Vector3d t = (centres.row(next) - centres.row(prev)).transpose();
      t = t.norm() > 0 ? Eigen::Vector3d(t.normalized()) : Eigen::Vector3d::UnitX();
      entry[b].push_back(Index(table.size()));
      table.push_back({first_node + prev, first_node + br[i], first_node + next});
      tangents.push_back(t);
    }
  }
  out.chain_nodes.resize(Index(table.size()), 3);
  out.tangents.resize(Index(table.size()), 3);
  for (std::size_t k = 0; k < table.size(); ++k) {
    for (int c = 0; c < 3; ++c) out.chain_nodes(Index(k), c) = table[k][std::size_t(c)];
    out.tangents.row(Index(k)) = tangents[k].transpose();
  }
  const Index n = Index(points.rows());
  out.entries.resize(n, 2);
  out.s.resize(n);
  out.offsets.resize(n, 3);
  for (Index v = 0; v < n; ++v) {
    const Eigen::Vector3d p = points.row(v).transpose();
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < branches.size(); ++b) {
      const auto& br = branches[b];
      const std::size_t segs = br.size() > 1 ? br.size() - 1 : 1;
      for (std::size_t i = 0; i < segs; ++i) {
        const std::size_t j = std::min(i + 1, br.size() - 1);
        const Eigen::Vector3d a = centres.row(br[i]).transpose(),
                              c = centres.row(br[j]).transpose();
        const Eigen::Vector3d d = c - a;
        const double s =
            d.squaredNorm() > 0 ? std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
        const Eigen::Vector3d q = (1 - s) * a + s * c;
        const double dist = (p - q).squaredNorm();
        if (dist < best) {
          best = dist;
          out.entries(v, 0) = entry[b][i];
          out.entries(v, 1) = entry[b][j];
          out.s[v] = s;
          out.offsets.row(v) = (p - q).transpose();
        }
      }
    }
  }
  return out;
}

}  // namespace fsm::build::detail
