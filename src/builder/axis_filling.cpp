// Axis filling: a sphere chain along the medial axis found by mesh contraction (CGAL's
// mean-curvature-flow skeleton, a successor of Au et al. 2008).

// First: it sets CGAL_ALLOCATOR for every CGAL container below (deterministic skeletons).
#include "deterministic_arena.hpp"

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Mean_curvature_flow_skeletonization.h>
#include <CGAL/Random.h>
#include <CGAL/extract_mean_curvature_flow_skeleton.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "cgal_mesh.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using K = cgal::Kernel;
using cgal::SurfaceMesh;
using cgal::to_cgal;
using Skeletonization = CGAL::Mean_curvature_flow_skeletonization<SurfaceMesh>;
using Skeleton = Skeletonization::Skeleton;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

Eigen::Vector3d eig(const K::Point_3& p) {
  return {p.x(), p.y(), p.z()};
}

}  // namespace

AxisFilling fill_axis(const TriangleMesh<double>& surface, const AxisSpec& spec, double radius,
                      const std::string& part) {
  const std::string where = "part '" + part + "'";
  const double spacing = spec.spacing > 0 ? spec.spacing : radius;
  const double rmin = spec.radius_min > 0 ? spec.radius_min : 0.5 * radius;
  const double rmax = spec.radius_max > 0 ? spec.radius_max : 2.0 * radius;
  if (rmin > rmax) throw Error("", where, "axis radius_min exceeds radius_max");

  SurfaceMesh sm = to_cgal(surface);
  Skeleton skeleton;
  // In one contiguous arena, so that the contraction's address-ordered choices follow allocation
  // order (deterministic_arena.hpp); a full arena restarts the extraction with twice the room.
  constexpr std::size_t k_max_arena = std::size_t(16) << 30;
  for (std::size_t bytes = (std::size_t(64) << 20) + 4096 * std::size_t(surface.num_faces());;
       bytes *= 2) {
    try {
      skeleton = Skeleton();
      detail::Arena arena(bytes);
      CGAL::get_default_random() = CGAL::Random(0);  // the medial poles' Delaunay uses it
      CGAL::extract_mean_curvature_flow_skeleton(sm, skeleton);
      break;
    } catch (const detail::ArenaExhausted&) {
      if (bytes >= k_max_arena)
        throw Error("", where, "medial axis extraction needs more than 16 GiB of working memory");
    } catch (const std::exception& e) {
      throw Error("", where, std::string("medial axis extraction failed: ") + e.what());
    }
  }
  const auto nv = boost::num_vertices(skeleton);
  if (nv == 0) throw Error("", where, "the medial axis is empty");

  // Split the skeleton graph into branches: maximal paths whose inner vertices have degree 2.
  std::vector<std::vector<std::size_t>> adjacency(nv);
  for (auto [e, end] = boost::edges(skeleton); e != end; ++e) {
    const std::size_t a = boost::source(*e, skeleton), b = boost::target(*e, skeleton);
    if (a == b) continue;
    adjacency[a].push_back(b);
    adjacency[b].push_back(a);
  }
  Tree tree(faces(sm).first, faces(sm).second, sm);
  tree.accelerate_distance_queries();

  // Prune spurs: a terminal branch (from a leaf to a branch point) shorter than twice the radius
  // is an artefact of contracting a cap (short tubes fork at their ends), not anatomy.
  {
    auto point = [&](std::size_t v) {
      return Eigen::Vector3d(skeleton[v].point.x(), skeleton[v].point.y(), skeleton[v].point.z());
    };
    auto erase_edge = [&](std::size_t a, std::size_t b) {
      auto& la = adjacency[a];
      la.erase(std::remove(la.begin(), la.end(), b), la.end());
      auto& lb = adjacency[b];
      lb.erase(std::remove(lb.begin(), lb.end(), a), lb.end());
    };
    for (bool changed = true; changed;) {
      changed = false;
      for (std::size_t leaf = 0; leaf < nv; ++leaf) {
        if (adjacency[leaf].size() != 1) continue;
        std::vector<std::size_t> spur{leaf};
        double length = 0;
        std::size_t prev = leaf, cur = adjacency[leaf][0];
        length += (point(cur) - point(prev)).norm();
        while (adjacency[cur].size() == 2) {
          const std::size_t nxt = adjacency[cur][0] == prev ? adjacency[cur][1] : adjacency[cur][0];
          spur.push_back(cur);
          length += (point(nxt) - point(cur)).norm();
          prev = cur;
          cur = nxt;
        }
        if (adjacency[cur].size() < 3 || length >= 2 * radius) continue;
        spur.push_back(cur);
        for (std::size_t k = 0; k + 1 < spur.size(); ++k) erase_edge(spur[k], spur[k + 1]);
        changed = true;
      }
    }
  }
  std::vector<std::vector<std::size_t>> paths;
  std::map<std::pair<std::size_t, std::size_t>, bool> used;
  auto is_stop = [&](std::size_t v) { return adjacency[v].size() != 2; };
  // Vertices left without edges by the pruning are not part of the axis any more, unless the
  // whole skeleton is one vertex.
  auto walk = [&](std::size_t from, std::size_t next) {
    std::vector<std::size_t> path{from, next};
    used[std::minmax(from, next)] = true;
    std::size_t prev = from, cur = next;
    while (!is_stop(cur)) {
      const std::size_t nxt = adjacency[cur][0] == prev ? adjacency[cur][1] : adjacency[cur][0];
      if (used[std::minmax(cur, nxt)]) break;  // a closed loop
      used[std::minmax(cur, nxt)] = true;
      path.push_back(nxt);
      prev = cur;
      cur = nxt;
    }
    return path;
  };
  for (std::size_t v = 0; v < nv; ++v)
    if (is_stop(v) && !adjacency[v].empty())
      for (std::size_t w : adjacency[v])
        if (!used[std::minmax(v, w)]) paths.push_back(walk(v, w));
  for (std::size_t v = 0; v < nv; ++v)  // loops without any stop vertex
    for (std::size_t w : adjacency[v])
      if (!used[std::minmax(v, w)]) paths.push_back(walk(v, w));

  AxisFilling out;
  std::vector<Eigen::Vector3d> centres;
  std::map<std::size_t, Index> stop_node;  // skeleton vertex (branch end) -> chain node
  auto node_at = [&](const Eigen::Vector3d& p) {
    centres.push_back(p);
    return Index(centres.size() - 1);
  };
  auto end_node = [&](std::size_t v, const Eigen::Vector3d& p) {
    auto it = stop_node.find(v);
    if (it != stop_node.end()) return it->second;
    return stop_node[v] = node_at(p);
  };
  if (paths.empty()) {  // a single skeleton vertex: one sphere
    out.branches.push_back({node_at(eig(skeleton[0].point))});
  }
  // Contraction pulls a free end of the skeleton back from the cap. The medial axis of a rounded
  // end reaches the point whose distance to the surface ahead equals its distance to the surface
  // around: extend each free end along its tangent by (distance to the surface ahead) minus
  // (distance to the surface), so the end sphere fills the cap.
  auto distance_to_surface = [&](const Eigen::Vector3d& p) {
    return std::sqrt(CGAL::to_double(tree.squared_distance(K::Point_3(p.x(), p.y(), p.z()))));
  };
  auto extend_end = [&](std::vector<Eigen::Vector3d>& pts, bool at_front) {
    if (pts.size() < 2) return;
    const Eigen::Vector3d end = at_front ? pts.front() : pts.back();
    // Tangent over the last stretch of about two radii.
    Eigen::Vector3d back = end;
    double walked = 0;
    for (std::size_t k = 1; k < pts.size() && walked < 2 * radius; ++k) {
      const Eigen::Vector3d q = at_front ? pts[k] : pts[pts.size() - 1 - k];
      walked += (q - back).norm();
      back = q;
    }
    const Eigen::Vector3d dir = (end - back).normalized();
    if (!dir.allFinite()) return;
    const K::Ray_3 ray(K::Point_3(end.x(), end.y(), end.z()),
                       K::Vector_3(dir.x(), dir.y(), dir.z()));
    const auto hit = tree.first_intersection(ray);
    if (!hit) return;
    const K::Point_3* p = boost::get<K::Point_3>(&hit->first);
    if (!p) return;
    const double ahead = (eig(*p) - end).norm();
    const double extension = ahead - distance_to_surface(end);
    if (extension > 0) (at_front ? pts.front() : pts.back()) = end + extension * dir;
  };
  for (const auto& path : paths) {
    std::vector<Eigen::Vector3d> pts;
    for (std::size_t v : path) pts.push_back(eig(skeleton[v].point));
    // The contracted curve zig-zags at the scale of the surface mesh, which lengthens it by a few
    // per cent and by a different amount from run to run (CGAL orders its edge collapses by
    // descriptor address). Laplacian smoothing of the inner points, ends held, removes that.
    for (int it = 0; it < 10 && pts.size() > 2; ++it) {
      std::vector<Eigen::Vector3d> next = pts;
      for (std::size_t i = 1; i + 1 < pts.size(); ++i)
        next[i] = 0.5 * pts[i] + 0.25 * (pts[i - 1] + pts[i + 1]);
      pts.swap(next);
    }
    if (adjacency[path.front()].size() == 1) extend_end(pts, true);
    if (adjacency[path.back()].size() == 1) extend_end(pts, false);
    std::vector<double> arc{0};
    for (std::size_t i = 1; i < pts.size(); ++i)
      arc.push_back(arc.back() + (pts[i] - pts[i - 1]).norm());
    const double length = arc.back();
    out.skeleton_length += length;
    const int segments = std::max(1, int(std::lround(length / spacing)));
    std::vector<Index> branch{end_node(path.front(), pts.front())};
    std::size_t seg = 1;
    for (int k = 1; k < segments; ++k) {
      const double s = length * k / segments;
      while (seg + 1 < arc.size() && arc[seg] < s) ++seg;
      const double t = (s - arc[seg - 1]) / std::max(arc[seg] - arc[seg - 1], 1e-15);
      branch.push_back(node_at((1 - t) * pts[seg - 1] + t * pts[seg]));
    }
    const Index last = end_node(path.back(), pts.back());
    if (last != branch.front() || segments > 1) branch.push_back(last);
    out.branches.push_back(branch);
  }

  out.centres.resize(Index(centres.size()), 3);
  out.radii.resize(Index(centres.size()));
  for (std::size_t i = 0; i < centres.size(); ++i) {
    out.centres.row(Index(i)) = centres[i].transpose();
    const double d = std::sqrt(CGAL::to_double(
        tree.squared_distance(K::Point_3(centres[i].x(), centres[i].y(), centres[i].z()))));
    out.radii[Index(i)] = std::clamp(d, rmin, rmax);
  }
  std::map<std::pair<Index, Index>, bool> linked;
  for (const auto& b : out.branches) {
    for (std::size_t i = 0; i + 1 < b.size(); ++i)
      if (b[i] != b[i + 1] && !linked[std::minmax(b[i], b[i + 1])]) {
        linked[std::minmax(b[i], b[i + 1])] = true;
        out.chain_links.emplace_back(b[i], b[i + 1]);
      }
    if (spec.bending)
      for (std::size_t i = 0; i + 2 < b.size(); ++i)
        if (b[i] != b[i + 2] && !linked[std::minmax(b[i], b[i + 2])]) {
          linked[std::minmax(b[i], b[i + 2])] = true;
          out.bending_links.emplace_back(b[i], b[i + 2]);
        }
  }
  return out;
}

}  // namespace fsm::build
