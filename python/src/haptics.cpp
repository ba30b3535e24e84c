// Haptics: DeviceState, DeviceLimits, Waypoint, the scripted device, Python-defined devices (a
// trampoline, for offline use only: a Python device takes the GIL on every call and must never
// drive a real-time loop), and the ServoLoop's fast (offline) mode and statistics.

#include <pybind11/functional.h>

#include "common.hpp"
#include "fsm/haptics/haptic_device.hpp"
#include "fsm/haptics/scripted_device.hpp"
#include "fsm/haptics/servo_loop.hpp"

namespace fsm::python {

namespace {

namespace fh = fsm::haptics;
using V3 = Vector3<double>;

Eigen::Quaterniond quaternion(const Eigen::Vector4d& wxyz) {
  Eigen::Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
  if (!(q.norm() > 0) || !q.coeffs().allFinite())
    throw Error("", "orientation", "needs a non-zero, finite quaternion (w, x, y, z)");
  return q.normalized();
}
Eigen::Vector4d wxyz(const Eigen::Quaterniond& q) {
  return {q.w(), q.x(), q.y(), q.z()};
}

// Python subclasses of fsm.HapticDevice.
class PyHapticDevice : public fh::HapticDevice {
 public:
  std::string name() const override { PYBIND11_OVERRIDE_PURE(std::string, fh::HapticDevice, name); }
  fh::DeviceLimits limits() const override {
    py::gil_scoped_acquire gil;
    py::function f = py::get_override(static_cast<const fh::HapticDevice*>(this), "limits");
    if (f) return f().cast<fh::DeviceLimits>();
    return fh::DeviceLimits{};  // a Python device that does not say: the default limits
  }
  void start() override { PYBIND11_OVERRIDE(void, fh::HapticDevice, start); }
  void stop() noexcept override {
    try {
      py::gil_scoped_acquire gil;
      py::function f = py::get_override(static_cast<const fh::HapticDevice*>(this), "stop");
      if (f) f();
    } catch (...) {
    }
  }
  fh::DeviceState read(double time) noexcept override {
    try {
      py::gil_scoped_acquire gil;
      py::function f = py::get_override(static_cast<const fh::HapticDevice*>(this), "read");
      if (f) return f(time).cast<fh::DeviceState>();
    } catch (const std::exception& e) {
      last_error = e.what();
    }
    fh::DeviceState s;
    s.time = time;
    return s;
  }
  V3 apply_force(const V3& force) noexcept override {
    const V3 f = clamp_force(force, safe_limit());
    try {
      py::gil_scoped_acquire gil;
      py::function fn = py::get_override(static_cast<const fh::HapticDevice*>(this), "apply_force");
      if (fn) fn(f);
    } catch (const std::exception& e) {
      last_error = e.what();
    }
    return f;
  }
  std::string last_error;

