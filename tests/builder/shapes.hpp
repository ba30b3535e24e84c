#pragma once

// Closed, manifold, outward test surfaces built in code.

#include <array>
#include <cmath>
#include <map>
#include <vector>

#include "fsm/triangle_mesh.hpp"

namespace fsm::test {

/// A subdivided icosahedron on a sphere of `radius` (m) around `centre`, scaled per axis by
/// `scale` (an ellipsoid). 20 * 4^subdivisions faces.
inline TriangleMesh<double> icosphere(double radius, int subdivisions,
                                      const Eigen::Vector3d& scale = Eigen::Vector3d::Ones(),
                                      const Eigen::Vector3d& centre = Eigen::Vector3d::Zero()) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<Index, 3>> f = {
      {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<Index, Index>, Index> mid;
    auto midpoint = [&](Index a, Index b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[std::size_t(a)] + v[std::size_t(b)]).normalized());
      return mid[key] = Index(v.size() - 1);
    };
    std::vector<std::array<Index, 3>> g;
    for (const auto& tri : f) {
      const Index a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]),
                  c = midpoint(tri[2], tri[0]);
      g.push_back({tri[0], a, c});
      g.push_back({tri[1], b, a});
      g.push_back({tri[2], c, b});
      g.push_back({a, b, c});
    }
    f.swap(g);
  }
  TriangleMesh<double> m;
  m.vertices.resize(Index(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i)
    m.vertices.row(Index(i)) = (centre + radius * v[i].cwiseProduct(scale)).transpose();
  m.faces.resize(Index(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i)
    for (int k = 0; k < 3; ++k) m.faces(Index(i), k) = f[i][std::size_t(k)];
  return m;
}

/// A capsule along x: a cylinder of radius r between x = -h and x = h with hemispherical caps,
/// `around` vertices per ring, rings about r * 2 pi / around apart.
inline TriangleMesh<double> capsule(double r, double h, int around = 24) {
  std::vector<Eigen::Vector3d> v;
  std::vector<std::array<Index, 3>> f;
  const double step = 2 * M_PI * r / around;
  std::vector<double> xs, rs;  // ring positions and radii, from the left pole to the right
  const int cap_rings = std::max(2, int(std::ceil(0.5 * M_PI * r / step)));
  for (int i = 1; i <= cap_rings; ++i) {          // left cap, excluding the pole
    const double a = 0.5 * M_PI * i / cap_rings;  // from the pole
    xs.push_back(-h - r * std::cos(a));
    rs.push_back(r * std::sin(a));
  }
  const int body = std::max(1, int(std::ceil(2 * h / step)));
  for (int i = 1; i < body; ++i) {
    xs.push_back(-h + 2 * h * i / body);
    rs.push_back(r);
  }
  for (int i = cap_rings; i >= 1; --i) {
    const double a = 0.5 * M_PI * i / cap_rings;
    xs.push_back(h + r * std::cos(a));
    rs.push_back(r * std::sin(a));
  }
  v.emplace_back(-h - r, 0, 0);  // left pole
  for (std::size_t k = 0; k < xs.size(); ++k)
    for (int j = 0; j < around; ++j) {
      const double phi = 2 * M_PI * j / around;
      v.emplace_back(xs[k], rs[k] * std::cos(phi), rs[k] * std::sin(phi));
    }
  v.emplace_back(h + r, 0, 0);  // right pole
  const Index rings = Index(xs.size()), right = Index(v.size() - 1);
  auto id = [&](Index ring, int j) { return 1 + ring * around + (j % around); };
  for (int j = 0; j < around; ++j) f.push_back({0, id(0, j + 1), id(0, j)});
  for (Index k = 0; k + 1 < rings; ++k)
    for (int j = 0; j < around; ++j) {
      f.push_back({id(k, j), id(k, j + 1), id(k + 1, j + 1)});
      f.push_back({id(k, j), id(k + 1, j + 1), id(k + 1, j)});
    }
  for (int j = 0; j < around; ++j) f.push_back({right, id(rings - 1, j), id(rings - 1, j + 1)});
  TriangleMesh<double> m;
  m.vertices.resize(Index(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(Index(i)) = v[i].transpose();
  m.faces.resize(Index(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i)
    for (int k = 0; k < 3; ++k) m.faces(Index(i), k) = f[i][std::size_t(k)];
  return m;
}

}  // namespace fsm::test
