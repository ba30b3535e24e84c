// TouchDevice against the fake libHD.so (tests/touch/fake_hd.cpp): call order, units, frames,
// force clamp, the servo callback's life cycle and every error path.

#include "fsm/haptics/touch_device.hpp"

#include <dlfcn.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "fake_hd.hpp"
#include "fsm/error.hpp"

namespace {

using fsm::Error;
using fsm::Vector3;
using fsm::haptics::DeviceState;
using fsm::haptics::TouchDevice;
using Clock = std::chrono::steady_clock;

/// The fake's control functions, from our own handle on the same libHD.so TouchDevice opens
/// (dlopen of one path gives one instance, so both see the same state).
struct FakeHd {
  void* handle{nullptr};
  fake_hd_reset_t reset{};
  fake_hd_set_failure_t set_failure{};
  fake_hd_set_max_force_t set_max_force{};
  fake_hd_set_buttons_t set_buttons{};
  fake_hd_calls_t calls_text{};
  fake_hd_frame_t frame{};
  fake_hd_device_open_t device_open{};
  fake_hd_scheduler_running_t scheduler_running{};
  fake_hd_force_output_t force_output{};
  fake_hd_scheduled_t scheduled{};

  template <typename F>
  void bind(F& f, const char* symbol) {
    f = reinterpret_cast<F>(dlsym(handle, symbol));
    if (f == nullptr) throw std::runtime_error(std::string("fake HD lacks ") + symbol);
  }

  FakeHd() {
    handle = dlopen(FSM_FAKE_HD, RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) throw std::runtime_error(dlerror());
    bind(reset, "fake_hd_reset");
    bind(set_failure, "fake_hd_set_failure");
    bind(set_max_force, "fake_hd_set_max_force");
    bind(set_buttons, "fake_hd_set_buttons");
    bind(calls_text, "fake_hd_calls");
    bind(frame, "fake_hd_frame");
    bind(device_open, "fake_hd_device_open");
    bind(scheduler_running, "fake_hd_scheduler_running");
    bind(force_output, "fake_hd_force_output");
    bind(scheduled, "fake_hd_scheduled");
  }

