// haptics/haptic_device.hpp: DeviceState, DeviceLimits, HapticDevice (subclassable from Python:
// a trampoline, for offline use only: a Python device takes the GIL on every call and must never
// drive a real-time loop) and the device registry.

#include "fsm/haptics/haptic_device.hpp"
#include "common.hpp"
#include "haptic_device.hpp"

namespace fsm::python {

namespace fh = fsm::haptics;

void define_haptic_device(py::module_& m) {
  py::class_<fh::DeviceState>(m, "DeviceState",
                              R"(One reading of a haptic device (SI units, simulation frame).

Fields: time (s), position (m, 3-vector), orientation (unit quaternion w, x, y, z),
linear_velocity (m/s), buttons (bit mask).)")
      .def(py::init([](double time, const V3& position, const Eigen::Vector4d& orientation,
                       const V3& velocity, std::uint32_t buttons) {
             fh::DeviceState s;
             s.time = time;
             s.position = position;
             s.orientation = to_quaternion(orientation);
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
          "orientation", [](const fh::DeviceState& s) { return to_wxyz(s.orientation); },
          [](fh::DeviceState& s, const Eigen::Vector4d& q) { s.orientation = to_quaternion(q); },
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
A Python device takes the GIL on every call: never use one in a real-time loop. An exception
raised by read(), apply_force() or stop() inside ServoLoop.run_fast cannot unwind through the
C++ loop: the loop goes on with the device at rest and no force, and run_fast raises the first
such exception when it returns (with a note saying where it came from).

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
}

}  // namespace fsm::python
