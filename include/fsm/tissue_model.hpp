#pragma once

/// @file tissue_model.hpp
/// @brief TissueModel: everything a model file holds — the sphere model, its parts and the skinned
/// render surface — as built offline and loaded by the runtime.

#include <string>
#include <vector>

#include "fsm/skinning.hpp"
#include "fsm/sphere_model.hpp"

namespace fsm {

/// @brief How a part was filled with spheres.
enum class Topology : std::uint8_t {
  tetrahedral = 0,  ///< Tetrahedral filling: one sphere per vertex, one link per edge.
  axis = 1,         ///< A sphere chain along the medial axis.
  grid = 2,         ///< Baseline: spheres on a cubic grid.
  packing = 3,      ///< Baseline: unequal-radius sphere packing.
};

/// @brief Name of a Topology ("tetrahedral", "axis", "grid", "packing").
[[nodiscard]] inline const char* to_string(Topology t) noexcept {
  switch (t) {
    case Topology::tetrahedral:
      return "tetrahedral";
    case Topology::axis:
      return "axis";
    case Topology::grid:
      return "grid";
    case Topology::packing:
      return "packing";
  }
  return "unknown";
}

/// @brief One part of a built model: where its spheres and links are, and its render surface.
struct Part {
  std::string name;
  Topology topology{Topology::tetrahedral};
  Index region{0};   ///< Its region in the SphereModel.
  double radius{0};  ///< The part's nominal sphere radius (m).
  Index first_node{0}, num_nodes{0};
  Index first_link{0}, num_links{0};  ///< Links inside the part (attachments are listed apart).
  Index surface{-1};                  ///< Index into Skin::surfaces, or -1.
};

/// @brief A built model: spheres, parts, attachment links, render surfaces.
template <typename Scalar>
struct TissueModel {
  std::string name;  ///< The scene's name.
  SphereModel<Scalar> spheres;
  std::vector<Part> parts;
  Index first_attachment_link{0};  ///< Attachment links between parts are the last links.
  Index num_attachment_links{0};
  Skin<Scalar> skin;
  std::string report_json;  ///< The builder's report (JSON text), kept for provenance.

  /// @brief The part of that name; fsm::Error listing the names otherwise.
  [[nodiscard]] const Part& part(const std::string& part_name) const {
    std::string names;
    for (const Part& p : parts) {
      if (p.name == part_name) return p;
      names += (names.empty() ? "'" : ", '") + p.name + "'";
    }
    throw Error("", "part '" + part_name + "'", "no such part; the model has " + names);
  }

  /// @brief Checks the spheres, the part ranges and the skin; throws fsm::Error.
  void validate() const {
    spheres.validate();
    for (const Part& p : parts) {
      const std::string what = "part '" + p.name + "'";
      if (p.region < 0 || p.region >= spheres.num_regions()) throw Error("", what, "bad region");
      if (p.first_node < 0 || p.num_nodes < 0 || p.first_node + p.num_nodes > spheres.num_nodes())
        throw Error("", what, "node range outside the model");
      if (p.first_link < 0 || p.num_links < 0 || p.first_link + p.num_links > spheres.num_links())
        throw Error("", what, "link range outside the model");
      if (p.surface >= Index(skin.surfaces.size()))
        throw Error("", what, "surface index out of range");
    }
    if (first_attachment_link < 0 || num_attachment_links < 0 ||
        first_attachment_link + num_attachment_links > spheres.num_links())
      throw Error("", "attachments", "link range outside the model");
    if (skin.num_vertices() > 0) skin.validate(spheres.num_nodes());
  }
};

}  // namespace fsm
