#pragma once

/// @file sphere_model.hpp
/// @brief SphereModel: the filled-sphere model as plain structure-of-arrays data.

#include <string>
#include <vector>

#include "fsm/error.hpp"
#include "fsm/material.hpp"
#include "fsm/types.hpp"
#include "fsm/voigt_link.hpp"

namespace fsm {

/// @brief How a region's spheres resist deformation (docs/physics.md sections 1 and 11).
enum class ForceLaw : std::uint8_t {
  /// The paper's Voigt links between spheres (Van Gelder's rule on tetrahedral parts, rods on
  /// chains). Cheapest; Poisson's ratio 1/4 whatever the material says.
  links = 0,
  /// Neo-Hookean elasticity on the region's tetrahedra (deviatoric per element, volumetric on
  /// nodal-averaged J), with Poisson's ratio and Voigt viscosity from the material. The region's
  /// links stay in the model (contacts, skinning) but carry no force.
  continuum = 1,
};

/// @brief Name of a ForceLaw ("links", "continuum").
[[nodiscard]] inline const char* to_string(ForceLaw law) noexcept {
  return law == ForceLaw::continuum ? "continuum" : "links";
}

/// @brief A named part of a model with its own material (the uterine body, an ovary, ...).
template <typename Scalar>
struct Region {
  std::string name;               ///< Unique, non-empty.
  Material<Scalar> material;      ///< Its Voigt material.
  ForceLaw law{ForceLaw::links};  ///< How its spheres resist deformation.
};

/// @brief Spheres (nodes) joined by Voigt links, grouped into regions; some nodes fixed.
///
/// Plain data in structure-of-arrays form, so a renderer can upload positions as they are and
/// numpy can view them without copying:
/// - per node: position, velocity, rest position (`|V| x 3`, row-major, m and m/s), mass (kg),
///   radius (m), region index, fixed flag;
/// - per link: node pair (`|L| x 2`), rest length (m), \f$k_s\f$ (N/m), \f$k_d\f$ (N s/m),
///   large-strain stiffness (N/m) and switch strain (see VoigtLink);
/// - per region: name and Material.
///
/// **Mass rule.** A node's mass is stored explicitly. The builders set it from the region's
/// density: add_tetrahedral_part() lumps \f$\rho\sum_{T\ni i} V_T/4\f$ onto each vertex (total
/// mass exact on any mesh); distribute_region_mass() gives every node of a region the same share
/// \f$\rho V/N\f$ (the paper's homogeneous-region rule, docs/physics.md section 10.1).
///
/// - per tetrahedron (`|T| x 4` node indices): the elements of tetrahedral fillings, positively
///   oriented at rest, each within one region; the continuum law acts on them.
///
/// Every add_* call checks its input and throws fsm::Error naming the element and the reason.
/// The arrays are also writable in place; validate() re-checks everything, and Simulation calls
/// it at construction, so bad values are caught before any step.
template <typename Scalar>
class SphereModel {
 public:
  using PositionsMap = Eigen::Map<Positions<Scalar>>;
  using ConstPositionsMap = Eigen::Map<const Positions<Scalar>>;
  using ScalarMap = Eigen::Map<ScalarArray<Scalar>>;
  using ConstScalarMap = Eigen::Map<const ScalarArray<Scalar>>;
  using IndexMap = Eigen::Map<Eigen::Matrix<Index, Eigen::Dynamic, 1>>;
  using ConstIndexMap = Eigen::Map<const Eigen::Matrix<Index, Eigen::Dynamic, 1>>;
  using FlagMap = Eigen::Map<Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1>>;
  using ConstFlagMap = Eigen::Map<const Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1>>;
  using LinkMap = Eigen::Map<LinkArray>;
  using ConstLinkMap = Eigen::Map<const LinkArray>;

  /// @brief Adds a region. @return its index. Throws if the name is empty or taken or the
  /// material is invalid.
  Index add_region(std::string name, const Material<Scalar>& material,
                   ForceLaw law = ForceLaw::links);
  /// @brief Sets a region's force law (a region with the continuum law needs tetrahedra: checked
  /// by validate(), so by Simulation). Throws for a region index out of range.
  void set_region_law(Index region, ForceLaw law);
  /// @brief Replaces a region's material (checked as add_region checks it). The links keep the
  /// constants they were given: rebuild them (tetrahedral_link) to follow a new modulus.
  void set_region_material(Index region, const Material<Scalar>& material);

  /// @brief Adds a node at rest (position = rest position, velocity 0).
  /// @param rest_position (m); @param radius (m), > 0; @param mass (kg), > 0;
  /// @param region an existing region index. @return the node's index.
  Index add_node(const Vector3<Scalar>& rest_position, Scalar radius, Scalar mass, Index region);

