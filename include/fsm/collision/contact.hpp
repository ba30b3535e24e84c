#pragma once

/// @file collision/contact.hpp
/// @brief ContactSolver: a spatial hash over the spheres, instrument-sphere and part-part contacts,
/// penalty forces with damping and regularised Coulomb friction, and the wrench on each instrument.

#include <string>
#include <vector>

#include "fsm/collision/shapes.hpp"
#include "fsm/sphere_model.hpp"

namespace fsm::collision {

/// @brief A rigid instrument posed by a device.
template <typename Scalar>
struct Instrument {
  std::string name;
  Shape<Scalar> shape{SphereShape<Scalar>{Scalar(0.002)}};
  Pose<Scalar> pose;
  Vector3<Scalar> linear_velocity{Vector3<Scalar>::Zero()};   ///< of the pose origin (m/s)
  Vector3<Scalar> angular_velocity{Vector3<Scalar>::Zero()};  ///< world frame (rad/s)
  Scalar friction{Scalar(0.2)};  ///< Coulomb coefficient against tissue (dimensionless)
  bool enabled{true};
};

/// @brief Force (N) and torque (N m, about the pose origin) the tissue exerts on an instrument.
template <typename Scalar>
struct Wrench {
  Vector3<Scalar> force{Vector3<Scalar>::Zero()};
  Vector3<Scalar> torque{Vector3<Scalar>::Zero()};
};

/// @brief One contact found by ContactSolver::compute().
template <typename Scalar>
struct Contact {
  Index sphere{-1};      ///< The sphere pushed.
  Index instrument{-1};  ///< The instrument, or -1 for a sphere-sphere contact.
  Index other{-1};       ///< The other sphere of a sphere-sphere contact, or -1.
  Vector3<Scalar> normal{Vector3<Scalar>::Zero()};  ///< Unit, the direction `sphere` is pushed.
  Scalar depth{0};                                  ///< Penetration (m).
  Vector3<Scalar> point{Vector3<Scalar>::Zero()};   ///< Contact point (m).
  Vector3<Scalar> force{Vector3<Scalar>::Zero()};   ///< Force on `sphere` (N); `other` gets -force.
};

/// @brief How contacts respond.
template <typename Scalar>
struct ContactOptions {
  /// Penalty stiffness \f$k = s E r\f$ (N/m) from the sphere's region modulus E and radius r (a
  /// linearised Hertz contact of a ball of radius r); this is s.
  Scalar stiffness_scale{Scalar(2)};
  /// Damping ratio \f$\zeta\f$ of the contact: \f$c = 2\zeta\sqrt{k m}\f$.
  Scalar damping_ratio{Scalar(0.5)};
  /// Regularisation speed (m/s) of Coulomb friction: \f$\mathbf{f}_t = -\mu f_n\mathbf{v}_t /
  /// \sqrt{|\mathbf{v}_t|^2 + \epsilon^2}\f$.
  Scalar friction_speed{Scalar(1e-3)};
  /// Contacts between spheres of different parts (regions).
  bool part_contact{true};
  /// Contacts between spheres of one part that are far apart at rest (more than twice their radii
  /// sum) and come together (folding).
  bool self_contact{false};
  /// Coulomb coefficient between parts.
  Scalar part_friction{Scalar(0)};
  /// Most contacts kept per compute() (capacity, allocated once).
  Index max_contacts{4096};
  /// Use the spatial hash (true) or test every sphere (false: the reference the tests compare
  /// with).
  bool spatial_hash{true};
  /// Part contacts keep a Verlet list of candidate pairs within reach plus this skin (m) and
  /// rescan only after some sphere moved more than half of it; 0 rescans every step.
  Scalar verlet_skin{Scalar(0.002)};
  /// The step (s) the contact forces will be applied over. Contact forces enter a step as
  /// external forces, explicitly, so a stiff contact on a light sphere (or a sphere pressed by many
  /// neighbours at once) would be unstable. Each sphere's contact stiffness is therefore capped:
  /// an instrument's at \f$\tfrac12(m_i/h^2 + \sum_l k_l)\f$ over the sphere's links (an
  /// implicit step's matrix \f$M + h^2K\f$ holds the links of a locally pressed sphere), and part
  /// contacts share \f$\tfrac12 m_i/h^2\f$ among the sphere's candidate pairs (a part pressed as
  /// a whole is not held by its links). This keeps \f$\omega h \le 1\f$ for the explicit part;
  /// an explicit integrator needs its own step to allow for the contact stiffness as well. 0
  /// removes the cap.
  Scalar time_step{Scalar(1e-3)};
};

/// @brief Contact detection and response for one SphereModel and its instruments.
///
/// compute() reads the model's positions and velocities, finds contacts (spatial hash broad
/// phase, closed-form or GJK narrow phase), and adds the contact forces to an external-force array
/// (pass Simulation::external_forces() after setting your own loads); each instrument's wrench is
/// minus the sum of what it applies. It allocates nothing and never throws; a model of another
/// size than the solver was sized for is reported by its return value, as TriangleBvh::refit()
/// and Integrator::step() report theirs.
///
/// Instrument-sphere contact: penalty \f$f_n = \max(0, k\delta + c\dot\delta)\f$ along the contact
/// normal (never pulling), plus regularised Coulomb friction on the tangential slip. Sphere-sphere
/// contact between parts: the same penalty where the spheres are closer than \f$\min(r_i + r_j,
/// |\bar{\mathbf{x}}_i - \bar{\mathbf{x}}_j|)\f$ (their rest distance when they overlap at rest,
/// so touching parts are at rest in contact), excluding linked pairs.
template <typename Scalar>
class ContactSolver {
 public:
  ContactSolver() = default;
  /// @brief Sizes the hash and contact list for `model` (allocates). fsm::Error for bad options.
  explicit ContactSolver(const SphereModel<Scalar>& model,
                         const ContactOptions<Scalar>& options = {});
  /// @brief Re-reads the model (after adding nodes or links, or changing radii).
  void refresh(const SphereModel<Scalar>& model);

