#pragma once

/// @file haptics/touch_device.hpp
/// @brief TouchDevice: the 3D Systems Touch (formerly Phantom Omni) through the OpenHaptics HD
/// API, loaded at run time (fsm::touch).

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "fsm/haptics/haptic_device.hpp"

namespace fsm::haptics {

namespace detail {
struct HdLibrary;
}  // namespace detail

/// @brief The 3D Systems Touch (Phantom Omni) as a HapticDevice, driven through OpenHaptics.
///
/// The HD library is opened with dlopen() by start(), so libfsm builds, links and tests without
/// the vendor SDK. The library tried is `$FSM_LIBHD` when that is set, else "libHD.so", then
/// "libHD.so.3.4" (through the loader's search path).
///
/// **Frames.** The Touch reports in its own frame: x to the user's right, y up, z toward the user
/// (origin near the centre of the workspace), in millimetres. The simulation uses SI units and
/// z up. TouchDevice converts mm → m and rotates by a fixed rotation `R` (device → simulation):
/// positions, velocities and orientations are multiplied by `R`, forces by `R^T`, the workspace box
/// is the axis-aligned box around the rotated one. The default, z_up(), keeps x, sends the
/// Touch's y (up) to z and its z (toward the user) to -y, so the simulation's y points away from
/// the user into the screen. Pass the identity for the device's own frame; any other placement
/// (scale, offset to the model) is the caller's to add.
///
/// **Threads.** OpenHaptics runs its own servo thread (about 1 kHz); has_scheduler() is true and
/// ServoLoop runs inside it through run_scheduler(). read() called from inside that tick reads the
/// device within the scheduler frame; called from any other thread it returns the state read by the
/// latest tick (all zero before the first). apply_force() from anywhere sets the force that every
/// frame sends until the next call; the HD API clears forces each frame, so the callback writes
/// it before hdEndFrame.
class TouchDevice final : public HapticDevice {
 public:
  /// @brief The default device → simulation rotation: x → x, y (up) → z, z (toward the user) → -y.
  [[nodiscard]] static Eigen::Matrix3d z_up();

  /// @brief A Touch. Nothing is opened until start().
  /// @param device_name the OpenHaptics device name ("Default Device", or the name given in Touch
  ///   Setup); empty for the default device
  /// @param device_to_simulation rotation `R`, 3 x 3, from the Touch's frame to the simulation's;
  ///   fsm::Error if it is not a rotation (orthonormal, determinant +1, to 1e-9)
  explicit TouchDevice(std::string device_name = std::string(),
                       const Eigen::Matrix3d& device_to_simulation = z_up());
  /// @brief Stops the device (see stop()).
  ~TouchDevice() override;

  TouchDevice(const TouchDevice&) = delete;
  TouchDevice& operator=(const TouchDevice&) = delete;

  /// @brief "touch:" and the device name ("touch:default" for the default device).
  [[nodiscard]] std::string name() const override;
  /// @brief Workspace (m, simulation frame) and force limit (N). Until start() reads the device's
  ///   HD_USABLE_WORKSPACE_DIMENSIONS and HD_NOMINAL_MAX_FORCE, the Touch's nominal figures
  ///   (160 x 120 x 70 mm, 3.3 N).
  [[nodiscard]] DeviceLimits limits() const override;

  /// @brief Opens the HD library, initialises the device, reads the limits, enables force output,
  ///   starts the HD scheduler and checks the calibration (updating it when the device can do so
  ///   by itself). fsm::Error naming "touch", the library or the device and the HD error code when
  ///   any of that fails, or when the calibration needs the stylus put in the inkwell; everything
  ///   opened so far is closed again. Does nothing when already started.
  void start() override;
  /// @brief Stops the servo callback (its last frame sends zero force), disables force output,
  ///   stops the HD scheduler, disables the device and closes the library. Never throws.
  void stop() noexcept override;

  /// @brief Position (m), orientation, velocity (m/s) and buttons, in the simulation frame. See the
  ///   class notes for calls from outside the servo tick.
  [[nodiscard]] DeviceState read(double time) noexcept override;
  /// @brief Sets the force (N, simulation frame), clamped to limits().max_force; non-finite → 0.
  Vector3<double> apply_force(const Vector3<double>& force) noexcept override;

  /// @brief True: the HD scheduler runs the servo loop.
  [[nodiscard]] bool has_scheduler() const noexcept override { return true; }
  /// @brief Schedules `tick` as an asynchronous HD callback at the default (servo) priority. Each
  ///   run opens a frame, calls `tick` (which reads and applies the force), writes the force and
  ///   closes the frame; it stops when `tick` returns false or throws, when stop_scheduler() is
  ///   called, or when the HD API reports a device or scheduler error (see servo_error()).
  ///   fsm::Error if the device is not started, a tick is still running, or the HD API refuses.
  void run_scheduler(std::function<bool()> tick) override;
  /// @brief Ends the callback (waiting for it, unscheduling it if it does not end by itself within
  ///   0.2 s) and returns when it can no longer run. Safe to call when nothing is scheduled.
  void stop_scheduler() noexcept override;

  /// @brief True between a successful start() and stop().
  [[nodiscard]] bool started() const noexcept { return m_library != nullptr; }
  /// @brief True while the servo callback is scheduled and has not ended.
  [[nodiscard]] bool servo_running() const noexcept { return m_servo_running.load(); }
  /// @brief The last HD error code the servo callback saw (0 = HD_SUCCESS: none).
  [[nodiscard]] std::uint32_t servo_error() const noexcept { return m_servo_error.load(); }
  /// @brief The rotation `R` from the Touch's frame to the simulation's.
  [[nodiscard]] const Eigen::Matrix3d& device_to_simulation() const noexcept { return m_rotation; }

 private:
  /// Runs one servo frame; the body of the HD callback. Never throws.
  unsigned run_frame() noexcept;
  /// Reads the device inside a frame (servo thread only).
  DeviceState read_in_frame(double time) noexcept;
  void close() noexcept;
  friend struct TouchCallbacks;

  std::string m_device_name;
  Eigen::Matrix3d m_rotation;
  DeviceLimits m_limits;
  std::unique_ptr<detail::HdLibrary> m_library;
  unsigned m_handle{0};

  std::function<bool()> m_tick;
  unsigned long m_schedule{0};
  std::atomic<bool> m_scheduled{false};
  std::atomic<bool> m_servo_running{false};
  std::atomic<bool> m_stop_requested{false};
  std::atomic<bool> m_in_frame{false};
  std::atomic<bool> m_in_callback{false};
  std::atomic<std::thread::id> m_servo_thread{};
  std::atomic<std::uint32_t> m_servo_error{0};

  // The commanded force in the device frame (N); components are atomic, a torn vector lasts one
  // frame at most.
  std::atomic<double> m_force[3]{};

  // The state the latest tick read, for readers outside the servo thread. The servo thread only
  // try_locks it, so it never waits.
  mutable std::mutex m_snapshot_mutex;
  DeviceState m_snapshot;
};

/// @brief Registers "touch" with the device registry (config = the device name, empty for the
/// default device).
void register_touch_device();

}  // namespace fsm::haptics
