// The device registry and the pieces every device shares.

#include "fsm/haptics/haptic_device.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>

#include "fsm/error.hpp"
#include "fsm/haptics/scripted_device.hpp"

namespace fsm::haptics {

namespace {

struct Registry {
  std::mutex mutex;
  std::map<std::string, DeviceFactory> factories;
};

Registry& registry() {
  static Registry* r = [] {
    auto* reg = new Registry;  // never destroyed: devices may be made during static destruction
    reg->factories["scripted"] = [](const std::string& config) -> std::unique_ptr<HapticDevice> {
      if (config.empty()) return std::make_unique<ScriptedHapticDevice>();
      return std::make_unique<ScriptedHapticDevice>(ScriptedHapticDevice::from_csv(config));
    };
    return reg;
  }();
  return *r;
}

}  // namespace

void HapticDevice::run_scheduler(std::function<bool()>) {
  throw Error("", name(), "this device has no scheduler of its own; ServoLoop runs it in a thread");
}

Vector3<double> HapticDevice::clamp_force(const Vector3<double>& force, double max_force) noexcept {
  if (!force.allFinite() || !(max_force > 0)) return Vector3<double>::Zero();
  const double n = force.norm();
  return n > max_force ? Vector3<double>(force * (max_force / n)) : force;
}

void register_device(const std::string& name, DeviceFactory factory) {
  if (name.empty() || !factory)
    throw Error("", "haptic devices", "a device needs a name and a factory");
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  r.factories[name] = std::move(factory);
}

std::vector<std::string> device_names() {
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  std::vector<std::string> names;
  for (const auto& [name, f] : r.factories) names.push_back(name);
  return names;
}

std::unique_ptr<HapticDevice> make_device(const std::string& name, const std::string& config) {
  DeviceFactory factory;
  {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    auto it = r.factories.find(name);
    if (it != r.factories.end()) factory = it->second;
  }
  if (!factory) {
    std::string valid;
    for (const auto& n : device_names()) valid += (valid.empty() ? "" : ", ") + n;
    throw Error(
        "", "haptic device '" + name + "'",
        "no such device; valid names: " + valid +
            (name == "touch" ? " (\"touch\" is registered by fsm::touch's register_touch_device())"
                             : ""));
  }
  return factory(config);
}

}  // namespace fsm::haptics
