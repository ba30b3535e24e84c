#pragma once

// Private to src/fsm/collision: the local result of a shape-point query, and the convex hull's
// narrow phase (hull_contact.cpp, the only file that uses libccd), as fcl keeps its primitive
// closed forms and its GJK algorithms apart.

#include <optional>

#include "fsm/collision/shapes.hpp"

namespace fsm::collision::detail {

/// A shape against a point, in the shape's local frame: the signed distance from the point to the
/// surface (negative inside), the unit outward normal at the nearest surface point (pointing from
/// the surface toward the point) and that point.
template <typename Scalar>
struct LocalContact {
  Scalar signed_distance;
  Vector3<Scalar> normal;
  Vector3<Scalar> point;
};

/// The convex hull against a sphere of radius `r` centred at `p_local` (hull frame): nullopt when
/// they are farther apart than r or the input is not finite. Runs in double whatever Scalar is.
template <typename Scalar>
std::optional<LocalContact<double>> hull_local(const ConvexHullShape<Scalar>& hull,
                                               const Vector3<Scalar>& p_local, Scalar r) noexcept;

extern template std::optional<LocalContact<double>> hull_local<float>(const ConvexHullShape<float>&,
                                                                      const Vector3<float>&,
                                                                      float) noexcept;
extern template std::optional<LocalContact<double>> hull_local<double>(
    const ConvexHullShape<double>&, const Vector3<double>&, double) noexcept;

}  // namespace fsm::collision::detail
