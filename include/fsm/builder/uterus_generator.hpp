#pragma once

/// @file build/uterus_generator.hpp
/// @brief The default data set: a procedural uterus with a fibroid and its adnexa, as closed
/// manifold surface meshes, and a scene with the paper's Table 1 settings.

#include <string>
#include <vector>

#include "fsm/triangle_mesh.hpp"

namespace fsm::build {

/// @brief Dimensions of the procedural uterus (m). Defaults are plausible adult values, tuned so
/// the built model lands near the paper's Table 1 sphere counts
/// (tests/builder/test_uterus_generator.cpp, data/uterus/README.md).
///
/// Frame: z up toward the fundus, +x the patient's left, +y anterior; the body's centre is the
/// origin. Left-side parts are generated and the right-side ones are their mirror images.
struct UterusShape {
  // Uterine body: a pear (tapered ellipsoid), fundus up (+z), anterior +y, patient's left +x.
  double body_length{0.077};  ///< fundus to internal os (along z)
  double body_width{0.050};   ///< largest width (x), near the fundus
  double body_depth{0.035};   ///< largest antero-posterior depth (y)
  double body_taper{0.45};    ///< cross-section scale at the cervical end relative to the fundus
  // Subserosal fibroid bulging from the fundal wall; the body is the pear minus its ball.
  double fibroid_radius{0.00535};
  double fibroid_protrusion{0.6};  ///< share of its diameter outside the body wall
  /// Direction from the body's centre to where the fibroid sits on the wall (any length).
  Eigen::Vector3d fibroid_direction{-0.25, 0.3, 1.0};
  // Ovaries: ellipsoids beside the body, long axis lateral (x).
  Eigen::Vector3d ovary_size{0.017, 0.011, 0.009};  ///< full lengths along x, y, z
  double ovary_offset{0.047};                       ///< |x| of the ovary centres
  double ovary_y{-0.006};      ///< y of the ovary centres (negative: posterior)
  double ovary_height{0.015};  ///< z of the ovary centres above the body centre
  // Cornua, ligaments and tubes (round cross-sections, hemispherical caps).
  double cornu_height{0.025};   ///< z of the tubes' insertion (the cornua) above the body centre
  double ligament_drop{0.010};  ///< how far below the cornu the ovarian ligament leaves the body
  double attachment_depth{0.0025};  ///< ligament axis ends lie this deep in the body and ovary
  double ligament_radius{0.0025};
  double tube_radius{0.0033};
  double tube_length{0.100};     ///< length of the tube's axis
  double tube_insertion{0.004};  ///< depth of the tube's axis start inside the cornu
  double tube_clearance{0.009};  ///< offset of the tube's path around the ovary from its surface
  // Meshing.
  double mesh_size{0.002};  ///< target surface triangle size (smaller on the thin tubes)
  unsigned seed{0};         ///< seed of the mesher's random initial points
};

/// @brief The generated surfaces, one per part (metres), each closed, manifold, outward.
struct UterusMeshes {
  std::vector<std::string> names;  ///< "body", "fibroid", "ovary_left", "ovary_right",
                                   ///< "ligament_left", "ligament_right", "tube_left", "tube_right"
  std::vector<TriangleMesh<double>> meshes;
};

/// @brief Generates the surfaces. Deterministic for a given shape.
UterusMeshes generate_uterus(const UterusShape& shape = UterusShape{});

/// @brief Writes the meshes (OBJ, in cm like the paper's scene) and `uterus.json`, the scene with
/// Table 1's topologies, radii and the paper's materials, into `directory` (created if needed).
/// @return the scene file's path.
std::string write_uterus_scene(const std::string& directory,
                               const UterusShape& shape = UterusShape{});

}  // namespace fsm::build
