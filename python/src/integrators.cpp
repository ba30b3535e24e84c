// Integrators, their registry and the stability bounds.

#include <cmath>

#include "common.hpp"

namespace fsm::python {

void define_integrators(py::module_& m) {
  using I = Integrator<Scalar>;
  using SB = SpectralBound<Scalar>;
  py::class_<SB>(m, "SpectralBound",
                 R"(Bounds a model's stability depends on (SI: rad/s, 1/s, s).)")
      .def(py::init([](Scalar omega, Scalar c) { return SB::oscillator(omega, c); }),
           py::arg("omega"), py::arg("damping_rate"),
           "The bound of one oscillator q'' = -omega^2 q - c q'.")
      .def_readwrite("omega_max", &SB::omega_max,
                     "bound on the highest angular eigenfrequency (rad/s)")
      .def_readwrite("damping_max", &SB::damping_max, "bound on the highest damping rate (1/s)")
      .def_readwrite("retardation_min", &SB::retardation_min,
                     "shortest retardation time eta / E of a link (s)");
  m.def(
      "spectral_bound",
      [](const SphereModel<Scalar>& model, const std::string& damping) {
        return spectral_bound(model, damping == "full_relative_velocity"
                                         ? DampingModel::full_relative_velocity
                                         : DampingModel::along_link);
      },
      py::arg("model"), py::arg("damping") = "along_link",
      "Block-Gershgorin bounds on the highest eigenfrequency and damping rate at rest.");

  py::class_<I>(m, "Integrator", R"(Base of the time-stepping schemes (step(model, forces, dt)).)")
      .def_property_readonly(
          "name", [](const I& i) { return std::string(i.name()); }, "the scheme's registry name")
      .def_property_readonly("order", &I::order, "order of accuracy in the time step")
      .def("stable_time_step", &I::stable_time_step, py::arg("bound"),
           "Largest stable step (s) for a SpectralBound; 0 = none, inf = any.")
      .def("__repr__", [](const I& i) { return "<fsm." + std::string(i.name()) + " integrator>"; });
  py::class_<ImprovedEulerIntegrator<Scalar>, I>(
      m, "ImprovedEulerIntegrator",
      "The paper's eq. 10: v+ = v + h a(x, v), x+ = x + h/2 (v + v+). First order.")
      .def(py::init<>());
  py::class_<HeunIntegrator<Scalar>, I>(
      m, "HeunIntegrator", "Heun's method (eq. 9): explicit RK2, two force evaluations.")
      .def(py::init<>());
  py::class_<SymplecticEulerIntegrator<Scalar>, I>(
      m, "SymplecticEulerIntegrator", "v+ = v + h a(x, v), x+ = x + h v+. First order.")
      .def(py::init<>());

  using IE = ImplicitEulerIntegrator<Scalar>;
  py::class_<IE, I>(m, "ImplicitEulerIntegrator",
                    R"(Linearised backward Euler (Baraff and Witkin 1998); stable at any step.

solver: "conjugate_gradient" (matrix-free, allocation-free; default), "eigen_ldlt" or "eigen_lu"
(assembled, exact; eigen_lu uses the exact non-symmetric Jacobian).
jacobian: "definite" (default), "symmetric" or "exact".
tolerance: CG stops when its residual, weighted by the preconditioner, falls to this fraction
of the right-hand side's (sqrt(r P^-1 r) <= tol sqrt(b P^-1 b)); max_iterations: CG cap per solve.
max_contact_passes: solves per step while the set of penetrating contacts changes (1: keep the
start's set).
preconditioner: CG's, "block_jacobi" (3 x 3 diagonal blocks; default) or "jacobi".
extrapolate_warm_start: CG starts from the velocity change extrapolated from the last two steps
(default True; False: from the last step's). The same solution to the tolerance, in fewer
iterations under smooth loading.
velocity_tolerance: CG also stops once the velocity change is solved to about this speed in m/s
(r^T P^-1 r <= v_tol^2 * the moving nodes' mass; default 1e-9; 0: the relative test alone). A
tissue at rest leaves a right-hand side of round-off, which the relative test alone chases.)")
      .def(
          py::init([](const std::string& solver, const std::string& jacobian, Scalar tolerance,
                      int max_iterations, int max_contact_passes, const std::string& preconditioner,
                      bool extrapolate_warm_start, Scalar velocity_tolerance) {
            typename IE::Options o;
            if (preconditioner == "block_jacobi")
              o.preconditioner = IE::Preconditioner::block_jacobi;
            else if (preconditioner == "jacobi")
              o.preconditioner = IE::Preconditioner::jacobi;
            else
              throw Error("", "preconditioner '" + preconditioner + "'",
                          "unknown; valid: block_jacobi, jacobi");
            if (solver == "conjugate_gradient")
              o.solver = IE::Solver::conjugate_gradient;
            else if (solver == "eigen_ldlt")
              o.solver = IE::Solver::eigen_ldlt;
            else if (solver == "eigen_lu")
              o.solver = IE::Solver::eigen_lu;
            else
              throw Error("", "solver '" + solver + "'",
                          "unknown; valid: conjugate_gradient, eigen_ldlt, eigen_lu");
            if (jacobian == "definite")
              o.jacobian = JacobianForm::definite;
            else if (jacobian == "symmetric")
              o.jacobian = JacobianForm::symmetric;
            else if (jacobian == "exact")
              o.jacobian = JacobianForm::exact;
            else
              throw Error("", "jacobian '" + jacobian + "'",
                          "unknown; valid: definite, symmetric, exact");
            if (!(tolerance > 0) || max_iterations < 1 || max_contact_passes < 1)
              throw Error("", "ImplicitEulerIntegrator",
                          "tolerance, max_iterations and max_contact_passes must be positive");
            if (!(velocity_tolerance >= 0) || !std::isfinite(velocity_tolerance))
              throw Error("", "ImplicitEulerIntegrator",
                          "velocity_tolerance must be finite and non-negative");
            o.tolerance = tolerance;
            o.max_iterations = max_iterations;
            o.max_contact_passes = max_contact_passes;
            o.extrapolate_warm_start = extrapolate_warm_start;
            o.velocity_tolerance = velocity_tolerance;
            return IE(o);
          }),
          py::arg("solver") = "conjugate_gradient", py::arg("jacobian") = "definite",
          py::arg("tolerance") = 1e-6, py::arg("max_iterations") = 200,
          py::arg("max_contact_passes") = 3, py::arg("preconditioner") = "block_jacobi",
          py::arg("extrapolate_warm_start") = true,
          py::arg("velocity_tolerance") = typename IE::Options{}.velocity_tolerance)
      .def_property_readonly(
          "preconditioner",
          [](const IE& ie) {
            return ie.options().preconditioner == IE::Preconditioner::jacobi ? "jacobi"
                                                                             : "block_jacobi";
          },
          "CG's preconditioner")
      .def_property_readonly(
          "tolerance", [](const IE& ie) { return ie.options().tolerance; },
          "CG's relative tolerance on the preconditioner-weighted residual")
      .def_property_readonly(
          "max_iterations", [](const IE& ie) { return ie.options().max_iterations; },
          "CG iteration cap per solve")
      .def_property_readonly(
          "max_contact_passes", [](const IE& ie) { return ie.options().max_contact_passes; },
          "solves per step while the contact set changes")
      .def_property_readonly(
          "extrapolate_warm_start",
          [](const IE& ie) { return ie.options().extrapolate_warm_start; },
          "whether CG starts from the velocity change extrapolated from the last two steps")
      .def_property_readonly(
          "velocity_tolerance", [](const IE& ie) { return ie.options().velocity_tolerance; },
          "the speed (m/s) to which CG solves the velocity change at least (0: none)");

  m.def("integrator_names", &integrator_names, "Names accepted wherever an integrator is chosen.");
  m.def(
      "make_integrator", [](const std::string& name) { return make_integrator<Scalar>(name); },
      py::arg("name"), "The integrator of that name; fsm.Error lists the valid names otherwise.");
}

}  // namespace fsm::python
