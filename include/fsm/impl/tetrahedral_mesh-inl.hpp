#pragma once

// Definitions for fsm/tetrahedral_mesh.hpp.

#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>
#include <vector>

namespace fsm {

template <typename Scalar>
void TetrahedralMesh<Scalar>::validate(const std::string& what) const {
  const Index nv = static_cast<Index>(vertices.rows());
  const Index nt = static_cast<Index>(tetrahedra.rows());
  if (nv == 0 || nt == 0) throw Error("", what, "tetrahedral mesh is empty");
  for (Index i = 0; i < nv; ++i)
    if (!vertices.row(i).allFinite())
      throw Error("", what, "vertex " + std::to_string(i) + " is not finite");
  std::vector<char> used(std::size_t(nv), 0);
  for (Index t = 0; t < nt; ++t) {
    for (int c = 0; c < 4; ++c) {
      const Index k = tetrahedra(t, c);
      if (k < 0 || k >= nv)
        throw Error("", what,
                    "tetrahedron " + std::to_string(t) + " names vertex " + std::to_string(k) +
                        ", out of range [0, " + std::to_string(nv) + ")");
      for (int d = 0; d < c; ++d)
        if (tetrahedra(t, d) == k)
          throw Error("", what,
                      "tetrahedron " + std::to_string(t) + " repeats vertex " + std::to_string(k));
      used[std::size_t(k)] = 1;
    }
    Scalar edge(0);
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        edge += (vertices.row(tetrahedra(t, a)) - vertices.row(tetrahedra(t, b))).norm();
    edge /= Scalar(6);
    if (!(std::abs(signed_volume(t)) > Scalar(1e-12) * edge * edge * edge))
      throw Error("", what, "tetrahedron " + std::to_string(t) + " is degenerate (zero volume)");
  }
  for (Index i = 0; i < nv; ++i)
    if (!used[std::size_t(i)])
      throw Error("", what, "vertex " + std::to_string(i) + " belongs to no tetrahedron");
  // The same four vertices twice would count that element's mass and stiffness twice.
  std::vector<std::pair<std::array<Index, 4>, Index>> sorted(static_cast<std::size_t>(nt));
  for (Index t = 0; t < nt; ++t) {
    std::array<Index, 4> k{tetrahedra(t, 0), tetrahedra(t, 1), tetrahedra(t, 2), tetrahedra(t, 3)};
    std::sort(k.begin(), k.end());
    sorted[std::size_t(t)] = {k, t};
  }
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 1; k < sorted.size(); ++k)
    if (sorted[k].first == sorted[k - 1].first)
      throw Error("", what,
                  "tetrahedron " + std::to_string(sorted[k].second) + " repeats tetrahedron " +
                      std::to_string(sorted[k - 1].second));
}

template <typename Scalar>
PartRange add_tetrahedral_part(SphereModel<Scalar>& model, const TetrahedralMesh<Scalar>& mesh,
                               Index region, Scalar radius) {
  if (region < 0 || region >= model.num_regions())
    throw Error("", "region " + std::to_string(region), "index out of range");
  const Region<Scalar>& reg = model.region(region);
  const std::string what = "region '" + reg.name + "'";
  mesh.validate(what);
  if (!(std::isfinite(radius) && radius > 0))
    throw Error("", what,
                "sphere radius " + detail::format_number(double(radius)) + " m must be positive");

  const Index nv = static_cast<Index>(mesh.vertices.rows());
  const Index nt = static_cast<Index>(mesh.tetrahedra.rows());
  std::vector<Scalar> lumped(std::size_t(nv), Scalar(0));
  // (a, b, volume) for each tetrahedron edge, a < b; sorted and merged into distinct edges.
  std::vector<std::tuple<Index, Index, Scalar>> edges;
  edges.reserve(6 * std::size_t(nt));
  for (Index t = 0; t < nt; ++t) {
    const Scalar vol = std::abs(mesh.signed_volume(t));
    for (int a = 0; a < 4; ++a) {
      lumped[std::size_t(mesh.tetrahedra(t, a))] += vol / Scalar(4);
      for (int b = a + 1; b < 4; ++b) {
        Index p = mesh.tetrahedra(t, a), q = mesh.tetrahedra(t, b);
        if (p > q) std::swap(p, q);
        edges.emplace_back(p, q, vol);
      }
    }
  }
  std::sort(edges.begin(), edges.end(), [](const auto& u, const auto& w) {
    return std::tie(std::get<0>(u), std::get<1>(u)) < std::tie(std::get<0>(w), std::get<1>(w));
  });

  SphereModel<Scalar> staged = model;  // strong guarantee: the model changes only on success
  PartRange range;
  range.first_node = staged.num_nodes();
  range.first_link = staged.num_links();
  staged.reserve(staged.num_nodes() + nv, staged.num_links() + Index(edges.size() / 4));
  const Scalar density = reg.material.density;
  for (Index i = 0; i < nv; ++i)
    staged.add_node(mesh.vertices.row(i).transpose(), radius, density * lumped[std::size_t(i)],
                    region);
  for (std::size_t k = 0; k < edges.size();) {
    const auto [p, q, v0] = edges[k];
    Scalar vol(0);
    for (; k < edges.size() && std::get<0>(edges[k]) == p && std::get<1>(edges[k]) == q; ++k)
      vol += std::get<2>(edges[k]);
    (void)v0;
    const Scalar len = (mesh.vertices.row(q) - mesh.vertices.row(p)).norm();
    staged.add_link(range.first_node + p, range.first_node + q,
                    tetrahedral_link(reg.material, vol, len));
  }
  // The tetrahedra, positively oriented (the continuum law acts on them).
  range.first_tetrahedron = staged.num_tetrahedra();
  for (Index t = 0; t < nt; ++t) {
    Index a = mesh.tetrahedra(t, 0), b = mesh.tetrahedra(t, 1), c = mesh.tetrahedra(t, 2),
          d = mesh.tetrahedra(t, 3);
    if (mesh.signed_volume(t) < Scalar(0)) std::swap(c, d);
    staged.add_tetrahedron(range.first_node + a, range.first_node + b, range.first_node + c,
                           range.first_node + d);
  }
  range.num_nodes = nv;
  range.num_links = staged.num_links() - range.first_link;
  range.num_tetrahedra = nt;
  model = std::move(staged);
  return range;
}

}  // namespace fsm
