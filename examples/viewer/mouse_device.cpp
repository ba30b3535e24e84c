// MouseDevice: the mouse as a haptic device for fsm-viewer.

#include "mouse_device.hpp"

#include <cmath>

namespace fsm::examples {

MouseDevice::MouseDevice(const haptics::DeviceLimits& limits, const MouseTarget& initial,
                         double smoothing)
    : m_limits(limits), m_smoothing(smoothing), m_target(initial) {
  m_state.position = initial.position;
  m_state.orientation = initial.orientation;
  m_state.buttons = initial.buttons;
}

void MouseDevice::start() {
  // A new run restarts the servo clock: jump to the target at the first read.
  m_fresh = true;
}

haptics::DeviceState MouseDevice::read(double time) noexcept {
  const MouseTarget& target = m_target.read();
  const double dt = time - m_state.time;
  if (m_fresh || !(dt > 0) || !(m_smoothing > 0)) {
    m_state.linear_velocity.setZero();
    m_state.position = target.position;
    m_state.orientation = target.orientation;
    m_fresh = false;
  } else {
    const double a = 1 - std::exp(-dt / m_smoothing);
    const Vector3<double> previous = m_state.position;
    m_state.position += a * (target.position - m_state.position);
    m_state.linear_velocity = (m_state.position - previous) / dt;
    m_state.orientation = m_state.orientation.slerp(a, target.orientation).normalized();
  }
  m_state.time = time;
  m_state.buttons = target.buttons;
  return m_state;
}

Vector3<double> MouseDevice::apply_force(const Vector3<double>& force) noexcept {
  const Vector3<double> f = clamp_force(force, m_limits.max_force);
  m_fx.store(f.x(), std::memory_order_relaxed);
  m_fy.store(f.y(), std::memory_order_relaxed);
  m_fz.store(f.z(), std::memory_order_relaxed);
  return f;
}

void MouseDevice::set_target(const MouseTarget& target) noexcept {
  MouseTarget t = target;
  t.position = t.position.cwiseMax(m_limits.workspace_min).cwiseMin(m_limits.workspace_max);
  t.orientation.normalize();
  m_target.write(t);
}

Vector3<double> MouseDevice::last_force() const noexcept {
  return {m_fx.load(std::memory_order_relaxed), m_fy.load(std::memory_order_relaxed),
          m_fz.load(std::memory_order_relaxed)};
}

}  // namespace fsm::examples
