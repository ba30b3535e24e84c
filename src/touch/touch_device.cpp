#include "fsm/haptics/touch_device.hpp"

#include <dlfcn.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>
#include <vector>

#include "fsm/error.hpp"
#include "hd_api.hpp"

namespace fsm::haptics {

namespace hd = detail::hd;

namespace detail {

/// The opened HD library and the functions we use from it.
struct HdLibrary {
  void* handle{nullptr};
  std::string path;

  hd::hdInitDevice_t init_device{};
  hd::hdMakeCurrentDevice_t make_current_device{};
  hd::hdDisableDevice_t disable_device{};
  hd::hdGetCurrentDevice_t get_current_device{};
  hd::hdBeginFrame_t begin_frame{};
  hd::hdEndFrame_t end_frame{};
  hd::hdGetError_t get_error{};
  hd::hdGetErrorString_t get_error_string{};  // optional
  hd::hdEnable_t enable{};
  hd::hdDisable_t disable{};
  hd::hdGetIntegerv_t get_integerv{};
  hd::hdGetDoublev_t get_doublev{};
  hd::hdSetDoublev_t set_doublev{};
  hd::hdCheckCalibration_t check_calibration{};
  hd::hdUpdateCalibration_t update_calibration{};
  hd::hdStartScheduler_t start_scheduler{};
  hd::hdStopScheduler_t stop_scheduler{};
  hd::hdScheduleSynchronous_t schedule_synchronous{};
  hd::hdScheduleAsynchronous_t schedule_asynchronous{};
  hd::hdUnschedule_t unschedule{};
  hd::hdWaitForCompletion_t wait_for_completion{};

  HdLibrary() = default;
  HdLibrary(const HdLibrary&) = delete;
  HdLibrary& operator=(const HdLibrary&) = delete;
  ~HdLibrary() {
    if (handle != nullptr) dlclose(handle);
  }

  /// Drains the HD error stack; returns the most recent error (HD_SUCCESS if none).
  hd::HDErrorInfo take_error() const noexcept {
    hd::HDErrorInfo first{hd::HD_SUCCESS, 0, 0};
    // The stack is finite; the bound only guards against a library that never empties it.
    for (int i = 0; i < 64; ++i) {
      const hd::HDErrorInfo e = get_error();
      if (e.errorCode == hd::HD_SUCCESS) break;
      if (i == 0) first = e;
    }
    return first;
  }

