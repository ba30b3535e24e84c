#pragma once

/// @file collision/contact.hpp
/// @brief ContactSolver: a spatial hash over the spheres, instrument-sphere and part-part contacts,
/// penalty forces with damping and regularised Coulomb friction, and the wrench on each instrument.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "fsm/collision/shapes.hpp"
#include "fsm/detail/reserved_vector.hpp"
#include "fsm/force_model.hpp"
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

/// @brief Force (N) and torque (N m, about the pose origin) the tissue exerts on an instrument,
/// and how the force changes as the instrument translates.
///
/// `stiffness` and `damping` are the sums of k n n^T and c n n^T over the contacts that push (the
/// penalty's normal stiffness N/m and damping N s/m): moving the instrument by dx at velocity
/// change dv changes the force by about -stiffness dx - damping dv. Whoever integrates the
/// instrument (ServoLoop's proxy) takes them implicitly, so contacts far stiffer than the tissue
/// do not make the instrument unstable.
template <typename Scalar>
struct Wrench {
  Vector3<Scalar> force{Vector3<Scalar>::Zero()};
  Vector3<Scalar> torque{Vector3<Scalar>::Zero()};
  Matrix3<Scalar> stiffness{Matrix3<Scalar>::Zero()};  ///< -d force / d position (N/m)
  Matrix3<Scalar> damping{Matrix3<Scalar>::Zero()};    ///< -d force / d velocity (N s/m)
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
  /// Penalty stiffness as a multiple of the sphere's own tissue stiffness (the Gershgorin row sum
  /// of its links' and elements' rest stiffness, ForceModel::node_stiffness): the contact yields
  /// 1/ratio as much as the tissue around it, so the penetration is a small, fixed share of the
  /// deformation at any resolution, set by non-penetration rather than by the tissue's modulus or
  /// the sphere's size. Implicit Euler takes the contact into its solve (ForceModel), so no
  /// stability cap softens it; an explicit integrator needs a step small enough for it (or a
  /// small ratio).
  Scalar stiffness_ratio{Scalar(100)};
  /// The same for contacts between parts (the softer sphere's). Parts that touch at rest (a
  /// fibroid in the body, the ovaries on their ligaments: about 100 contacts in the bundled
  /// uterus) sit at the contact's threshold all the time; at 100 they made the implicit solve of
  /// the uterus take 600 CG iterations (10 ms) a step. At 1 the part contact is as stiff as the
  /// tissue around it: a guard against parts passing through each other, not a rigid wall.
  Scalar part_stiffness_ratio{Scalar(1)};
  /// The onset of a part contact (PenaltyContact::onset) as a fraction of its threshold distance:
  /// the force ramps in quadratically over the first `part_contact_onset` of the threshold, and
  /// past it is the plain penalty shifted by half the onset. Parts that touch at rest (about 100
  /// pairs in the bundled uterus) sit at the threshold: with the plain penalty (0) each pair
  /// becomes, at the first micrometre of compression, a spring as stiff as all the links of its
  /// sphere together, coupling the two parts; the implicit solve of the uterus then took 2.2x the
  /// CG iterations (docs/benchmarks.md). With the onset a barely touching pair is barely stiff.
  /// An instrument's contact has no onset.
  Scalar part_contact_onset{Scalar(0.1)};
  /// Damping ratio \f$\zeta\f$ of the contact: \f$c = 2\zeta\sqrt{k m}\f$.
  Scalar damping_ratio{Scalar(0.5)};
  /// Regularisation speed (m/s) of Coulomb friction: \f$\mathbf{f}_t = -\mu f_n\mathbf{v}_t /
  /// \sqrt{|\mathbf{v}_t|^2 + \epsilon^2}\f$.
  Scalar friction_speed{Scalar(1e-3)};
  /// Spheres that are vertices of tetrahedra (a tetrahedral filling's boundary vertices lie on
  /// the organ's surface) meet instruments at their centres; other spheres (chains, grids,
  /// packings, which lie inside their surface) at their radius. False: every sphere at its radius
  /// (the paper's filled-sphere contact).
  bool tetrahedral_surface{true};
  /// With tetrahedral_surface: instruments meet a tetrahedral part through its boundary faces
  /// (true) rather than at its vertices only (false: the sphere centres). Each boundary face
  /// carries sample points (the centroids of an m x m split of the face, m set by
  /// `face_sample_spacing`); a sample inside an instrument is a penalty of pressure stiffness
  /// \f$\kappa\f$ (N/m^3, interpolated from its vertices' \f$k_i / A_i\f$, \f$A_i\f$ a third of
  /// the area of the vertex's boundary faces) over its share of the face's area, and its force
  /// goes to the face's three vertices by its barycentric weights. Under a uniform press the
  /// total stiffness is the vertices' own (the same as false); an instrument smaller than the
  /// vertex spacing, or between vertices, still meets the surface, and the force changes
  /// continuously as the instrument slides across faces (docs/physics.md section 8). Each vertex
  /// gets one PenaltyContact per instrument: the sum of its samples' laws. Vertices not on a
  /// boundary face (inside, or exposed by a cut) still meet instruments at their centres.
  /// For smooth instruments (spheres, capsules): against a flat end's rim or a box's edge the
  /// triangles that straddle the edge must clear it, which stiffens the contact and lets vertices
  /// sink under the edge (docs/physics.md section 8); use the vertices there. Each vertex's
  /// contact, and an interior node's, stays in an implicit step's solve once in it
  /// (PenaltyContact::stays_in_solve).
  bool face_contact{false};
  /// Instrument contacts are also detected, at zero force, for spheres within this fraction of
  /// their radius outside the instrument. Such a near contact joins the implicit step's solve in a
  /// later contact pass if the step carries the sphere into the instrument (the passes re-solve
  /// with the contacts that penetrate at the end). Without it a sphere held at the surface by its
  /// penalty (depth ~ 0) and found just outside at the next step's start (the tangent plane of a
  /// curved surface lies outside it) is free for that whole step: under a rounded cylinder's rim at
  /// 1.25 mm spacing such spheres went 0.2-0.3 mm into the tool every other step (docs/
  /// validation.md). 0: only penetrating spheres, as before.
  Scalar detection_margin{Scalar(0.25)};
  /// Largest spacing (m) of a boundary face's sample points: a face whose longest edge is e gets
  /// ceil(e / spacing)^2 samples (at most 64).
  Scalar face_sample_spacing{Scalar(0.001)};
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
  /// rescan only once two regions' largest moves since the list was built add up to more than
  /// the skin (or, for two regions whose boxes of sphere centres were farther apart than their
  /// largest radii plus the skin, more than that gap less those radii); with more than 32 regions,
  /// once some sphere moved more than half the skin. 0 rescans every step.
  Scalar verlet_skin{Scalar(0.002)};
};