  std::vector<std::string> calls() const {
    std::vector<std::string> out;
    std::istringstream in(calls_text());
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
  }
};

FakeHd& fake() {
  static FakeHd f;  // kept open for the whole run
  return f;
}

/// Index of the first call at or after `from` that starts with `prefix`, or -1.
long find_call(const std::vector<std::string>& calls, const std::string& prefix, long from = 0) {
  for (long i = std::max(from, 0L); i < long(calls.size()); ++i) {
    if (calls[std::size_t(i)].rfind(prefix, 0) == 0) return i;
  }
  return -1;
}

long find_last_call(const std::vector<std::string>& calls, const std::string& prefix) {
  for (long i = long(calls.size()) - 1; i >= 0; --i) {
    if (calls[std::size_t(i)].rfind(prefix, 0) == 0) return i;
  }
  return -1;
}

/// The calls appear in this order (others may come between).
::testing::AssertionResult in_order(const std::vector<std::string>& calls,
                                    const std::vector<std::string>& expected) {
  long at = 0;
  for (const std::string& e : expected) {
    const long i = find_call(calls, e, at);
    if (i < 0) {
      std::string log;
      for (const auto& c : calls) log += "  " + c + "\n";
      return ::testing::AssertionFailure() << "\"" << e << "\" missing or out of order in\n" << log;
    }
    at = i + 1;
  }
  return ::testing::AssertionSuccess();
}

/// The fake logs a "!" line when the HD API's rules are broken (frames off the scheduler thread,
/// current state outside a frame).
::testing::AssertionResult no_violations(const std::vector<std::string>& calls) {
  for (const auto& c : calls) {
    if (!c.empty() && c[0] == '!') return ::testing::AssertionFailure() << c;
  }
  return ::testing::AssertionSuccess();
}

template <typename Predicate>
bool wait_for(Predicate p, std::chrono::milliseconds timeout = std::chrono::milliseconds(3000)) {
  const auto end = Clock::now() + timeout;
  while (!p()) {
    if (Clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

/// The fake's state at frame n in the simulation frame given by `r`, in SI units.
Vector3<double> expected_position(long n, const Eigen::Matrix3d& r) {
  double mm[3];
  fake_hd::position_mm(n, mm);
  return r * Vector3<double>(mm[0], mm[1], mm[2]) * 1e-3;
}

/// Runs `make` and returns the fsm::Error it throws (fails the test if it throws nothing else).
template <typename F>
std::string error_of(F make) {
  try {
    make();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no fsm::Error thrown";
  return std::string();
}

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "\"" << (text) << "\""

class TouchDeviceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    setenv("FSM_LIBHD", FSM_FAKE_HD, 1);
    fake().reset();
  }
  void TearDown() override { fake().reset(); }
};

// Positions, velocities and orientations go through these; 1e-12 m is far below a micrometre and
// far above the rounding of a 3 x 3 product of numbers below 1.
constexpr double kTight = 1e-12;

TEST_F(TouchDeviceTest, LimitsBeforeStartAreTheTouchsNominalOnesInTheSimulationFrame) {
  const TouchDevice device;
  const auto limits = device.limits();
  EXPECT_DOUBLE_EQ(limits.max_force, 3.3);
  // 160 x 120 x 70 mm (device x, y, z); z_up sends device y to z and z to -y.
  EXPECT_TRUE(limits.workspace_min.isApprox(Vector3<double>(-0.08, -0.035, -0.06), kTight));
  EXPECT_TRUE(limits.workspace_max.isApprox(Vector3<double>(0.08, 0.035, 0.06), kTight));
  EXPECT_EQ(device.name(), "touch:default");
  EXPECT_TRUE(device.has_scheduler());
  EXPECT_FALSE(device.started());
  EXPECT_TRUE(fake().calls().empty()) << "the constructor must not touch the library";
}

TEST_F(TouchDeviceTest, ZUpIsARotationSendingDeviceUpToSimulationUp) {
  const Eigen::Matrix3d r = TouchDevice::z_up();
  EXPECT_NEAR(r.determinant(), 1.0, kTight);
  EXPECT_TRUE((r * Vector3<double>::UnitY()).isApprox(Vector3<double>::UnitZ()));   // up
  EXPECT_TRUE((r * Vector3<double>::UnitZ()).isApprox(-Vector3<double>::UnitY()));  // to user
  EXPECT_TRUE((r * Vector3<double>::UnitX()).isApprox(Vector3<double>::UnitX()));   // right
}

TEST_F(TouchDeviceTest, ConstructorRejectsAMatrixThatIsNotARotation) {
  const Eigen::Matrix3d mirror = Eigen::Vector3d(1, 1, -1).asDiagonal();
  EXPECT_CONTAINS(error_of([&] { TouchDevice d("", mirror); }), "rotation");
  EXPECT_CONTAINS(error_of([&] { TouchDevice d("", 2.0 * Eigen::Matrix3d::Identity()); }),
                  "rotation");
}

TEST_F(TouchDeviceTest, StartAndStopFollowTheHdSequence) {
  fake().set_max_force(2.5);
  {
    TouchDevice device;
    device.start();
    EXPECT_TRUE(device.started());
    EXPECT_EQ(fake().device_open(), 1);
    EXPECT_EQ(fake().scheduler_running(), 1);
    EXPECT_EQ(fake().force_output(), 1);

    const auto limits = device.limits();
    EXPECT_DOUBLE_EQ(limits.max_force, 2.5);  // read from HD_NOMINAL_MAX_FORCE, not the default
    // (-80, -60, -35) .. (80, 60, 35) mm, rotated to z up.
    EXPECT_TRUE(limits.workspace_min.isApprox(Vector3<double>(-0.08, -0.035, -0.06), kTight));
    EXPECT_TRUE(limits.workspace_max.isApprox(Vector3<double>(0.08, 0.035, 0.06), kTight));

    const auto calls = fake().calls();
    EXPECT_TRUE(in_order(calls, {"hdInitDevice(NULL)", "hdGetError()", "hdMakeCurrentDevice(1)",
                                 "hdGetDoublev(0x2603)", "hdGetDoublev(0x2551)", "hdEnable(0x4000)",
                                 "hdStartScheduler()", "hdScheduleSynchronous(32767)",
                                 "hdBeginFrame(1)", "hdCheckCalibration()", "hdEndFrame(1)"}));
    EXPECT_EQ(find_call(calls, "hdUpdateCalibration"), -1) << "calibration was OK";
    EXPECT_TRUE(no_violations(calls));

    device.start();  // a second start does nothing
    EXPECT_EQ(find_call(fake().calls(), "hdInitDevice", find_call(calls, "hdInitDevice") + 1), -1);

    device.stop();
    EXPECT_FALSE(device.started());
    EXPECT_EQ(fake().device_open(), 0);
    EXPECT_EQ(fake().scheduler_running(), 0);
    EXPECT_EQ(fake().force_output(), 0);
    const auto after = fake().calls();
    const long stop_at = long(calls.size());
    EXPECT_TRUE(in_order(std::vector<std::string>(after.begin() + stop_at, after.end()),
                         {"hdDisable(0x4000)", "hdStopScheduler()", "hdDisableDevice(1)"}));
    device.stop();  // and a second stop too
    EXPECT_EQ(fake().calls().size(), after.size());
  }
}

TEST_F(TouchDeviceTest, DestructorStopsTheDevice) {
  {
    TouchDevice device;
    device.start();
    device.run_scheduler([] { return true; });
  }
  EXPECT_EQ(fake().device_open(), 0);
  EXPECT_EQ(fake().scheduler_running(), 0);
  EXPECT_EQ(fake().scheduled(), 0);
}

TEST_F(TouchDeviceTest, NamedDeviceIsInitialisedByName) {
  TouchDevice device("Touch2");
  EXPECT_EQ(device.name(), "touch:Touch2");
  device.start();
  const auto calls = fake().calls();
  EXPECT_TRUE(in_order(calls, {"hdInitDevice(Touch2)", "hdMakeCurrentDevice(2)"}));
  device.stop();
  EXPECT_TRUE(in_order(fake().calls(), {"hdDisableDevice(2)"}));
}

/// What one servo tick saw.
struct Sample {
  DeviceState state;
  long frame{0};
  std::thread::id thread;
};

/// Runs `ticks` servo ticks that read the device, and returns what they saw.
std::vector<Sample> run_ticks(TouchDevice& device, int ticks) {
  std::vector<Sample> samples(static_cast<std::size_t>(ticks));
  std::atomic<int> count{0};
  device.run_scheduler([&] {
    const int k = count.load();
    Sample& s = samples[std::size_t(k)];
    s.state = device.read(0.001 * k);
    s.frame = fake().frame();
    s.thread = std::this_thread::get_id();
    count.store(k + 1);
    return k + 1 < ticks;
  });
  EXPECT_TRUE(wait_for([&] { return !device.servo_running(); })) << "the tick never ended";
  device.stop_scheduler();
  EXPECT_EQ(count.load(), ticks);
  return samples;
}

TEST_F(TouchDeviceTest, ServoTicksReadMetresAndTheStylusPoseInTheSimulationFrame) {
  fake().set_buttons(0b101);
  for (const Eigen::Matrix3d& r : {TouchDevice::z_up(), Eigen::Matrix3d::Identity().eval()}) {
    fake().reset();
    fake().set_buttons(0b101);
    TouchDevice device("", r);
    device.start();
    const auto samples = run_ticks(device, 5);
    const Eigen::Quaterniond stylus(
        Eigen::AngleAxisd(0.5 * double(EIGEN_PI), Vector3<double>::UnitY()));
    const Eigen::Quaterniond expected_orientation(r * stylus.toRotationMatrix());
    const Vector3<double> expected_velocity =
        r *
        Vector3<double>(fake_hd::kVelocityMm[0], fake_hd::kVelocityMm[1], fake_hd::kVelocityMm[2]) *
        1e-3;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      const Sample& s = samples[k];
      SCOPED_TRACE("tick " + std::to_string(k));
      EXPECT_NE(s.thread, std::this_thread::get_id()) << "ticks run on the HD scheduler's thread";
      EXPECT_DOUBLE_EQ(s.state.time, 0.001 * double(k));
      EXPECT_LT((s.state.position - expected_position(s.frame, r)).norm(), kTight);
      EXPECT_LT((s.state.linear_velocity - expected_velocity).norm(), kTight);
      EXPECT_LT(s.state.orientation.angularDistance(expected_orientation), 1e-9);
      EXPECT_EQ(s.state.buttons, 0b101u);
      if (k > 0) {
        EXPECT_EQ(s.frame, samples[k - 1].frame + 1) << "one tick per frame";
      }
    }
    // The parameter values are written out here (hdDefines.h) rather than taken from hd_api.hpp,
    // which the fake shares: a wrong value there fails this.
    EXPECT_TRUE(in_order(
        fake().calls(), {"hdScheduleAsynchronous(32767)", "hdBeginFrame(1)", "hdGetDoublev(0x2050)",
                         "hdGetDoublev(0x2051)", "hdGetDoublev(0x2052)", "hdGetIntegerv(0x2000)",
                         "hdSetDoublev(0x2700", "hdEndFrame(1)", "hdGetError()"}));
    EXPECT_TRUE(no_violations(fake().calls()));

    // Outside the servo thread, read() gives the latest tick's state with the caller's time.
    const DeviceState outside = device.read(7.0);
    EXPECT_DOUBLE_EQ(outside.time, 7.0);
    EXPECT_LT((outside.position - samples.back().state.position).norm(), kTight);
    EXPECT_TRUE(no_violations(fake().calls())) << "read() outside the tick touched the device";
    device.stop();
  }
}

TEST_F(TouchDeviceTest, ForceIsClampedAndSentInNewtonsInTheDeviceFrame) {
  fake().set_max_force(2.5);
  TouchDevice device;  // z_up: simulation z is device y
  device.start();
  std::vector<Vector3<double>> commanded(3, Vector3<double>::Constant(-1));
  std::atomic<int> count{0};
  device.run_scheduler([&] {
    const int k = count.load();
    if (k == 0) commanded[0] = device.apply_force(Vector3<double>(0, 0, 10));  // too strong
    if (k == 1) commanded[1] = device.apply_force(Vector3<double>(0.3, -0.4, 1.2));
    if (k == 2) {
      commanded[2] =
          device.apply_force(Vector3<double>(std::numeric_limits<double>::quiet_NaN(), 0, 1));
    }
    count.store(k + 1);
    return k + 1 < 4;
  });
  ASSERT_TRUE(wait_for([&] { return !device.servo_running(); }));
  device.stop_scheduler();

  EXPECT_TRUE(commanded[0].isApprox(Vector3<double>(0, 0, 2.5), kTight));       // magnitude 2.5 N
  EXPECT_TRUE(commanded[1].isApprox(Vector3<double>(0.3, -0.4, 1.2), kTight));  // under the limit
  EXPECT_TRUE(commanded[2].isZero()) << "a non-finite force commands zero";

  // One HD_CURRENT_FORCE per frame, inside it, in the device frame (x, y, z) = (x, z, -y)_sim;
  // the frame that ends the callback sends zero.
  std::vector<std::string> forces;
  const auto calls = fake().calls();
  for (const auto& c : calls) {
    if (c.rfind("hdSetDoublev(0x2700", 0) == 0) forces.push_back(c);
  }
  ASSERT_EQ(forces.size(), 4u);
  EXPECT_EQ(forces[0], "hdSetDoublev(0x2700, 0, 2.5, 0)");
  EXPECT_EQ(forces[1], "hdSetDoublev(0x2700, 0.3, 1.2, 0.4)");
  EXPECT_EQ(forces[2], "hdSetDoublev(0x2700, 0, 0, 0)");
  EXPECT_EQ(forces[3], "hdSetDoublev(0x2700, 0, 0, 0)");
  EXPECT_TRUE(no_violations(calls));
  device.stop();
}

TEST_F(TouchDeviceTest, StopSchedulerEndsATickThatNeverReturnsFalse) {
  TouchDevice device;
  device.start();
  std::atomic<int> count{0};
  for (int round = 0; round < 2; ++round) {  // and the device can be scheduled again
    SCOPED_TRACE("round " + std::to_string(round));
    const int before = count.load();
    device.run_scheduler([&] {
      device.apply_force(Vector3<double>(0, 0, 1));
      count.fetch_add(1);
      return true;
    });
    EXPECT_TRUE(device.servo_running());
    ASSERT_TRUE(wait_for([&] { return count.load() >= before + 3; }));
    device.stop_scheduler();
    EXPECT_FALSE(device.servo_running());
    EXPECT_EQ(fake().scheduled(), 0);
    const int after = count.load();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // 20 scheduler periods
    EXPECT_EQ(count.load(), after) << "the tick ran after stop_scheduler() returned";
    const auto calls = fake().calls();
    EXPECT_EQ(calls[std::size_t(find_last_call(calls, "hdSetDoublev(0x2700"))],
              "hdSetDoublev(0x2700, 0, 0, 0)")
        << "the last frame must send zero force";
    EXPECT_GT(find_last_call(calls, "hdWaitForCompletion"), find_last_call(calls, "hdEndFrame"))
        << "stop_scheduler() waits for the callback";
    device.stop_scheduler();  // nothing scheduled: no effect
  }
  device.stop();
  const auto calls = fake().calls();
  EXPECT_GT(find_call(calls, "hdDisable(0x4000)"), find_last_call(calls, "hdEndFrame"));
  EXPECT_TRUE(no_violations(calls));
}

TEST_F(TouchDeviceTest, ATickThatThrowsEndsTheCallbackWithZeroForce) {
  TouchDevice device;
  device.start();
  std::atomic<int> count{0};
  device.run_scheduler([&]() -> bool {
    device.apply_force(Vector3<double>(1, 0, 0));
    if (count.fetch_add(1) == 2) throw std::runtime_error("simulation diverged");
    return true;
  });
  ASSERT_TRUE(wait_for([&] { return !device.servo_running(); }));
  EXPECT_EQ(count.load(), 3);
  device.stop_scheduler();
  const auto calls = fake().calls();
  EXPECT_EQ(calls[std::size_t(find_last_call(calls, "hdSetDoublev(0x2700"))],
            "hdSetDoublev(0x2700, 0, 0, 0)");
  EXPECT_EQ(device.servo_error(), 0u);

  // A callback that ended by itself needs no stop_scheduler() before the next.
  device.run_scheduler([&] { return count.fetch_add(1) < 5; });
  ASSERT_TRUE(wait_for([&] { return !device.servo_running(); }));
  EXPECT_EQ(count.load(), 6);  // ticks saw 3, 4, 5
  device.run_scheduler([] { return false; });
  EXPECT_TRUE(wait_for([&] { return !device.servo_running(); }));
  device.stop();
  EXPECT_EQ(fake().scheduled(), 0);
}

TEST_F(TouchDeviceTest, AServoFaultEndsTheCallbackAndIsReported) {
  TouchDevice device;
  device.start();
  fake().set_failure(fake_hd::kServoFault);  // every frame from now on fails
  std::atomic<int> count{0};
  device.run_scheduler([&] {
    count.fetch_add(1);
    return true;
  });
  ASSERT_TRUE(wait_for([&] { return !device.servo_running(); }));
  EXPECT_EQ(count.load(), 1);
  EXPECT_EQ(device.servo_error(), 0x0302u);  // HD_COMM_ERROR
  device.stop_scheduler();
  device.stop();
  EXPECT_EQ(fake().device_open(), 0);
}

TEST_F(TouchDeviceTest, RunSchedulerErrors) {
  TouchDevice device;
  EXPECT_CONTAINS(error_of([&] { device.run_scheduler([] { return true; }); }), "before start");
  device.start();
  EXPECT_CONTAINS(error_of([&] { device.run_scheduler(nullptr); }), "tick");
  device.run_scheduler([] { return true; });
  EXPECT_CONTAINS(error_of([&] { device.run_scheduler([] { return true; }); }), "already running");
  device.stop_scheduler();

  fake().set_failure(fake_hd::kScheduleFailure);
  const std::string what = error_of([&] { device.run_scheduler([] { return true; }); });
  EXPECT_CONTAINS(what, "touch");
  EXPECT_CONTAINS(what, "hdScheduleAsynchronous");
  EXPECT_CONTAINS(what, "0x0501");  // HD_SCHEDULER_FULL
  EXPECT_FALSE(device.servo_running());
  device.stop();
}

/// After a failed start() nothing may stay open.
void expect_all_closed(const TouchDevice& device) {
  EXPECT_FALSE(device.started());
  EXPECT_EQ(fake().device_open(), 0);
  EXPECT_EQ(fake().scheduler_running(), 0);
  EXPECT_EQ(fake().force_output(), 0);
}

TEST_F(TouchDeviceTest, NoDeviceGivesAnErrorWithTheHdCode) {
  fake().set_failure(fake_hd::kNoDevice);
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "touch");
  EXPECT_CONTAINS(what, FSM_FAKE_HD);
  EXPECT_CONTAINS(what, "default device");
  EXPECT_CONTAINS(what, "0x0303");                      // HD_COMM_CONFIG_ERROR
  EXPECT_CONTAINS(what, "fake: no device configured");  // hdGetErrorString
  expect_all_closed(device);
}

TEST_F(TouchDeviceTest, UnknownDeviceNameIsNamedInTheError) {
  TouchDevice device("Left Touch");
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "\"Left Touch\"");
  EXPECT_CONTAINS(what, "hdInitDevice");
  expect_all_closed(device);
}

