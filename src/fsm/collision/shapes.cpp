// Instrument shapes against one sphere: validation, bounding boxes, and the closed forms for
// sphere, capsule and cylinder. The convex hull's narrow phase (GJK, EPA, libccd's MPR) is in
// hull_contact.cpp. See collision/shapes.hpp for the conventions.

#include "fsm/collision/shapes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "fsm/error.hpp"
#include "hull_contact.hpp"

namespace fsm::collision {
namespace {

using detail::LocalContact;

template <typename... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <typename... F>
Overloaded(F...) -> Overloaded<F...>;

template <typename Scalar>
bool finite(Scalar x) noexcept {
  return std::isfinite(x);
}

template <typename Scalar>
std::string str(Scalar x) {
  std::ostringstream s;
  s.precision(std::numeric_limits<Scalar>::max_digits10);
  s << x;
  return s.str();
}

template <typename Scalar>
void check_size(Scalar value, const char* shape, const char* field, const std::string& what) {
  if (!finite(value) || value < Scalar(0))
    throw Error(
        std::string(), what,
        std::string(shape) + " " + field + " is " + str(value) + " m; it must be finite and >= 0");
}

// ------------------------------------------------------------------------------------------------
// Closed forms, in the shape's local frame (LocalContact: hull_contact.hpp).
// ------------------------------------------------------------------------------------------------

/// Below this length a direction is rounding noise: relative to the size of the coordinates.
template <typename Scalar>
Scalar noise_length(Scalar scale) noexcept {
  return Scalar(8) * std::numeric_limits<Scalar>::epsilon() * scale;
}

template <typename Scalar>
LocalContact<Scalar> sphere_local(Scalar radius, const Vector3<Scalar>& p, Scalar scale) noexcept {
  const Scalar d = p.norm();
  // The centre is equidistant from the whole surface; +z is as good as any and deterministic.
  const Vector3<Scalar> n =
      d > noise_length(scale) ? Vector3<Scalar>(p / d) : Vector3<Scalar>::UnitZ();
  return {d - radius, n, radius * n};
}

template <typename Scalar>
LocalContact<Scalar> capsule_local(Scalar radius, Scalar half_length, const Vector3<Scalar>& p,
                                   Scalar scale) noexcept {
  const Vector3<Scalar> axis_point(0, 0, std::clamp(p.z(), -half_length, half_length));
  const Vector3<Scalar> v = p - axis_point;
  const Scalar d = v.norm();
  Vector3<Scalar> n;
  if (d > noise_length(scale)) {
    n = v / d;
  } else if (half_length - std::abs(p.z()) <= noise_length(scale)) {
    // On the axis at an end (or a zero-length capsule): out through that end, like a sphere.
    n = Vector3<Scalar>(0, 0, p.z() >= Scalar(0) ? Scalar(1) : Scalar(-1));
  } else {
    // On the axis between the ends: every radial direction is nearest; take local +x.
    n = Vector3<Scalar>::UnitX();
  }
  return {d - radius, n, axis_point + radius * n};
}

template <typename Scalar>
LocalContact<Scalar> cylinder_local(Scalar radius, Scalar half_length, const Vector3<Scalar>& p,
                                    Scalar scale) noexcept {
  const Scalar rho = std::hypot(p.x(), p.y());
  const bool on_axis = rho <= noise_length(scale);
  const Vector3<Scalar> radial =
      on_axis ? Vector3<Scalar>::UnitX() : Vector3<Scalar>(p.x() / rho, p.y() / rho, Scalar(0));
  const Scalar cap_sign = p.z() >= Scalar(0) ? Scalar(1) : Scalar(-1);
  const Vector3<Scalar> cap_normal(0, 0, cap_sign);
  const Scalar abs_z = std::abs(p.z());

  if (rho <= radius && abs_z <= half_length) {
    // Inside: leave through the nearest face; a tie (the centre of a cylinder with radius equal
    // to its half length, or a point on the medial surface) goes through the cap.
    const Scalar to_side = radius - rho;
    const Scalar to_cap = half_length - abs_z;
    if (to_cap <= to_side)
      return {-to_cap, cap_normal, Vector3<Scalar>(p.x(), p.y(), cap_sign * half_length)};
    return {-to_side, radial, Vector3<Scalar>(radius * radial.x(), radius * radial.y(), p.z())};
  }
  if (abs_z <= half_length) {
    // Beside the side wall.
    return {rho - radius, radial, Vector3<Scalar>(radius * radial.x(), radius * radial.y(), p.z())};
  }
  if (rho <= radius) {
    // Above or below a flat end.
    return {abs_z - half_length, cap_normal, Vector3<Scalar>(p.x(), p.y(), cap_sign * half_length)};
  }
  // Beyond a rim: the nearest point is on the circle of radius `radius` at z = +-half_length.
  const Vector3<Scalar> rim(radius * radial.x(), radius * radial.y(), cap_sign * half_length);
  const Vector3<Scalar> v = p - rim;
  const Scalar d = v.norm();  // >= abs_z - half_length > 0
  const Vector3<Scalar> n = d > Scalar(0) ? Vector3<Scalar>(v / d) : cap_normal;
  return {d, n, rim};
}

template <typename Scalar>
bool finite_inputs(const Pose<Scalar>& pose, const Vector3<Scalar>& c, Scalar r) noexcept {
  return pose.position.allFinite() && pose.orientation.coeffs().allFinite() && c.allFinite() &&
         finite(r) && r >= Scalar(0);
}

}  // namespace

template <typename Scalar>
void validate(const Shape<Scalar>& shape, const std::string& what) {
  std::visit(
      Overloaded{
          [&](const SphereShape<Scalar>& s) { check_size(s.radius, "sphere", "radius", what); },
          [&](const CapsuleShape<Scalar>& s) {
            check_size(s.radius, "capsule", "radius", what);
            check_size(s.half_length, "capsule", "half_length", what);
          },
          [&](const CylinderShape<Scalar>& s) {
            check_size(s.radius, "cylinder", "radius", what);
            check_size(s.half_length, "cylinder", "half_length", what);
            check_size(s.edge_radius, "cylinder", "edge_radius", what);
            if (s.edge_radius > std::min(s.radius, s.half_length))
              throw Error(std::string(), what,
                          "cylinder edge_radius is " + str(s.edge_radius) +
                              " m; it must be at most the radius (" + str(s.radius) +
                              " m) and the half length (" + str(s.half_length) + " m)");
          },
          [&](const ConvexHullShape<Scalar>& s) {
            const auto& p = s.points;
            if (p.rows() < 4)
              throw Error(std::string(), what,
                          "convex hull points: got " + std::to_string(p.rows()) +
                              " x 3, need at least 4 x 3 (not all on one plane)");
            for (Index i = 0; i < Index(p.rows()); ++i)
              if (!p.row(i).allFinite())
                throw Error(std::string(), what,
                            "convex hull points: row " + std::to_string(i) + " is not finite");
            // The thickest tetrahedron greedily: p0, the point farthest from it, the point
            // farthest from that line, the point farthest from that plane. All points lie within
            // `flat` of one plane exactly when the last distance does.
            using V = Vector3<double>;
            auto row = [&](Index i) { return V(p.row(i).transpose().template cast<double>()); };
            const V a = row(0);
            Index ib = 0;
            double best = -1;
            for (Index i = 0; i < Index(p.rows()); ++i)
              if ((row(i) - a).squaredNorm() > best) best = (row(i) - a).squaredNorm(), ib = i;
            const double size = std::sqrt(best);
            const double flat = 1e3 * double(std::numeric_limits<Scalar>::epsilon()) * size;
            const V ab = row(ib) - a;
            Index ic = 0;
            best = -1;
            for (Index i = 0; i < Index(p.rows()); ++i) {
              const double d = size > 0 ? ab.cross(row(i) - a).norm() / size : 0.0;
              if (d > best) best = d, ic = i;
            }
            const bool collinear = !(best > flat);
            double height = 0;
            if (!collinear) {
              const V n = ab.cross(row(ic) - a).normalized();
              for (Index i = 0; i < Index(p.rows()); ++i)
                height = std::max(height, std::abs(n.dot(row(i) - a)));
            }
            if (!(height > flat))
              throw Error(std::string(), what,
                          "convex hull points: all " + std::to_string(p.rows()) +
                              " lie on one plane (within " + str(flat) +
                              " m); a hull needs volume");
          }},
      shape);
}

template <typename Scalar>
std::pair<Vector3<Scalar>, Vector3<Scalar>> bounding_box(const Shape<Scalar>& shape,
                                                         const Pose<Scalar>& pose) noexcept {
  using V = Vector3<Scalar>;
  const Eigen::Quaternion<Scalar> q = pose.orientation.normalized();
  const V axis = q * V::UnitZ();
  // A disc of radius R with unit normal a spans R sqrt(1 - a_i^2) along world axis i.
  auto disc = [&](Scalar radius) {
    return V(radius * (V::Ones() - axis.cwiseAbs2()).cwiseMax(Scalar(0)).cwiseSqrt());
  };
  return std::visit(Overloaded{[&](const SphereShape<Scalar>& s) {
                                 return std::pair<V, V>(pose.position - V::Constant(s.radius),
                                                        pose.position + V::Constant(s.radius));
                               },
                               [&](const CapsuleShape<Scalar>& s) {
                                 const V e =
                                     s.half_length * axis.cwiseAbs() + V::Constant(s.radius);
                                 return std::pair<V, V>(pose.position - e, pose.position + e);
                               },
                               [&](const CylinderShape<Scalar>& s) {
                                 const V e = s.half_length * axis.cwiseAbs() + disc(s.radius);
                                 return std::pair<V, V>(pose.position - e, pose.position + e);
                               },
                               [&](const ConvexHullShape<Scalar>& s) {
                                 if (s.points.rows() == 0)
                                   return std::pair<V, V>(pose.position, pose.position);
                                 const Matrix3<Scalar> rot = q.toRotationMatrix();
                                 V lo = V::Constant(std::numeric_limits<Scalar>::infinity());
                                 V hi = -lo;
                                 for (Index i = 0; i < Index(s.points.rows()); ++i) {
                                   const V w = rot * s.points.row(i).transpose();
                                   lo = lo.cwiseMin(w);
                                   hi = hi.cwiseMax(w);
                                 }
                                 return std::pair<V, V>(pose.position + lo, pose.position + hi);
                               }},
                    shape);
}

template <typename Scalar>
std::optional<ShapeContact<Scalar>> contact(const Shape<Scalar>& shape, const Pose<Scalar>& pose,
                                            const Vector3<Scalar>& c, Scalar r) noexcept {
  if (!finite_inputs(pose, c, r)) return std::nullopt;
  const Scalar qn = pose.orientation.norm();
  if (!(qn > Scalar(0)) || !finite(qn)) return std::nullopt;
  const Eigen::Quaternion<Scalar> q(pose.orientation.coeffs() / qn);
  const Vector3<Scalar> p = q.conjugate() * (c - pose.position);
  // Coordinates are only as precise as the larger of the inputs.
  const Scalar coord_scale =
      std::max({c.cwiseAbs().maxCoeff(), pose.position.cwiseAbs().maxCoeff(), r});

  auto finish = [&](const auto& local) -> std::optional<ShapeContact<Scalar>> {
    const Scalar depth = r - Scalar(local.signed_distance);
    if (!(depth > Scalar(0)) || !finite(depth)) return std::nullopt;
    ShapeContact<Scalar> out;
    out.normal = (q * local.normal.template cast<Scalar>()).normalized();
    out.depth = depth;
    out.point = pose.position + q * local.point.template cast<Scalar>();
    if (!out.normal.allFinite() || !out.point.allFinite()) return std::nullopt;
    return out;
  };

  return std::visit(
      Overloaded{[&](const SphereShape<Scalar>& s) -> std::optional<ShapeContact<Scalar>> {
                   if (!finite(s.radius) || s.radius < Scalar(0)) return std::nullopt;
                   return finish(sphere_local(s.radius, p, std::max(coord_scale, s.radius)));
                 },
                 [&](const CapsuleShape<Scalar>& s) -> std::optional<ShapeContact<Scalar>> {
                   if (!finite(s.radius) || !finite(s.half_length) || s.radius < Scalar(0) ||
                       s.half_length < Scalar(0))
                     return std::nullopt;
                   const Scalar scale = std::max({coord_scale, s.radius, s.half_length});
                   return finish(capsule_local(s.radius, s.half_length, p, scale));
                 },
                 [&](const CylinderShape<Scalar>& s) -> std::optional<ShapeContact<Scalar>> {
                   const Scalar e = s.edge_radius;
                   if (!finite(s.radius) || !finite(s.half_length) || !finite(e) ||
                       s.radius < Scalar(0) || s.half_length < Scalar(0) || e < Scalar(0) ||
                       e > std::min(s.radius, s.half_length))
                     return std::nullopt;
                   const Scalar scale = std::max({coord_scale, s.radius, s.half_length});
                   // A rounded rim: the inner cylinder's distance less the edge radius (the
                   // points within e of it), its nearest point pushed out by e along the normal.
                   auto local = cylinder_local(s.radius - e, s.half_length - e, p, scale);
                   local.signed_distance -= e;
                   local.point += e * local.normal;
                   return finish(local);
                 },
                 [&](const ConvexHullShape<Scalar>& s) -> std::optional<ShapeContact<Scalar>> {
                   const auto local = detail::hull_local(s, p, r);
                   if (!local) return std::nullopt;
                   return finish(*local);
                 }},
      shape);
}

template void validate<double>(const Shape<double>&, const std::string&);
template void validate<float>(const Shape<float>&, const std::string&);
template std::pair<Vector3<double>, Vector3<double>> bounding_box<double>(
    const Shape<double>&, const Pose<double>&) noexcept;
template std::pair<Vector3<float>, Vector3<float>> bounding_box<float>(const Shape<float>&,
                                                                       const Pose<float>&) noexcept;
template std::optional<ShapeContact<double>> contact<double>(const Shape<double>&,
                                                             const Pose<double>&,
                                                             const Vector3<double>&,
                                                             double) noexcept;
template std::optional<ShapeContact<float>> contact<float>(const Shape<float>&, const Pose<float>&,
                                                           const Vector3<float>&, float) noexcept;

}  // namespace fsm::collision
