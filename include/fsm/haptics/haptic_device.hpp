#pragma once

/// @file haptics/haptic_device.hpp
/// @brief HapticDevice: what libfsm needs from a haptic device (pose in, force out), and the
/// registry that makes devices by name.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fsm/types.hpp"

namespace fsm::haptics {

/// @brief One reading of a device, in the simulation's frame and SI units.
struct DeviceState {
  double time{0};  ///< when it was read (s, on the servo clock that asked)
  Vector3<double> position{Vector3<double>::Zero()};               ///< the end effector's tip (m)
  Eigen::Quaterniond orientation{Eigen::Quaterniond::Identity()};  ///< of the stylus
  Vector3<double> linear_velocity{Vector3<double>::Zero()};        ///< of the tip (m/s)
  std::uint32_t buttons{0};  ///< bit i set while button i is pressed
};

/// @brief What a device can do.
struct DeviceLimits {
  /// Workspace box (m), in the device's (= the simulation's) frame.
  Vector3<double> workspace_min{Vector3<double>::Constant(-0.1)};
  Vector3<double> workspace_max{Vector3<double>::Constant(0.1)};
  /// Largest force the device may be commanded (N); apply_force clamps its magnitude to this.
  double max_force{3.3};
};

/// @brief A haptic device: reads a pose, writes a force. No hidden threads: a device does work
/// only when called (a device with its own scheduler, like the Touch, says so and runs the
/// callback it is given by ServoLoop).
///
/// read() and apply_force() are called from the servo thread at up to 1 kHz: implementations
/// must not allocate, block or throw there. start() and stop() may (they throw fsm::Error when the
/// device cannot be used).
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;

  /// @brief The registered name ("scripted", "touch", ...) and an instance label.
  [[nodiscard]] virtual std::string name() const = 0;
  /// @brief Workspace and force limit.
  [[nodiscard]] virtual DeviceLimits limits() const = 0;

  /// @brief Prepares the device and enables force output. fsm::Error if it cannot.
  virtual void start() {}
  /// @brief Sets the force to zero and disables force output. Never throws.
  virtual void stop() noexcept {}

  /// @brief The device's state now. `time` (s) is the servo clock's time of the call; devices
  /// that play a script use it as their clock, physical devices only record it.
  [[nodiscard]] virtual DeviceState read(double time) noexcept = 0;

  /// @brief Commands a force (N) on the tip, in the simulation's frame, from now until the next
  /// call. The device clamps the magnitude to limits().max_force and ignores a non-finite force
  /// (commanding zero instead). Returns the force actually commanded.
  virtual Vector3<double> apply_force(const Vector3<double>& force) noexcept = 0;

  /// @brief True when the device runs its own servo scheduler (ServoLoop then runs inside it
  /// through run_scheduler() rather than in a thread of its own).
  [[nodiscard]] virtual bool has_scheduler() const noexcept { return false; }
  /// @brief Runs `tick` from the device's scheduler at its rate until `tick` returns false or
  /// stop_scheduler() is called; returns at once (the scheduler has its own thread). Only for
  /// devices with has_scheduler().
  virtual void run_scheduler(std::function<bool()> tick);
  /// @brief Stops the scheduler started by run_scheduler() and waits for the last tick.
  virtual void stop_scheduler() noexcept {}

 protected:
  /// @brief The force clamp every device applies: magnitude at most `max_force`, non-finite → 0.
  [[nodiscard]] static Vector3<double> clamp_force(const Vector3<double>& force,
                                                   double max_force) noexcept;
};

/// @brief Makes a device from a configuration string (what it means is the device's: a script
/// file for "scripted", a device name for "touch").
using DeviceFactory = std::function<std::unique_ptr<HapticDevice>(const std::string& config)>;

/// @brief Registers a device kind under `name` (replacing one of the same name). "scripted" is
/// registered by libfsm; fsm::touch registers "touch" through register_touch_device().
void register_device(const std::string& name, DeviceFactory factory);

/// @brief The registered device names, sorted.
[[nodiscard]] std::vector<std::string> device_names();

/// @brief Makes the device registered as `name`. fsm::Error naming the valid names for an unknown
/// name, or the device's own error when it cannot be made.
[[nodiscard]] std::unique_ptr<HapticDevice> make_device(const std::string& name,
                                                        const std::string& config = "");

}  // namespace fsm::haptics
