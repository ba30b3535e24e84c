#pragma once

// MouseDevice: the mouse as a haptic device for fsm-viewer. Example code: not part of the library.

#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include "fsm/haptics/haptic_device.hpp"

namespace fsm::examples {

/// A single-producer single-consumer mailbox holding the latest value: the writer never waits, the
/// reader always gets the newest complete value; lock-free and allocation-free. (The same
/// three-slot scheme as the servo loop's snapshots; kept here because examples use only the public
/// API.)
template <typename T>
class LatestValue {
 public:
  explicit LatestValue(const T& initial = T()) : m_slots{initial, initial, initial} {}

  /// Writer: publishes `value` as the latest.
  void write(const T& value) noexcept {
    m_slots[m_back] = value;
    const std::uint8_t old =
        m_middle.exchange(std::uint8_t(m_back | kFresh), std::memory_order_acq_rel);
    m_back = old & kIndex;
  }
  /// Reader: the latest value written (or the initial one).
  const T& read() noexcept {
    if (m_middle.load(std::memory_order_relaxed) & kFresh) {
      const std::uint8_t old = m_middle.exchange(m_front, std::memory_order_acq_rel);
      m_front = old & kIndex;
    }
    return m_slots[m_front];
  }

 private:
  static constexpr std::uint8_t kIndex = 3, kFresh = 4;
  std::array<T, 3> m_slots;
  std::uint8_t m_back{0};   // writer only
  std::uint8_t m_front{1};  // reader only
  std::atomic<std::uint8_t> m_middle{2};
};

/// The pose the user asks for: the instrument's pose origin (m, simulation frame) and orientation.
struct MouseTarget {
  Vector3<double> position{Vector3<double>::Zero()};
  Eigen::Quaterniond orientation{Eigen::Quaterniond::Identity()};
  std::uint32_t buttons{0};
};

/// A HapticDevice driven by the mouse. The window thread calls set_target() (at the frame rate);
/// the servo thread calls read() (at 1 kHz), which follows the target through a first-order lag
/// of `smoothing` seconds (a hand has inertia; a mouse target jumps once a frame, and a step in
/// the device position would be a step in the coupling force) and reports the lag's velocity.
/// Nothing is felt: apply_force() only records the force, for display.
///
/// read() and apply_force() take no lock, allocate nothing and never throw. read() must be called
/// from one thread only (the servo thread), set_target() from one thread only (the window's).
class MouseDevice final : public haptics::HapticDevice {
 public:
  /// @param limits workspace box (m) the target is clamped to, and the force limit (N)
  /// @param initial the pose at start
  /// @param smoothing time constant (s) of the lag behind the target; 0 follows it at once
  MouseDevice(const haptics::DeviceLimits& limits, const MouseTarget& initial,
              double smoothing = 0.03);

  [[nodiscard]] std::string name() const override { return "mouse"; }
  [[nodiscard]] haptics::DeviceLimits limits() const override { return m_limits; }
  void start() override;

  [[nodiscard]] haptics::DeviceState read(double time) noexcept override;
  Vector3<double> apply_force(const Vector3<double>& force) noexcept override;

  /// Window thread: the pose to move to (its position is clamped to the workspace).
  void set_target(const MouseTarget& target) noexcept;
  /// The last force commanded (N), from any thread.
  [[nodiscard]] Vector3<double> last_force() const noexcept;

 private:
  haptics::DeviceLimits m_limits;
  double m_smoothing;
  LatestValue<MouseTarget> m_target;
  // Servo thread only.
  haptics::DeviceState m_state;
  bool m_fresh{true};
  std::atomic<double> m_fx{0}, m_fy{0}, m_fz{0};
};

}  // namespace fsm::examples
