// collision/shapes.hpp: instrument shapes, poses, and one shape against one sphere.

#include <cmath>

#include "common.hpp"
#include "fsm/collision/shapes.hpp"

namespace fsm::python {

namespace {
namespace fc = fsm::collision;
using Pose = fc::Pose<Scalar>;
using Shape = fc::Shape<Scalar>;

// A unit quaternion from (w, x, y, z) or a 3 x 3 rotation matrix.
Eigen::Quaternion<Scalar> to_orientation(const Array& a) {
  if (a.ndim() == 1 && a.shape(0) == 4) {
    Eigen::Quaternion<Scalar> q(a.data()[0], a.data()[1], a.data()[2], a.data()[3]);
    const Scalar n = q.norm();
    if (!std::isfinite(n) || !(n > 1e-12))
      throw Error("", "orientation", "quaternion (w, x, y, z) must be finite and non-zero");
    q.coeffs() /= n;
    return q;
  }
  if (a.ndim() == 2 && a.shape(0) == 3 && a.shape(1) == 3) {
    const Eigen::Map<const Eigen::Matrix<Scalar, 3, 3, Eigen::RowMajor>> R(a.data());
    const Eigen::Matrix<Scalar, 3, 3> RtR = R.transpose() * R;
    if (!R.allFinite() ||
        (RtR - Eigen::Matrix<Scalar, 3, 3>::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
        R.determinant() < 0)
      throw Error("", "orientation",
                  "3 x 3 matrix is not a rotation (want R^T R = I within 1e-6 and det R = +1)");
    Eigen::Quaternion<Scalar> q{Eigen::Matrix<Scalar, 3, 3>(R)};
    q.normalize();
    return q;
  }
  throw Error(
      "", "orientation",
      "has shape " + shape_string(a) + ", wanted (4,) quaternion (w, x, y, z) or (3, 3) rotation");
}

py::array_t<Scalar> quaternion_array(const Eigen::Quaternion<Scalar>& q) {
  py::array_t<Scalar> out(4);
  auto o = out.mutable_unchecked<1>();
  o(0) = q.w();
  o(1) = q.x();
  o(2) = q.y();
  o(3) = q.z();
  return out;
}

template <typename S>
S validated(S shape, const char* what) {
  fc::validate<Scalar>(Shape(shape), what);
  return shape;
}

}  // namespace

void define_shapes(py::module_& m) {
  // ---- shapes ----------------------------------------------------------------------------------
  py::class_<fc::SphereShape<Scalar>>(m, "SphereShape",
                                      R"(A ball of `radius` (m) centred at the pose's origin.

SphereShape(radius). Raises fsm.Error for a negative or non-finite radius.)")
      .def(py::init([](Scalar radius) {
             return validated(fc::SphereShape<Scalar>{radius}, "SphereShape");
           }),
           py::arg("radius"))
      .def_readwrite("radius", &fc::SphereShape<Scalar>::radius, "m")
      .def("__repr__", [](const fc::SphereShape<Scalar>& s) {
        return "SphereShape(radius=" + std::to_string(s.radius) + ")";
      });

  py::class_<fc::CapsuleShape<Scalar>>(m, "CapsuleShape", R"(A capsule, e.g. an instrument shaft.

CapsuleShape(radius, half_length): the points within `radius` (m) of the segment from
(0, 0, -half_length) to (0, 0, +half_length) (m) in the local frame. Raises fsm.Error for a
negative or non-finite size.)")
      .def(py::init([](Scalar radius, Scalar half_length) {
             return validated(fc::CapsuleShape<Scalar>{radius, half_length}, "CapsuleShape");
           }),
           py::arg("radius"), py::arg("half_length"))
      .def_readwrite("radius", &fc::CapsuleShape<Scalar>::radius, "m")
      .def_readwrite("half_length", &fc::CapsuleShape<Scalar>::half_length, "m")
      .def("__repr__", [](const fc::CapsuleShape<Scalar>& s) {
        return "CapsuleShape(radius=" + std::to_string(s.radius) +
               ", half_length=" + std::to_string(s.half_length) + ")";
      });

  py::class_<fc::CylinderShape<Scalar>>(m, "CylinderShape",
                                        R"(A solid cylinder with flat ends (a flat punch).

CylinderShape(radius, half_length, edge_radius=0): radius (m) about local z, from
z = -half_length to +half_length (m); edge_radius (m) rounds the rims without changing the overall
size (each flat end keeps a disc of radius radius - edge_radius). Raises fsm.Error for a negative
or non-finite size, or an edge radius above the radius or the half length.)")
      .def(py::init([](Scalar radius, Scalar half_length, Scalar edge_radius) {
             return validated(fc::CylinderShape<Scalar>{radius, half_length, edge_radius},
                              "CylinderShape");
           }),
           py::arg("radius"), py::arg("half_length"), py::arg("edge_radius") = Scalar(0))
      .def_readwrite("radius", &fc::CylinderShape<Scalar>::radius, "m")
      .def_readwrite("half_length", &fc::CylinderShape<Scalar>::half_length, "m")
      .def_readwrite("edge_radius", &fc::CylinderShape<Scalar>::edge_radius, "m")
      .def("__repr__", [](const fc::CylinderShape<Scalar>& s) {
        return "CylinderShape(radius=" + std::to_string(s.radius) +
               ", half_length=" + std::to_string(s.half_length) +
               ", edge_radius=" + std::to_string(s.edge_radius) + ")";
      });

  using Hull = fc::ConvexHullShape<Scalar>;
  py::class_<Hull>(m, "ConvexHullShape", R"(The convex hull of points (a grasper's jaw, a box).

ConvexHullShape(points): points is an (N, 3) array in the local frame (m), N >= 4 and not all on
one plane; contact uses GJK + EPA (libccd). Raises fsm.Error for a bad point set.)")
      .def(py::init([](const Array& points) {
             return validated(Hull{rows3(points, "ConvexHullShape points")}, "ConvexHullShape");
           }),
           py::arg("points"))
      .def_property(
          "points", [](const Hull& h) { return Positions<Scalar>(h.points); },
          [](Hull& h, const Array& points) {
            h = validated(Hull{rows3(points, "ConvexHullShape points")}, "ConvexHullShape");
          },
          "(N, 3) points in the local frame (m); a copy. Assigning re-validates.")
      .def("__repr__", [](const Hull& h) {
        return "ConvexHullShape(" + std::to_string(h.points.rows()) + " points)";
      });

  // ---- pose ------------------------------------------------------------------------------------
  py::class_<Pose> pose(m, "Pose", R"(A rigid pose: the shape's local frame in world coordinates.

Pose(position=(0, 0, 0), orientation=None)

position (m) is a length-3 vector. orientation is None (identity), a unit quaternion
(w, x, y, z) (normalised here) or a 3 x 3 rotation matrix (local to world). Raises fsm.Error for a
zero quaternion or a matrix that is not a rotation.

pose.position is a numpy view of the pose (writing into it moves the pose); pose.orientation
gives (w, x, y, z) and pose.rotation the 3 x 3 matrix (copies; assign to change).)");
  pose.def(py::init([](const Array& position, const py::object& orientation) {
             Pose p;
             p.position = vec3(position, "position");
             if (!p.position.allFinite()) throw Error("", "position", "is not finite");
             if (!orientation.is_none()) p.orientation = to_orientation(orientation.cast<Array>());
             return p;
           }),
           py::arg("position") = Vector3<Scalar>::Zero().eval(),
           py::arg("orientation") = py::none())
      .def_property(
          "orientation", [](const Pose& p) { return quaternion_array(p.orientation); },
          [](Pose& p, const Array& q) { p.orientation = to_orientation(q); },
          "unit quaternion (w, x, y, z), a copy; accepts (w, x, y, z) or a 3 x 3 rotation")
      .def_property(
          "rotation",
          [](const Pose& p) {
            return Eigen::Matrix<Scalar, 3, 3, Eigen::RowMajor>(p.orientation.toRotationMatrix());
          },
          [](Pose& p, const Array& r) { p.orientation = to_orientation(r); },
          "3 x 3 rotation matrix (local to world), a copy")
      .def(
          "to_world", [](const Pose& p, const Vector3<Scalar>& x) { return p.to_world(x); },
          py::arg("local"), "A local point (m) in world coordinates.")
      .def(
          "to_local", [](const Pose& p, const Vector3<Scalar>& x) { return p.to_local(x); },
          py::arg("world"), "A world point (m) in the local frame.")
      .def("__repr__", [](const Pose& p) {
        const auto& q = p.orientation;
        return "Pose(position=(" + std::to_string(p.position.x()) + ", " +
               std::to_string(p.position.y()) + ", " + std::to_string(p.position.z()) +
               "), orientation=(" + std::to_string(q.w()) + ", " + std::to_string(q.x()) + ", " +
               std::to_string(q.y()) + ", " + std::to_string(q.z()) + "))";
      });

  vec3_property(pose, "position", &Pose::position, "origin of the local frame (m), a view");

  m.def(
      "shape_contact",
      [](const Shape& shape, const Pose& pose, const Vector3<Scalar>& centre,
         Scalar radius) -> py::object {
        require_finite(centre, "centre");
        require_non_negative(radius, "radius");
        const auto c = fc::contact(shape, pose, centre, radius);
        if (!c) return py::none();
        py::dict d;
        d["normal"] = Vector3<Scalar>(c->normal);
        d["depth"] = c->depth;
        d["point"] = Vector3<Scalar>(c->point);
        return std::move(d);
      },
      py::arg("shape"), py::arg("pose"), py::arg("centre"), py::arg("radius"),
      R"(Contact of a shape at a pose with one sphere (centre in m, radius in m).

Returns None when they are apart, else a dict: normal (unit, from the shape into the sphere),
depth (m, > 0: how far the sphere must move along normal to touch) and point (on the shape's
surface, world, m).)");
}

}  // namespace fsm::python
