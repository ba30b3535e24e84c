#pragma once

// Geometric fidelity of a tetrahedral filling against the surface it was filled from (private to
// the builder; CGAL-free): volumes, areas, and areas inside the scene's fixed regions.

#include <string>
#include <vector>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/scene.hpp"
#include "fsm/tetrahedral_mesh.hpp"
#include "fsm/triangle_mesh.hpp"

namespace fsm::build::detail {

/// Relative differences above this (1 %) are warned about.
inline constexpr double kFidelityTolerance = 0.01;

/// The boundary of a tetrahedral mesh: the faces of exactly one tetrahedron, outward (for
/// positively oriented tetrahedra), on the mesh's own vertices.
TriangleMesh<double> boundary_surface(const TetrahedralMesh<double>& mesh);

/// The area of `mesh` inside a fixed region: each triangle clipped to the box, or to the
/// half-space (x - point) . normal <= 0, grown by `tolerance` (m) so that a face lying on the
/// region's boundary counts whole. Regions that are not geometric (vertices, chain_end) give 0.
double area_in_region(const TriangleMesh<double>& mesh, const FixedSpec& region, double tolerance);

/// Volumes and areas of `filling` against `surface`, and areas inside `regions` (the part's
/// fixed boxes and half-spaces; `names` says which, e.g. "fixed region 0 (box)").
FidelityReport measure_fidelity(const TriangleMesh<double>& surface,
                                const TetrahedralMesh<double>& filling,
                                const std::vector<FixedSpec>& regions,
                                const std::vector<std::string>& names);

/// The warnings for differences above kFidelityTolerance, in words.
std::vector<std::string> fidelity_warnings(const FidelityReport& fidelity, double radius);

}  // namespace fsm::build::detail
