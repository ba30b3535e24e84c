#pragma once

/// @file build/scene.hpp
/// @brief The scene description the builder reads (JSON; schema in docs/scene.md), in SI units.

#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fsm/builder/metric_field.hpp"
#include "fsm/material.hpp"
#include "fsm/tissue_model.hpp"

namespace fsm::build {

/// @brief Alpha wrapping of a part's meshes into one closed surface (lengths in m).
struct AlphaWrapSpec {
  double alpha{0};   ///< Smallest feature kept.
  double offset{0};  ///< Distance of the wrap from the input.
};

/// @brief Options of an axis (sphere chain) part.
struct AxisSpec {
  double spacing{0};     ///< Between chain spheres (m); 0 = the part's radius.
  double radius_min{0};  ///< Clamp of the fitted sphere radius (m); 0 = radius / 2.
  double radius_max{0};  ///< 0 = 2 x radius.
  bool bending{true};    ///< Links to second neighbours, which resist bending.
};

/// @brief Options of the grid baseline.
struct GridSpec {
  int neighbours{6};  ///< 6, 18 or 26.
  double spacing{0};  ///< Grid spacing (m); 0 = 2 x radius.
};

/// @brief Options of the unequal-radius packing baseline.
struct PackingSpec {
  double radius_min{0};  ///< Stop packing below this radius (m); 0 = radius / 2.
  double radius_max{0};  ///< Largest ball (m); 0 = 2 x radius.
};

/// @brief One part of a scene.
struct PartSpec {
  std::string name;
  std::vector<std::string> meshes;  ///< Absolute paths.
  /// Per mesh (may be shorter than `meshes`: missing means none): the glTF nodes to take from it;
  /// empty takes the whole file.
  std::vector<std::vector<std::string>> mesh_nodes;
  double mesh_scale{1};  ///< Factor from mesh coordinates to m.
  Topology topology{Topology::tetrahedral};
  double radius{0};  ///< Nominal sphere radius (m).
  Material<double> material;
  /// The part's force law ("law": "links" or "continuum"; the continuum law needs a tetrahedral
  /// part). Default: links.
  ForceLaw law{ForceLaw::links};
  bool orient{false};                 ///< Repair: reorient faces outward.
  std::optional<AlphaWrapSpec> wrap;  ///< Repair: alpha-wrap the meshes into one closed surface.
  std::shared_ptr<const MetricField> metric;  ///< Tetrahedral only; null = isotropic(radius).
  std::string optimiser;  ///< Tetrahedral only: "odt", "lloyd", "perturb", "exude",
                          ///< "none"; "" = the default (docs/builder.md).
  AxisSpec axis;
  GridSpec grid;
  PackingSpec packing;
};

/// @brief Links between two parts where they touch.
struct AttachmentSpec {
  std::string a, b;
  double tolerance{0};        ///< Sphere surfaces closer than this are linked (m).
  double stiffness_scale{1};  ///< Multiplies the link stiffness rule (docs/builder.md).
  /// The attachment's links tear past this strain (or their parts' materials' if smaller);
  /// infinity (absent from the scene) = the materials decide.
  double tear_strain{std::numeric_limits<double>::infinity()};
};

/// @brief Nodes of a part held fixed.
struct FixedSpec {
  enum class Kind { box, plane, vertices, chain_end };
  std::string part;
  Kind kind{Kind::box};
  Eigen::Vector3d min{Eigen::Vector3d::Zero()}, max{Eigen::Vector3d::Zero()};  ///< box (m)
  Eigen::Vector3d point{Eigen::Vector3d::Zero()}, normal{Eigen::Vector3d::UnitZ()};
  ///< plane: nodes with (x - point) . normal <= 0 are fixed (m)
  std::vector<Index> vertices;  ///< node indices within the part
  bool last{false};             ///< chain_end: the last chain node instead of the first
};

/// @brief How much work a build may do (docs/builder.md, "Resource budget"). Before it fills a
/// part (or wraps its meshes) the builder estimates the spheres, elements and memory that will
/// take, and refuses, naming the estimate, when the scene's running total would pass a limit.
struct BuildLimits {
  double spheres{200'000};     ///< Spheres of the whole model.
  double elements{3'000'000};  ///< Tetrahedra, links and alpha-wrap faces of the whole model.
  double memory_bytes{4.0e9};  ///< Peak memory the build is estimated to need (bytes).
};

/// @brief A scene: parts, attachments, fixed regions.
struct Scene {
  std::string name;
  std::string file;  ///< The scene file, for messages ("" when built in code).
  std::vector<PartSpec> parts;
  std::vector<AttachmentSpec> attachments;
  std::vector<FixedSpec> fixed;
  BuildLimits limits;  ///< The scene's "limits", else the defaults.
};

/// @brief Reads and checks a scene file. Paths are resolved against the scene file's folder,
/// lengths converted to m once here. fsm::Error naming the file, the part and the reason for
/// anything wrong: bad JSON, a newer format version, an unknown key or topology, a missing mesh
/// file, a non-positive radius, a bad material, an attachment or fixed region naming an unknown
/// part.
Scene load_scene(const std::string& path);

/// @brief The same from JSON text; `base_dir` resolves relative paths, `file` names it in errors.
Scene parse_scene(const std::string& json_text, const std::string& base_dir,
                  const std::string& file = "");

}  // namespace fsm::build