 private:
  double safe_limit() noexcept {
    try {
      return limits().max_force;
    } catch (...) {
      return 0;
    }
  }
};

}  // namespace

void define_haptics(py::module_& m) {
  py::class_<fh::DeviceState>(m, "DeviceState",
                              R"(One reading of a haptic device (SI units, simulation frame).

Fields: time (s), position (m, 3-vector), orientation (unit quaternion w, x, y, z),
linear_velocity (m/s), buttons (bit mask).)")
      .def(py::init([](double time, const V3& position, const Eigen::Vector4d& orientation,
                       const V3& velocity, std::uint32_t buttons) {
             fh::DeviceState s;
             s.time = time;
             s.position = position;
             s.orientation = quaternion(orientation);
             s.linear_velocity = velocity;
             s.buttons = buttons;
             return s;
           }),
           py::arg("time") = 0.0, py::arg("position") = V3::Zero(),
           py::arg("orientation") = Eigen::Vector4d(1, 0, 0, 0),
           py::arg("linear_velocity") = V3::Zero(), py::arg("buttons") = 0u,
           "Makes a state (a quaternion as w, x, y, z).")
      .def_readwrite("time", &fh::DeviceState::time, "s")
      .def_readwrite("position", &fh::DeviceState::position, "m")
      .def_property(
          "orientation", [](const fh::DeviceState& s) { return wxyz(s.orientation); },
          [](fh::DeviceState& s, const Eigen::Vector4d& q) { s.orientation = quaternion(q); },
          "unit quaternion (w, x, y, z)")
      .def_readwrite("linear_velocity", &fh::DeviceState::linear_velocity, "m/s")
      .def_readwrite("buttons", &fh::DeviceState::buttons, "bit i set while button i is pressed");

  py::class_<fh::DeviceLimits>(m, "DeviceLimits",
                               R"(A device's workspace box (m) and force limit (N).)")
      .def(py::init([](double max_force, const V3& lo, const V3& hi) {
             fh::DeviceLimits l;
             l.max_force = max_force;
             l.workspace_min = lo;
             l.workspace_max = hi;
             return l;
           }),
           py::arg("max_force") = 3.3, py::arg("workspace_min") = V3::Constant(-0.1),
           py::arg("workspace_max") = V3::Constant(0.1), "Makes limits.")
      .def_readwrite("max_force", &fh::DeviceLimits::max_force, "N: apply_force clamps to this")
      .def_readwrite("workspace_min", &fh::DeviceLimits::workspace_min, "m")
      .def_readwrite("workspace_max", &fh::DeviceLimits::workspace_max, "m");

  py::class_<fh::HapticDevice, PyHapticDevice>(m, "HapticDevice",
                                               R"(A haptic device: reads a pose, takes a force.

Subclass it in Python to script a device for OFFLINE experiments (ServoLoop.run_fast): implement
name(), read(time) -> DeviceState and optionally limits(), apply_force(force), start(), stop().
A Python device takes the GIL on every call: never use one in a real-time loop. Exceptions in
read() or apply_force() are caught (the loop must not throw) and kept in last_error.

    class Circle(fsm.HapticDevice):
        def name(self): return "circle"
        def read(self, t):
            return fsm.DeviceState(t, (0.01 * np.cos(t), 0.01 * np.sin(t), 0.02))
        def apply_force(self, f): self.forces.append(f)

Devices made in C++ come from fsm.make_device(name, config).)")
      .def(py::init<>(), "For Python subclasses.")
      .def("name", &fh::HapticDevice::name, "The registered name, e.g. 'scripted'.")
      .def("limits", &fh::HapticDevice::limits, "Workspace and force limit (DeviceLimits).")
      .def("start", &fh::HapticDevice::start, "Prepares the device and enables force output.")
      .def("stop", &fh::HapticDevice::stop, "Zero force, force output off.")
      .def("read", &fh::HapticDevice::read, py::arg("time"), "The state at servo time `time` (s).")
      .def("apply_force", &fh::HapticDevice::apply_force, py::arg("force"),
           "Commands a force (N, simulation frame); returns what was commanded after the clamp.");

  m.def("device_names", &fh::device_names, "The registered device names (e.g. ['scripted']).");
  m.def(
      "make_device", &fh::make_device, py::arg("name"), py::arg("config") = "",
      R"(Makes a device by name: 'scripted' (config: a CSV script path, or empty for a device at rest)
or 'touch' when fsm.touch is registered. fsm.Error lists the valid names for an unknown one.)");

  py::class_<fh::Waypoint>(m, "Waypoint",
                           R"(A pose a script passes through: time (s), position (m), orientation
(w, x, y, z), buttons.)")
      .def(py::init([](double t, const V3& p, const Eigen::Vector4d& q, std::uint32_t b) {
             return fh::Waypoint{t, p, quaternion(q), b};
           }),
           py::arg("time"), py::arg("position"),
           py::arg("orientation") = Eigen::Vector4d(1, 0, 0, 0), py::arg("buttons") = 0u,
           "Makes a waypoint.")
      .def_readwrite("time", &fh::Waypoint::time, "s")
      .def_readwrite("position", &fh::Waypoint::position, "m")
      .def_property(
          "orientation", [](const fh::Waypoint& w) { return wxyz(w.orientation); },
          [](fh::Waypoint& w, const Eigen::Vector4d& q) { w.orientation = quaternion(q); },
          "(w, x, y, z)")
      .def_readwrite("buttons", &fh::Waypoint::buttons, "bit mask");

  py::class_<fh::ScriptedHapticDevice, fh::HapticDevice>(
      m, "ScriptedHapticDevice",
      R"(A device that plays timed waypoints and records every force.

ScriptedHapticDevice(waypoints, limits=DeviceLimits(), record_capacity=1<<20)
ScriptedHapticDevice.from_csv(path, limits=DeviceLimits())

Position is interpolated linearly, orientation by slerp, buttons held; before the first and after
the last waypoint it rests there. Its clock is the servo loop's tick time, so runs are
deterministic. forces() returns an (n, 4) array of [time, fx, fy, fz].)")
      .def(py::init<std::vector<fh::Waypoint>, fh::DeviceLimits, std::size_t>(),
           py::arg("waypoints"), py::arg("limits") = fh::DeviceLimits{},
           py::arg("record_capacity") = std::size_t(1) << 20,
           "Plays `waypoints` (strictly increasing times).")
      .def_static("from_csv", &fh::ScriptedHapticDevice::from_csv, py::arg("path"),
                  py::arg("limits") = fh::DeviceLimits{},
                  "Reads a CSV script (time,x,y,z[,qw,qx,qy,qz][,buttons]).")
      .def("state_at", &fh::ScriptedHapticDevice::state_at, py::arg("time"),
           "The scripted state at `time` (s).")
      .def_property_readonly("duration", &fh::ScriptedHapticDevice::duration,
                             "time of the last waypoint (s)")
      .def(
          "forces",
          [](const fh::ScriptedHapticDevice& d) {
            const auto f = d.forces();
            py::array_t<double> a({py::ssize_t(f.size()), py::ssize_t(4)});
            auto r = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < f.size(); ++i) {
              r(py::ssize_t(i), 0) = f[i].time;
              for (int c = 0; c < 3; ++c) r(py::ssize_t(i), c + 1) = f[i].force[c];
            }
            return a;
          },
          "The commanded forces so far: an (n, 4) array [time (s), fx, fy, fz (N)].")
      .def_property_readonly("dropped", &fh::ScriptedHapticDevice::dropped,
                             "forces not recorded (record full)")
      .def("clear_forces", &fh::ScriptedHapticDevice::clear_forces, "Forgets the recorded forces.");

