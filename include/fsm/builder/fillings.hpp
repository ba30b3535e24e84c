#pragma once

/// @file builder/fillings.hpp
/// @brief The builder's per-part fillings, one function each: a closed surface in, spheres (and,
/// for the tetrahedral filling, the tetrahedra) out. Part of fsm::build (GPL-3.0-or-later); this
/// header is CGAL-free, each filling is its own CGAL translation unit in src/builder.
///
/// HybridTopologyBuilder calls these for every part of a scene; benchmarks, validation tools and
/// tests call them to look at one filling alone.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/metric_field.hpp"
#include "fsm/builder/scene.hpp"
#include "fsm/tetrahedral_mesh.hpp"
#include "fsm/triangle_mesh.hpp"

namespace fsm::build {

/// @brief The default sharp-edge angle of the tetrahedral filling (degrees between face normals).
inline constexpr double kFeatureAngleDeg = 60;

/// @brief A tetrahedral filling of a closed surface under a metric, and its quality.
struct TetraFilling {
  TetrahedralMesh<double> mesh;  ///< vertices `|V| x 3` (m), tetrahedra `|T| x 4`, positive volume
  QualityStats quality;          ///< Q(K) measured in the metric
  std::string optimiser;         ///< the one actually used
  double feature_angle_deg{0};   ///< an edge is sharp when its face normals differ by more
  Index feature_edges{0};        ///< sharp edges of the surface protected in the filling
  Index feature_corners{0};      ///< vertices of the filling where protected chains end or meet
  /// Cells dropped because their piece hung on the rest by a vertex or an edge only and held less
  /// than kMinComponentShare of the largest piece's volume, and their volume (m^3).
  Index dropped_cells{0};
  double dropped_volume{0};
};

/// A face-connected piece of a tetrahedral filling smaller than this share of the largest piece's
/// volume is dropped (fill_tetrahedral).
inline constexpr double kMinComponentShare = 0.01;

namespace detail {
/// @brief Drops the pieces of a filling that hang on the rest by a vertex or an edge only: the
/// cells are grouped into components joined through shared faces, and a component with less than
/// kMinComponentShare of the largest one's volume is removed with the vertices only it used (the
/// others renumbered in their order). Mesh_3 leaves such pieces (often a single flat cell) where a
/// surface pinches; a piece joined by a vertex swings freely about it, and one of a fraction of a
/// cubic millimetre with nodes of tens of micrograms is what the continuum law's step could not
/// follow on the Visible Human uterus (docs/builder.md).
void drop_hanging_pieces(std::vector<Eigen::Vector3d>& points,
                         std::vector<std::array<Index, 4>>& tets, Index& removed_cells,
                         double& removed_volume);
}  // namespace detail

/// @brief Mesh_3 Delaunay refinement under `metric`: constant metrics exactly (map by M^1/2, fill
/// with unit size, map back), varying metrics by their smallest size. Criteria in the unit space:
/// cell circumradius <= 1, surface Delaunay balls <= 1, surface distance <= 1/4, facet angle >= 25
/// degrees, radius-edge ratio <= 2. Seeded: the same input gives the same mesh.
/// Sharp edges (the normals of their two faces more than `feature_angle_deg` apart, measured where
/// the metric is the identity), in chains at least one element size long, are protected with edge
/// size 1 in that space: they become edges of the filling, their ends and meeting points (a box's
/// corners) vertices. A surface without such chains is filled exactly as without protection.
/// @param surface a closed, outward-oriented surface (m).
/// @param optimiser "odt", "odt_perturb", "lloyd", "perturb", "exude", "none", or "" for the
/// default (odt).
/// @param part the part's name, for messages.
/// @param feature_angle_deg the sharp-edge angle (default 60, CGAL's: a dihedral angle below 120
/// degrees); 0 protects nothing (the builder's choice for an alpha-wrapped surface).
/// @throws fsm::Error naming the part: meshing failed or produced no tetrahedra.
TetraFilling fill_tetrahedral(const TriangleMesh<double>& surface, const MetricField& metric,
                              const std::string& optimiser, const std::string& part,
                              double feature_angle_deg = kFeatureAngleDeg);

/// @brief Quality statistics of a tetrahedral mesh in a metric (for reports and baselines).
QualityStats measure_quality(const TetrahedralMesh<double>& mesh, const MetricField& metric);

/// @brief A sphere chain along a surface's medial axis.
struct AxisFilling {
  Positions<double> centres;                 ///< `|N| x 3` (m)
  Eigen::VectorXd radii;                     ///< fitted to the distance to the surface, clamped (m)
  std::vector<std::vector<Index>> branches;  ///< node sequences; junction nodes are shared
  std::vector<std::pair<Index, Index>> chain_links;    ///< consecutive nodes along a branch
  std::vector<std::pair<Index, Index>> bending_links;  ///< second neighbours along a branch
  double skeleton_length{0};                           ///< m, before resampling
};

/// @brief Mean-curvature-flow skeleton (CGAL, after Au et al. 2008), split into branches at
/// nodes of degree != 2, resampled at `spec.spacing` (or `radius`).
/// @throws fsm::Error naming the part: the skeleton is empty or the options contradict.
AxisFilling fill_axis(const TriangleMesh<double>& surface, const AxisSpec& spec, double radius,
                      const std::string& part);

/// @brief Baseline: grid nodes inside the surface, links to 6, 18 or 26 neighbours.
struct GridFilling {
  Positions<double> centres;                   ///< `|N| x 3` (m)
  std::vector<std::pair<Index, Index>> links;  ///< node pairs
  std::vector<std::uint8_t> link_kind;         ///< 0 axis, 1 face diagonal, 2 body diagonal
  double spacing{0};                           ///< m
};
/// @brief Grid filling at `spacing` (m) with 6, 18 or 26 neighbours.
GridFilling fill_grid(const TriangleMesh<double>& surface, double spacing, int neighbours,
                      const std::string& part);

/// @brief Baseline: greedy unequal-radius packing of medial balls.
struct PackingFilling {
  Positions<double> centres;                   ///< `|N| x 3` (m)
  Eigen::VectorXd radii;                       ///< m
  std::vector<std::pair<Index, Index>> links;  ///< overlapping or touching spheres
};
/// @brief Packs balls of radius in [radius_min, radius_max] (m) into the surface, largest first.
PackingFilling fill_packing(const TriangleMesh<double>& surface, double radius_min,
                            double radius_max, const std::string& part);

/// @brief Delaunay tetrahedralisation of points (binds render surfaces to the baselines'
/// spheres). @throws fsm::Error when the points span no volume.
TetrahedralMesh<double> tetrahedralise(const Positions<double>& points);

}  // namespace fsm::build