TEST_F(TouchDeviceTest, CalibrationNeedingAnUpdateIsUpdatedWithTheAutoStyle) {
  fake().set_failure(fake_hd::kCalibrationUpdate);
  TouchDevice device;
  device.start();
  const auto calls = fake().calls();
  EXPECT_TRUE(in_order(
      calls, {"hdCheckCalibration()", "hdUpdateCalibration(0x2)", "hdCheckCalibration()"}));
  EXPECT_TRUE(no_violations(calls));
  device.stop();
}

TEST_F(TouchDeviceTest, CalibrationNeedingManualInputAsksForTheInkwell) {
  fake().set_failure(fake_hd::kCalibrationManual);
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "touch");
  EXPECT_CONTAINS(what, "inkwell");
  expect_all_closed(device);
}

TEST_F(TouchDeviceTest, CalibrationThatDoesNotCompleteIsAnError) {
  fake().set_failure(fake_hd::kCalibrationStuck);
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "not calibrated");
  EXPECT_CONTAINS(what, "0x5001");  // HD_CALIBRATION_NEEDS_UPDATE
  EXPECT_CONTAINS(what, "HD_CALIBRATION_AUTO");
  expect_all_closed(device);
}

TEST_F(TouchDeviceTest, SchedulerFailureGivesAnErrorWithTheHdCode) {
  fake().set_failure(fake_hd::kSchedulerFailure);
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "hdStartScheduler");
  EXPECT_CONTAINS(what, "0x0304");  // HD_TIMER_ERROR
  EXPECT_CONTAINS(what, "internal code 11");
  expect_all_closed(device);
}

