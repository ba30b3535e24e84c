#pragma once

/// @file tissue_model.hpp
/// @brief TissueModel: everything a model file holds — the sphere model, its parts and the skinned
/// render surface — as built offline and loaded by the runtime.

#include <algorithm>
#include <cmath>
#include <cstdint>
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
  /// Its rows of spheres.tetrahedra() (tetrahedral parts; none for the others, and none in a
  /// model file of format version 1).
  Index first_tetrahedron{0}, num_tetrahedra{0};
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

  /// @brief Part `p`'s tetrahedra (`|T_p| x 4` node indices into `spheres`).
  [[nodiscard]] auto part_tetrahedra(const Part& p) const {
    return spheres.tetrahedra().middleRows(p.first_tetrahedron, p.num_tetrahedra);
  }

  /// @brief The part of that name; fsm::Error listing the names otherwise.
  [[nodiscard]] const Part& part(const std::string& part_name) const {
    std::string names;
    for (const Part& p : parts) {
      if (p.name == part_name) return p;
      names += (names.empty() ? "'" : ", '") + p.name + "'";
    }
    throw Error("", "part '" + part_name + "'", "no such part; the model has " + names);
  }

  /// @brief Checks the spheres, the part ranges, the tetrahedra and the skin; throws fsm::Error
  /// naming the element and the reason. Ranges are compared in 64 bits, so no count or index (a
  /// crafted file's near 2^31) can overflow the check.
  void validate() const {
    spheres.validate();
    const auto inside = [](Index first, Index count, Index size) {
      return first >= 0 && count >= 0 && std::int64_t(first) + std::int64_t(count) <= size;
    };
    const Index num_tets = spheres.num_tetrahedra();
    const auto tetrahedra = spheres.tetrahedra();
    for (const Part& p : parts) {
      const std::string what = "part '" + p.name + "'";
      if (p.region < 0 || p.region >= spheres.num_regions()) throw Error("", what, "bad region");
      if (!(p.radius > 0) || !std::isfinite(p.radius))
        throw Error(
            "", what,
            "nominal radius " + std::to_string(p.radius) + " m must be positive and finite");
      if (!inside(p.first_node, p.num_nodes, spheres.num_nodes()))
        throw Error("", what, "node range outside the model");
      if (!inside(p.first_link, p.num_links, spheres.num_links()))
        throw Error("", what, "link range outside the model");
      if (p.surface < -1 || p.surface >= Index(skin.surfaces.size()))
        throw Error("", what, "surface index out of range");
      if (!inside(p.first_tetrahedron, p.num_tetrahedra, num_tets))
        throw Error("", what, "tetrahedron range outside the model");
      if (p.num_tetrahedra > 0 && p.topology != Topology::tetrahedral)
        throw Error(
            "", what,
            std::string("a part of topology '") + to_string(p.topology) + "' has tetrahedra");
      for (Index t = p.first_tetrahedron; t < p.first_tetrahedron + p.num_tetrahedra; ++t) {
        const std::string tet = what + " tetrahedron " + std::to_string(t - p.first_tetrahedron);
        for (int k = 0; k < 4; ++k) {
          const Index i = tetrahedra(t, k);
          if (i < p.first_node || i - p.first_node >= p.num_nodes)
            throw Error("", tet,
                        "node " + std::to_string(i) + " is outside the part's nodes [" +
                            std::to_string(p.first_node) + ", " +
                            std::to_string(std::int64_t(p.first_node) + p.num_nodes) + ")");
        }
      }
    }
    if (!inside(first_attachment_link, num_attachment_links, spheres.num_links()))
      throw Error("", "attachments", "link range outside the model");
    if (skin.num_vertices() > 0) skin.validate(spheres.num_nodes());
  }
};

}  // namespace fsm
