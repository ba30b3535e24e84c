// libFuzzer target: the scene parser on arbitrary text (relative mesh paths resolve against the
// current folder; fuzz/run.sh runs it in a folder holding a few meshes).

#include <cstddef>
#include <cstdint>
#include <string>

#include "fsm/builder/scene.hpp"
#include "fsm/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const fsm::build::Scene scene = fsm::build::parse_scene(text, ".", "fuzz.json");
    for (const auto& p : scene.parts)
      if (!(p.radius > 0) || p.meshes.empty()) __builtin_trap();  // what the parser promises
  } catch (const fsm::Error&) {
  }
  return 0;
}