  using Opt = fh::ServoOptions;
  py::class_<Opt> opt(m, "ServoOptions",
                      R"(How ServoLoop runs and couples (SI units). See the C++ docs of
fsm::haptics::ServoOptions: rate (Hz), coupling_stiffness (N/m), coupling_damping (N s/m),
proxy_mass (kg), max_force (N, 0 = the device's), ramp_time (s), watchdog_timeout (s),
recover_time (s), device_offset (m), device_scale.)");
  opt.def(py::init<>(), "Defaults: 1 kHz, 400 N/m, 4 N s/m, 20 g, 0.25 s ramp, 1.5 ms watchdog.")
      .def_readwrite("rate", &Opt::rate, "Hz")
      .def_readwrite("coupling_stiffness", &Opt::coupling_stiffness, "N/m")
      .def_readwrite("coupling_damping", &Opt::coupling_damping, "N s/m")
      .def_readwrite("proxy_mass", &Opt::proxy_mass, "kg")
      .def_readwrite("max_force", &Opt::max_force, "N (0: the device's limit)")
      .def_readwrite("ramp_time", &Opt::ramp_time, "s")
      .def_readwrite("watchdog_timeout", &Opt::watchdog_timeout, "s")
      .def_readwrite("recover_time", &Opt::recover_time, "s")
      .def_readwrite("device_offset", &Opt::device_offset, "m")
      .def_readwrite("device_scale", &Opt::device_scale, "dimensionless");

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
      .def_readonly("peak_force", &fh::ServoStats::peak_force, "N");

  py::class_<fh::ServoLoop>(m, "ServoLoop",
                            R"(A haptic device coupled to a Simulation through a virtual coupling.

ServoLoop(simulation, contacts, instrument, device, options=ServoOptions())

run_fast(seconds) runs the loop offline, as fast as possible, deterministically (the same force
curve as the real-time loop): each tick reads the device, commands the coupling force (clamped,
ramped in) and steps the simulation with contacts. The objects passed in must outlive the loop.
Real-time running (run_real_time) is for C++ devices only; with a Python device use run_fast.)")
      .def(py::init([](Simulation<double>& sim, BoundContactSolver& contacts, Index instrument,
                       fh::HapticDevice& device, const Opt& o) {
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
          },
          py::arg("seconds"), py::arg("device") = py::none(),
          "Runs `seconds` of servo time offline (pass the device again to release the GIL for C++ "
          "devices).")
      .def(
          "run_real_time",
          [](fh::ServoLoop& l, double seconds) {
            py::gil_scoped_release release;
            l.run_real_time(seconds);
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
