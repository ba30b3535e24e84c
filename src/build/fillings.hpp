#pragma once

// The builder's per-part fillings. CGAL-free interface; each filling's implementation is its own
// CGAL translation unit (tetra_filling.cpp, axis_filling.cpp, baselines.cpp).

#include <string>
#include <utility>
#include <vector>

#include "fsm/build/builder.hpp"
#include "fsm/build/metric_field.hpp"
#include "fsm/build/scene.hpp"
#include "fsm/tetrahedral_mesh.hpp"
#include "fsm/triangle_mesh.hpp"

namespace fsm::build::detail {

/// A tetrahedral filling of a closed surface under a metric, and its quality.
struct TetraFilling {
  TetrahedralMesh<double> mesh;
  QualityStats quality;
  std::string optimiser;  ///< the one actually used
};

/// Mesh_3 Delaunay refinement: constant metrics exactly (map by M^1/2, fill with unit size, map
/// back), varying metrics by their smallest size. Criteria in the unit space: cell circumradius
/// <= 1, surface Delaunay balls <= 1, surface distance <= 1/4, facet angle >= 25 degrees,
/// radius-edge ratio <= 2. `optimiser` "" means the default (odt).
TetraFilling fill_tetrahedral(const TriangleMesh<double>& surface, const MetricField& metric,
                              const std::string& optimiser, const std::string& part);

/// Quality statistics of a tetrahedral mesh in a metric (for reports and baselines).
QualityStats measure_quality(const TetrahedralMesh<double>& mesh, const MetricField& metric);

/// A sphere chain along a surface's medial axis.
struct AxisFilling {
  Positions<double> centres;                 ///< |N| x 3, m
  Eigen::VectorXd radii;                     ///< fitted to the distance to the surface, clamped (m)
  std::vector<std::vector<Index>> branches;  ///< node sequences; junction nodes are shared
  std::vector<std::pair<Index, Index>> chain_links;    ///< consecutive nodes along a branch
  std::vector<std::pair<Index, Index>> bending_links;  ///< second neighbours along a branch
  double skeleton_length{0};                           ///< m, before resampling
};

/// Mean-curvature-flow skeleton (CGAL, after Au et al. 2008), split into branches at nodes of
/// degree != 2, resampled at `spacing`.
AxisFilling fill_axis(const TriangleMesh<double>& surface, const AxisSpec& spec, double radius,
                      const std::string& part);

/// Baseline: grid nodes inside the surface, links to 6, 18 or 26 neighbours.
struct GridFilling {
  Positions<double> centres;
  std::vector<std::pair<Index, Index>> links;
  std::vector<std::uint8_t> link_kind;  ///< 0 axis, 1 face diagonal, 2 body diagonal
  double spacing{0};
};
GridFilling fill_grid(const TriangleMesh<double>& surface, double spacing, int neighbours,
                      const std::string& part);

/// Baseline: greedy unequal-radius packing of medial balls.
struct PackingFilling {
  Positions<double> centres;
  Eigen::VectorXd radii;
  std::vector<std::pair<Index, Index>> links;  ///< overlapping or touching spheres
};
PackingFilling fill_packing(const TriangleMesh<double>& surface, double radius_min,
                            double radius_max, const std::string& part);

/// Delaunay tetrahedralisation of points (used to bind render surfaces to the baselines' spheres).
TetrahedralMesh<double> tetrahedralise(const Positions<double>& points);

}  // namespace fsm::build::detail
