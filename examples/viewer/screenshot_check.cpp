// fsm-viewer --check-screenshot: reads a PNG back with stb_image (static, so it cannot clash with
// another copy of stb in the program).

#include "screenshot_check.hpp"

#include <vector>

#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#include <stb/stb_image.h>

#include "fsm/error.hpp"
#include "gl_scene.hpp"

namespace fsm::examples {

double png_non_background_fraction(const std::string& path) {
  int width = 0, height = 0, channels = 0;
  unsigned char* data = stbi_load(path.c_str(), &width, &height, &channels, 4);
  if (data == nullptr)
    throw Error(path, "PNG", std::string("cannot read: ") + stbi_failure_reason());
  const std::vector<unsigned char> rgba(data, data + std::size_t(width) * std::size_t(height) * 4);
  stbi_image_free(data);
  return non_background_fraction(rgba, width, height);
}

}  // namespace fsm::examples