/// @brief Contact detection and response for one SphereModel and its instruments.
///
/// Each step: compute(model, forces) reads the model's positions and velocities, finds contacts
/// (spatial hash broad phase, closed-form or GJK narrow phase) and hands them to the ForceModel as
/// penalty contacts (Simulation::forces()), which the step integrates (implicitly with implicit
/// Euler: the contact's stiffness is in the solve); after the step, collect(forces) reads their
/// end-of-step forces into contacts() and each instrument's wrench (minus the sum of what it
/// applies). compute(model, array) instead adds the forces at the current state to an array
/// (analysis, or explicit use). Nothing allocates or throws; a model of another size than the
/// solver was sized for is reported by the return value, as TriangleBvh::refit() and
/// Integrator::step() report theirs.
///
/// Instrument-sphere contact: penalty \f$f_n = \max(0, k\delta + c\dot\delta)\f$ along the contact
/// normal (never pulling), plus regularised Coulomb friction on the tangential slip, with \f$k\f$
/// from ContactOptions::stiffness_ratio. Sphere-sphere contact between parts: the same penalty
/// where the spheres are closer than \f$\min(r_i + r_j, |\bar{\mathbf{x}}_i -
/// \bar{\mathbf{x}}_j|)\f$ (their rest distance when they overlap at rest, so touching parts are at
/// rest in contact), excluding linked pairs, with the softer sphere's stiffness.
template <typename Scalar>
class ContactSolver {
 public:
  ContactSolver() = default;
  /// @brief Sizes the hash and contact list for `model` (allocates). fsm::Error for bad options.
  explicit ContactSolver(const SphereModel<Scalar>& model,
                         const ContactOptions<Scalar>& options = {});
  /// @brief The same, and makes room in `forces` for max_contacts contacts (allocates once, so
  /// that compute() never does).
  ContactSolver(const SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                const ContactOptions<Scalar>& options = {})
      : ContactSolver(model, options) {
    forces.reserve_contacts(m_options.max_contacts);
  }
  /// @brief Re-reads the model (after adding nodes, links or regions, or changing radii, rest
  /// positions or the spheres' regions: the part-contact list keeps each pair's threshold).
  void refresh(const SphereModel<Scalar>& model);

