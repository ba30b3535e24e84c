#pragma once

// The trampoline of Python subclasses of fsm.HapticDevice (haptic_device.cpp binds it; the servo
// loop's binding asks whether a device is one).

#include "common.hpp"
#include "fsm/haptics/haptic_device.hpp"

namespace fsm::python {

namespace fh = fsm::haptics;
using V3 = Vector3<double>;

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

}  // namespace fsm::python
