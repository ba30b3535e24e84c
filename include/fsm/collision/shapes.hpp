#pragma once

/// @file collision/shapes.hpp
/// @brief Instrument shapes, their pose, and the contact of a shape with one sphere.

#include <optional>
#include <variant>
#include <vector>

#include "fsm/types.hpp"

namespace fsm::collision {

/// @brief A rigid pose: the shape's local frame in world coordinates (m).
template <typename Scalar>
struct Pose {
  Vector3<Scalar> position{Vector3<Scalar>::Zero()};
  Eigen::Quaternion<Scalar> orientation{Eigen::Quaternion<Scalar>::Identity()};

  [[nodiscard]] Vector3<Scalar> to_world(const Vector3<Scalar>& local) const noexcept {
    return position + orientation * local;
  }
  [[nodiscard]] Vector3<Scalar> to_local(const Vector3<Scalar>& world) const noexcept {
    return orientation.conjugate() * (world - position);
  }
};

/// @brief A ball of `radius` (m) centred at the local origin.
template <typename Scalar>
struct SphereShape {
  Scalar radius{0};
};

/// @brief A capsule (an instrument shaft): the points within `radius` of the segment from
/// (0, 0, -half_length) to (0, 0, +half_length) in the local frame (m).
template <typename Scalar>
struct CapsuleShape {
  Scalar radius{0};
  Scalar half_length{0};
};

/// @brief A solid cylinder of `radius` along local z from -half_length to +half_length (m), flat
/// ends. `edge_radius` (m, 0 = sharp) rounds the rims: the shape is then the points within
/// `edge_radius` of the cylinder of radius `radius - edge_radius` and half length
/// `half_length - edge_radius`, so its overall size does not change and each flat end keeps a disc
/// of radius `radius - edge_radius`. At most min(radius, half_length).
template <typename Scalar>
struct CylinderShape {
  Scalar radius{0};
  Scalar half_length{0};
  Scalar edge_radius{0};
};

/// @brief The convex hull of points given in the local frame (m), e.g. a grasper's jaw.
template <typename Scalar>
struct ConvexHullShape {
  Positions<Scalar> points;  ///< |P| x 3, at least 4 points not on one plane
};

template <typename Scalar>
using Shape = std::variant<SphereShape<Scalar>, CapsuleShape<Scalar>, CylinderShape<Scalar>,
                           ConvexHullShape<Scalar>>;

/// @brief One shape-sphere contact.
template <typename Scalar>
struct ShapeContact {
  /// Unit normal pointing from the shape into the sphere (the direction the shape pushes it).
  Vector3<Scalar> normal{Vector3<Scalar>::UnitZ()};
  /// Penetration depth (m), > 0: how far the sphere would have to move along `normal` to touch.
  Scalar depth{0};
  /// Contact point on the shape's surface (m), world coordinates.
  Vector3<Scalar> point{Vector3<Scalar>::Zero()};
};

/// @brief Throws fsm::Error naming `what` for a negative or non-finite size, or a hull with fewer
/// than four points not on one plane. A zero radius or half length is allowed (a point, a segment).
template <typename Scalar>
void validate(const Shape<Scalar>& shape, const std::string& what);

/// @brief The shape's world-space bounding box (min, max) at a pose.
template <typename Scalar>
[[nodiscard]] std::pair<Vector3<Scalar>, Vector3<Scalar>> bounding_box(
    const Shape<Scalar>& shape, const Pose<Scalar>& pose) noexcept;

/// @brief Contact between a shape at a pose and a sphere (centre `c`, radius `r`), or nothing when
/// they are apart. Closed forms for sphere, capsule and cylinder; libccd (GJK + EPA) for convex
/// hulls. Allocates nothing and never throws; a non-finite input gives no contact.
template <typename Scalar>
[[nodiscard]] std::optional<ShapeContact<Scalar>> contact(const Shape<Scalar>& shape,
                                                          const Pose<Scalar>& pose,
                                                          const Vector3<Scalar>& c,
                                                          Scalar r) noexcept;

extern template void validate<double>(const Shape<double>&, const std::string&);
extern template void validate<float>(const Shape<float>&, const std::string&);
extern template std::pair<Vector3<double>, Vector3<double>> bounding_box<double>(
    const Shape<double>&, const Pose<double>&) noexcept;
extern template std::pair<Vector3<float>, Vector3<float>> bounding_box<float>(
    const Shape<float>&, const Pose<float>&) noexcept;
extern template std::optional<ShapeContact<double>> contact<double>(const Shape<double>&,
                                                                    const Pose<double>&,
                                                                    const Vector3<double>&,
                                                                    double) noexcept;
extern template std::optional<ShapeContact<float>> contact<float>(const Shape<float>&,
                                                                  const Pose<float>&,
                                                                  const Vector3<float>&,
                                                                  float) noexcept;

}  // namespace fsm::collision
