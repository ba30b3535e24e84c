// The _fsm extension module: one define_<concept>() per binding file.

#include "common.hpp"

PYBIND11_MODULE(_fsm, m) {
  namespace py = pybind11;
  m.doc() = R"(libfsm: filled-sphere soft-tissue simulation (compiled core; import fsm instead).)";
  m.attr("__version__") = fsm::version;
  // fsm::Error derives from std::runtime_error; Python sees fsm.Error(RuntimeError).
  static py::exception<fsm::Error> error(m, "Error", PyExc_RuntimeError);
  error.attr("__doc__") =
      R"(The one exception of libfsm (a RuntimeError): its message names the file, the part or
argument, and the reason, e.g. "instrument 'probe': friction must be non-negative". Running out
of memory inside the library is an fsm.Error too ("out of memory: ...").)";
  // Everything the library throws reaches Python as fsm.Error, as promised: its own errors, and
  // what the standard library throws underneath (bad_alloc for an allocation the machine cannot
  // make, length_error, ...). pybind11's own (IndexError for an index, TypeError for arguments)
  // pass through.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const fsm::Error& e) {
      error(e.what());
    } catch (const py::builtin_exception&) {
      throw;
    } catch (const py::error_already_set&) {
      throw;
    } catch (const std::bad_alloc&) {
      error("out of memory: an allocation the machine cannot make (check the sizes asked for)");
    } catch (const std::exception& e) {
      error((std::string("internal error: ") + e.what()).c_str());
    }
  });
  fsm::python::define_material(m);
  fsm::python::define_cutting(m);
  fsm::python::define_sphere_model(m);
  fsm::python::define_tetrahedral_mesh(m);
  fsm::python::define_integrators(m);
  fsm::python::define_simulation(m);
  fsm::python::define_tissue_model(m);
  fsm::python::define_shapes(m);
  fsm::python::define_contact(m);
  fsm::python::define_grasper(m);
  fsm::python::define_triangle_bvh(m);
  fsm::python::define_haptic_device(m);
  fsm::python::define_scripted_device(m);
  fsm::python::define_servo_loop(m);
  fsm::python::define_volume_term(m);
}
