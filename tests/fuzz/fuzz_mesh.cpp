// libFuzzer target: the mesh parsers (OBJ, OFF, STL, PLY) on arbitrary bytes; the first byte
// picks the format (modulo 4), the rest is the file.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fsm/builder/mesh_io.hpp"
#include "fsm/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto format = static_cast<fsm::build::MeshFormat>(data[0] % 4);
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    const fsm::build::PolygonSoup soup = fsm::build::parse_mesh(bytes, format, "fuzz");
    // What the parser promises: finite points, polygons of at least 3 indices in range.
    for (const auto& p : soup.points)
      for (const double c : p)
        if (!std::isfinite(c)) __builtin_trap();
    for (const auto& f : soup.polygons) {
      if (f.size() < 3) __builtin_trap();
      for (const std::size_t v : f)
        if (v >= soup.points.size()) __builtin_trap();
    }
  } catch (const fsm::Error&) {
  }
  return 0;
}
