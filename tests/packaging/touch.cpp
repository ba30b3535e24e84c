// fsm::touch from an installed tree: the Touch registers by name, and without OpenHaptics on the
// machine opening it is a clear fsm::Error (never a crash).
#include <fsm/error.hpp>
#include <fsm/haptics/haptic_device.hpp>
#include <fsm/haptics/touch_device.hpp>

#include <algorithm>
#include <cstdio>

int main() {
  fsm::haptics::register_touch_device();
  const auto names = fsm::haptics::device_names();
  if (std::find(names.begin(), names.end(), "touch") == names.end()) return 1;
  try {
    auto device = fsm::haptics::make_device("touch", "");
    device->start();
    std::printf("fsm::touch downstream: a Touch answered\n");
  } catch (const fsm::Error& e) {
    std::printf("fsm::touch downstream: registered; without a device: %s\n", e.what());
  }
  return 0;
}