  /// @brief Adds an instrument (fsm::Error for a bad shape); returns its index.
  Index add_instrument(const Instrument<Scalar>& instrument);
  [[nodiscard]] Instrument<Scalar>& instrument(Index i) { return m_instruments.at(std::size_t(i)); }
  [[nodiscard]] const Instrument<Scalar>& instrument(Index i) const {
    return m_instruments.at(std::size_t(i));
  }
  [[nodiscard]] Index num_instruments() const noexcept { return Index(m_instruments.size()); }
  [[nodiscard]] const ContactOptions<Scalar>& options() const noexcept { return m_options; }

  /// @brief Finds contacts at the model's state and gives them to `forces` (replacing its
  /// contacts) for the next step to integrate; contacts() and wrench() hold the forces at the
  /// current state until collect().
  /// @return false, with no contact, when the model does not have the num_nodes() spheres the
  /// solver was sized for (call refresh() after growing the model).
  bool compute(const SphereModel<Scalar>& model, ForceModel<Scalar>& forces) noexcept;
  /// @brief After a step: the contacts' forces at the end of the step (ForceModel::
  /// finish_contacts) into contacts() and the wrenches. Returns false when `forces` does not hold
  /// this solver's contacts.
  bool collect(const ForceModel<Scalar>& forces) noexcept;
  /// @brief Finds contacts at the model's state and adds their forces at that state to `forces`
  /// (`|V| x 3`, N): the same contacts and laws, applied explicitly.
  /// @return false, with nothing found and `forces` untouched, when the model or `forces` does not
  /// have the num_nodes() rows the solver was sized for.
  bool compute(const SphereModel<Scalar>& model, Eigen::Ref<Positions<Scalar>> forces) noexcept;

  /// @brief Moves every sphere that penetrates an instrument out of it along the contact normal
  /// (position projection; call after a step). Returns how many spheres moved, or -1 (nothing
  /// moved) when the model does not have num_nodes() spheres.
  Index project(SphereModel<Scalar>& model) noexcept;

  /// @brief Sphere i's penalty stiffness against instruments (N/m): stiffness_ratio times its
  /// tissue stiffness (ForceModel::node_stiffness).
  [[nodiscard]] Scalar contact_stiffness(Index i) const { return m_k.at(std::size_t(i)); }
  /// @brief The radius sphere i meets instruments with (m): 0 for a vertex of a tetrahedron when
  /// ContactOptions::tetrahedral_surface, else its radius.
  [[nodiscard]] Scalar contact_radius(Index i) const { return m_contact_radius.at(std::size_t(i)); }
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

