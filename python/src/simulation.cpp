// Simulation: stepping with divergence detection; the GIL is released while C++ steps.

#include "common.hpp"

namespace fsm::python {

namespace {
using Sim = Simulation<Scalar>;

std::unique_ptr<Integrator<Scalar>> to_integrator(const py::object& spec) {
  if (py::isinstance<py::str>(spec)) return make_integrator<Scalar>(spec.cast<std::string>());
  if (py::isinstance<Integrator<Scalar>>(spec))
    return spec.cast<const Integrator<Scalar>&>().clone();
  throw Error(
      "", "integrator", "must be a name (" + [] {
        std::string s;
        for (const auto& n : integrator_names()) s += (s.empty() ? "" : ", ") + n;
        return s;
      }() + ") or an fsm.Integrator");
}

DampingModel to_damping(const std::string& name) {
  if (name == "along_link") return DampingModel::along_link;
  if (name == "full_relative_velocity") return DampingModel::full_relative_velocity;
  throw Error("", "damping '" + name + "'", "unknown; valid: along_link, full_relative_velocity");
}

StrainSmoothing to_smoothing(const std::string& name) {
  for (const StrainSmoothing s : {StrainSmoothing::element, StrainSmoothing::face,
                                  StrainSmoothing::edge, StrainSmoothing::node})
    if (name == to_string(s)) return s;
  throw Error("", "strain_smoothing '" + name + "'", "unknown; valid: element, face, edge, node");
}
}  // namespace

void define_simulation(py::module_& m) {
  using R = StepReport<Scalar>;
  py::class_<R>(m, "StepReport", "What Simulation.step() reports.")
      .def_property_readonly(
          "status", [](const R& r) { return std::string(to_string(r.status)); },
          "'ok', 'recovered', 'diverged' or 'invalid_time_step'")
      .def_readonly(
          "substeps", &R::substeps,
          "integrator steps run, rejected attempts included (1 normally; 1 + 2 + ... + 2^k after k "
          "halvings, fewer where a solver broke down)")
      .def_readonly("solver_iterations", &R::solver_iterations,
                    "linear-solver iterations (CG) summed over sub-steps; 0 for explicit schemes")
      .def_readonly("unconverged_solves", &R::unconverged_solves,
                    "sub-steps with a linear solve (any contact pass) stopped at its iteration "
                    "cap short of its tolerance (taken anyway if the divergence checks passed)")
      .def_readonly("energy", &R::energy, "J after the step (nan when not checked)")
      .def_readonly("energy_gain", &R::energy_gain,
                    "J the step ended with beyond its start energy plus the work done on it "
                    "(negative when it removed energy; nan when not checked)")
      .def_readonly("energy_gain_retries", &R::energy_gain_retries,
                    "sub-step levels run again because they gained more than energy_gain_strain "
                    "allows")
      .def_readonly("inverted_elements", &R::inverted_elements,
                    "continuum elements with J <= 0 after the step (0 without the law)")
      .def_readonly("softened_contacts", &R::softened_contacts,
                    "penalty contacts capped to an explicit step's limit (0 with implicit Euler)")
      .def_readonly("torn", &R::torn, "TopologyChange: what the step tore")
      .def_property_readonly("advanced", &R::advanced,
                             "True when the state moved on (status 'ok' or 'recovered')")
      .def("__repr__", [](const R& r) {
        return "StepReport(status='" + std::string(to_string(r.status)) +
               "', substeps=" + std::to_string(r.substeps) + ")";
      });

  using E = EnergyReport<Scalar>;
  py::class_<E>(m, "EnergyReport", "Energy account in J.")
      .def_readonly("kinetic", &E::kinetic, "kinetic energy 1/2 sum m v^2 (J)")
      .def_readonly("elastic", &E::elastic, "elastic energy stored in the links (J)")
      .def_readonly("gravity", &E::gravity, "gravitational potential energy (J)")
      .def_readonly("external_work", &E::external_work,
                    "work done by external forces since the reference was taken (J)")
      .def_readonly("reference", &E::reference, "total energy when the reference was taken (J)")
      .def_property_readonly("total", &E::total, "kinetic + elastic + gravity (J)")
      .def_property_readonly("budget", &E::budget,
                             "reference + external_work (J): what total may not exceed");

  py::class_<Sim>(m, "Simulation", R"(A SphereModel stepped in time, with divergence detection.

Simulation(model, integrator="implicit_euler", gravity=(0, 0, -9.81), damping="along_link",
           threads=1, check_energy=True, energy_tolerance=1.0, max_substep_halvings=0,
           drag=0.0, element_tangent_quality=0.3, strain_smoothing="element",
           smoothing_element_share=0.1, flutter_guard=True, reuse_end_forces=True,
           adaptive_threads=False, check_step_energy=True, energy_gain_strain=0.005)

The model is copied in; sim.model is the simulated one. integrator is a name from
fsm.integrator_names() or an fsm.Integrator instance (copied). drag (1/s) is the surroundings'
mass-proportional damping. element_tangent_quality: continuum elements of shape quality below it
(6 sqrt(2) V / l_rms^3, 1 for a regular tetrahedron) get the exact-shape element tangent in the
implicit solve (0 = none, above 1 = all; strongly strained elements get it whatever this is).
strain_smoothing: how the continuum law measures the deviatoric strain, "element" (each
tetrahedron's own), or averaged over the tetrahedra at each "face", "edge" or "node" (softer,
closer to the continuum under bulk loads, softer under a point load; docs/physics.md section 11),
with smoothing_element_share of the energy kept on each element's own strain. flutter_guard:
a continuum element whose volume swings back and forth from step to step gets the element tangent
from then on (False: the negative control). reuse_end_forces: the energy check at the end of an
implicit step evaluates the continuum elements' forces there, and the next step reuses them (the
same run to the last bit; False evaluates both). adaptive_threads: with threads above 1, time
steps on the worker pool and without it now and then and keep the faster (sim.uses_pool says
which runs; the two agree to rounding). A diverging step is rolled back and reported, never left
as NaN: with check_energy, a step whose energy exceeds the budget (the reference energy plus the
external work since) by more than energy_tolerance times it; with check_step_energy as well, one
that exceeds its own start energy plus its work by as much (the cumulative budget grows slack as
damping removes energy). energy_gain_strain: an implicit step that passes those checks but ends
with more energy than it started with plus its work, by more than the energy of every link and
element strained that much, is retried as sub-steps (with max_substep_halvings above 0; the last
level stands; 0 turns this off; StepReport.energy_gain says how much a step gained). Raises
fsm.Error for a bad model or option.)")
      .def(py::init([](const SphereModel<Scalar>& model, const py::object& integrator,
                       const Vector3<Scalar>& gravity, const std::string& damping, int threads,
                       bool check_energy, Scalar energy_tolerance, int max_substep_halvings,
                       Scalar drag, Scalar element_tangent_quality,
                       const std::string& strain_smoothing, Scalar smoothing_element_share,
                       bool flutter_guard, bool reuse_end_forces, bool adaptive_threads,
                       bool check_step_energy, Scalar energy_gain_strain) {
             typename Sim::Options o;
             o.adaptive_threads = adaptive_threads;
             o.forces.strain_smoothing = to_smoothing(strain_smoothing);
             o.forces.smoothing_element_share = smoothing_element_share;
             o.forces.drag = drag;
             o.forces.element_tangent_quality = element_tangent_quality;
             o.forces.flutter_guard = flutter_guard;
             o.forces.reuse_end_forces = reuse_end_forces;
             o.forces.gravity = gravity;
             o.forces.damping = to_damping(damping);
             o.forces.threads = threads;
             o.divergence.check_energy = check_energy;
             o.divergence.energy_tolerance = energy_tolerance;
             o.divergence.max_substep_halvings = max_substep_halvings;
             o.divergence.check_step_energy = check_step_energy;
             o.divergence.energy_gain_strain = energy_gain_strain;
             return std::make_unique<Sim>(model, to_integrator(integrator), o);
           }),
           py::arg("model"), py::arg("integrator") = "implicit_euler",
           py::arg("gravity") = Vector3<Scalar>(0, 0, -9.81), py::arg("damping") = "along_link",
           py::arg("threads") = 1, py::arg("check_energy") = true,
           py::arg("energy_tolerance") = 1.0, py::arg("max_substep_halvings") = 0,
           py::arg("drag") = 0.0, py::arg("element_tangent_quality") = 0.3,
           py::arg("strain_smoothing") = "element", py::arg("smoothing_element_share") = 0.1,
           py::arg("flutter_guard") = true, py::arg("reuse_end_forces") = true,
           py::arg("adaptive_threads") = false, py::arg("check_step_energy") = true,
           py::arg("energy_gain_strain") = DivergencePolicy<Scalar>{}.energy_gain_strain)
      .def("step", &Sim::step, py::arg("dt"), py::call_guard<py::gil_scoped_release>(),
           "Advances by dt seconds; returns a StepReport. Never raises.")
      .def_property_readonly("uses_pool", &Sim::uses_pool,
                             "Whether the steps now run on the worker pool (threads above 1, not "
                             "set aside by adaptive_threads).")
      .def(
          "run",
          [](Sim& sim, int steps, Scalar dt) {
            if (steps < 0) throw Error("", "steps", "is " + std::to_string(steps) + ", not >= 0");
            if (!(dt > 0) || !std::isfinite(dt))
              throw Error("", "dt",
                          "is " + std::to_string(dt) + " s; it must be positive and finite");
            int advanced = 0;
            {
              py::gil_scoped_release release;
              for (int s = 0; s < steps; ++s) advanced += sim.step(dt).advanced();
            }
            return advanced;
          },
          py::arg("steps"), py::arg("dt"),
          "Takes `steps` steps of dt seconds without the GIL; returns how many advanced. "
          "fsm.Error for a negative count or a dt that is not positive and finite (step(dt) "
          "reports those as a status instead, as the C++ step does).")
      .def_property_readonly(
          "model", [](Sim& sim) -> SphereModel<Scalar>& { return sim.model(); },
          py::return_value_policy::reference_internal, "The simulated model (arrays are views).")
      .def_property(
          "external_forces",
          [](py::object self) {
            Sim& sim = self.cast<Sim&>();
            auto f = sim.external_forces();
            return view(f.data(), py::ssize_t(f.rows()), 3, self);
          },
          [](Sim& sim, const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& v) {
            assign_rows3(sim.external_forces(), v, "external_forces");
          },
          "|V| x 3 external force per node (N), a view; held until changed.")
      .def(
          "internal_forces",
          [](Sim& sim) {
            const auto& m = sim.model();
            Positions<Scalar> f(m.num_nodes(), 3);
            {
              py::gil_scoped_release release;
              sim.forces().evaluate(m, m.positions(), m.velocities(), f);
              f -= sim.external_forces();
              const Vector3<Scalar> g = sim.forces().options().gravity;
              for (Index i = 0; i < m.num_nodes(); ++i) f.row(i) -= m.masses()[i] * g.transpose();
            }
            py::array_t<Scalar> out({py::ssize_t(f.rows()), py::ssize_t(3)});
            std::copy(f.data(), f.data() + f.size(), out.mutable_data());
            return out;
          },
          "|V| x 3 forces (N) at the current state from the tissue itself: links or the continuum "
          "law's elements (elastic and viscous), drag and the penalty contacts the force model "
          "holds; not gravity or external forces. On a held (fixed) node, what the tissue pushes "
          "it with: summed over a tool's held nodes, the tool's reaction.")
      .def("cut", &Sim::cut, py::arg("blade"), py::call_guard<py::gil_scoped_release>(),
           "Cuts the links and tetrahedra the Blade swept through at the current positions; "
           "returns a TopologyChange (`rejected` for an invalid blade: nothing changed).")
      .def_property_readonly(
          "broken_links", [](const Sim& sim) { return sim.topology().broken_links(); },
          "Links broken by the last cut or step's tear (a list of indices).")
      .def_property_readonly(
          "removed_tetrahedra", [](const Sim& sim) { return sim.topology().removed_tetrahedra(); },
          "Tetrahedra removed by the last cut or step's tear (a list of indices).")
      .def_property(
          "tear_strains",
          [](py::object self) {
            Sim& sim = self.cast<Sim&>();
            auto t = sim.topology().tear_strains();
            return view<Scalar>(t.data(), py::ssize_t(t.rows()), 0, self, true);
          },
          [](Sim& sim, const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& v) {
            auto t = sim.topology().tear_strains();
            if (v.ndim() != 1 || v.shape(0) != t.rows())
              throw Error("", "tear_strains",
                          "must have " + std::to_string(t.rows()) + " entries, one per link");
            const ScalarArray<Scalar> old = t;
            std::copy(v.data(), v.data() + t.rows(), t.data());
            try {
              sim.topology().refresh_tearing(sim.model());
            } catch (...) {
              t = old;
              throw;
            }
          },
          "|L| effective tear strain per link (the smallest of the link's own and its materials'; "
          "inf = never), a read-only view; assign a whole array to change it until the next "
          "refresh() (fsm.Error for an entry that is not positive).")
      .def_property_readonly(
          "element_tangents",
          [](const Sim& sim) { return sim.forces().continuum_element_tangents(); },
          "Continuum elements that had the exact-shape element tangent at the last force "
          "evaluation: poorly shaped (element_tangent_quality), strongly strained or fluttering.")
      .def_property_readonly(
          "fluttered_elements",
          [](const Sim& sim) { return sim.forces().continuum_fluttered_elements(); },
          "Continuum elements the flutter guard found swinging back and forth from step to step "
          "(they keep the element tangent; 0 with flutter_guard=False).")
      .def("set_fixed", &Sim::set_fixed, py::arg("node"), py::arg("fixed") = true,
           "Fixes (or frees) a node; a fixed node's velocity is zeroed and it moves only when its "
           "position is written.")
      .def("refresh", &Sim::refresh,
           "Re-validates and re-derives everything after editing model arrays in place.")
      .def_property_readonly(
          "integrator", [](Sim& sim) { return std::string(sim.integrator().name()); },
          "The current scheme's name (see fsm.integrator_names()).")
      .def(
          "set_integrator",
          [](Sim& sim, const py::object& spec) { sim.set_integrator(to_integrator(spec)); },
          py::arg("integrator"), "Swaps the scheme (a name or an fsm.Integrator).")
      .def_property_readonly("stable_time_step", &Sim::stable_time_step,
                             "The integrator's largest stable step for this model (s).")
      .def_property_readonly("spectral_bound", &Sim::spectral_bound,
                             "The model's SpectralBound (highest eigenfrequency, damping rate).")
      .def("energy", &Sim::energy, "The EnergyReport at the current state.")
      .def_property_readonly("energy_gain_limit", &Sim::energy_gain_limit,
                             "J an implicit step may gain before it is retried finer "
                             "(energy_gain_strain as an energy; 0 when off)")
      .def("reset_energy_reference", &Sim::reset_energy_reference,
           "Takes the current energy as the new reference (after editing the state by hand).")
      .def_property_readonly("time", &Sim::time, "Simulated seconds.")
      .def("reset", &Sim::reset, "Back to rest, zero velocity and external force, time 0.");
}

}  // namespace fsm::python
