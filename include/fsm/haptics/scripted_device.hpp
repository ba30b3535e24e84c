#pragma once

/// @file haptics/scripted_device.hpp
/// @brief ScriptedHapticDevice: a device that plays timed waypoints and records every force it is
/// commanded. For tests, benchmarks, the demo, and offline experiments.

#include <atomic>
#include <string>
#include <vector>

#include "fsm/haptics/haptic_device.hpp"

namespace fsm::haptics {

/// @brief A pose the script passes through at a time.
struct Waypoint {
  double time{0};                                                  ///< s, from the script's start
  Vector3<double> position{Vector3<double>::Zero()};               ///< m
  Eigen::Quaterniond orientation{Eigen::Quaterniond::Identity()};  ///< unit
  std::uint32_t buttons{0};                                        ///< bit i: button i pressed
};

/// @brief A commanded force and when (the time of the last read()).
struct ForceSample {
  double time{0};                                  ///< s
  Vector3<double> force{Vector3<double>::Zero()};  ///< N, after the clamp
};

/// @brief Plays waypoints: position interpolated linearly (the velocity is the segment's slope),
/// orientation by spherical interpolation, buttons held from each waypoint to the next. Before the
/// first waypoint it stays at the first, after the last at the last (at rest).
///
/// Its clock is the `time` passed to read() (the servo loop's nominal tick time), so a run is
/// deterministic whether the loop runs in real time or as fast as it can. Every apply_force() is
/// recorded (up to `record_capacity` samples, allocated up front; further ones are counted in
/// dropped()). apply_force() may be called from two threads at once (the servo loop and its
/// watchdog).
///
/// CSV script (`from_csv`): one waypoint per line, comma-separated, `#` starts a comment, an
/// optional header line starting with `time`. Columns: `time` (s), `x, y, z` (m), then optionally
/// `qw, qx, qy, qz` (a quaternion, normalised on reading), then optionally `buttons` (an
/// integer bit mask). Times must increase strictly.
class ScriptedHapticDevice final : public HapticDevice {
 public:
  /// @brief A device at rest at the origin.
  ScriptedHapticDevice();
  /// @brief Plays `waypoints` (at least one, strictly increasing finite times, finite positions,
  /// non-zero quaternions). fsm::Error naming the waypoint otherwise.
  explicit ScriptedHapticDevice(std::vector<Waypoint> waypoints, DeviceLimits limits = {},
                                std::size_t record_capacity = std::size_t(1) << 20);
  /// @brief Reads a CSV script (format above). fsm::Error naming the file and line.
  [[nodiscard]] static ScriptedHapticDevice from_csv(const std::string& path,
                                                     DeviceLimits limits = {});

  ScriptedHapticDevice(ScriptedHapticDevice&& other) noexcept;
  ScriptedHapticDevice& operator=(ScriptedHapticDevice&&) = delete;
  ScriptedHapticDevice(const ScriptedHapticDevice&) = delete;

  [[nodiscard]] std::string name() const override { return "scripted"; }
  [[nodiscard]] DeviceLimits limits() const override { return m_limits; }
  void stop() noexcept override;
  [[nodiscard]] DeviceState read(double time) noexcept override;
  Vector3<double> apply_force(const Vector3<double>& force) noexcept override;

  /// @brief The state the script gives at `time` (s); what read() returns.
  [[nodiscard]] DeviceState state_at(double time) const noexcept;
  /// @brief Time of the last waypoint (s).
  [[nodiscard]] double duration() const noexcept { return m_waypoints.back().time; }
  [[nodiscard]] const std::vector<Waypoint>& waypoints() const noexcept { return m_waypoints; }

  /// @brief The forces commanded so far, in order (call when no thread is commanding).
  [[nodiscard]] std::vector<ForceSample> forces() const;
  /// @brief Forces not recorded because the record was full.
  [[nodiscard]] std::size_t dropped() const noexcept;
  /// @brief Forgets the recorded forces.
  void clear_forces() noexcept;
  /// @brief The last force commanded (N).
  [[nodiscard]] Vector3<double> last_force() const noexcept;

 private:
  std::vector<Waypoint> m_waypoints;
  DeviceLimits m_limits;
  std::vector<ForceSample> m_record;
  std::atomic<std::size_t> m_count{0};
  std::atomic<double> m_last_read{0};
  std::atomic<double> m_last_fx{0}, m_last_fy{0}, m_last_fz{0};
};

}  // namespace fsm::haptics