  /// @brief Work counters of the last compute(): candidates (spheres an instrument's box reached,
  /// part-contact pairs in the list) and narrow-phase tests (spheres tested against an
  /// instrument's shape, pairs closer than their contact threshold).
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
  bool region_pairs(Index a, Index b) const noexcept;
  void set_region_thresholds(const SphereModel<Scalar>& model) noexcept;
  bool list_holds(const SphereModel<Scalar>& model) noexcept;
  template <typename Visit>
  void for_each_part_pair(const SphereModel<Scalar>& model, Scalar reach_extra,
                          Visit&& visit) const;
  // A candidate pair for part contact and the distance its spheres touch closer than.
  struct PartPair {
    Index i, j;
    Scalar threshold;
  };
  Scalar pair_threshold(const SphereModel<Scalar>& model, Index i, Index j) const noexcept;
  // The contact of a pair whose spheres (x_j - x_i = d, |d|^2 = dist2) are closer than its
  // threshold.
  template <typename Emit>
  void part_contact(const SphereModel<Scalar>& model, const PartPair& pair,
                    const Vector3<Scalar>& d, Scalar dist2, Emit&& emit) noexcept;
  // Finds every contact at the model's state and calls emit(PenaltyContact) for each (its
  // `force` the force at that state); records and wrenches follow the emitted forces.
  template <typename Emit>
  void detect(const SphereModel<Scalar>& model, Emit&& emit) noexcept;
  void record_and_add(const PenaltyContact<Scalar>& c) noexcept;
  void build_faces(const SphereModel<Scalar>& model);
  // One instrument against the boundary faces of the nodes visited: accumulates per node.
  void sample_face(const SphereModel<Scalar>& model, const Instrument<Scalar>& ins, Index f,
                   const Vector3<Scalar>& lo, const Vector3<Scalar>& hi) noexcept;

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
  // Per node: contact stiffness (N/m) and the radius it meets instruments with (m); the most
  // populous region (not scanned for part contact).
  std::vector<Scalar> m_k, m_contact_radius;
  // Face contact (ContactOptions::face_contact): the tetrahedral parts' boundary faces at
  // refresh() (vertices, owning tetrahedron, samples per side), each node's faces (CSR), whether
  // a node meets instruments through its faces, its pressure stiffness (N/m^3), the longest
  // boundary edge; per-compute scratch: a stamp per face, per-node accumulators, touched nodes.
  std::vector<std::array<Index, 3>> m_faces;
  std::vector<Index> m_face_tet;
  std::vector<std::uint8_t> m_face_div;
  std::vector<Index> m_node_face_start, m_node_faces;
  std::vector<std::uint8_t> m_on_faces;
  std::vector<Scalar> m_kappa;
  Scalar m_max_face_edge{0};
  std::vector<std::uint32_t> m_face_stamp;
  std::uint32_t m_stamp{0};
  std::vector<Scalar> m_face_acc;  // 11 per node: k, F (3), k delta, k delta p (3), k delta v_s (3)
  fsm::detail::ReservedVector<Index> m_touched;  // (capacity n; a copy keeps it)
  Index m_dominant_region{-1};
  Scalar m_max_radius{0};
  std::vector<Contact<Scalar>> m_contacts;
  Index m_num_contacts{0};
  bool m_overflow{false};
  Index m_candidates{0}, m_narrow_tests{0};
  // Verlet list of part-contact candidate pairs and the positions it was built at.
  // (a copy keeps the reserved capacity: a list that does not fit is rescanned every step)
  fsm::detail::ReservedVector<PartPair> m_pairs;
  Positions<Scalar> m_list_x;
  bool m_list_valid{false};
  Index m_rebuilds{0};
  // Per region, for models with at most k_max_list_regions of them (list_holds): the largest
  // move since the list's build, the box of its centres and its largest radius at the build, and
  // per pair of regions the moves allowed before a rebuild (R x R).
  static constexpr Index k_max_list_regions = 32;
  std::vector<Scalar> m_region_move, m_region_threshold, m_region_radius;
  std::vector<Vector3<Scalar>> m_region_box;
  const ForceModel<Scalar>* m_filled{nullptr};  // the force model compute() last filled
};

extern template class ContactSolver<float>;
extern template class ContactSolver<double>;

}  // namespace fsm::collision

#include "fsm/collision/impl/contact-inl.hpp"
