// HapticDevice registry and ScriptedHapticDevice: names, interpolation, CSV scripts and their
// errors, the force clamp and the record.

#include <cstdio>
#include <fstream>

#include "common.hpp"
#include "fsm/haptics/scripted_device.hpp"

namespace fsm::test {
namespace {

using namespace fsm::haptics;
using V3 = Vector3<double>;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

TEST(HapticDevice, RegistryMakesByNameAndListsValidNames) {
  const auto names = device_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "scripted"), names.end());
  auto d = make_device("scripted");
  ASSERT_TRUE(d);
  EXPECT_EQ(d->name(), "scripted");
  const std::string msg = error_of([] { (void)make_device("phantom"); });
  EXPECT_NE(msg.find("phantom"), std::string::npos) << msg;
  EXPECT_NE(msg.find("scripted"), std::string::npos) << msg;  // the valid names
  register_device("fake",
                  [](const std::string&) { return std::make_unique<ScriptedHapticDevice>(); });
  EXPECT_NO_THROW((void)make_device("fake"));
  EXPECT_THROW(register_device("", nullptr), Error);
}

TEST(ScriptedHapticDevice, InterpolatesPositionOrientationAndButtons) {
  const Eigen::Quaterniond q1(Eigen::AngleAxisd(M_PI / 2, V3::UnitZ()));
  ScriptedHapticDevice d({{0.0, V3(0, 0, 0), Eigen::Quaterniond::Identity(), 0},
                          {1.0, V3(0.01, 0, 0), q1, 1},
                          {3.0, V3(0.01, 0.02, 0), q1, 0}});
  EXPECT_DOUBLE_EQ(d.duration(), 3.0);
  auto s = d.read(0.25);
  EXPECT_TRUE(s.position.isApprox(V3(0.0025, 0, 0), 1e-14));
  EXPECT_TRUE(s.linear_velocity.isApprox(V3(0.01, 0, 0), 1e-14));
  EXPECT_EQ(s.buttons, 0u);
  EXPECT_DOUBLE_EQ(s.time, 0.25);
  // Halfway in angle at u = 0.5.
  s = d.read(0.5);
  EXPECT_NEAR(s.orientation.angularDistance(Eigen::Quaterniond::Identity()), M_PI / 4, 1e-12);
  s = d.read(2.0);
  EXPECT_TRUE(s.position.isApprox(V3(0.01, 0.01, 0), 1e-14));
  EXPECT_TRUE(s.linear_velocity.isApprox(V3(0, 0.01, 0), 1e-14));
  EXPECT_EQ(s.buttons, 1u);  // held from the waypoint at 1 s
  // Before the start and after the end: at the end points, at rest.
  s = d.read(-1.0);
  EXPECT_EQ(s.position, V3::Zero());
  EXPECT_EQ(s.linear_velocity, V3::Zero());
  s = d.read(10.0);
  EXPECT_EQ(s.position, V3(0.01, 0.02, 0));
  EXPECT_EQ(s.linear_velocity, V3::Zero());
  // Exactly at a waypoint: that waypoint.
  EXPECT_EQ(d.read(1.0).position, V3(0.01, 0, 0));
  EXPECT_TRUE(d.read(std::nan("")).position.allFinite());
}

TEST(ScriptedHapticDevice, ClampsAndRecordsForces) {
  DeviceLimits lim;
  lim.max_force = 2.0;
  ScriptedHapticDevice d({Waypoint{}}, lim, 3);
  (void)d.read(0.1);
  EXPECT_EQ(d.apply_force(V3(0, 0, 1)), V3(0, 0, 1));
  (void)d.read(0.2);
  const V3 f = d.apply_force(V3(3, 4, 0));  // |f| = 5 > 2: scaled along itself
  EXPECT_TRUE(f.isApprox(V3(1.2, 1.6, 0), 1e-14));
  EXPECT_EQ(d.apply_force(V3(std::nan(""), 0, 0)), V3::Zero());
  EXPECT_EQ(d.apply_force(V3(1, 0, 0)), V3(1, 0, 0));  // not recorded: capacity 3
  const auto rec = d.forces();
  ASSERT_EQ(rec.size(), 3u);
  EXPECT_DOUBLE_EQ(rec[0].time, 0.1);
  EXPECT_DOUBLE_EQ(rec[1].time, 0.2);
  EXPECT_TRUE(rec[1].force.isApprox(V3(1.2, 1.6, 0), 1e-14));
  EXPECT_EQ(d.dropped(), 1u);
  EXPECT_EQ(d.last_force(), V3(1, 0, 0));
  d.stop();
  EXPECT_EQ(d.last_force(), V3::Zero());  // stop commands zero
}

TEST(ScriptedHapticDevice, ReadsCsvScripts) {
  const std::string path = ::testing::TempDir() + "fsm_script.csv";
  {
    std::ofstream f(path);
    f << "# a probe\ntime,x,y,z,qw,qx,qy,qz,buttons\n0, 0, 0, 0.05\n"
         "1.5, 0, 0, 0.04, 1, 0, 0, 0, 1  # pressed\n2.0,0.01,0,0.04,0,0,0,2,0\n";
  }
  ScriptedHapticDevice d = ScriptedHapticDevice::from_csv(path);
  ASSERT_EQ(d.waypoints().size(), 3u);
  EXPECT_EQ(d.waypoints()[1].buttons, 1u);
  EXPECT_TRUE(
      d.waypoints()[2].orientation.coeffs().isApprox(Eigen::Quaterniond(0, 0, 0, 1).coeffs()));
  EXPECT_TRUE(d.read(0.75).position.isApprox(V3(0, 0, 0.045), 1e-14));
  // The registry's "scripted" takes the file as its configuration.
  EXPECT_EQ(make_device("scripted", path)->read(1.5).buttons, 1u);

  auto bad = [&](const std::string& text) {
    {
      std::ofstream f(path);
      f << text;
    }
    return error_of([&] { (void)ScriptedHapticDevice::from_csv(path); });
  };
  std::string e = bad("0,0,0,0\n1,0,zero,0\n");
  EXPECT_NE(e.find(path), std::string::npos) << e;
  EXPECT_NE(e.find("line 2"), std::string::npos) << e;
  e = bad("0,0,0,0\n0,0,0,1\n");
  EXPECT_NE(e.find("increase"), std::string::npos) << e;
  e = bad("0,0,0\n");
  EXPECT_NE(e.find("line 1"), std::string::npos) << e;
  e = bad("0,0,0,0,0,0,0,0\n");
  EXPECT_NE(e.find("quaternion"), std::string::npos) << e;
  e = bad("# nothing\n");
  EXPECT_NE(e.find("at least one"), std::string::npos) << e;
  e = error_of([] { (void)ScriptedHapticDevice::from_csv("/nonexistent/script.csv"); });
  EXPECT_NE(e.find("/nonexistent/script.csv"), std::string::npos) << e;
  std::remove(path.c_str());
}

}  // namespace
}  // namespace fsm::test
