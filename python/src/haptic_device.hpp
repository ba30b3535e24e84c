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
    py::gil_scoped_acquire gil;
    try {
      py::function f = py::get_override(static_cast<const fh::HapticDevice*>(this), "stop");
      if (f) f();
    } catch (py::error_already_set& e) {
      keep(e, "stop");
    }
  }
  fh::DeviceState read(double time) noexcept override {
    py::gil_scoped_acquire gil;
    try {
      py::function f = py::get_override(static_cast<const fh::HapticDevice*>(this), "read");
      if (f) return f(time).cast<fh::DeviceState>();
    } catch (py::error_already_set& e) {
      keep(e, "read");
    } catch (const std::exception& e) {  // a cast error: read() returned something else
      keep_message(std::string("read() must return a DeviceState: ") + e.what());
    }
    fh::DeviceState s;
    s.time = time;
    return s;
  }
  V3 apply_force(const V3& force) noexcept override {
    const V3 f = clamp_force(force, safe_limit());
    py::gil_scoped_acquire gil;
    try {
      py::function fn = py::get_override(static_cast<const fh::HapticDevice*>(this), "apply_force");
      if (fn) fn(f);
    } catch (py::error_already_set& e) {
      keep(e, "apply_force");
    }
    return f;
  }

  /// Raises, with the GIL held, the first exception a method of this device raised inside a loop
  /// (a Python exception cannot unwind through the C++ loop: the loop went on with the device at
  /// rest, and the exception comes back here, with a note saying so).
  void raise_pending(const char* loop) {
    if (!m_pending) return;
    py::object value = std::move(m_pending);
    m_pending = py::object();
    if (py::hasattr(value, "add_note"))
      value.attr("add_note")("raised by HapticDevice." + m_pending_method + "() inside " + loop +
                             "; the loop went on with the device at rest and no force");
    PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(value.ptr())), value.ptr());
    throw py::error_already_set();
  }

 private:
  // Keeps the first exception (GIL held).
  void keep(py::error_already_set& e, const char* method) {
    if (m_pending) return;
    m_pending = e.value();
    m_pending_method = method;
  }
  void keep_message(const std::string& message) {
    if (m_pending) return;
    m_pending = py::reinterpret_steal<py::object>(
        PyObject_CallFunction(PyExc_TypeError, "s", message.c_str()));
    m_pending_method = "read";
  }
  double safe_limit() noexcept {
    try {
      return limits().max_force;
    } catch (...) {
      return 0;
    }
  }

  py::object m_pending;
  std::string m_pending_method;
};

}  // namespace fsm::python
