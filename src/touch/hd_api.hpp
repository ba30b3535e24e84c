#pragma once

/// @file touch/hd_api.hpp
/// @brief Our own declarations of the part of the OpenHaptics HD API that TouchDevice uses, so that
/// libfsm builds without the vendor SDK and loads libHD.so at run time.
///
/// Sources of the numeric values (OpenHaptics 3.x, SensAble/3D Systems; written here from the
/// published values, not copied):
/// - types, error codes, parameter names, capabilities, calibration codes and styles, the
///   scheduler priority range and HD_INVALID_HANDLE: HD/hdDefines.h (as mirrored in
///   github.com/hhmai/PhantomAPI, include/HD/hdDefines.h);
/// - HDCallbackCode, HD_CALLBACK_DONE/CONTINUE, HDSchedulerHandle, HDWaitCode and
///   HD_WAIT_CHECK_STATUS/INFINITE, and the scheduler prototypes: HD/hdScheduler.h;
/// - the device prototypes (hdInitDevice ... hdUpdateCalibration): HD/hdDevice.h.
/// The library name on Linux (libHD.so) agrees with github.com/mikelitu/pyOpenHaptics (hd.py).
/// On Linux HDAPIENTRY and HDCALLBACK expand to nothing: plain C calling convention.

#include <climits>

