// A stand-in for OpenHaptics' libHD.so, built by the tests as libHD.so in a directory of its own.
// It is the contract TouchDevice is tested against: the HD functions with the HD semantics that
// matter to it (an error stack, frames, a scheduler thread running callbacks at about 1 kHz by
// priority), plus a call log and failure switches (fake_hd.hpp). It allocates freely; it is a test.

#include "fake_hd.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "hd_api.hpp"

using namespace fsm::haptics::detail::hd;

namespace {

struct Op {
  HDSchedulerHandle id;
  HDSchedulerCallback callback;
  void* data;
  HDushort priority;
  bool* done;  // set for synchronous operations
};

struct Fake {
  std::mutex mutex;  // guards everything but the scheduler thread itself
  std::condition_variable changed;
  std::vector<std::string> calls;
  std::string calls_text;
  std::vector<HDErrorInfo> errors;
  // Read by the scheduler thread and the test's thread alike.
  std::atomic<int> failure{fake_hd::kNone};
  std::atomic<double> max_force{3.3};
  std::atomic<int> buttons{0};
  std::atomic<HHD> open{HD_INVALID_HANDLE};
  std::atomic<bool> force_output{false};
  std::atomic<bool> calibration_updated{false};
  std::atomic<long> frame{0};
  std::atomic<bool> in_frame{false};

  std::mutex exec;  // held by the scheduler thread while it runs callbacks
  std::thread thread;
  std::atomic<bool> running{false};
  std::atomic<std::thread::id> scheduler_id{};
  std::vector<Op> ops;
  HDSchedulerHandle next_id = 1;

  ~Fake() { stop(); }

  void stop() {
    if (running.exchange(false) && thread.joinable()) thread.join();
    if (thread.joinable()) thread.join();
  }

