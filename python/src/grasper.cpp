// The grasper (fsm/collision/grasper.hpp).

#include "common.hpp"

namespace fsm::python {

void define_grasper(py::module_& m) {
  namespace fc = fsm::collision;
  using O = fc::GrasperOptions<Scalar>;
  using G = fc::Grasper<Scalar>;
  using Sim = Simulation<Scalar>;
  py::class_<O>(m, "GrasperOptions", R"(A grasper's jaws and grip.

GrasperOptions(jaw_length=0.012, jaw_width=0.004, grip_angle=0.1, release_angle=0.2,
               stiffness=1e4, damping=0.5, max_held=64, margin=0.001)

Lengths in m, angles in rad, stiffness in N/m and damping in N s/m per held sphere. In the
grasper's frame the jaws hinge at the origin, reach along +x and open in the x-z plane.)")
      .def(py::init([](Scalar length, Scalar width, Scalar grip, Scalar release, Scalar k, Scalar c,
                       Index max_held, Scalar margin) {
             O o;
             o.jaw_length = length;
             o.jaw_width = width;
             o.grip_angle = grip;
             o.release_angle = release;
             o.stiffness = k;
             o.damping = c;
             o.max_held = max_held;
             o.margin = margin;
             o.validate();
             return o;
           }),
           py::arg("jaw_length") = O{}.jaw_length, py::arg("jaw_width") = O{}.jaw_width,
           py::arg("grip_angle") = O{}.grip_angle, py::arg("release_angle") = O{}.release_angle,
           py::arg("stiffness") = O{}.stiffness, py::arg("damping") = O{}.damping,
           py::arg("max_held") = O{}.max_held, py::arg("margin") = O{}.margin)
      .def_readonly("jaw_length", &O::jaw_length, "m, from the hinge along +x")
      .def_readonly("jaw_width", &O::jaw_width, "m, along y")
      .def_readonly("grip_angle", &O::grip_angle, "rad: closing past it grips")
      .def_readonly("release_angle", &O::release_angle, "rad: opening past it releases")
      .def_readonly("stiffness", &O::stiffness, "N/m per held sphere")
      .def_readonly("damping", &O::damping, "N s/m per held sphere")
      .def_readonly("max_held", &O::max_held, "at most this many spheres held")
      .def_readonly("margin", &O::margin,
                    "m: a sphere whose centre is this close to the space between the jaws is held");

  py::class_<fc::GraspEvent>(m, "GraspEvent", "What Grasper.update() did.")
      .def_readonly("grasped", &fc::GraspEvent::grasped, "spheres gripped by this update")
      .def_readonly("released", &fc::GraspEvent::released, "spheres let go by this update")
      .def_readonly("invalid", &fc::GraspEvent::invalid,
                    "the pose, velocities or angle were not finite: nothing changed");

  py::class_<G>(m, "Grasper", R"(Two jaws that hold the spheres they close on.

Grasper(sim, opening, options=GrasperOptions()): `opening` is the jaws' angle at start (rad);
fsm.Error if it is at or below grip_angle (closed jaws at start). Each step: update(sim, pose,
opening, velocity, angular_velocity) before sim.step(dt), then wrench(sim) for the force on the
jaws. The grasper owns the simulation's held-node list.)")
      .def(py::init([](Sim& sim, Scalar opening, const O& options) {
             return G(sim.model(), sim.forces(), options, opening);
           }),
           py::arg("sim"), py::arg("opening"), py::arg("options") = O{})
      .def(
          "update",
          [](G& g, Sim& sim, const fc::Pose<Scalar>& pose, Scalar opening,
             const Vector3<Scalar>& velocity, const Vector3<Scalar>& angular_velocity) {
            return g.update(sim.model(), sim.forces(), pose, velocity, angular_velocity, opening);
          },
          py::arg("sim"), py::arg("pose"), py::arg("opening"),
          py::arg("velocity") = Vector3<Scalar>::Zero(),
          py::arg("angular_velocity") = Vector3<Scalar>::Zero(),
          "Moves the jaws (pose, m/s, rad/s) and sets their opening (rad): closing past the grip "
          "angle holds what lies between them, opening past the release angle lets go.")
      .def(
          "wrench",
          [](const G& g, const Sim& sim, Scalar step) { return g.wrench(sim.forces(), step); },
          py::arg("sim"), py::arg("step") = 0.0,
          "The held spheres' reaction on the jaws after the last step (a Wrench); with `step` (s) "
          "its stiffness is what the jaws feel over a step as the spheres follow.")
      .def_property_readonly("held", &G::held, "Indices of the spheres held now.")
      .def_property_readonly("holding", &G::holding, "True while spheres are held")
      .def_property_readonly("opening", &G::opening, "the jaws' last opening angle (rad)");
}

}  // namespace fsm::python
