// haptics/servo_loop.hpp: ServoOptions, ServoStats and the ServoLoop's offline (run_fast) and
// real-time modes.

#include "fsm/haptics/servo_loop.hpp"
#include "common.hpp"
#include "fsm/collision/contact.hpp"
#include "fsm/haptics/scripted_device.hpp"
#include "haptic_device.hpp"

namespace fsm::python {

void define_servo_loop(py::module_& m) {
  using Opt = fh::ServoOptions;
  py::class_<Opt> opt(m, "ServoOptions",
                      R"(How ServoLoop runs and couples (SI units). See the C++ docs of
fsm::haptics::ServoOptions: rate (Hz), coupling_stiffness (N/m), coupling_damping (N s/m),
proxy_mass (kg), max_force (N, 0 = the device's), ramp_time (s), watchdog_timeout (s),
recover_time (s), device_offset (m), device_scale, realtime_priority (0: off; 2-98: SCHED_FIFO
for the loop's threads where the system allows), realtime_spin (s).)");
  opt.def(py::init<>(), "Defaults: 1 kHz, 400 N/m, 4 N s/m, 20 g, 0.25 s ramp, 1.5 ms watchdog.")
      .def_readwrite("rate", &Opt::rate, "Hz")
      .def_readwrite("coupling_stiffness", &Opt::coupling_stiffness, "N/m")
      .def_readwrite("coupling_damping", &Opt::coupling_damping, "N s/m")
      .def_readwrite("proxy_mass", &Opt::proxy_mass, "kg")
      .def_readwrite("max_force", &Opt::max_force, "N (0: the device's limit)")
      .def_readwrite("ramp_time", &Opt::ramp_time, "s")
      .def_readwrite("watchdog_timeout", &Opt::watchdog_timeout, "s")
      .def_readwrite("recover_time", &Opt::recover_time, "s")
      .def_readwrite("local_model_timeout", &Opt::local_model_timeout,
                     "s the decoupled tick's local contact model may stand in for a late step")
      .def_readwrite("device_offset", &Opt::device_offset, "m")
      .def_readwrite("device_scale", &Opt::device_scale, "dimensionless")
      .def_readwrite("realtime_priority", &Opt::realtime_priority,
                     "0: default scheduler; 2-98: SCHED_FIFO priority of the servo thread")
      .def_readwrite("realtime_spin", &Opt::realtime_spin,
                     "s a real-time servo thread spins before each deadline");

  py::class_<fh::ServoStats>(m, "ServoStats",
                             R"(Timing and safety figures of a ServoLoop run (s unless named).)")
      .def_readonly("ticks", &fh::ServoStats::ticks, "device ticks")
      .def_readonly("steps", &fh::ServoStats::steps, "simulation steps")
      .def_readonly("missed_deadlines", &fh::ServoStats::missed_deadlines,
                    "ticks a period or more late")
      .def_readonly("period_p50", &fh::ServoStats::period_p50, "s")
      .def_readonly("period_p99", &fh::ServoStats::period_p99, "s")
      .def_readonly("period_max", &fh::ServoStats::period_max, "s")
      .def_readonly("step_p50", &fh::ServoStats::step_p50, "s")
      .def_readonly("step_p99", &fh::ServoStats::step_p99, "s")
      .def_readonly("step_max", &fh::ServoStats::step_max, "s")
      .def_readonly("watchdog_trips", &fh::ServoStats::watchdog_trips, "times the force was zeroed")
      .def_readonly("diverged_steps", &fh::ServoStats::diverged_steps, "steps rolled back")
      .def_readonly("unconverged_solves", &fh::ServoStats::unconverged_solves,
                    "integrator steps whose linear solve stopped at its iteration cap")
      .def_readonly("energy_gain_retries", &fh::ServoStats::energy_gain_retries,
                    "sub-step levels run again because they gained energy an implicit step "
                    "cannot make (energy_gain_strain)")
      .def_readonly("largest_energy_gain", &fh::ServoStats::largest_energy_gain,
                    "J: the largest energy_gain of an accepted step (nan when none was checked)")
      .def_readonly("peak_force", &fh::ServoStats::peak_force, "N")
      .def_readonly("peak_tissue_force", &fh::ServoStats::peak_tissue_force,
                    "N: the largest contact force on the instrument, over every step")
      .def_readonly("realtime", &fh::ServoStats::realtime,
                    "every thread that asked for real-time scheduling got it");

  py::class_<fh::ServoLoop>(m, "ServoLoop",
                            R"(A haptic device coupled to a Simulation through a virtual coupling.

ServoLoop(simulation, contacts, instrument, device, options=ServoOptions())

run_fast(seconds) runs the loop offline, as fast as possible, deterministically (the same force
curve as the real-time loop): each tick reads the device, commands the coupling force (clamped,
ramped in) and steps the simulation with contacts. The objects passed in must outlive the loop.
Real-time running (run_real_time) is for C++ devices only; with a Python device use run_fast.)")
      .def(py::init([](Simulation<double>& sim, collision::ContactSolver<Scalar>& contacts,
                       Index instrument, fh::HapticDevice& device, const Opt& o) {
             return std::make_unique<fh::ServoLoop>(sim, contacts, instrument, device, o);
           }),
           py::arg("simulation"), py::arg("contacts"), py::arg("instrument"), py::arg("device"),
           py::arg("options") = Opt{}, py::keep_alive<1, 2>(), py::keep_alive<1, 3>(),
           py::keep_alive<1, 5>(),
           "Couples `device` to instrument `instrument` of `contacts` in `simulation`.")
      .def(
          "run_fast",
          [](fh::ServoLoop& l, double seconds, py::object device) {
            // A Python device needs the GIL inside the loop: keep it then; release it otherwise.
            const bool python_device =
                py::isinstance<PyHapticDevice>(device) ||
                (device && !py::isinstance<fh::ScriptedHapticDevice>(device));
            if (python_device) {
              l.run_fast(seconds);
            } else {
              py::gil_scoped_release release;
              l.run_fast(seconds);
            }
            if (auto* d = dynamic_cast<PyHapticDevice*>(&l.device()))
              d->raise_pending("ServoLoop.run_fast");
          },
          py::arg("seconds"), py::arg("device") = py::none(),
          "Runs `seconds` of servo time offline (pass the device again to release the GIL for C++ "
          "devices).")
      .def(
          "run_real_time",
          [](fh::ServoLoop& l, double seconds) {
            {
              py::gil_scoped_release release;
              l.run_real_time(seconds);
            }
            if (auto* d = dynamic_cast<PyHapticDevice*>(&l.device()))
              d->raise_pending("ServoLoop.run_real_time");
          },
          py::arg("seconds"), "Runs in real time (C++ devices only; the GIL is released).")
      .def("stats", &fh::ServoLoop::stats, "ServoStats of the last run.")
      .def_property_readonly("tripped", &fh::ServoLoop::tripped,
                             "True while the force is held at zero")
      .def(
          "step_times",
          [](const fh::ServoLoop& l) {
            const auto& t = l.step_times();
            return py::array_t<float>(py::ssize_t(t.size()), t.data());
          },
          "Duration (s) of each simulation step of the last run.");
}

}  // namespace fsm::python