  void loop() {
    while (running.load()) {
      {
        std::lock_guard<std::mutex> run(exec);
        std::vector<Op> now;
        {
          std::lock_guard<std::mutex> lock(mutex);
          now = ops;
        }
        std::stable_sort(now.begin(), now.end(),
                         [](const Op& a, const Op& b) { return a.priority > b.priority; });
        for (const Op& op : now) {
          if (op.callback(op.data) == HD_CALLBACK_DONE) {
            std::lock_guard<std::mutex> lock(mutex);
            ops.erase(
                std::remove_if(ops.begin(), ops.end(), [&](const Op& o) { return o.id == op.id; }),
                ops.end());
            if (op.done != nullptr) *op.done = true;
            changed.notify_all();
          }
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
};

Fake& fake() {
  static Fake f;
  return f;
}

void record(const char* format, ...) {
  char line[256];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  std::lock_guard<std::mutex> lock(fake().mutex);
  fake().calls.emplace_back(line);
}

void push_error(HDerror code, int internal = 0) {
  std::lock_guard<std::mutex> lock(fake().mutex);
  fake().errors.push_back(HDErrorInfo{code, internal, fake().open.load()});
}

bool on_scheduler_thread() {
  return fake().running.load() && std::this_thread::get_id() == fake().scheduler_id;
}

/// Current-state parameters may only be touched inside a frame.
bool check_in_frame(const char* what, HDenum name) {
  if (fake().in_frame && on_scheduler_thread()) return true;
  record("!%s(0x%04X) outside a frame", what, name);
  push_error(HD_INVALID_OPERATION);
  return false;
}

}  // namespace

extern "C" {

// ----- the HD API ------------------------------------------------------------------------------

HHD hdInitDevice(HDstring name) {
  record("hdInitDevice(%s)", name == nullptr ? "NULL" : name);
  Fake& f = fake();
  const bool known = name == nullptr || std::strcmp(name, "Default Device") == 0 ||
                     std::strcmp(name, "Touch2") == 0;
  if (f.failure == fake_hd::kNoDevice || !known) {
    push_error(HD_COMM_CONFIG_ERROR, 5);
    return HD_INVALID_HANDLE;
  }
  if (f.open != HD_INVALID_HANDLE) {
    push_error(HD_DEVICE_ALREADY_INITIATED);
    return HD_INVALID_HANDLE;
  }
  f.open = (name != nullptr && std::strcmp(name, "Touch2") == 0) ? 2u : 1u;
  return f.open.load();
}

void hdMakeCurrentDevice(HHD handle) {
  record("hdMakeCurrentDevice(%u)", handle);
  if (handle != fake().open) push_error(HD_BAD_HANDLE);
}

void hdDisableDevice(HHD handle) {
  record("hdDisableDevice(%u)", handle);
  if (handle != fake().open) {
    push_error(HD_BAD_HANDLE);
    return;
  }
  fake().open = HD_INVALID_HANDLE;
  fake().force_output = false;
}

HHD hdGetCurrentDevice() {
  record("hdGetCurrentDevice()");
  return fake().open.load();
}

void hdBeginFrame(HHD handle) {
  record("hdBeginFrame(%u)", handle);
  Fake& f = fake();
  if (!on_scheduler_thread()) {
    record("!hdBeginFrame outside the scheduler thread");
    push_error(HD_ILLEGAL_BEGIN);
    return;
  }
  if (handle != f.open || f.in_frame) {
    push_error(f.in_frame ? HD_ILLEGAL_BEGIN : HD_BAD_HANDLE);
    return;
  }
  ++f.frame;
  f.in_frame = true;
}

void hdEndFrame(HHD handle) {
  record("hdEndFrame(%u)", handle);
  Fake& f = fake();
  if (!f.in_frame || !on_scheduler_thread()) {
    record("!hdEndFrame without hdBeginFrame");
    push_error(HD_ILLEGAL_END);
    return;
  }
  f.in_frame = false;
  if (f.failure == fake_hd::kServoFault) push_error(HD_COMM_ERROR, 7);
}

HDErrorInfo hdGetError() {
  record("hdGetError()");
  std::lock_guard<std::mutex> lock(fake().mutex);
  auto& errors = fake().errors;
  if (errors.empty()) return HDErrorInfo{HD_SUCCESS, 0, fake().open.load()};
  const HDErrorInfo e = errors.back();  // most recent first
  errors.pop_back();
  return e;
}

HDstring hdGetErrorString(HDerror code) {
  switch (code) {
    case HD_COMM_CONFIG_ERROR:
      return "fake: no device configured";
    case HD_TIMER_ERROR:
      return "fake: scheduler timer failed";
    default:
      return "";
  }
}

void hdEnable(HDenum capability) {
  record("hdEnable(0x%04X)", capability);
  if (capability == HD_FORCE_OUTPUT) fake().force_output = true;
}

void hdDisable(HDenum capability) {
  record("hdDisable(0x%04X)", capability);
  if (capability == HD_FORCE_OUTPUT) fake().force_output = false;
}

void hdGetIntegerv(HDenum name, HDint* values) {
  record("hdGetIntegerv(0x%04X)", name);
  switch (name) {
    case HD_CURRENT_BUTTONS:
      if (check_in_frame("hdGetIntegerv", name)) values[0] = fake().buttons;
      return;
    case HD_CALIBRATION_STYLE:
      values[0] = HD_CALIBRATION_AUTO | HD_CALIBRATION_INKWELL;
      return;
    default:
      push_error(HD_INVALID_ENUM);
  }
}

void hdGetDoublev(HDenum name, HDdouble* values) {
  record("hdGetDoublev(0x%04X)", name);
  Fake& f = fake();
  double p[3];
  fake_hd::position_mm(f.frame.load(), p);
  switch (name) {
    case HD_CURRENT_POSITION:
      if (check_in_frame("hdGetDoublev", name)) std::copy(p, p + 3, values);
      return;
    case HD_CURRENT_VELOCITY:
      if (check_in_frame("hdGetDoublev", name)) {
        std::copy(fake_hd::kVelocityMm, fake_hd::kVelocityMm + 3, values);
      }
      return;
    case HD_CURRENT_TRANSFORM:
      if (check_in_frame("hdGetDoublev", name)) {
        // +90 deg about y, column-major: columns are the images of x, y, z.
        const double m[16] = {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, p[0], p[1], p[2], 1};
        std::copy(m, m + 16, values);
      }
      return;
    case HD_NOMINAL_MAX_FORCE:
      values[0] = f.max_force;
      return;
    case HD_USABLE_WORKSPACE_DIMENSIONS: {
      const double box[6] = {-80, -60, -35, 80, 60, 35};
      std::copy(box, box + 6, values);
      return;
    }
    default:
      push_error(HD_INVALID_ENUM);
  }
}

void hdSetDoublev(HDenum name, const HDdouble* values) {
  if (name != HD_CURRENT_FORCE) {
    record("hdSetDoublev(0x%04X)", name);
    push_error(HD_INVALID_ENUM);
    return;
  }
  record("hdSetDoublev(0x%04X, %g, %g, %g)", name, values[0], values[1], values[2]);
  check_in_frame("hdSetDoublev", name);
}

HDenum hdCheckCalibration() {
  record("hdCheckCalibration()");
  switch (fake().failure) {
    case fake_hd::kCalibrationManual:
      return HD_CALIBRATION_NEEDS_MANUAL_INPUT;
    case fake_hd::kCalibrationUpdate:
      return fake().calibration_updated ? HD_CALIBRATION_OK : HD_CALIBRATION_NEEDS_UPDATE;
    case fake_hd::kCalibrationStuck:
      return HD_CALIBRATION_NEEDS_UPDATE;
    default:
      return HD_CALIBRATION_OK;
  }
}

void hdUpdateCalibration(HDenum style) {
  record("hdUpdateCalibration(0x%X)", style);
  if (style == static_cast<HDenum>(HD_CALIBRATION_AUTO)) fake().calibration_updated = true;
}

void hdStartScheduler() {
  record("hdStartScheduler()");
  Fake& f = fake();
  if (f.failure == fake_hd::kSchedulerFailure) {
    push_error(HD_TIMER_ERROR, 11);
    return;
  }
  if (f.running.load()) return;
  f.running.store(true);
  f.thread = std::thread([&f] {
    f.scheduler_id = std::this_thread::get_id();
    f.loop();
  });
  // The thread id must be known before any caller checks it.
  while (f.scheduler_id.load() == std::thread::id()) std::this_thread::yield();
}

void hdStopScheduler() {
  record("hdStopScheduler()");
  fake().stop();
  fake().scheduler_id = std::thread::id();
}

void hdScheduleSynchronous(HDSchedulerCallback callback, void* data, HDushort priority) {
  record("hdScheduleSynchronous(%u)", unsigned(priority));
  Fake& f = fake();
  if (!f.running.load()) {  // the real one would wait for ever
    push_error(HD_INVALID_OPERATION);
    return;
  }
  bool done = false;
  std::unique_lock<std::mutex> lock(f.mutex);
  f.ops.push_back(Op{f.next_id++, callback, data, priority, &done});
  f.changed.wait(lock, [&] { return done; });
}

HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback callback, void* data,
                                         HDushort priority) {
  record("hdScheduleAsynchronous(%u)", unsigned(priority));
  Fake& f = fake();
  if (f.failure == fake_hd::kScheduleFailure) {
    push_error(HD_SCHEDULER_FULL);
    return 0;
  }
  std::lock_guard<std::mutex> lock(f.mutex);
  f.ops.push_back(Op{f.next_id, callback, data, priority, nullptr});
  return f.next_id++;
}

void hdUnschedule(HDSchedulerHandle handle) {
  record("hdUnschedule(%lu)", handle);
  Fake& f = fake();
  std::unique_lock<std::mutex> run(f.exec, std::defer_lock);
  if (!on_scheduler_thread()) run.lock();  // wait for a callback in progress
  std::lock_guard<std::mutex> lock(f.mutex);
  f.ops.erase(
      std::remove_if(f.ops.begin(), f.ops.end(), [&](const Op& o) { return o.id == handle; }),
      f.ops.end());
}

#ifndef FAKE_HD_OMIT_WAIT_FOR_COMPLETION
HDboolean hdWaitForCompletion(HDSchedulerHandle handle, HDWaitCode wait) {
  record("hdWaitForCompletion(%lu, %u)", handle, wait);
  Fake& f = fake();
  std::unique_lock<std::mutex> lock(f.mutex);
  auto scheduled = [&] {
    return std::any_of(f.ops.begin(), f.ops.end(), [&](const Op& o) { return o.id == handle; });
  };
  if (wait == HD_WAIT_CHECK_STATUS) return scheduled() ? HD_TRUE : HD_FALSE;
  if (!f.running.load()) return HD_FALSE;
  f.changed.wait(lock, [&] { return !scheduled() || !f.running.load(); });
  return HD_FALSE;
}
#endif

// ----- test control ----------------------------------------------------------------------------

void fake_hd_reset() {
  Fake& f = fake();
  f.stop();
  f.scheduler_id = std::thread::id();
  std::lock_guard<std::mutex> lock(f.mutex);
  f.calls.clear();
  f.errors.clear();
  f.ops.clear();
  f.failure = fake_hd::kNone;
  f.max_force = 3.3;
  f.buttons = 0;
  f.open = HD_INVALID_HANDLE;
  f.force_output = false;
  f.calibration_updated = false;
  f.frame = 0;
  f.in_frame = false;
}

void fake_hd_set_failure(int failure) {
  fake().failure = failure;
}
void fake_hd_set_max_force(double newtons) {
  fake().max_force = newtons;
}
void fake_hd_set_buttons(int buttons) {
  fake().buttons = buttons;
}

const char* fake_hd_calls() {
  Fake& f = fake();
  std::lock_guard<std::mutex> lock(f.mutex);
  f.calls_text.clear();
  for (const std::string& c : f.calls) f.calls_text += c + "\n";
  return f.calls_text.c_str();
}

long fake_hd_frame() {
  return fake().frame.load();
}
int fake_hd_device_open() {
  return fake().open != HD_INVALID_HANDLE ? 1 : 0;
}
int fake_hd_scheduler_running() {
  return fake().running.load() ? 1 : 0;
}
int fake_hd_force_output() {
  return fake().force_output ? 1 : 0;
}
int fake_hd_scheduled() {
  std::lock_guard<std::mutex> lock(fake().mutex);
  return static_cast<int>(fake().ops.size());
}

}  // extern "C"
