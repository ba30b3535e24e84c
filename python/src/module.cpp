// The _fsm extension module: one define_<concept>() per binding file.

#include "common.hpp"

PYBIND11_MODULE(_fsm, m) {
  namespace py = pybind11;
  m.doc() = R"(libfsm: filled-sphere soft-tissue simulation (compiled core; import fsm instead).)";
  m.attr("__version__") = fsm::version;
  // fsm::Error derives from std::runtime_error; Python sees fsm.Error(RuntimeError).
  py::register_exception<fsm::Error>(m, "Error", PyExc_RuntimeError).attr("__doc__") =
      R"(The one exception of libfsm (a RuntimeError): its message names the file, the part or
argument, and the reason, e.g. "instrument 'probe': friction must be non-negative".)";
  fsm::python::define_material(m);
  fsm::python::define_sphere_model(m);
  fsm::python::define_tetrahedral_mesh(m);
  fsm::python::define_integrators(m);
  fsm::python::define_simulation(m);
  fsm::python::define_tissue_model(m);
  fsm::python::define_shapes(m);
  fsm::python::define_contact(m);
  fsm::python::define_triangle_bvh(m);
  fsm::python::define_haptic_device(m);
  fsm::python::define_scripted_device(m);
  fsm::python::define_servo_loop(m);
  fsm::python::define_volume_term(m);
}