namespace fsm::haptics::detail::hd {

// hdDefines.h: scalar types.
using HDuint = unsigned int;
using HDboolean = unsigned char;
using HDulong = unsigned long;
using HDushort = unsigned short;
using HDint = int;
using HDdouble = double;
using HDerror = unsigned int;
using HDenum = unsigned int;
using HDstring = const char*;
using HHD = unsigned int;

/// @brief hdGetError's answer (returned by value, a C struct).
struct HDErrorInfo {
  HDerror errorCode;      ///< an HD_ error code, HD_SUCCESS when the stack is empty
  int internalErrorCode;  ///< the driver's own code
  HHD hHD;                ///< the device current when the error happened
};

// hdScheduler.h: scheduler types.
using HDCallbackCode = unsigned int;
using HDSchedulerHandle = unsigned long;
using HDWaitCode = unsigned int;
extern "C" {
/// @brief A scheduler callback (C linkage, plain calling convention on Linux).
typedef HDCallbackCode (*HDSchedulerCallback)(void* user_data);
}

constexpr HDboolean HD_TRUE = 1;
constexpr HDboolean HD_FALSE = 0;

// Error codes (hdDefines.h).
constexpr HDerror HD_SUCCESS = 0x0000;
constexpr HDerror HD_INVALID_ENUM = 0x0100;
constexpr HDerror HD_INVALID_VALUE = 0x0101;
constexpr HDerror HD_INVALID_OPERATION = 0x0102;
constexpr HDerror HD_INVALID_INPUT_TYPE = 0x0103;
constexpr HDerror HD_BAD_HANDLE = 0x0104;
constexpr HDerror HD_WARM_MOTORS = 0x0200;
constexpr HDerror HD_EXCEEDED_MAX_FORCE = 0x0201;
constexpr HDerror HD_EXCEEDED_MAX_FORCE_IMPULSE = 0x0202;
constexpr HDerror HD_EXCEEDED_MAX_VELOCITY = 0x0203;
constexpr HDerror HD_FORCE_ERROR = 0x0204;
constexpr HDerror HD_DEVICE_FAULT = 0x0300;
constexpr HDerror HD_DEVICE_ALREADY_INITIATED = 0x0301;
constexpr HDerror HD_COMM_ERROR = 0x0302;
constexpr HDerror HD_COMM_CONFIG_ERROR = 0x0303;
constexpr HDerror HD_TIMER_ERROR = 0x0304;
constexpr HDerror HD_ILLEGAL_BEGIN = 0x0400;
constexpr HDerror HD_ILLEGAL_END = 0x0401;
constexpr HDerror HD_FRAME_ERROR = 0x0402;
constexpr HDerror HD_INVALID_PRIORITY = 0x0500;
constexpr HDerror HD_SCHEDULER_FULL = 0x0501;
constexpr HDerror HD_INVALID_LICENSE = 0x0600;

// Get/set parameters (hdDefines.h).
constexpr HDenum HD_CURRENT_BUTTONS = 0x2000;              // HDint bit mask
constexpr HDenum HD_CURRENT_POSITION = 0x2050;             // 3 HDdouble (mm)
constexpr HDenum HD_CURRENT_VELOCITY = 0x2051;             // 3 HDdouble (mm/s)
constexpr HDenum HD_CURRENT_TRANSFORM = 0x2052;            // 16 HDdouble, column-major, mm
constexpr HDenum HD_DEVICE_MODEL_TYPE = 0x2501;            // string
constexpr HDenum HD_DEVICE_SERIAL_NUMBER = 0x2504;         // string
constexpr HDenum HD_USABLE_WORKSPACE_DIMENSIONS = 0x2551;  // 6 HDdouble: min xyz, max xyz (mm)
constexpr HDenum HD_CALIBRATION_STYLE = 0x2555;            // HDint: the supported styles
constexpr HDenum HD_NOMINAL_MAX_FORCE = 0x2603;            // 1 HDdouble (N)
constexpr HDenum HD_CURRENT_FORCE = 0x2700;                // 3 HDdouble (N)

// Capabilities for hdEnable/hdDisable (hdDefines.h).
constexpr HDenum HD_FORCE_OUTPUT = 0x4000;

// Scheduler priorities (hdDefines.h): the default is the middle of [0, USHRT_MAX].
constexpr HDushort HD_MAX_SCHEDULER_PRIORITY = USHRT_MAX;
constexpr HDushort HD_MIN_SCHEDULER_PRIORITY = 0;
constexpr HDushort HD_DEFAULT_SCHEDULER_PRIORITY =
    (HD_MAX_SCHEDULER_PRIORITY + HD_MIN_SCHEDULER_PRIORITY) / 2;

// hdCheckCalibration's answers and the calibration styles (hdDefines.h).
constexpr HDenum HD_CALIBRATION_OK = 0x5000;
constexpr HDenum HD_CALIBRATION_NEEDS_UPDATE = 0x5001;
constexpr HDenum HD_CALIBRATION_NEEDS_MANUAL_INPUT = 0x5002;
constexpr HDint HD_CALIBRATION_ENCODER_RESET = 1 << 0;
constexpr HDint HD_CALIBRATION_AUTO = 1 << 1;
constexpr HDint HD_CALIBRATION_INKWELL = 1 << 2;

/// @brief The null device handle; hdInitDevice returns it when no device answers.
constexpr HHD HD_INVALID_HANDLE = 0xFFFFFFFF;

// hdScheduler.h.
constexpr HDCallbackCode HD_CALLBACK_DONE = 0;
constexpr HDCallbackCode HD_CALLBACK_CONTINUE = 1;
constexpr HDWaitCode HD_WAIT_CHECK_STATUS = 0;
constexpr HDWaitCode HD_WAIT_INFINITE = 1;

/// @brief The HD functions TouchDevice calls, as C function-pointer types (hdDevice.h,
/// hdScheduler.h). The names match the exported symbols.
extern "C" {
typedef HHD (*hdInitDevice_t)(HDstring config_name);
typedef void (*hdMakeCurrentDevice_t)(HHD handle);
typedef void (*hdDisableDevice_t)(HHD handle);
typedef HHD (*hdGetCurrentDevice_t)();
typedef void (*hdBeginFrame_t)(HHD handle);
typedef void (*hdEndFrame_t)(HHD handle);
typedef HDErrorInfo (*hdGetError_t)();
typedef HDstring (*hdGetErrorString_t)(HDerror code);
typedef void (*hdEnable_t)(HDenum capability);
typedef void (*hdDisable_t)(HDenum capability);
typedef void (*hdGetIntegerv_t)(HDenum name, HDint* values);
typedef void (*hdGetDoublev_t)(HDenum name, HDdouble* values);
typedef HDstring (*hdGetString_t)(HDenum name);
typedef void (*hdSetDoublev_t)(HDenum name, const HDdouble* values);
typedef HDenum (*hdCheckCalibration_t)();
typedef void (*hdUpdateCalibration_t)(HDenum style);
typedef void (*hdStartScheduler_t)();
typedef void (*hdStopScheduler_t)();
typedef void (*hdScheduleSynchronous_t)(HDSchedulerCallback callback, void* user_data,
                                        HDushort priority);
typedef HDSchedulerHandle (*hdScheduleAsynchronous_t)(HDSchedulerCallback callback, void* user_data,
                                                      HDushort priority);
typedef void (*hdUnschedule_t)(HDSchedulerHandle handle);
typedef HDboolean (*hdWaitForCompletion_t)(HDSchedulerHandle handle, HDWaitCode wait);
}

}  // namespace fsm::haptics::detail::hd
