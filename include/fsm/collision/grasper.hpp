#pragma once

/// @file grasper.hpp
/// @brief A grasper: two jaws on a pose that hold the spheres they close on (docs/physics.md
/// section 12).

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "fsm/collision/contact.hpp"
#include "fsm/collision/shapes.hpp"
#include "fsm/detail/reserved_vector.hpp"
#include "fsm/error.hpp"
#include "fsm/force_model.hpp"
#include "fsm/sphere_model.hpp"

namespace fsm::collision {

/// @brief A grasper's geometry and grip.
///
/// In the grasper's frame (its Pose) the jaws hinge at the origin and reach along +x; they open
/// symmetrically in the x-z plane, each at half the opening angle from the x axis, and are
/// `jaw_width` wide along y.
template <typename Scalar>
struct GrasperOptions {
  Scalar jaw_length{Scalar(0.012)};  ///< m, > 0
  Scalar jaw_width{Scalar(0.004)};   ///< m, > 0
  /// Closing past this opening angle (rad) grips what lies between the jaws.
  Scalar grip_angle{Scalar(0.1)};
  /// Opening past this angle (rad, > grip_angle) releases (the gap is the hysteresis).
  Scalar release_angle{Scalar(0.2)};
  /// k of each held sphere's tie to its jaw (N/m). A held sphere lags its jaw by its load over k:
  /// with the default, a 0.1 N share lags 0.01 mm. It is in the implicit solve, so it costs no
  /// stability; about ten times a tissue node's own stiffness at 5 mm spacing.
  Scalar stiffness{Scalar(10000)};
  Scalar damping{Scalar(0.5)};  ///< c of each tie (N s/m), >= 0
  /// A sphere is gripped when its centre lies within this distance (m) of the space between the
  /// jaws (the jaws close on its surface, so about the spheres' spacing or less: a larger margin
  /// picks up the neighbouring tissue too).
  Scalar margin{Scalar(0.001)};
  Index max_held{64};  ///< At most this many spheres held (the nearest the jaws' plane).

  /// @brief fsm::Error ("grasper", reason) for a value out of range.
  void validate() const {
    auto bad = [](const std::string& why) { throw Error("", "grasper", why); };
    if (!(jaw_length > 0 && std::isfinite(jaw_length))) bad("jaw_length must be positive");
    if (!(jaw_width > 0 && std::isfinite(jaw_width))) bad("jaw_width must be positive");
    if (!(grip_angle > 0 && grip_angle < Scalar(3.1))) bad("grip_angle must be in (0, 3.1) rad");
    if (!(release_angle > grip_angle && release_angle < Scalar(3.1)))
      bad("release_angle must be above grip_angle and below 3.1 rad");
    if (!(stiffness > 0 && std::isfinite(stiffness))) bad("stiffness must be positive");
    if (!(damping >= 0 && std::isfinite(damping))) bad("damping must be non-negative");
    if (max_held < 1) bad("max_held must be at least 1");
    if (!(margin >= 0 && std::isfinite(margin))) bad("margin must be non-negative");
  }
};

/// @brief What a Grasper::update() did.
struct GraspEvent {
  Index grasped{0};     ///< Spheres gripped by this update (the jaws closed past grip_angle).
  Index released{0};    ///< Spheres let go by this update (the jaws opened past release_angle).
  bool invalid{false};  ///< The pose, velocities or angle were not finite: nothing changed.
};

/// @brief A grasper instrument: closing its jaws on tissue ties the spheres between them to the
/// jaws (stiff spring-dampers in the implicit solve, ForceModel::add_held()); opening releases
/// them; the ties' reaction is the instrument's wrench.
///
/// Each tick, before the step: update() with the jaws' pose, velocities and opening angle (the
/// device's button or a script). After the step: wrench(). update() and wrench() allocate nothing
/// and never throw. The grasper owns the force model's held list (update() rewrites it).
template <typename Scalar>
class Grasper {
 public:
  /// @param opening the opening angle at start (rad): fsm::Error if the jaws are closed (at or
  /// below grip_angle), since what they would hold is undefined; `id` tags the held nodes.
  /// Makes room for max_held nodes in `forces` (ForceModel::reserve_held()).
  Grasper(const SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
          const GrasperOptions<Scalar>& options, Scalar opening, Index id = 0)
      : m_options(options), m_id(id), m_opening(opening), m_widest(opening) {
    options.validate();
    forces.reserve_held(options.max_held);
    if (!(std::isfinite(opening) && opening > options.grip_angle))
      throw Error("", "grasper",
                  "its jaws are closed at start (opening " + std::to_string(opening) +
                      " rad, grip_angle " + std::to_string(options.grip_angle) + " rad)");
    m_candidates.reserve(std::size_t(model.num_nodes()));
    m_held.reserve(std::size_t(options.max_held));
    m_offsets.reserve(std::size_t(options.max_held));
  }