  /// @brief Adds a link between two distinct existing nodes. @return the link's index.
  Index add_link(Index i, Index j, const VoigtLink<Scalar>& law);

  /// @brief Adds a linear link whose rest length is the nodes' rest distance.
  /// @param stiffness \f$k_s\f$ (N/m); @param damping \f$k_d\f$ (N s/m).
  Index add_link(Index i, Index j, Scalar stiffness, Scalar damping);

  /// @brief Adds a tetrahedron of four distinct existing nodes of one region, positively oriented
  /// at rest (\f$(x_b - x_a)\cdot((x_c - x_a)\times(x_d - x_a)) > 0\f$, not degenerate).
  /// @return its index.
  Index add_tetrahedron(Index a, Index b, Index c, Index d);

  /// @brief Marks a node fixed (it never moves) or free. A fixed node's velocity is set to 0.
  void set_fixed(Index node, bool fixed = true);

  /// @brief Reserves storage for a number of nodes and links.
  void reserve(Index nodes, Index links);

  [[nodiscard]] Index num_nodes() const noexcept { return static_cast<Index>(m_mass.size()); }
  [[nodiscard]] Index num_links() const noexcept {
    return static_cast<Index>(m_rest_length.size());
  }
  [[nodiscard]] Index num_regions() const noexcept { return static_cast<Index>(m_regions.size()); }
  [[nodiscard]] Index num_tetrahedra() const noexcept {
    return static_cast<Index>(m_tetrahedron.size() / 4);
  }
  [[nodiscard]] Index num_fixed() const noexcept;

  /// @name Node arrays (|V| rows)
  /// @{
  PositionsMap positions() noexcept { return {m_position.data(), num_nodes(), 3}; }
  ConstPositionsMap positions() const noexcept { return {m_position.data(), num_nodes(), 3}; }
  PositionsMap velocities() noexcept { return {m_velocity.data(), num_nodes(), 3}; }
  ConstPositionsMap velocities() const noexcept { return {m_velocity.data(), num_nodes(), 3}; }
  PositionsMap rest_positions() noexcept { return {m_rest_position.data(), num_nodes(), 3}; }
  ConstPositionsMap rest_positions() const noexcept {
    return {m_rest_position.data(), num_nodes(), 3};
  }
  ScalarMap masses() noexcept { return {m_mass.data(), num_nodes()}; }
  ConstScalarMap masses() const noexcept { return {m_mass.data(), num_nodes()}; }
  ScalarMap radii() noexcept { return {m_radius.data(), num_nodes()}; }
  ConstScalarMap radii() const noexcept { return {m_radius.data(), num_nodes()}; }
  IndexMap node_regions() noexcept { return {m_node_region.data(), num_nodes()}; }
  ConstIndexMap node_regions() const noexcept { return {m_node_region.data(), num_nodes()}; }
  /// 1 for a fixed node, 0 for a free one.
  FlagMap fixed() noexcept { return {m_fixed.data(), num_nodes()}; }
  ConstFlagMap fixed() const noexcept { return {m_fixed.data(), num_nodes()}; }
  /// @}

  /// @name Link arrays (|L| rows)
  /// @{
  LinkMap links() noexcept { return {m_link.data(), num_links(), 2}; }
  ConstLinkMap links() const noexcept { return {m_link.data(), num_links(), 2}; }
  ScalarMap rest_lengths() noexcept { return {m_rest_length.data(), num_links()}; }
  ConstScalarMap rest_lengths() const noexcept { return {m_rest_length.data(), num_links()}; }
  ScalarMap stiffness() noexcept { return {m_stiffness.data(), num_links()}; }
  ConstScalarMap stiffness() const noexcept { return {m_stiffness.data(), num_links()}; }
  ScalarMap damping() noexcept { return {m_damping.data(), num_links()}; }
  ConstScalarMap damping() const noexcept { return {m_damping.data(), num_links()}; }
  ScalarMap large_stiffness() noexcept { return {m_large_stiffness.data(), num_links()}; }
  ConstScalarMap large_stiffness() const noexcept {
    return {m_large_stiffness.data(), num_links()};
  }
  ScalarMap switch_strain() noexcept { return {m_switch_strain.data(), num_links()}; }
  ConstScalarMap switch_strain() const noexcept { return {m_switch_strain.data(), num_links()}; }
  /// The link's own tear strain (l - l0) / l0: it breaks past the smallest of this and its two
  /// nodes' regions' Material::tear_strain (an attachment can be weaker than both parts).
  /// > 0; infinity (the default) = only the materials decide. Simulation::refresh() reads it.
  ScalarMap tear_strain() noexcept { return {m_tear_strain.data(), num_links()}; }
  ConstScalarMap tear_strain() const noexcept { return {m_tear_strain.data(), num_links()}; }
  /// 1 for a link that holds, 0 for one a cut or a tear has broken (docs/physics.md section 12).
  /// A broken link carries no force and is kept (indices stay valid); after editing this in place
  /// call Simulation::refresh() or ForceModel::update_topology().
  FlagMap link_intact() noexcept { return {m_link_intact.data(), num_links()}; }
  ConstFlagMap link_intact() const noexcept { return {m_link_intact.data(), num_links()}; }
  /// @}

