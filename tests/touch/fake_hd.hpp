#pragma once

/// @file fake_hd.hpp
/// @brief The control interface of the fake libHD.so (fake_hd.cpp) the TouchDevice tests load.
///
/// The fake implements the HD functions TouchDevice uses, records every call in order, plays one
/// device whose state is a function of the frame number n (frames begun since the last reset):
///   position (mm)  = (10 + n, 20 - 2 n, -30 + 0.5 n)
///   velocity (mm/s) = (1000, -2000, 500)          (the position's rate at 1 kHz)
///   transform       = rotation of +90 deg about the device's y axis, translation = position
///   buttons         = fake_hd_set_buttons(...)
///   HD_NOMINAL_MAX_FORCE = fake_hd_set_max_force(...) (3.3 N after a reset)
///   HD_USABLE_WORKSPACE_DIMENSIONS = (-80, -60, -35) .. (80, 60, 35) mm
/// and can be told to fail. It enforces two rules of the real API and records a call starting with
/// "!" when they are broken: frames only on the scheduler thread, and current-state parameters
/// (position, velocity, transform, buttons, force) only inside a frame.

namespace fake_hd {

/// @brief What fake_hd_set_failure() makes go wrong.
enum Failure : int {
  kNone = 0,
  kNoDevice = 1,           ///< hdInitDevice answers HD_INVALID_HANDLE, HD_COMM_CONFIG_ERROR
  kCalibrationManual = 2,  ///< hdCheckCalibration answers HD_CALIBRATION_NEEDS_MANUAL_INPUT
  kCalibrationUpdate = 3,  ///< HD_CALIBRATION_NEEDS_UPDATE until hdUpdateCalibration(AUTO)
  kCalibrationStuck = 4,   ///< HD_CALIBRATION_NEEDS_UPDATE whatever is done
  kSchedulerFailure = 5,   ///< hdStartScheduler fails with HD_TIMER_ERROR
  kScheduleFailure = 6,    ///< hdScheduleAsynchronous fails with HD_SCHEDULER_FULL
  kServoFault = 7,         ///< every hdEndFrame raises HD_COMM_ERROR
};

/// @brief Position law of the fake (mm) at frame n.
inline void position_mm(long n, double out[3]) {
  out[0] = 10.0 + double(n);
  out[1] = 20.0 - 2.0 * double(n);
  out[2] = -30.0 + 0.5 * double(n);
}

/// @brief The fake's velocity (mm/s).
constexpr double kVelocityMm[3] = {1000.0, -2000.0, 500.0};

}  // namespace fake_hd

extern "C" {
/// Clears the call log, the errors, the frame counter and the failure; stops the scheduler.
typedef void (*fake_hd_reset_t)();
/// Sets a fake_hd::Failure.
typedef void (*fake_hd_set_failure_t)(int failure);
typedef void (*fake_hd_set_max_force_t)(double newtons);
typedef void (*fake_hd_set_buttons_t)(int buttons);
/// The calls so far, one a line ("hdEnable(0x4000)"). Valid until the next call of this function.
typedef const char* (*fake_hd_calls_t)();
/// Frames begun since the reset.
typedef long (*fake_hd_frame_t)();
/// 1 while a device is initialised / the scheduler runs / force output is enabled.
typedef int (*fake_hd_device_open_t)();
typedef int (*fake_hd_scheduler_running_t)();
typedef int (*fake_hd_force_output_t)();
/// Operations (synchronous or asynchronous) still scheduled.
typedef int (*fake_hd_scheduled_t)();
}