TEST_F(TouchDeviceTest, MissingLibraryIsNamed) {
  const std::string path = "/nonexistent/fsm-test/libHD.so";
  setenv("FSM_LIBHD", path.c_str(), 1);
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "touch");
  EXPECT_CONTAINS(what, path);
  EXPECT_CONTAINS(what, "FSM_LIBHD");
  EXPECT_FALSE(device.started());
}

TEST_F(TouchDeviceTest, LibraryWithoutAnHdFunctionIsNamedWithTheSymbol) {
  setenv("FSM_LIBHD", FSM_FAKE_HD_INCOMPLETE, 1);
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, FSM_FAKE_HD_INCOMPLETE);
  EXPECT_CONTAINS(what, "hdWaitForCompletion");
  EXPECT_FALSE(device.started());
}

TEST_F(TouchDeviceTest, WithoutFsmLibhdTheStandardNamesAreTried) {
  unsetenv("FSM_LIBHD");
  if (void* real = dlopen("libHD.so", RTLD_NOW | RTLD_LOCAL)) {
    dlclose(real);
    GTEST_SKIP() << "a libHD.so is installed here; not testing the search failure";
  }
  TouchDevice device;
  const std::string what = error_of([&] { device.start(); });
  EXPECT_CONTAINS(what, "libHD.so (");
  EXPECT_CONTAINS(what, "libHD.so.3.4");
  EXPECT_CONTAINS(what, "FSM_LIBHD");
}

TEST_F(TouchDeviceTest, RegisteredAsTouchInTheDeviceRegistry) {
  fsm::haptics::register_touch_device();
  const auto names = fsm::haptics::device_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "touch"), names.end());
  auto device = fsm::haptics::make_device("touch", "Touch2");
  ASSERT_NE(device, nullptr);
  EXPECT_EQ(device->name(), "touch:Touch2");
  EXPECT_TRUE(device->has_scheduler());
  device->start();
  EXPECT_TRUE(in_order(fake().calls(), {"hdInitDevice(Touch2)"}));
  device->stop();
}

}  // namespace
