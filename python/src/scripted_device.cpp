// haptics/scripted_device.hpp: Waypoint and the ScriptedHapticDevice (timed poses in, forces
// recorded).

#include "fsm/haptics/scripted_device.hpp"
#include "common.hpp"

namespace fsm::python {

namespace fh = fsm::haptics;
using V3 = Vector3<double>;

void define_scripted_device(py::module_& m) {
  py::class_<fh::Waypoint>(m, "Waypoint",
                           R"(A pose a script passes through: time (s), position (m), orientation
(w, x, y, z), buttons.)")
      .def(py::init([](double t, const V3& p, const Eigen::Vector4d& q, std::uint32_t b) {
             return fh::Waypoint{t, p, to_quaternion(q), b};
           }),
           py::arg("time"), py::arg("position"),
           py::arg("orientation") = Eigen::Vector4d(1, 0, 0, 0), py::arg("buttons") = 0u,
           "Makes a waypoint.")
      .def_readwrite("time", &fh::Waypoint::time, "s")
      .def_readwrite("position", &fh::Waypoint::position, "m")
      .def_property(
          "orientation", [](const fh::Waypoint& w) { return to_wxyz(w.orientation); },
          [](fh::Waypoint& w, const Eigen::Vector4d& q) { w.orientation = to_quaternion(q); },
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
}

}  // namespace fsm::python