  /// @brief Moves the jaws and opens or closes them; grips or releases; writes the held nodes
  /// into `forces` (its held list is cleared first). `velocity` and `angular_velocity` (rad/s,
  /// world) move the jaws through the coming step.
  GraspEvent update(const SphereModel<Scalar>& model, ForceModel<Scalar>& forces,
                    const Pose<Scalar>& pose, const Vector3<Scalar>& velocity,
                    const Vector3<Scalar>& angular_velocity, Scalar opening) noexcept {
    GraspEvent event;
    if (!pose.position.allFinite() || !pose.orientation.coeffs().allFinite() ||
        !velocity.allFinite() || !angular_velocity.allFinite() || !std::isfinite(opening)) {
      event.invalid = true;
      return event;
    }
    m_pose = pose;
    if (!m_held.empty() && opening > m_options.release_angle) {
      event.released = Index(m_held.size());
      m_held.clear();
      m_offsets.clear();
      m_widest = opening;
    } else if (m_held.empty()) {
      if (opening <= m_options.grip_angle && m_opening > m_options.grip_angle)
        event.grasped = grip(model);
      m_widest = event.grasped > 0 ? opening : std::max(m_widest, opening);
    }
    m_opening = opening;
    forces.clear_held();
    const Scalar t = forces.contact_time();
    for (std::size_t k = 0; k < m_held.size(); ++k) {
      HeldNode<Scalar> hn;
      hn.node = m_held[k];
      hn.instrument = m_id;
      const Vector3<Scalar> p = pose.to_world(m_offsets[k]);
      hn.target_velocity = velocity + angular_velocity.cross(p - pose.position);
      hn.target = p - t * hn.target_velocity;  // the point at contact time 0
      hn.stiffness = m_options.stiffness;
      hn.damping = m_options.damping;
      (void)forces.add_held(hn);
    }
    return event;
  }

  /// @brief The reaction of the held spheres on the jaws at the end of the last step: force
  /// (N), torque about the pose's position (N m), and how the force changes as the jaws move.
  ///
  /// With `step` = 0 the stiffness and damping are the ties' own (the jaws moved against spheres
  /// that stay put). Over a step of length `step` (s) a held sphere of mass m follows its tie:
  /// the jaws feel only \f$k/(1 + (h^2 k + h c)/m)\f$ of it (and the damping likewise), about
  /// \f$m/h^2\f$ for a tie far stiffer than that. Whoever integrates the instrument implicitly
  /// (ServoLoop's proxy) should take that one: the ties' own would damp its motion by about
  /// \f$h \sum k\f$ (70 N s/m for seven spheres at the default k) while the spheres follow.
  [[nodiscard]] Wrench<Scalar> wrench(const ForceModel<Scalar>& forces,
                                      Scalar step = Scalar(0)) const noexcept {
    Wrench<Scalar> w;
    const HeldNode<Scalar>* h = forces.held();
    const ScalarArray<Scalar>& inverse_mass = forces.inverse_masses();
    for (Index k = 0; k < forces.num_held(); ++k) {
      if (h[k].instrument != m_id) continue;
      const Vector3<Scalar> p = h[k].target + forces.contact_time() * h[k].target_velocity;
      w.force -= h[k].force;
      w.torque += (p - m_pose.position).cross(-h[k].force);
      const Scalar follow =
          Scalar(1) + (step * step * h[k].stiffness + step * h[k].damping) *
                          (h[k].node < inverse_mass.size() ? inverse_mass[h[k].node] : Scalar(0));
      w.stiffness += h[k].stiffness / follow * Matrix3<Scalar>::Identity();
      w.damping += h[k].damping / follow * Matrix3<Scalar>::Identity();
    }
    return w;
  }

  /// @brief The spheres held now, and each one's place in the jaws' frame (m).
  [[nodiscard]] const std::vector<Index>& held() const noexcept { return m_held; }
  [[nodiscard]] const std::vector<Vector3<Scalar>>& held_offsets() const noexcept {
    return m_offsets;
  }
  [[nodiscard]] bool holding() const noexcept { return !m_held.empty(); }
  [[nodiscard]] Scalar opening() const noexcept { return m_opening; }
  [[nodiscard]] const GrasperOptions<Scalar>& options() const noexcept { return m_options; }
  /// @brief True if a sphere centred at `local` (the jaws' frame) lies between jaws opened to
  /// `opening`, within options().margin: within the jaws' length and width, and within the wedge
  /// between them.
  [[nodiscard]] bool between_jaws(const Vector3<Scalar>& local, Scalar opening) const noexcept {
    const Scalar e = m_options.margin;
    if (local.x() < -e || local.x() > m_options.jaw_length + e) return false;
    if (std::abs(local.y()) > m_options.jaw_width / 2 + e) return false;
    const Scalar half = std::tan(std::min(opening, Scalar(3)) / 2);
    return std::abs(local.z()) <= std::max(Scalar(0), local.x()) * half + e;
  }

 private:
  // The jaws closed past the grip angle: hold the spheres in the wedge they swept (opened to
  // the widest angle since the last release), nearest the jaws' plane first.
  Index grip(const SphereModel<Scalar>& model) noexcept {
    m_candidates.clear();
    const auto x = model.positions();
    const auto fixed = model.fixed();
    for (Index i = 0; i < model.num_nodes(); ++i) {
      if (fixed[i]) continue;
      const Vector3<Scalar> local = m_pose.to_local(x.row(i).transpose());
      if (between_jaws(local, m_widest)) m_candidates.emplace_back(std::abs(local.z()), i);
    }
    std::sort(m_candidates.begin(), m_candidates.end());  // in place: no allocation
    const std::size_t n = std::min(m_candidates.size(), std::size_t(m_options.max_held));
    for (std::size_t k = 0; k < n; ++k) {
      const Index i = m_candidates[k].second;
      m_held.push_back(i);
      m_offsets.push_back(m_pose.to_local(x.row(i).transpose()));
    }
    return Index(n);
  }

  GrasperOptions<Scalar> m_options;
  Index m_id{0};
  Scalar m_opening{0}, m_widest{0};
  Pose<Scalar> m_pose{};
  // Refilled in update() within the capacity the constructor reserved (a copy keeps it).
  fsm::detail::ReservedVector<std::pair<Scalar, Index>> m_candidates;
  fsm::detail::ReservedVector<Index> m_held;
  fsm::detail::ReservedVector<Vector3<Scalar>> m_offsets;
};

}  // namespace fsm::collision
