#pragma once

/// @file tetrahedral_mesh.hpp
/// @brief TetrahedralMesh and add_tetrahedral_part(): a tetrahedral filling becomes spheres
/// (one per vertex) joined by links (one per edge) with Van Gelder's stiffness rule.

#include <string>

#include "fsm/sphere_model.hpp"

namespace fsm {

/// @brief A tetrahedral mesh: vertices (`|V| x 3`, m) and tetrahedra (`|T| x 4` vertex indices).
template <typename Scalar>
struct TetrahedralMesh {
  Positions<Scalar> vertices;
  TetrahedronArray tetrahedra;

  /// @brief Signed volume of tetrahedron t (m^3); positive when (b-a, c-a, d-a) is right-handed.
  [[nodiscard]] Scalar signed_volume(Index t) const noexcept {
    const Vector3<Scalar> a = vertices.row(tetrahedra(t, 0)).transpose();
    const Vector3<Scalar> b = vertices.row(tetrahedra(t, 1)).transpose();
    const Vector3<Scalar> c = vertices.row(tetrahedra(t, 2)).transpose();
    const Vector3<Scalar> d = vertices.row(tetrahedra(t, 3)).transpose();
    return (b - a).dot((c - a).cross(d - a)) / Scalar(6);
  }
  /// @brief Total volume (m^3).
  [[nodiscard]] Scalar volume() const noexcept {
    Scalar v(0);
    for (Index t = 0; t < tetrahedra.rows(); ++t) v += std::abs(signed_volume(t));
    return v;
  }
  /// @brief Throws fsm::Error naming `what` and the bad element: an empty mesh, a non-finite
  /// vertex, an index out of range, a repeated vertex in a tetrahedron, a degenerate tetrahedron
  /// (|V| below 1e-12 of the mean edge length cubed), a vertex used by no tetrahedron, the same
  /// tetrahedron twice.
  void validate(const std::string& what) const;
};

/// @brief Where a part's nodes and links landed in the model.
struct PartRange {
  Index first_node{0};
  Index num_nodes{0};
  Index first_link{0};
  Index num_links{0};
  Index first_tetrahedron{0};
  Index num_tetrahedra{0};
};

/// @brief Adds a tetrahedral filling to `model` as nodes of `region`.
///
/// One node per vertex, radius `radius` (m); one link per distinct edge, its constants from the
/// region's material by tetrahedral_link() (Van Gelder's rule: \f$k = E\sum_{T\ni e}V_T/l_e^2\f$);
/// lumped masses \f$m_i = \rho\sum_{T\ni i}V_T/4\f$, so the part's mass is exactly
/// \f$\rho V\f$. Links are ordered by their first node, which keeps the force loop's memory access
/// local when the vertices are spatially ordered. The tetrahedra are added too, positively
/// oriented (the continuum law acts on them). Throws fsm::Error for a bad mesh or radius, leaving
/// the model unchanged.
template <typename Scalar>
PartRange add_tetrahedral_part(SphereModel<Scalar>& model, const TetrahedralMesh<Scalar>& mesh,
                               Index region, Scalar radius);

extern template struct TetrahedralMesh<float>;
extern template struct TetrahedralMesh<double>;
extern template PartRange add_tetrahedral_part(SphereModel<float>&, const TetrahedralMesh<float>&,
                                               Index, float);
extern template PartRange add_tetrahedral_part(SphereModel<double>&, const TetrahedralMesh<double>&,
                                               Index, double);

}  // namespace fsm

#include "fsm/impl/tetrahedral_mesh-inl.hpp"