  /// @brief Adds an instrument (fsm::Error for a bad shape); returns its index.
  Index add_instrument(const Instrument<Scalar>& instrument);
  [[nodiscard]] Instrument<Scalar>& instrument(Index i) { return m_instruments.at(std::size_t(i)); }
  [[nodiscard]] const Instrument<Scalar>& instrument(Index i) const {
    return m_instruments.at(std::size_t(i));
  }
  [[nodiscard]] Index num_instruments() const noexcept { return Index(m_instruments.size()); }
  [[nodiscard]] const ContactOptions<Scalar>& options() const noexcept { return m_options; }

  /// @brief Finds contacts at the model's state and adds their forces to `forces` (`|V| x 3`, N).
  /// @return false, with nothing found and `forces` untouched, when the model or `forces` does not
  /// have the num_nodes() rows the solver was sized for (call refresh() after growing the model).
  bool compute(const SphereModel<Scalar>& model, Eigen::Ref<Positions<Scalar>> forces) noexcept;

  /// @brief Moves every sphere that penetrates an instrument out of it along the contact normal
  /// (position projection; call after a step). Returns how many spheres moved, or -1 (nothing
  /// moved) when the model does not have num_nodes() spheres.
  Index project(SphereModel<Scalar>& model) noexcept;

  /// @brief The sphere count the solver was sized for (by the constructor or refresh()).
  [[nodiscard]] Index num_nodes() const noexcept { return Index(m_next.size()); }

  /// @brief The contacts of the last compute() (at most options().max_contacts).
  [[nodiscard]] const Contact<Scalar>* contacts() const noexcept { return m_contacts.data(); }
  [[nodiscard]] Index num_contacts() const noexcept { return m_num_contacts; }
  /// @brief True when the last compute() found more contacts than max_contacts (forces of the
  /// extra ones were still applied; only the list is short).
  [[nodiscard]] bool overflowed() const noexcept { return m_overflow; }
  /// @brief The wrench on instrument i from the last compute().
  [[nodiscard]] const Wrench<Scalar>& wrench(Index i) const {
    return m_wrenches.at(std::size_t(i));
  }

  /// @brief Work counters of the last compute(): candidate pairs from the hash, narrow-phase tests.
  [[nodiscard]] Index candidates() const noexcept { return m_candidates; }
  [[nodiscard]] Index narrow_tests() const noexcept { return m_narrow_tests; }
  /// @brief How many times the part-contact pair list was rebuilt since construction.
  [[nodiscard]] Index pair_list_rebuilds() const noexcept { return m_rebuilds; }

 private:
  void update_hash(const SphereModel<Scalar>& model) noexcept;
  std::uint32_t slot(const Eigen::Vector3i& cell) const noexcept;
  template <typename Visit>
  void for_each_in_box(const Vector3<Scalar>& lo, const Vector3<Scalar>& hi, Visit&& visit) const;
  bool linked(Index i, Index j) const noexcept;
  void record(const Contact<Scalar>& c) noexcept;
  template <typename Visit>
  void for_each_part_pair(const SphereModel<Scalar>& model, Scalar reach_extra,
                          Visit&& visit) const;
  void part_contact(const SphereModel<Scalar>& model, Index i, Index j,
                    Eigen::Ref<Positions<Scalar>> forces) noexcept;

  ContactOptions<Scalar> m_options;
  std::vector<Instrument<Scalar>> m_instruments;
  std::vector<Wrench<Scalar>> m_wrenches;
  // Spatial hash: cells of edge m_cell; doubly linked lists per slot.
  Scalar m_cell{0};
  std::uint32_t m_mask{0};
  std::vector<Index> m_head, m_next, m_prev;
  std::vector<Eigen::Vector3i> m_cell_of;
  std::vector<std::uint32_t> m_slot_of;
  bool m_hashed{false};
  // Link adjacency (CSR) to skip linked pairs.
  std::vector<Index> m_adj_start, m_adj;
  // Per node: contact stiffness k = s E r (N/m); the most populous region (not scanned for part
  // contact).
  std::vector<Scalar> m_k;
  // Per node: the stability budget m / h^2 (N/m), and its candidate part contacts.
  std::vector<Scalar> m_budget, m_tool_budget;
  std::vector<Index> m_pair_count;
  Index m_dominant_region{-1};
  Scalar m_max_radius{0};
  std::vector<Contact<Scalar>> m_contacts;
  Index m_num_contacts{0};
  bool m_overflow{false};
  Index m_candidates{0}, m_narrow_tests{0};
  // Verlet list of part-contact candidate pairs and the positions it was built at.
  std::vector<std::pair<Index, Index>> m_pairs;
  Positions<Scalar> m_list_x;
  bool m_list_valid{false};
  Index m_rebuilds{0};
};

extern template class ContactSolver<float>;
extern template class ContactSolver<double>;

}  // namespace fsm::collision

#include "fsm/collision/impl/contact-inl.hpp"
