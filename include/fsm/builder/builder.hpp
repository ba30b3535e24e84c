#pragma once

/// @file build/builder.hpp
/// @brief HybridTopologyBuilder: a scene in, a TissueModel (spheres, parts, attachments, fixed
/// nodes, skinned render surface) and a build report out.

#include <functional>
#include <string>
#include <vector>

#include "fsm/builder/mesh_io.hpp"
#include "fsm/builder/scene.hpp"
#include "fsm/tissue_model.hpp"

namespace fsm::build {

/// @brief Quality of a tetrahedral filling, measured in its metric.
struct QualityStats {
  Index tetrahedra{0};
  double q_min{0}, q_mean{0}, q_max{0};  ///< Q(K), 1 = regular.
  double fraction_q_1_3{0};              ///< Share of elements with Q in [1, 3].
  std::vector<Index> histogram;  ///< Counts in [1,1.5), [1.5,2), [2,3), [3,5), [5,10), [10,inf).
  double min_dihedral_deg{0};
  double mean_edge{0};  ///< m
};

/// @brief What filling a part is estimated to cost, before it is filled (BuildLimits).
struct WorkEstimate {
  double spheres{0};       ///< Spheres the filling will make.
  double elements{0};      ///< Tetrahedra, links, or faces of an alpha wrap.
  double memory_bytes{0};  ///< Peak memory of the filling (bytes).
  std::string basis;       ///< How it was estimated, in words ("volume 64 cm^3 at 5 mm").
};

/// @brief A fixed region's share of a tetrahedral part's surface, against the filling's.
struct RegionFidelity {
  std::string region;     ///< "fixed region 0 (box)"
  double input_area{0};   ///< m^2 of the surface the part was filled from, clipped to the region
  double filled_area{0};  ///< m^2 of the filling's boundary faces, clipped to the region
  double difference{0};   ///< filled_area / input_area - 1 (0 when the region holds no surface)
};

/// @brief How closely a tetrahedral filling follows the surface it was filled from
/// (docs/builder.md, "Geometric fidelity").
struct FidelityReport {
  double input_volume{0}, filled_volume{0};  ///< m^3: the surface's, the tetrahedra's
  double input_area{0}, filled_area{0};      ///< m^2: the surface's, the filling's boundary
  double volume_difference{0};               ///< filled_volume / input_volume - 1
  double area_difference{0};                 ///< filled_area / input_area - 1
  double feature_angle_deg{0};               ///< sharp-edge angle used (0: no protection)
  Index feature_edges{0};                    ///< sharp edges of the surface protected
  Index feature_corners{0};                  ///< filling vertices where protected edges end/meet
  Index dropped_cells{0};               ///< cells of pieces hanging by a vertex or an edge, dropped
  double dropped_volume{0};             ///< their volume (m^3)
  std::vector<RegionFidelity> regions;  ///< the part's fixed boxes and half-spaces
};

/// @brief One part's line of the report (the paper's Table 1 and more).
struct PartReport {
  std::string name;
  Topology topology{Topology::tetrahedral};
  double radius{0};  ///< m
  Index spheres{0}, links{0};
  QualityStats quality;     ///< Tetrahedral parts only.
  FidelityReport fidelity;  ///< Tetrahedral parts only.
  Index surface_vertices{0}, surface_faces{0};
  double volume{0};   ///< m^3 of the surface the part was filled from
  double mass{0};     ///< kg
  double seconds{0};  ///< Wall time to build the part.
  std::vector<MeshReport> meshes;
  std::string metric;                 ///< Tetrahedral: the metric's description.
  std::string optimiser;              ///< Tetrahedral: the optimiser used.
  WorkEstimate estimate;              ///< The work estimated before filling.
  std::vector<std::string> warnings;  ///< What built but may not be what was meant.
};

/// @brief What a build produced.
struct BuildReport {
  std::string scene;
  std::vector<PartReport> parts;
  Index spheres{0}, links{0}, attachment_links{0}, fixed_nodes{0};
  double seconds{0};

  /// @brief A Table-1-like text table (warnings below it).
  [[nodiscard]] std::string table() const;
  /// @brief Every part's warnings, prefixed with the part's name.
  [[nodiscard]] std::vector<std::string> warnings() const;
  /// @brief The same as JSON (field names in docs/builder.md). Without `wall_times` the
  /// `seconds` fields are left out: the report a model file keeps is then a function of the scene
  /// and the library's version only, so building twice gives the same bytes.
  [[nodiscard]] std::string json(bool wall_times = true) const;
};

/// @brief Builds a scene into a TissueModel.
class HybridTopologyBuilder {
 public:
  /// Called with (part, stage, fraction done of the whole build in [0, 1]).
  using Progress = std::function<void(const std::string&, const std::string&, double)>;

  explicit HybridTopologyBuilder(Scene scene);
  void set_progress(Progress progress) { m_progress = std::move(progress); }
  /// @brief Replaces the scene's limits (a command-line override). fsm::Error for a limit that is
  /// not positive.
  void set_limits(const BuildLimits& limits);
  /// @brief Builds every part, joins them, fixes anchors, binds the render surface. fsm::Error
  /// naming file, part and reason on bad input; the scene is left untouched.
  TissueModel<double> build();
  [[nodiscard]] const BuildReport& report() const noexcept { return m_report; }
  [[nodiscard]] const Scene& scene() const noexcept { return m_scene; }

 private:
  Scene m_scene;
  BuildLimits m_limits;
  Progress m_progress;
  BuildReport m_report;
};

/// @brief One-off: load a scene file and build it.
TissueModel<double> build_model(const std::string& scene_path, BuildReport* report = nullptr);

}  // namespace fsm::build
