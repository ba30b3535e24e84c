// Collision: instrument shapes and poses, the ContactSolver, and the triangle AABB tree.
// compute() writes contact forces straight into the caller's numpy array (no copy), so the
// array must already be float64, C-contiguous, writeable and |V| x 3: Simulation.external_forces
// is exactly that.

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "common.hpp"
#include "fsm/collision/contact.hpp"
#include "fsm/collision/shapes.hpp"
#include "fsm/collision/triangle_bvh.hpp"

namespace fsm::python {

namespace {
namespace fc = fsm::collision;
using Pose = fc::Pose<Scalar>;
using Shape = fc::Shape<Scalar>;
using Instrument = fc::Instrument<Scalar>;
using Options = fc::ContactOptions<Scalar>;
using Wrench = fc::Wrench<Scalar>;
using Contact = fc::Contact<Scalar>;
using Bvh = fc::TriangleBvh<Scalar>;
using RayHit = fc::RayHit<Scalar>;
using Model = SphereModel<Scalar>;
using Sim = Simulation<Scalar>;
using Array = py::array_t<Scalar, py::array::c_style | py::array::forcecast>;

std::string shape_string(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// A (rows x 3) float array from numpy (copied); fsm::Error with the shape got and wanted.
Positions<Scalar> rows3(const Array& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw Error("", what, "has shape " + shape_string(a) + ", wanted (n, 3)");
  Positions<Scalar> out(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), out.data());
  return out;
}

Vector3<Scalar> vec3(const Array& a, const char* what) {
  if (a.size() != 3 || a.ndim() > 2)
    throw Error("", what, "has shape " + shape_string(a) + ", wanted (3,)");
  return Vector3<Scalar>(a.data()[0], a.data()[1], a.data()[2]);
}

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

// Forces as a writable numpy array over the caller's memory, checked without converting:
// a conversion would write into a temporary and lose the forces.
Eigen::Map<Positions<Scalar>> force_map(py::array& forces, Index rows) {
  if (!py::isinstance<py::array_t<Scalar>>(forces) || forces.dtype().kind() != 'f' ||
      forces.itemsize() != sizeof(Scalar))
    throw Error("", "forces", "must be a float64 numpy array (e.g. Simulation.external_forces)");
  if (forces.ndim() != 2 || forces.shape(0) != rows || forces.shape(1) != 3)
    throw Error("", "forces",
                "has shape " + shape_string(forces) + ", wanted (" + std::to_string(rows) + ", 3)");
  if (!(forces.flags() & py::array::c_style))
    throw Error("", "forces",
                "must be C-contiguous (row-major): the solver writes into it in place");
  if (!forces.writeable()) throw Error("", "forces", "is read-only");
  return Eigen::Map<Positions<Scalar>>(static_cast<Scalar*>(forces.mutable_data()), rows, 3);
}

// The numpy dtype of a Contact record, with the C++ struct's own offsets (so a copy is a memcpy).
py::dtype contact_dtype() {
  const Contact c{};
  const auto at = [&c](const void* p) {
    return py::int_(static_cast<const char*>(p) - reinterpret_cast<const char*>(&c));
  };
  py::dict d;
  d["names"] = py::make_tuple("sphere", "instrument", "other", "normal", "depth", "point", "force");
  d["formats"] = py::make_tuple("<i4", "<i4", "<i4", "(3,)<f8", "<f8", "(3,)<f8", "(3,)<f8");
  d["offsets"] = py::make_tuple(at(&c.sphere), at(&c.instrument), at(&c.other), at(c.normal.data()),
                                at(&c.depth), at(c.point.data()), at(c.force.data()));
  d["itemsize"] = py::int_(sizeof(Contact));
  return py::dtype::from_args(d);
}

// A read-write length-3 property that reads as a numpy view of the member (writing into it
// changes the object) and accepts any length-3 sequence.
template <typename C>
void vec3_property(py::class_<C>& c, const char* name, Vector3<Scalar> C::*member,
                   const char* doc) {
  c.def_property(
      name,
      [member](py::object self) {
        C& obj = self.cast<C&>();
        return view((obj.*member).data(), 3, 0, self);
      },
      [member, name](C& obj, const Array& v) {
        const Vector3<Scalar> x = vec3(v, name);
        if (!x.allFinite()) throw Error("", name, "is not finite");
        obj.*member = x;
      },
      doc);
}

static_assert(sizeof(Index) == 4, "the contact dtype says int32");
}  // namespace

void define_collision(py::module_& m) {
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

CylinderShape(radius, half_length): radius (m) about local z, from z = -half_length to
+half_length (m). Raises fsm.Error for a negative or non-finite size.)")
      .def(py::init([](Scalar radius, Scalar half_length) {
             return validated(fc::CylinderShape<Scalar>{radius, half_length}, "CylinderShape");
           }),
           py::arg("radius"), py::arg("half_length"))
      .def_readwrite("radius", &fc::CylinderShape<Scalar>::radius, "m")
      .def_readwrite("half_length", &fc::CylinderShape<Scalar>::half_length, "m")
      .def("__repr__", [](const fc::CylinderShape<Scalar>& s) {
        return "CylinderShape(radius=" + std::to_string(s.radius) +
               ", half_length=" + std::to_string(s.half_length) + ")";
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

  // ---- instruments and options -----------------------------------------------------------------
  py::class_<Instrument> instrument(m, "Instrument", R"(A rigid instrument posed by a device.

Instrument(shape, pose=Pose(), name="", linear_velocity=(0, 0, 0), angular_velocity=(0, 0, 0),
           friction=0.2, enabled=True)

shape is a SphereShape, CapsuleShape, CylinderShape or ConvexHullShape; pose places it (m);
linear_velocity (m/s) is that of the pose origin and angular_velocity (rad/s) is in the world
frame (both feed contact damping and friction); friction is the Coulomb coefficient against tissue.
pose, linear_velocity and angular_velocity read as views: inst.pose.position[2] -= 1e-3 moves it.)");
  instrument
      .def(py::init(
               [](const Shape& shape, const Pose& at, const std::string& name,
                  const Vector3<Scalar>& v, const Vector3<Scalar>& w, Scalar friction,
                  bool enabled) { return Instrument{name, shape, at, v, w, friction, enabled}; }),
           py::arg("shape"), py::arg("pose") = Pose{}, py::arg("name") = "",
           py::arg("linear_velocity") = Vector3<Scalar>::Zero().eval(),
           py::arg("angular_velocity") = Vector3<Scalar>::Zero().eval(), py::arg("friction") = 0.2,
           py::arg("enabled") = true)
      .def_readwrite("name", &Instrument::name, "a label used in error messages")
      .def_property(
          "shape", [](const Instrument& i) { return i.shape; },
          [](Instrument& i, const Shape& s) {
            fc::validate(s, "instrument '" + i.name + "' shape");
            i.shape = s;
          },
          "the shape (a copy; assign a new one to change it, which is validated)")
      .def_readwrite("pose", &Instrument::pose, "the Pose (m); mutable in place")
      .def_readwrite("friction", &Instrument::friction, "Coulomb coefficient (dimensionless)")
      .def_readwrite("enabled", &Instrument::enabled, "False: the instrument touches nothing")
      .def("__repr__", [](const Instrument& i) {
        return "Instrument('" + i.name + "', enabled=" + (i.enabled ? "True" : "False") + ")";
      });

  vec3_property(instrument, "linear_velocity", &Instrument::linear_velocity,
                "velocity of the pose origin (m/s), a view");
  vec3_property(instrument, "angular_velocity", &Instrument::angular_velocity,
                "angular velocity, world frame (rad/s), a view");

  py::class_<Wrench>(m, "Wrench",
                     R"(Force (N) and torque (N m, about the pose origin) the tissue exerts on an
instrument; what a haptic device renders (its negative is what the instrument applies).)")
      .def_readonly("force", &Wrench::force, "N, world frame")
      .def_readonly("torque", &Wrench::torque, "N m about the instrument's pose origin")
      .def("__repr__", [](const Wrench& w) {
        return "Wrench(force=(" + std::to_string(w.force.x()) + ", " + std::to_string(w.force.y()) +
               ", " + std::to_string(w.force.z()) + "))";
      });

  py::class_<Options>(m, "ContactOptions", R"(How contacts respond (SI units).

ContactOptions(stiffness_scale=2, damping_ratio=0.5, friction_speed=1e-3, part_contact=True,
               self_contact=False, part_friction=0, max_contacts=4096, spatial_hash=True,
               verlet_skin=0.002, time_step=1e-3)

stiffness_scale s: penalty stiffness k = s E r (N/m) from the sphere's region modulus E (Pa) and
radius r (m). damping_ratio zeta: contact damping c = 2 zeta sqrt(k m). friction_speed (m/s):
regularisation of Coulomb friction. part_contact: spheres of different regions collide;
self_contact: spheres of one region far apart at rest collide (folding). part_friction: Coulomb
coefficient between parts. max_contacts: length of the contact list. spatial_hash: False tests
every sphere (the reference). verlet_skin (m): slack of the part-contact pair list. time_step (s):
the step the forces will be applied over; it caps each sphere's contact stiffness so the explicit
contact force stays stable (0 removes the cap). Validated when a ContactSolver is made.)")
      .def(
          py::init([](Scalar stiffness_scale, Scalar damping_ratio, Scalar friction_speed,
                      bool part_contact, bool self_contact, Scalar part_friction,
                      Index max_contacts, bool spatial_hash, Scalar verlet_skin, Scalar time_step) {
            Options o;
            o.stiffness_scale = stiffness_scale;
            o.damping_ratio = damping_ratio;
            o.friction_speed = friction_speed;
            o.part_contact = part_contact;
            o.self_contact = self_contact;
            o.part_friction = part_friction;
            o.max_contacts = max_contacts;
            o.spatial_hash = spatial_hash;
            o.verlet_skin = verlet_skin;
            o.time_step = time_step;
            return o;
          }),
          py::arg("stiffness_scale") = 2.0, py::arg("damping_ratio") = 0.5,
          py::arg("friction_speed") = 1e-3, py::arg("part_contact") = true,
          py::arg("self_contact") = false, py::arg("part_friction") = 0.0,
          py::arg("max_contacts") = 4096, py::arg("spatial_hash") = true,
          py::arg("verlet_skin") = 0.002, py::arg("time_step") = 1e-3)
      .def_readwrite("stiffness_scale", &Options::stiffness_scale, "s in k = s E r")
      .def_readwrite("damping_ratio", &Options::damping_ratio, "zeta in c = 2 zeta sqrt(k m)")
      .def_readwrite("friction_speed", &Options::friction_speed, "m/s")
      .def_readwrite("part_contact", &Options::part_contact, "spheres of different regions collide")
      .def_readwrite("self_contact", &Options::self_contact,
                     "spheres of one region far apart at rest collide (folding)")
      .def_readwrite("part_friction", &Options::part_friction, "Coulomb coefficient between parts")
      .def_readwrite("max_contacts", &Options::max_contacts,
                     "length of the contact list (allocated once)")
      .def_readwrite("spatial_hash", &Options::spatial_hash,
                     "False tests every sphere (the reference the tests compare with)")
      .def_readwrite("verlet_skin", &Options::verlet_skin, "m")
      .def_readwrite("time_step", &Options::time_step, "s (0: no stiffness cap)");

  // ---- the solver ------------------------------------------------------------------------------
  py::class_<BoundContactSolver>(m, "ContactSolver",
                                 R"(Contact detection and response for one SphereModel.

ContactSolver(model, options=ContactOptions())   # model: a SphereModel, e.g. sim.model
ContactSolver(simulation, options=ContactOptions())

Each step: set your own loads in sim.external_forces (contact forces are *added*), call
solver.compute(sim) (or compute(sim.model, sim.external_forces)), then sim.step(dt). compute()
finds instrument-sphere and part-part contacts (spatial hash, closed forms or GJK), writes the
penalty + damping + friction forces into the force array in place, and records each
instrument's wrench (minus the sum of what it applies), the contacts and work counters.

    solver = fsm.ContactSolver(sim.model)
    tip = solver.add_instrument(fsm.Instrument(fsm.SphereShape(0.002), fsm.Pose((0, 0, 0.01))))
    for _ in range(100):
        solver.instrument(tip).pose.position[2] -= 1e-5
        sim.external_forces[:] = 0
        solver.compute(sim)
        sim.step(1e-3)
    print(solver.wrench(tip).force)

Raises fsm.Error for bad options or a bad model; the GIL is released inside compute() and
project().)")
      .def(py::init([](const Model& model, const Options& options) {
             return std::make_unique<BoundContactSolver>(model, options);
           }),
           py::arg("model"), py::arg("options") = Options{},
           "Sizes the solver for a SphereModel (allocates).")
      .def(py::init([](Sim& sim, const Options& options) {
             return std::make_unique<BoundContactSolver>(sim.model(), options);
           }),
           py::arg("simulation"), py::arg("options") = Options{},
           "Sizes the solver for a Simulation's model.")
      .def("refresh", &BoundContactSolver::refresh, py::arg("model"),
           "Re-reads the model after adding nodes or links, or changing radii.")
      .def(
          "add_instrument",
          [](BoundContactSolver& s, const Instrument& i) { return s.add_instrument(i); },
          py::arg("instrument"),
          R"(Adds a copy of an Instrument; returns its index. fsm.Error for a bad shape, pose or
friction. Invalidates Instrument references taken earlier with instrument(i).)")
      .def(
          "instrument",
          [](BoundContactSolver& s, Index i) -> Instrument& {
            if (i < 0 || i >= s.num_instruments())
              throw py::index_error("instrument " + std::to_string(i) + " of " +
                                    std::to_string(s.num_instruments()));
            return s.instrument(i);
          },
          py::arg("index"), py::return_value_policy::reference_internal,
          R"(Instrument i, by reference: set its pose and velocities here each frame. The reference
is valid until the next add_instrument().)")
      .def_property_readonly(
          "num_instruments", [](const BoundContactSolver& s) { return s.num_instruments(); },
          "how many instruments were added")
      .def_property_readonly("num_nodes", &BoundContactSolver::num_nodes,
                             "the model size the solver was sized for")
      .def_property_readonly(
          "options", [](const BoundContactSolver& s) { return s.options(); }, "a copy")
      .def(
          "compute",
          [](BoundContactSolver& s, const Model& model, py::array forces) {
            s.check(model, "model");
            auto f = force_map(forces, model.num_nodes());
            {
              py::gil_scoped_release release;
              s.compute(model, f);
            }
            return s.num_contacts();
          },
          py::arg("model"), py::arg("forces"),
          R"(Finds contacts at the model's state and *adds* their forces (N) to forces in place.

forces must be a float64, C-contiguous, writeable (|V|, 3) numpy array; pass
sim.external_forces, which is a view of the simulation's own array, so the next sim.step() sees
the contact forces. Returns the number of contacts recorded. fsm.Error for a wrong array (no
silent copy is ever made) or a model of another size.)")
      .def(
          "compute",
          [](BoundContactSolver& s, Sim& sim) {
            s.check(sim.model(), "simulation model");
            {
              py::gil_scoped_release release;
              s.compute(sim.model(), sim.external_forces());
            }
            return s.num_contacts();
          },
          py::arg("simulation"),
          "compute(sim.model, sim.external_forces): adds contact forces to the simulation's "
          "external forces.")
      .def(
          "project",
          [](BoundContactSolver& s, Model& model) {
            s.check(model, "model");
            py::gil_scoped_release release;
            return s.project(model);
          },
          py::arg("model"),
          R"(Moves every free sphere that penetrates an instrument out along the contact normal and
removes its velocity into the instrument (call after a step). Returns how many moved.)")
      .def(
          "wrench",
          [](const BoundContactSolver& s, Index i) {
            if (i < 0 || i >= s.num_instruments())
              throw py::index_error("instrument " + std::to_string(i) + " of " +
                                    std::to_string(s.num_instruments()));
            return s.wrench(i);
          },
          py::arg("index"),
          "The Wrench (force N, torque N m) tissue exerted on instrument i in the last compute().")
      .def_property_readonly(
          "contacts",
          [](const BoundContactSolver& s) {
            py::array out(contact_dtype(), std::vector<py::ssize_t>{py::ssize_t(s.num_contacts())});
            if (s.num_contacts() > 0)
              std::memcpy(out.mutable_data(), s.contacts(), sizeof(Contact) * s.num_contacts());
            return out;
          },
          R"(The contacts of the last compute() as a numpy structured array (a copy), fields:
sphere, instrument (-1 for sphere-sphere), other (the other sphere or -1) as int32; normal (3,),
depth (m), point (3,) (m) and force (3,) (N, on `sphere`; `other` gets -force) as float64.)")
      .def_property_readonly(
          "num_contacts", [](const BoundContactSolver& s) { return s.num_contacts(); },
          "contacts recorded by the last compute()")
      .def_property_readonly(
          "overflowed", [](const BoundContactSolver& s) { return s.overflowed(); },
          "True when the last compute() found more than max_contacts (their "
          "forces were still applied; only the list is short)")
      .def_property_readonly(
          "candidates", [](const BoundContactSolver& s) { return s.candidates(); },
          "candidate pairs from the broad phase in the last compute()")
      .def_property_readonly(
          "narrow_tests", [](const BoundContactSolver& s) { return s.narrow_tests(); },
          "narrow-phase tests in the last compute()")
      .def_property_readonly(
          "pair_list_rebuilds", [](const BoundContactSolver& s) { return s.pair_list_rebuilds(); },
          "part-contact pair list rebuilds since construction")
      .def("__repr__", [](const BoundContactSolver& s) {
        return "ContactSolver(" + std::to_string(s.num_nodes()) + " spheres, " +
               std::to_string(s.num_instruments()) + " instruments)";
      });

  // ---- triangle BVH ----------------------------------------------------------------------------
  py::class_<RayHit>(m, "RayHit", R"(A ray hit: face index, distance (m) and barycentrics.

u and v weight the face's vertices 1 and 2 (vertex 0 gets 1 - u - v).)")
      .def_readonly("face", &RayHit::face, "the face index (-1 from intersect_ray_triangle)")
      .def_readonly("distance", &RayHit::distance, "m from the ray origin")
      .def_readonly("u", &RayHit::u, "barycentric weight of the face's vertex 1")
      .def_readonly("v", &RayHit::v, "barycentric weight of the face's vertex 2")
      .def("__repr__", [](const RayHit& h) {
        return "RayHit(face=" + std::to_string(h.face) +
               ", distance=" + std::to_string(h.distance) + ", u=" + std::to_string(h.u) +
               ", v=" + std::to_string(h.v) + ")";
      });

  const auto faces_of = [](const py::array_t<Index, py::array::c_style | py::array::forcecast>& f) {
    if (f.ndim() != 2 || f.shape(1) != 3)
      throw Error("", "faces", "has shape " + shape_string(f) + ", wanted (n, 3)");
    FaceArray out(f.shape(0), 3);
    std::copy(f.data(), f.data() + f.size(), out.data());
    return out;
  };

  py::class_<Bvh>(m, "TriangleBvh", R"(An AABB tree over a moving triangle surface (picking,
surface contact).

TriangleBvh(vertices, faces): vertices (|V|, 3) in m, faces (|F|, 3) vertex indices. Build once,
refit(vertices) each frame as the surface deforms (same |V|), then ray_cast() or faces_near().
Raises fsm.Error naming a bad vertex or face. The tree keeps its own copy of the triangles.)")
      .def(
          py::init([faces_of](
                       const Array& vertices,
                       const py::array_t<Index, py::array::c_style | py::array::forcecast>& faces) {
            const Positions<Scalar> v = rows3(vertices, "vertices");
            const FaceArray f = faces_of(faces);
            auto bvh = std::make_unique<Bvh>();
            {
              py::gil_scoped_release release;
              bvh->build(v, f);
            }
            return bvh;
          }),
          py::arg("vertices"), py::arg("faces"))
      .def(
          "build",
          [faces_of](Bvh& bvh, const Array& vertices,
                     const py::array_t<Index, py::array::c_style | py::array::forcecast>& faces) {
            const Positions<Scalar> v = rows3(vertices, "vertices");
            const FaceArray f = faces_of(faces);
            py::gil_scoped_release release;
            bvh.build(v, f);
          },
          py::arg("vertices"), py::arg("faces"),
          "Rebuilds the tree for a new surface (fsm.Error for a bad one; the tree is then "
          "unchanged).")
      .def(
          "refit",
          [](Bvh& bvh, const Array& vertices) {
            if (vertices.ndim() != 2 || vertices.shape(0) != bvh.num_vertices() ||
                vertices.shape(1) != 3)
              throw Error("", "vertices",
                          "has shape " + shape_string(vertices) + ", wanted (" +
                              std::to_string(bvh.num_vertices()) + ", 3) as at build()");
            const Eigen::Map<const Positions<Scalar>> v(vertices.data(), vertices.shape(0), 3);
            py::gil_scoped_release release;
            bvh.refit(v);
          },
          py::arg("vertices"),
          "Moves the surface to new vertex positions (|V|, 3) in O(|F|); the topology is kept.")
      .def(
          "ray_cast",
          [](const Bvh& bvh, const Vector3<Scalar>& origin, const Vector3<Scalar>& direction,
             Scalar max_distance) -> std::optional<RayHit> {
            return bvh.ray_cast(origin, direction, max_distance);
          },
          py::arg("origin"), py::arg("direction"),
          py::arg("max_distance") = std::numeric_limits<Scalar>::infinity(),
          R"(The nearest hit of the ray origin + t direction (any non-zero length), or None.

Returns a RayHit with the Euclidean distance (m) from origin, 0 <= distance <= max_distance.
Faces are two-sided and the test is watertight; ties go to the smallest face index.)")
      .def(
          "faces_near",
          [](const Bvh& bvh, const Vector3<Scalar>& centre, Scalar radius) {
            const Index n = bvh.faces_near(centre, radius, nullptr, 0);
            py::array_t<Index> out(n);
            if (n > 0) bvh.faces_near(centre, radius, out.mutable_data(), n);
            return out;
          },
          py::arg("centre"), py::arg("radius"),
          R"(Indices (int32 array, tree order) of the faces whose triangle comes within radius (m) of
centre (m).)")
      .def_property_readonly("num_faces", &Bvh::num_faces, "|F|")
      .def_property_readonly("num_vertices", &Bvh::num_vertices, "|V| that refit() expects")
      .def_property_readonly("depth", &Bvh::depth, "depth of the deepest leaf")
      .def("__repr__", [](const Bvh& b) {
        return "TriangleBvh(" + std::to_string(b.num_faces()) + " faces, depth " +
               std::to_string(b.depth()) + ")";
      });

  m.def(
      "intersect_ray_triangle",
      [](const Vector3<Scalar>& origin, const Vector3<Scalar>& direction, const Vector3<Scalar>& a,
         const Vector3<Scalar>& b, const Vector3<Scalar>& c,
         Scalar max_t) -> std::optional<RayHit> {
        return fc::intersect_ray_triangle(origin, direction, a, b, c, max_t);
      },
      py::arg("origin"), py::arg("direction"), py::arg("a"), py::arg("b"), py::arg("c"),
      py::arg("max_t") = std::numeric_limits<Scalar>::infinity(),
      R"(Watertight ray-triangle test (Woop, Benthin and Wald 2013): a RayHit whose distance is the
ray parameter t (hit = origin + t direction) and face -1, or None.)");
  m.def("closest_point_on_triangle", &fc::closest_point_on_triangle<Scalar>, py::arg("p"),
        py::arg("a"), py::arg("b"), py::arg("c"),
        "The point (m) of the closed triangle (a, b, c) nearest to p (Ericson 2005, 5.1.5).");
}

}  // namespace fsm::python
