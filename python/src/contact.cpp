// collision/contact.hpp: instruments, contact options, the ContactSolver and its wrenches.
// compute() writes contact forces straight into the caller's numpy array (no copy), so the
// array must already be float64, C-contiguous, writeable and |V| x 3: Simulation.external_forces
// is exactly that.

#include <cstring>
#include <vector>

#include "common.hpp"
#include "fsm/collision/contact.hpp"

namespace fsm::python {

namespace {
namespace fc = fsm::collision;
using Pose = fc::Pose<Scalar>;
using Shape = fc::Shape<Scalar>;
using Instrument = fc::Instrument<Scalar>;
using Options = fc::ContactOptions<Scalar>;
using Wrench = fc::Wrench<Scalar>;
using Contact = fc::Contact<Scalar>;
using Solver = fc::ContactSolver<Scalar>;
using Model = SphereModel<Scalar>;
using Sim = Simulation<Scalar>;

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

// What compute() and project() report as `false` / -1, in words.
Error size_error(const Solver& s, const Model& model, const char* what) {
  return Error("", what,
               "has " + std::to_string(model.num_nodes()) +
                   " spheres but the solver was sized for " + std::to_string(s.num_nodes()) +
                   " (call refresh(model) after growing the model)");
}

static_assert(sizeof(Index) == 4, "the contact dtype says int32");
}  // namespace

void define_contact(py::module_& m) {
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

ContactOptions(stiffness_ratio=100, damping_ratio=0.5, friction_speed=1e-3,
               tetrahedral_surface=True, part_contact=True, self_contact=False, part_friction=0,
               max_contacts=4096, spatial_hash=True, verlet_skin=0.002, part_stiffness_ratio=1,
               part_contact_onset=0.1, face_contact=False, face_sample_spacing=0.001,
               detection_margin=0.25)

stiffness_ratio: penalty stiffness as a multiple of the sphere's own tissue stiffness (the row sum
of its links' and elements' rest stiffness), so the penetration is a fixed small share of the
deformation at any resolution. part_stiffness_ratio: the same between parts (default 1: as stiff
as the tissue; parts touching at rest sit at the threshold). part_contact_onset: the fraction of
a part contact's threshold over which its force ramps in (quadratically; 0: the plain penalty).
damping_ratio zeta: contact damping c = 2 zeta sqrt(k m).
friction_speed (m/s): regularisation of Coulomb friction. tetrahedral_surface: vertices of
tetrahedra (on the organ's surface) meet instruments at their centres, other spheres at their
radius; False: every sphere at its radius (the paper's contact). part_contact: spheres of different
regions collide; self_contact: spheres of one region far apart at rest collide (folding).
part_friction: Coulomb coefficient between parts. max_contacts: length of the contact list.
spatial_hash: False tests every sphere (the reference). verlet_skin (m): slack of the part-contact
pair list. face_contact: with tetrahedral_surface, instruments meet tetrahedral parts through sample
points on their boundary faces (at most face_sample_spacing apart, m) instead of at the vertices,
so a probe smaller than the vertex spacing cannot slip between vertices; for smooth instruments
(spheres, capsules), not flat ends or boxes, whose edges it cannot wrap. detection_margin: spheres
within this fraction of their radius outside an instrument are handed to the implicit step at zero
force and join it if the step carries them in (0: penetrating spheres only). Validated when a
ContactSolver is made.)")
      .def(py::init([](Scalar stiffness_ratio, Scalar damping_ratio, Scalar friction_speed,
                       bool tetrahedral_surface, bool part_contact, bool self_contact,
                       Scalar part_friction, Index max_contacts, bool spatial_hash,
                       Scalar verlet_skin, Scalar part_stiffness_ratio, Scalar part_contact_onset,
                       bool face_contact, Scalar face_sample_spacing, Scalar detection_margin) {
             Options o;
             o.detection_margin = detection_margin;
             o.face_contact = face_contact;
             o.face_sample_spacing = face_sample_spacing;
             o.part_contact_onset = part_contact_onset;
             o.stiffness_ratio = stiffness_ratio;
             o.part_stiffness_ratio = part_stiffness_ratio;
             o.damping_ratio = damping_ratio;
             o.friction_speed = friction_speed;
             o.tetrahedral_surface = tetrahedral_surface;
             o.part_contact = part_contact;
             o.self_contact = self_contact;
             o.part_friction = part_friction;
             o.max_contacts = max_contacts;
             o.spatial_hash = spatial_hash;
             o.verlet_skin = verlet_skin;
             return o;
           }),
           py::arg("stiffness_ratio") = 100.0, py::arg("damping_ratio") = 0.5,
           py::arg("friction_speed") = 1e-3, py::arg("tetrahedral_surface") = true,
           py::arg("part_contact") = true, py::arg("self_contact") = false,
           py::arg("part_friction") = 0.0, py::arg("max_contacts") = 4096,
           py::arg("spatial_hash") = true, py::arg("verlet_skin") = 0.002,
           py::arg("part_stiffness_ratio") = 1.0, py::arg("part_contact_onset") = 0.1,
           py::arg("face_contact") = false, py::arg("face_sample_spacing") = 0.001,
           py::arg("detection_margin") = 0.25)
      .def_readwrite("stiffness_ratio", &Options::stiffness_ratio,
                     "contact stiffness / the sphere's tissue stiffness")
      .def_readwrite("part_stiffness_ratio", &Options::part_stiffness_ratio,
                     "part contact stiffness / the softer sphere's tissue stiffness")
      .def_readwrite("part_contact_onset", &Options::part_contact_onset,
                     "fraction of a part contact's threshold over which its force ramps in")
      .def_readwrite("damping_ratio", &Options::damping_ratio, "zeta in c = 2 zeta sqrt(k m)")
      .def_readwrite("friction_speed", &Options::friction_speed, "m/s")
      .def_readwrite("tetrahedral_surface", &Options::tetrahedral_surface,
                     "tetrahedra's vertices meet instruments at their centres")
      .def_readwrite("part_contact", &Options::part_contact, "spheres of different regions collide")
      .def_readwrite("self_contact", &Options::self_contact,
                     "spheres of one region far apart at rest collide (folding)")
      .def_readwrite("part_friction", &Options::part_friction, "Coulomb coefficient between parts")
      .def_readwrite("max_contacts", &Options::max_contacts,
                     "length of the contact list (allocated once)")
      .def_readwrite("spatial_hash", &Options::spatial_hash,
                     "False tests every sphere (the reference the tests compare with)")
      .def_readwrite("verlet_skin", &Options::verlet_skin, "m")
      .def_readwrite("face_contact", &Options::face_contact,
                     "instruments meet tetrahedral parts at sample points on their boundary faces")
      .def_readwrite("face_sample_spacing", &Options::face_sample_spacing,
                     "m: largest spacing of a boundary face's sample points")
      .def_readwrite("detection_margin", &Options::detection_margin,
                     "near contacts: fraction of the sphere's radius outside an instrument");

  // ---- the solver ------------------------------------------------------------------------------
  py::class_<Solver>(m, "ContactSolver",
                     R"(Contact detection and response for one SphereModel.

ContactSolver(model, options=ContactOptions())   # model: a SphereModel, e.g. sim.model
ContactSolver(simulation, options=ContactOptions())

Each step: solver.step(sim, dt), which is solver.compute(sim) (find the contacts, instrument-sphere
and part-part, with a spatial hash and closed forms or GJK, and hand them to the simulation's
force model as penalty contacts: implicit Euler takes their stiffness into its solve), then
sim.step(dt), then solver.collect(sim) (their end-of-step forces into contacts and each
instrument's wrench, minus the sum of what it applies). compute(model, forces) instead adds the
forces at the current state to an array (analysis, or your own integrator).

    solver = fsm.ContactSolver(sim)
    tip = solver.add_instrument(fsm.Instrument(fsm.SphereShape(0.002), fsm.Pose((0, 0, 0.01))))
    for _ in range(100):
        solver.instrument(tip).pose.position[2] -= 1e-5
        solver.step(sim, 1e-3)
    print(solver.wrench(tip).force)

Raises fsm.Error for bad options or a bad model; the GIL is released inside compute() and
project().)")
      .def(py::init([](const Model& model, const Options& options) {
             return std::make_unique<Solver>(model, options);
           }),
           py::arg("model"), py::arg("options") = Options{},
           "Sizes the solver for a SphereModel (allocates).")
      .def(py::init([](Sim& sim, const Options& options) {
             return std::make_unique<Solver>(sim.model(), sim.forces(), options);
           }),
           py::arg("simulation"), py::arg("options") = Options{},
           "Sizes the solver for a Simulation's model.")
      .def("refresh", &Solver::refresh, py::arg("model"),
           "Re-reads the model after adding nodes or links, or changing radii.")
      .def(
          "add_instrument", [](Solver& s, const Instrument& i) { return s.add_instrument(i); },
          py::arg("instrument"),
          R"(Adds a copy of an Instrument; returns its index. fsm.Error for a bad shape, pose or
friction. Invalidates Instrument references taken earlier with instrument(i).)")
      .def(
          "instrument",
          [](Solver& s, Index i) -> Instrument& {
            if (i < 0 || i >= s.num_instruments())
              throw py::index_error("instrument " + std::to_string(i) + " of " +
                                    std::to_string(s.num_instruments()));
            return s.instrument(i);
          },
          py::arg("index"), py::return_value_policy::reference_internal,
          R"(Instrument i, by reference: set its pose and velocities here each frame. The reference
is valid until the next add_instrument().)")
      .def_property_readonly(
          "num_instruments", [](const Solver& s) { return s.num_instruments(); },
          "how many instruments were added")
      .def_property_readonly("num_nodes", &Solver::num_nodes,
                             "the sphere count the solver was sized for")
      .def_property_readonly(
          "options", [](const Solver& s) { return s.options(); }, "a copy")
      .def(
          "compute",
          [](Solver& s, const Model& model, py::array forces) {
            auto f = force_map(forces, model.num_nodes());
            bool sized = false;
            {
              py::gil_scoped_release release;
              sized = s.compute(model, f);
            }
            if (!sized) throw size_error(s, model, "model");
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
          [](Solver& s, Sim& sim) {
            bool sized = false;
            {
              py::gil_scoped_release release;
              sized = s.compute(sim.model(), sim.forces());
            }
            if (!sized) throw size_error(s, sim.model(), "simulation model");
            return s.num_contacts();
          },
          py::arg("simulation"),
          R"(Finds contacts at the simulation's state and gives them to its force model (replacing
its contacts) for the next sim.step(); contacts and wrenches hold the forces at the current state
until collect(). Returns the number of contacts.)")
      .def(
          "collect",
          [](Solver& s, const Sim& sim) {
            if (!s.collect(sim.forces()))
              throw Error("", "contacts",
                          "collect() needs the simulation that compute(simulation) filled");
            return s.num_contacts();
          },
          py::arg("simulation"),
          "After sim.step(): the contacts' end-of-step forces into contacts and the wrenches.")
      .def(
          "step",
          [](Solver& s, Sim& sim, Scalar dt) {
            StepReport<Scalar> r;
            bool sized = false;
            {
              py::gil_scoped_release release;
              sized = s.compute(sim.model(), sim.forces());
              if (sized) {
                r = sim.step(dt);
                s.collect(sim.forces());
              }
            }
            if (!sized) throw size_error(s, sim.model(), "simulation model");
            return r;
          },
          py::arg("simulation"), py::arg("dt"),
          "compute(sim), sim.step(dt), collect(sim); returns the StepReport.")
      .def(
          "project",
          [](Solver& s, Model& model) {
            Index moved = 0;
            {
              py::gil_scoped_release release;
              moved = s.project(model);
            }
            if (moved < 0) throw size_error(s, model, "model");
            return moved;
          },
          py::arg("model"),
          R"(Moves every free sphere that penetrates an instrument out along the contact normal and
removes its velocity into the instrument (call after a step). Returns how many moved.)")
      .def(
          "wrench",
          [](const Solver& s, Index i) {
            if (i < 0 || i >= s.num_instruments())
              throw py::index_error("instrument " + std::to_string(i) + " of " +
                                    std::to_string(s.num_instruments()));
            return s.wrench(i);
          },
          py::arg("index"),
          "The Wrench (force N, torque N m) tissue exerted on instrument i in the last compute().")
      .def_property_readonly(
          "contacts",
          [](const Solver& s) {
            py::array out(contact_dtype(), std::vector<py::ssize_t>{py::ssize_t(s.num_contacts())});
            if (s.num_contacts() > 0)
              std::memcpy(out.mutable_data(), s.contacts(), sizeof(Contact) * s.num_contacts());
            return out;
          },
          R"(The contacts of the last compute() as a numpy structured array (a copy), fields:
sphere, instrument (-1 for sphere-sphere), other (the other sphere or -1) as int32; normal (3,),
depth (m), point (3,) (m) and force (3,) (N, on `sphere`; `other` gets -force) as float64.)")
      .def_property_readonly(
          "num_contacts", [](const Solver& s) { return s.num_contacts(); },
          "contacts recorded by the last compute()")
      .def_property_readonly(
          "overflowed", [](const Solver& s) { return s.overflowed(); },
          "True when the last compute() found more than max_contacts (their "
          "forces were still applied; only the list is short)")
      .def_property_readonly(
          "candidates", [](const Solver& s) { return s.candidates(); },
          "candidate pairs from the broad phase in the last compute()")
      .def_property_readonly(
          "narrow_tests", [](const Solver& s) { return s.narrow_tests(); },
          "narrow-phase tests in the last compute()")
      .def_property_readonly(
          "pair_list_rebuilds", [](const Solver& s) { return s.pair_list_rebuilds(); },
          "part-contact pair list rebuilds since construction")
      .def("__repr__", [](const Solver& s) {
        return "ContactSolver(" + std::to_string(s.num_nodes()) + " spheres, " +
               std::to_string(s.num_instruments()) + " instruments)";
      });
}

}  // namespace fsm::python