  /// "HD error 0x0302 (description), internal code 5".
  std::string describe(const hd::HDErrorInfo& e) const {
    char code[64];
    std::snprintf(code, sizeof code, "HD error 0x%04X", e.errorCode);
    std::string s = code;
    if (get_error_string != nullptr) {
      const char* text = get_error_string(e.errorCode);
      if (text != nullptr && *text != '\0') s += std::string(" (") + text + ")";
    }
    return s + ", internal code " + std::to_string(e.internalErrorCode);
  }
};

}  // namespace detail

namespace {

constexpr double kMm = 1e-3;  // m per mm

// The Touch's nominal figures (3D Systems data sheet), used until start() reads the device's own.
constexpr double kNominalMaxForce = 3.3;                       // N
constexpr double kNominalWorkspace[3] = {160.0, 120.0, 70.0};  // mm, device x, y, z

template <typename F>
bool resolve(detail::HdLibrary& lib, F& fn, const char* symbol, std::string& missing) {
  dlerror();
  void* p = dlsym(lib.handle, symbol);
  if (p == nullptr) {
    if (!missing.empty()) missing += ", ";
    missing += symbol;
    return false;
  }
  fn = reinterpret_cast<F>(p);
  return true;
}

/// The library names to try, in order.
std::vector<std::string> library_candidates() {
  const char* env = std::getenv("FSM_LIBHD");
  if (env != nullptr && *env != '\0') return {env};
  return {"libHD.so", "libHD.so.3.4"};
}

std::unique_ptr<detail::HdLibrary> open_library() {
  auto lib = std::make_unique<detail::HdLibrary>();
  std::string tried;
  for (const std::string& candidate : library_candidates()) {
    lib->handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (lib->handle != nullptr) {
      lib->path = candidate;
      break;
    }
    const char* why = dlerror();
    if (!tried.empty()) tried += "; ";
    tried += candidate + " (" + (why != nullptr ? why : "not found") + ")";
  }
  if (lib->handle == nullptr) {
    throw Error("", "touch",
                "cannot load the OpenHaptics HD library: tried " + tried +
                    ". Install OpenHaptics for Linux or set FSM_LIBHD to the path of libHD.so");
  }

  std::string missing;
  resolve(*lib, lib->init_device, "hdInitDevice", missing);
  resolve(*lib, lib->make_current_device, "hdMakeCurrentDevice", missing);
  resolve(*lib, lib->disable_device, "hdDisableDevice", missing);
  resolve(*lib, lib->get_current_device, "hdGetCurrentDevice", missing);
  resolve(*lib, lib->begin_frame, "hdBeginFrame", missing);
  resolve(*lib, lib->end_frame, "hdEndFrame", missing);
  resolve(*lib, lib->get_error, "hdGetError", missing);
  resolve(*lib, lib->enable, "hdEnable", missing);
  resolve(*lib, lib->disable, "hdDisable", missing);
  resolve(*lib, lib->get_integerv, "hdGetIntegerv", missing);
  resolve(*lib, lib->get_doublev, "hdGetDoublev", missing);
  resolve(*lib, lib->set_doublev, "hdSetDoublev", missing);
  resolve(*lib, lib->check_calibration, "hdCheckCalibration", missing);
  resolve(*lib, lib->update_calibration, "hdUpdateCalibration", missing);
  resolve(*lib, lib->start_scheduler, "hdStartScheduler", missing);
  resolve(*lib, lib->stop_scheduler, "hdStopScheduler", missing);
  resolve(*lib, lib->schedule_synchronous, "hdScheduleSynchronous", missing);
  resolve(*lib, lib->schedule_asynchronous, "hdScheduleAsynchronous", missing);
  resolve(*lib, lib->unschedule, "hdUnschedule", missing);
  resolve(*lib, lib->wait_for_completion, "hdWaitForCompletion", missing);
  if (!missing.empty()) {
    throw Error(lib->path, "touch",
                "not a usable OpenHaptics HD library: missing symbol(s) " + missing);
  }
  std::string optional;
  resolve(*lib, lib->get_error_string, "hdGetErrorString", optional);
  return lib;
}

bool is_rotation(const Eigen::Matrix3d& r) {
  return r.allFinite() &&
         (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
         std::abs(r.determinant() - 1.0) < 1e-9;
}

/// Axis-aligned box (simulation frame) around the device box [lo, hi] rotated by r.
void rotate_box(const Eigen::Matrix3d& r, const Vector3<double>& lo, const Vector3<double>& hi,
                DeviceLimits& out) {
  const Vector3<double> centre = r * (0.5 * (lo + hi));
  const Vector3<double> half = r.cwiseAbs() * (0.5 * (hi - lo));
  out.workspace_min = centre - half;
  out.workspace_max = centre + half;
}

/// What the synchronous calibration callback exchanges with start().
struct CalibrationJob {
  const detail::HdLibrary* lib{nullptr};
  hd::HHD handle{0};
  hd::HDint style{0};    // the style hdUpdateCalibration gets
  bool updated{false};   // whether hdUpdateCalibration was called
  hd::HDenum status{0};  // hdCheckCalibration's final answer
};

const char* style_name(hd::HDint style) {
  switch (style) {
    case hd::HD_CALIBRATION_AUTO:
      return "HD_CALIBRATION_AUTO";
    case hd::HD_CALIBRATION_INKWELL:
      return "HD_CALIBRATION_INKWELL";
    case hd::HD_CALIBRATION_ENCODER_RESET:
      return "HD_CALIBRATION_ENCODER_RESET";
    default:
      return "an unknown style";
  }
}

/// Errors after which the servo callback cannot go on (device, communication, scheduler).
bool is_fatal(hd::HDerror code) {
  return (code >= hd::HD_DEVICE_FAULT && code <= hd::HD_TIMER_ERROR) ||
         code == hd::HD_INVALID_PRIORITY || code == hd::HD_SCHEDULER_FULL ||
         code == hd::HD_BAD_HANDLE;
}

}  // namespace

/// The HD callbacks' way into TouchDevice's private members.
struct TouchCallbacks {
  static hd::HDCallbackCode servo(void* data) noexcept {
    return static_cast<TouchDevice*>(data)->run_frame();
  }
};

}  // namespace fsm::haptics

// The HD API calls C functions; these trampolines have C language linkage and internal linkage.
namespace {

extern "C" fsm::haptics::detail::hd::HDCallbackCode fsm_touch_servo_callback(void* data) {
  return fsm::haptics::TouchCallbacks::servo(data);
}

/// Checks the calibration in a frame, updates it when the device can do that by itself, checks
/// again (OpenHaptics' own calibration example does the same steps in the scheduler).
extern "C" fsm::haptics::detail::hd::HDCallbackCode fsm_touch_calibration_callback(void* data) {
  namespace hd = fsm::haptics::detail::hd;
  auto& job = *static_cast<fsm::haptics::CalibrationJob*>(data);
  const auto& lib = *job.lib;
  lib.begin_frame(job.handle);
  job.status = lib.check_calibration();
  lib.end_frame(job.handle);
  if (job.status == hd::HD_CALIBRATION_NEEDS_UPDATE) {
    lib.update_calibration(static_cast<hd::HDenum>(job.style));
    job.updated = true;
    lib.begin_frame(job.handle);
    job.status = lib.check_calibration();
    lib.end_frame(job.handle);
  }
  return hd::HD_CALLBACK_DONE;
}

}  // namespace

namespace fsm::haptics {

Eigen::Matrix3d TouchDevice::z_up() {
  Eigen::Matrix3d r;
  // Columns: where the device's x, y, z go in the simulation frame.
  r << 1, 0, 0,  //
      0, 0, -1,  //
      0, 1, 0;
  return r;
}

TouchDevice::TouchDevice(std::string device_name, const Eigen::Matrix3d& device_to_simulation)
    : m_device_name(std::move(device_name)), m_rotation(device_to_simulation) {
  if (!is_rotation(m_rotation)) {
    throw Error("", "touch",
                "device_to_simulation must be a rotation (orthonormal, determinant +1); got "
                "determinant " +
                    std::to_string(m_rotation.determinant()));
  }
  m_limits.max_force = kNominalMaxForce;
  const Vector3<double> half =
      0.5 * kMm * Vector3<double>(kNominalWorkspace[0], kNominalWorkspace[1], kNominalWorkspace[2]);
  rotate_box(m_rotation, -half, half, m_limits);
  for (auto& f : m_force) f.store(0.0);
}

TouchDevice::~TouchDevice() {
  stop();
}

std::string TouchDevice::name() const {
  return "touch:" + (m_device_name.empty() ? std::string("default") : m_device_name);
}

DeviceLimits TouchDevice::limits() const {
  return m_limits;
}

void TouchDevice::start() {
  if (m_library != nullptr) return;
  std::unique_ptr<detail::HdLibrary> lib = open_library();
  const std::string& path = lib->path;
  const std::string device = m_device_name.empty() ? std::string("the default device")
                                                   : "device \"" + m_device_name + "\"";
  auto fail = [&](const std::string& what, const hd::HDErrorInfo& e) {
    throw Error(path, "touch", what + " for " + device + ": " + lib->describe(e));
  };

  lib->take_error();
  const hd::HHD handle = lib->init_device(m_device_name.empty() ? nullptr : m_device_name.c_str());
  const hd::HDErrorInfo init_error = lib->take_error();
  if (handle == hd::HD_INVALID_HANDLE || init_error.errorCode != hd::HD_SUCCESS) {
    if (handle != hd::HD_INVALID_HANDLE) lib->disable_device(handle);
    throw Error(path, "touch",
                "hdInitDevice failed, no answer from " + device + ": " + lib->describe(init_error) +
                    ". Is the Touch plugged in and set up (Touch_Setup / Touch_Diagnostic)?");
  }

  bool force_enabled = false;
  bool scheduler_started = false;
  DeviceLimits limits;
  try {
    lib->make_current_device(handle);

    double max_force = 0;
    double workspace[6] = {0, 0, 0, 0, 0, 0};
    hd::HDint styles = 0;
    lib->get_doublev(hd::HD_NOMINAL_MAX_FORCE, &max_force);
    lib->get_doublev(hd::HD_USABLE_WORKSPACE_DIMENSIONS, workspace);
    lib->get_integerv(hd::HD_CALIBRATION_STYLE, &styles);
    if (const auto e = lib->take_error(); e.errorCode != hd::HD_SUCCESS) {
      fail("reading HD_NOMINAL_MAX_FORCE / HD_USABLE_WORKSPACE_DIMENSIONS failed", e);
    }
    if (!(std::isfinite(max_force) && max_force > 0)) {
      throw Error(path, "touch",
                  device + " reports HD_NOMINAL_MAX_FORCE = " + std::to_string(max_force) +
                      " N; expected a positive force");
    }
    const Vector3<double> lo = kMm * Vector3<double>(workspace[0], workspace[1], workspace[2]);
    const Vector3<double> hi = kMm * Vector3<double>(workspace[3], workspace[4], workspace[5]);
    if (!lo.allFinite() || !hi.allFinite() || (hi.array() <= lo.array()).any()) {
      throw Error(path, "touch",
                  device + " reports an empty HD_USABLE_WORKSPACE_DIMENSIONS box (mm): " +
                      std::to_string(workspace[0]) + ", " + std::to_string(workspace[1]) + ", " +
                      std::to_string(workspace[2]) + " .. " + std::to_string(workspace[3]) + ", " +
                      std::to_string(workspace[4]) + ", " + std::to_string(workspace[5]));
    }
    limits.max_force = max_force;
    rotate_box(m_rotation, lo, hi, limits);

    lib->enable(hd::HD_FORCE_OUTPUT);
    force_enabled = true;
    if (const auto e = lib->take_error(); e.errorCode != hd::HD_SUCCESS) {
      fail("hdEnable(HD_FORCE_OUTPUT) failed", e);
    }
    lib->start_scheduler();
    if (const auto e = lib->take_error(); e.errorCode != hd::HD_SUCCESS) {
      fail("hdStartScheduler failed", e);
    }
    scheduler_started = true;

    // Prefer the styles that need nobody: auto (the Touch), then inkwell (the Omni: automatic once
    // the stylus sits in the inkwell), then encoder reset.
    CalibrationJob job;
    job.lib = lib.get();
    job.handle = handle;
    job.style = (styles & hd::HD_CALIBRATION_AUTO) != 0      ? hd::HD_CALIBRATION_AUTO
                : (styles & hd::HD_CALIBRATION_INKWELL) != 0 ? hd::HD_CALIBRATION_INKWELL
                : (styles & hd::HD_CALIBRATION_ENCODER_RESET) != 0
                    ? hd::HD_CALIBRATION_ENCODER_RESET
                    : hd::HD_CALIBRATION_AUTO;
    lib->schedule_synchronous(&fsm_touch_calibration_callback, &job,
                              hd::HD_DEFAULT_SCHEDULER_PRIORITY);
    if (const auto e = lib->take_error(); e.errorCode != hd::HD_SUCCESS) {
      fail("checking the calibration failed", e);
    }
    if (job.status == hd::HD_CALIBRATION_NEEDS_MANUAL_INPUT) {
      throw Error(path, "touch",
                  device +
                      " needs calibrating by hand: put the stylus in the inkwell (its holder on "
                      "the base)" +
                      (job.style == hd::HD_CALIBRATION_ENCODER_RESET
                           ? std::string(", or hold the arm in its reset position,")
                           : std::string()) +
                      " and start again");
    }
    if (job.status != hd::HD_CALIBRATION_OK) {
      char status[16];
      std::snprintf(status, sizeof status, "0x%04X", job.status);
      throw Error(path, "touch",
                  device + " is not calibrated (hdCheckCalibration returned " + status +
                      (job.updated ? std::string(" after hdUpdateCalibration(") +
                                         style_name(job.style) + ")"
                                   : std::string()) +
                      "); run Touch_Diagnostic to calibrate it");
    }
  } catch (...) {
    if (force_enabled) lib->disable(hd::HD_FORCE_OUTPUT);
    if (scheduler_started) lib->stop_scheduler();
    lib->disable_device(handle);
    lib->take_error();
    throw;
  }

  m_limits = limits;
  m_handle = handle;
  for (auto& f : m_force) f.store(0.0);
  m_servo_error.store(0);
  {
    std::lock_guard<std::mutex> lock(m_snapshot_mutex);
    m_snapshot = DeviceState();
  }
  m_library = std::move(lib);
}

void TouchDevice::stop() noexcept {
  if (m_library == nullptr) return;
  for (auto& f : m_force) f.store(0.0);
  stop_scheduler();  // its last frame sends zero force
  const detail::HdLibrary& lib = *m_library;
  lib.make_current_device(m_handle);
  lib.disable(hd::HD_FORCE_OUTPUT);
  lib.stop_scheduler();
  lib.disable_device(m_handle);
  lib.take_error();
  m_library.reset();  // dlclose
  m_handle = 0;
}

void TouchDevice::run_scheduler(std::function<bool()> tick) {
  if (m_library == nullptr) throw Error("", "touch", "run_scheduler() called before start()");
  if (!tick) throw Error("", "touch", "run_scheduler() needs a tick function");
  if (m_scheduled.load()) {
    if (m_servo_running.load()) {
      throw Error("", "touch",
                  "a servo callback is already running; call stop_scheduler() before scheduling "
                  "another");
    }
    stop_scheduler();  // the previous one has ended by itself: tidy up after it
  }
  const detail::HdLibrary& lib = *m_library;
  m_tick = std::move(tick);
  m_stop_requested.store(false);
  m_servo_error.store(0);
  m_servo_running.store(true);
  lib.take_error();
  const hd::HDSchedulerHandle schedule =
      lib.schedule_asynchronous(&fsm_touch_servo_callback, this, hd::HD_DEFAULT_SCHEDULER_PRIORITY);
  if (const auto e = lib.take_error(); e.errorCode != hd::HD_SUCCESS) {
    m_servo_running.store(false);
    m_tick = nullptr;
    throw Error(lib.path, "touch", "hdScheduleAsynchronous failed: " + lib.describe(e));
  }
  m_schedule = schedule;
  m_scheduled.store(true);
}

void TouchDevice::stop_scheduler() noexcept {
  if (!m_scheduled.load() || m_library == nullptr) return;
  using Clock = std::chrono::steady_clock;
  const detail::HdLibrary& lib = *m_library;
  m_stop_requested.store(true);
  // The callback ends by itself at its next frame (writing zero force); 0.2 s is 200 servo
  // frames, ample unless the scheduler has stalled, in which case we unschedule it.
  const auto deadline = Clock::now() + std::chrono::milliseconds(200);
  bool scheduled = lib.wait_for_completion(m_schedule, hd::HD_WAIT_CHECK_STATUS) != hd::HD_FALSE;
  while (scheduled && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    scheduled = lib.wait_for_completion(m_schedule, hd::HD_WAIT_CHECK_STATUS) != hd::HD_FALSE;
  }
  if (scheduled) lib.unschedule(m_schedule);
  // An unscheduled callback may still be inside its last run.
  const auto last = Clock::now() + std::chrono::milliseconds(200);
  while (m_in_callback.load() && Clock::now() < last) std::this_thread::yield();
  lib.take_error();
  m_servo_running.store(false);
  m_scheduled.store(false);
  m_schedule = 0;
  m_tick = nullptr;
}

hd::HDCallbackCode TouchDevice::run_frame() noexcept {
  m_in_callback.store(true);
  const detail::HdLibrary& lib = *m_library;
  m_servo_thread.store(std::this_thread::get_id());
  lib.begin_frame(m_handle);
  bool keep = !m_stop_requested.load();
  if (keep) {
    m_in_frame.store(true);
    try {
      keep = m_tick();
    } catch (...) {
      keep = false;
    }
    m_in_frame.store(false);
  }
  if (!keep) {
    for (auto& f : m_force) f.store(0.0);
  }
  const double force[3] = {m_force[0].load(), m_force[1].load(), m_force[2].load()};
  lib.set_doublev(hd::HD_CURRENT_FORCE, force);
  lib.end_frame(m_handle);
  const hd::HDErrorInfo e = lib.take_error();
  if (e.errorCode != hd::HD_SUCCESS) {
    m_servo_error.store(e.errorCode);
    if (is_fatal(e.errorCode)) keep = false;
  }
  if (!keep) m_servo_running.store(false);
  m_in_callback.store(false);
  return keep ? hd::HD_CALLBACK_CONTINUE : hd::HD_CALLBACK_DONE;
}

DeviceState TouchDevice::read(double time) noexcept {
  if (m_in_frame.load() && m_servo_thread.load() == std::this_thread::get_id()) {
    return read_in_frame(time);
  }
  std::lock_guard<std::mutex> lock(m_snapshot_mutex);
  DeviceState s = m_snapshot;
  s.time = time;
  return s;
}

DeviceState TouchDevice::read_in_frame(double time) noexcept {
  const detail::HdLibrary& lib = *m_library;
  double position[3] = {0, 0, 0};
  double velocity[3] = {0, 0, 0};
  double transform[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  hd::HDint buttons = 0;
  lib.get_doublev(hd::HD_CURRENT_POSITION, position);
  lib.get_doublev(hd::HD_CURRENT_VELOCITY, velocity);
  lib.get_doublev(hd::HD_CURRENT_TRANSFORM, transform);
  lib.get_integerv(hd::HD_CURRENT_BUTTONS, &buttons);

  DeviceState s;
  s.time = time;
  s.position = kMm * (m_rotation * Eigen::Map<const Vector3<double>>(position));
  s.linear_velocity = kMm * (m_rotation * Eigen::Map<const Vector3<double>>(velocity));
  // HD_CURRENT_TRANSFORM is column-major, Eigen's default storage.
  const Eigen::Map<const Eigen::Matrix4d> t(transform);
  const Eigen::Matrix3d rotation = m_rotation * t.topLeftCorner<3, 3>();
  s.orientation = Eigen::Quaterniond(rotation);
  s.orientation.normalize();
  s.buttons = static_cast<std::uint32_t>(buttons);
  if (m_snapshot_mutex.try_lock()) {
    m_snapshot = s;
    m_snapshot_mutex.unlock();
  }
  return s;
}

Vector3<double> TouchDevice::apply_force(const Vector3<double>& force) noexcept {
  const Vector3<double> commanded = clamp_force(force, m_limits.max_force);
  const Vector3<double> device = m_rotation.transpose() * commanded;
  for (int i = 0; i < 3; ++i) m_force[i].store(device[i]);
  return commanded;
}

void register_touch_device() {
  register_device("touch", [](const std::string& config) -> std::unique_ptr<HapticDevice> {
    return std::make_unique<TouchDevice>(config);
  });
}

}  // namespace fsm::haptics