  /// @name Tetrahedra (|T| x 4 node indices)
  /// @{
  using TetrahedronMap = Eigen::Map<TetrahedronArray>;
  using ConstTetrahedronMap = Eigen::Map<const TetrahedronArray>;
  ConstTetrahedronMap tetrahedra() const noexcept {
    return {m_tetrahedron.data(), num_tetrahedra(), 4};
  }
  /// 1 for a tetrahedron that holds, 0 for one a cut or a tear has removed (it carries no force;
  /// its nodes keep their mass).
  FlagMap tetrahedron_intact() noexcept { return {m_tetrahedron_intact.data(), num_tetrahedra()}; }
  ConstFlagMap tetrahedron_intact() const noexcept {
    return {m_tetrahedron_intact.data(), num_tetrahedra()};
  }
  /// @brief Links and tetrahedra broken so far (cut or torn).
  [[nodiscard]] Index num_broken_links() const noexcept;
  [[nodiscard]] Index num_removed_tetrahedra() const noexcept;
  /// @brief Makes every link and tetrahedron whole again (refresh the simulation after).
  void restore_topology() noexcept;
  /// @brief True if any region uses the continuum law.
  [[nodiscard]] bool has_continuum() const noexcept;
  /// @}

  /// @brief Link l's force law gathered from the link arrays.
  [[nodiscard]] VoigtLink<Scalar> link(Index l) const;
  /// @brief Overwrites link l's force law (checked like add_link).
  void set_link(Index l, const VoigtLink<Scalar>& law);
  /// @brief True if any link has a finite switch strain.
  [[nodiscard]] bool has_bilinear_links() const noexcept;

  [[nodiscard]] const Region<Scalar>& region(Index r) const { return m_regions.at(r); }
  [[nodiscard]] const std::vector<Region<Scalar>>& regions() const noexcept { return m_regions; }
  /// @brief Index of the region with this name; throws fsm::Error listing the names if absent.
  [[nodiscard]] Index region_index(const std::string& name) const;

  /// @brief Puts every node back at its rest position with zero velocity.
  void reset_to_rest() noexcept;

  /// @brief Total mass (kg).
  [[nodiscard]] Scalar total_mass() const noexcept;

  /// @brief Gives every node of a region the mass \f$\rho V / N\f$ (the paper's rule).
  /// @param volume the region's volume (m^3), > 0.
  void distribute_region_mass(Index region, Scalar volume);

  /// @brief Checks every node, link and region; throws fsm::Error naming the first bad element
  /// ("node 12 (region 'body')", "link 40 (nodes 3-9)") and the reason.
  void validate() const;

  /// @brief The same model in another scalar type (e.g. double to float).
  template <typename Other>
  [[nodiscard]] SphereModel<Other> cast() const;

 private:
  template <typename>
  friend class SphereModel;

  [[nodiscard]] std::string describe_node(Index i) const;
  [[nodiscard]] std::string describe_link(Index l) const;
  void check_node(Index i) const;
  void check_link(Index l) const;
  void check_tetrahedron(Index t) const;

  std::vector<Region<Scalar>> m_regions;
  std::vector<Scalar> m_position, m_velocity, m_rest_position;  // 3 per node
  std::vector<Scalar> m_mass, m_radius;
  std::vector<Index> m_node_region;
  std::vector<std::uint8_t> m_fixed;
  std::vector<Index> m_link;  // 2 per link
  std::vector<Scalar> m_rest_length, m_stiffness, m_damping, m_large_stiffness, m_switch_strain;
  std::vector<Scalar> m_tear_strain;
  std::vector<Index> m_tetrahedron;  // 4 per tetrahedron
  std::vector<std::uint8_t> m_link_intact, m_tetrahedron_intact;
};

extern template class SphereModel<float>;
extern template class SphereModel<double>;

}  // namespace fsm

#include "fsm/impl/sphere_model-inl.hpp"
