#pragma once

/// @file lattice.hpp
/// @brief Regular tetrahedral lattices built in code: test blocks, benchmark models and a quick
/// way to fill a simple shape without the CGAL builder.

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "fsm/tetrahedral_mesh.hpp"

namespace fsm {

/// @brief The Freudenthal (Kuhn) triangulation of a box of `cells` cubes of edge `spacing` (m):
/// each cube is split into six tetrahedra around its (0,0,0)-(1,1,1) diagonal. Every cube is
/// split the same way, so the lattice is translation-invariant and fills the box exactly.
/// Vertices are numbered x fastest, then y, then z; tetrahedra are positively oriented.
///
/// With Van Gelder's rule the lattice's modulus along a cube axis is \f$30E/29\f$ and its bulk
/// modulus exactly \f$2E/3\f$ (docs/physics.md).
/// @param origin the box's minimum corner (m); @param cells cubes along x, y, z (each >= 1).
/// @param inside optional filter: a cube is kept when inside(centre) is true (centre in m).
template <typename Scalar, typename Inside>
TetrahedralMesh<Scalar> make_cube_lattice(const Vector3<Scalar>& origin,
                                          const Eigen::Vector3i& cells, Scalar spacing,
                                          Inside&& inside) {
  if ((cells.array() < 1).any()) throw Error("", "lattice", "needs at least one cell per axis");
  if (!(spacing > 0) || !std::isfinite(spacing))
    throw Error("", "lattice", "spacing must be positive and finite");
  // Counted in 64 bits: the vertex ids and the 6 tetrahedra per cell must fit an Index.
  const double vertices = (double(cells[0]) + 1) * (double(cells[1]) + 1) * (double(cells[2]) + 1);
  const double tetrahedra = 6.0 * double(cells[0]) * double(cells[1]) * double(cells[2]);
  if (vertices > double(std::numeric_limits<Index>::max()) ||
      4 * tetrahedra > double(std::numeric_limits<Index>::max()))
    throw Error("", "lattice",
                std::to_string(cells[0]) + " x " + std::to_string(cells[1]) + " x " +
                    std::to_string(cells[2]) + " cells: more vertices or tetrahedra than an "
                    "Index (2^31 - 1) can count");
  const Index nx = cells[0] + 1, ny = cells[1] + 1, nz = cells[2] + 1;
  auto vid = [&](Index i, Index j, Index k) { return i + nx * (j + ny * k); };
  // The six permutations of the axes; consecutive corners differ by one unit step.
  static constexpr std::array<std::array<int, 3>, 6> perms{
      {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  std::vector<Index> tets;
  std::vector<char> used(std::size_t(nx * ny * nz), 0);
  for (Index k = 0; k < cells[2]; ++k)
    for (Index j = 0; j < cells[1]; ++j)
      for (Index i = 0; i < cells[0]; ++i) {
        const Vector3<Scalar> centre =
            origin + spacing * Vector3<Scalar>(Scalar(i) + Scalar(0.5), Scalar(j) + Scalar(0.5),
                                               Scalar(k) + Scalar(0.5));
        if (!inside(centre)) continue;
        for (const auto& p : perms) {
          std::array<Index, 3> c{i, j, k};
          std::array<Index, 4> t;
          t[0] = vid(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[std::size_t(p[std::size_t(s)])];
            t[std::size_t(s + 1)] = vid(c[0], c[1], c[2]);
          }
          // Odd permutations give left-handed tetrahedra: swap two corners.
          const bool odd =
              (p[0] == 0 && p[1] == 2) || (p[0] == 1 && p[1] == 0) || (p[0] == 2 && p[1] == 1);
          if (odd) std::swap(t[2], t[3]);
          for (Index v : t) {
            tets.push_back(v);
            used[std::size_t(v)] = 1;
          }
        }
      }
  if (tets.empty()) throw Error("", "lattice", "no cell lies inside the shape");
  // Keep the used vertices, in grid order.
  std::vector<Index> remap(used.size(), -1);
  Index count = 0;
  for (std::size_t v = 0; v < used.size(); ++v)
    if (used[v]) remap[v] = count++;
  TetrahedralMesh<Scalar> mesh;
  mesh.vertices.resize(count, 3);
  for (Index k = 0; k < nz; ++k)
    for (Index j = 0; j < ny; ++j)
      for (Index i = 0; i < nx; ++i) {
        const Index r = remap[std::size_t(vid(i, j, k))];
        if (r >= 0)
          mesh.vertices.row(r) =
              (origin + spacing * Vector3<Scalar>(Scalar(i), Scalar(j), Scalar(k))).transpose();
      }
  mesh.tetrahedra.resize(Index(tets.size() / 4), 4);
  for (std::size_t t = 0; t < tets.size(); ++t)
    mesh.tetrahedra(Index(t / 4), Index(t % 4)) = remap[std::size_t(tets[t])];
  return mesh;
}

/// @brief The full box (no filter).
template <typename Scalar>
TetrahedralMesh<Scalar> make_cube_lattice(const Vector3<Scalar>& origin,
                                          const Eigen::Vector3i& cells, Scalar spacing) {
  return make_cube_lattice(origin, cells, spacing, [](const Vector3<Scalar>&) { return true; });
}

}  // namespace fsm
