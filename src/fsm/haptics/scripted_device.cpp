// ScriptedHapticDevice: waypoints in, forces recorded.

#include "fsm/haptics/scripted_device.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "fsm/error.hpp"

namespace fsm::haptics {

ScriptedHapticDevice::ScriptedHapticDevice()
    : ScriptedHapticDevice(std::vector<Waypoint>{Waypoint{}}) {}

ScriptedHapticDevice::ScriptedHapticDevice(std::vector<Waypoint> waypoints, DeviceLimits limits,
                                           std::size_t record_capacity)
    : m_waypoints(std::move(waypoints)), m_limits(limits), m_record(record_capacity) {
  if (m_waypoints.empty())
    throw Error("", "scripted device", "a script needs at least one waypoint");
  if (!(m_limits.max_force > 0) || !std::isfinite(m_limits.max_force))
    throw Error("", "scripted device", "max_force must be positive and finite");
  for (std::size_t i = 0; i < m_waypoints.size(); ++i) {
    Waypoint& w = m_waypoints[i];
    const std::string what = "waypoint " + std::to_string(i);
    if (!std::isfinite(w.time) || !w.position.allFinite() || !w.orientation.coeffs().allFinite())
      throw Error("", "scripted device", what + ": time, position and orientation must be finite");
    if (!(w.orientation.norm() > 0))
      throw Error("", "scripted device", what + ": the orientation quaternion is zero");
    w.orientation.normalize();
    if (i > 0 && !(w.time > m_waypoints[i - 1].time))
      throw Error("", "scripted device", what + ": times must increase strictly");
  }
}

ScriptedHapticDevice::ScriptedHapticDevice(ScriptedHapticDevice&& other) noexcept
    : m_waypoints(std::move(other.m_waypoints)),
      m_limits(other.m_limits),
      m_record(std::move(other.m_record)),
      m_count(other.m_count.load()) {}

ScriptedHapticDevice ScriptedHapticDevice::from_csv(const std::string& path, DeviceLimits limits) {
  std::ifstream in(path);
  if (!in) throw Error(path, "scripted device", "cannot open the script");
  std::vector<Waypoint> w;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (line.find("time") != std::string::npos) continue;  // header
    std::vector<double> v;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      try {
        std::size_t used = 0;
        v.push_back(std::stod(cell, &used));
        if (cell.find_first_not_of(" \t\r", used) != std::string::npos)
          throw std::invalid_argument(cell);
      } catch (const std::exception&) {
        throw Error(path, "line " + std::to_string(number), "not a number: '" + cell + "'");
      }
    }
    if (v.size() != 4 && v.size() != 5 && v.size() != 8 && v.size() != 9)
      throw Error(path, "line " + std::to_string(number),
                  "expected time,x,y,z[,qw,qx,qy,qz][,buttons], got " + std::to_string(v.size()) +
                      " values");
    Waypoint p;
    p.time = v[0];
    p.position = Vector3<double>(v[1], v[2], v[3]);
    if (v.size() >= 8) p.orientation = Eigen::Quaterniond(v[4], v[5], v[6], v[7]);
    if (v.size() == 5 || v.size() == 9) {
      const double b = v.back();
      if (!(b >= 0) || b != std::floor(b) || b > 4294967295.0)
        throw Error(path, "line " + std::to_string(number),
                    "buttons must be a non-negative integer");
      p.buttons = std::uint32_t(b);
    }
    w.push_back(p);
  }
  try {
    return ScriptedHapticDevice(std::move(w), limits);
  } catch (const Error& e) {
    throw Error(path, e.part(), e.reason());
  }
}

DeviceState ScriptedHapticDevice::state_at(double time) const noexcept {
  DeviceState s;
  s.time = time;
  const auto& w = m_waypoints;
  if (!(time > w.front().time) || w.size() == 1) {
    const Waypoint& p = std::isnan(time) || time <= w.front().time ? w.front() : w.back();
    s.position = p.position;
    s.orientation = p.orientation;
    s.buttons = p.buttons;
    return s;
  }
  if (time >= w.back().time) {
    s.position = w.back().position;
    s.orientation = w.back().orientation;
    s.buttons = w.back().buttons;
    return s;
  }
  // The segment [a, b] holding `time`: binary search.
  std::size_t lo = 0, hi = w.size() - 1;
  while (hi - lo > 1) {
    const std::size_t mid = (lo + hi) / 2;
    (w[mid].time <= time ? lo : hi) = mid;
  }
  const Waypoint& a = w[lo];
  const Waypoint& b = w[hi];
  const double span = b.time - a.time;
  const double u = (time - a.time) / span;
  s.position = a.position + u * (b.position - a.position);
  s.linear_velocity = (b.position - a.position) / span;
  s.orientation = a.orientation.slerp(u, b.orientation);
  s.buttons = a.buttons;
  return s;
}

DeviceState ScriptedHapticDevice::read(double time) noexcept {
  m_last_read.store(time, std::memory_order_relaxed);
  return state_at(time);
}

Vector3<double> ScriptedHapticDevice::apply_force(const Vector3<double>& force) noexcept {
  const Vector3<double> f = clamp_force(force, m_limits.max_force);
  m_last_fx.store(f.x(), std::memory_order_relaxed);
  m_last_fy.store(f.y(), std::memory_order_relaxed);
  m_last_fz.store(f.z(), std::memory_order_relaxed);
  const std::size_t slot = m_count.fetch_add(1, std::memory_order_acq_rel);
  if (slot < m_record.size()) m_record[slot] = {m_last_read.load(std::memory_order_relaxed), f};
  return f;
}

void ScriptedHapticDevice::stop() noexcept {
  apply_force(Vector3<double>::Zero());
}

std::vector<ForceSample> ScriptedHapticDevice::forces() const {
  const std::size_t n = std::min(m_count.load(std::memory_order_acquire), m_record.size());
  return {m_record.begin(), m_record.begin() + std::ptrdiff_t(n)};
}

std::size_t ScriptedHapticDevice::dropped() const noexcept {
  const std::size_t n = m_count.load(std::memory_order_acquire);
  return n > m_record.size() ? n - m_record.size() : 0;
}

void ScriptedHapticDevice::clear_forces() noexcept {
  m_count.store(0, std::memory_order_release);
}

Vector3<double> ScriptedHapticDevice::last_force() const noexcept {
  return {m_last_fx.load(std::memory_order_relaxed), m_last_fy.load(std::memory_order_relaxed),
          m_last_fz.load(std::memory_order_relaxed)};
}

}  // namespace fsm::haptics
