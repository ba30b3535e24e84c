// The _fsm extension module: one define_<concept>() per binding file.

#include "common.hpp"

PYBIND11_MODULE(_fsm, m) {
  namespace py = pybind11;
  m.doc() = R"(libfsm: filled-sphere soft-tissue simulation (compiled core; import fsm instead).)";
  m.attr("__version__") = fsm::version;
  // fsm::Error derives from std::runtime_error; Python sees fsm.Error(RuntimeError).
  py::register_exception<fsm::Error>(m, "Error", PyExc_RuntimeError);
  fsm::python::define_material(m);
  fsm::python::define_sphere_model(m);
  fsm::python::define_tetrahedral_mesh(m);
  fsm::python::define_integrators(m);
  fsm::python::define_simulation(m);
  fsm::python::define_tissue_model(m);
  fsm::python::define_collision(m);
}
