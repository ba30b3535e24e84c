#pragma once

// An offscreen OpenGL context through Mesa's OSMesa (software rendering, no display, no GPU).

#include <GL/osmesa.h>

#include <vector>

#include "fsm/error.hpp"

namespace fsm::examples {

class OffscreenContext {
 public:
  OffscreenContext(int width, int height)
      : m_width(width), m_height(height), m_buffer(std::size_t(width) * height * 4) {
    m_context = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
    if (m_context == nullptr)
      throw Error("libOSMesa", "offscreen rendering", "cannot create an OSMesa context");
    if (!OSMesaMakeCurrent(m_context, m_buffer.data(), GL_UNSIGNED_BYTE, width, height)) {
      OSMesaDestroyContext(m_context);
      throw Error("libOSMesa", "offscreen rendering", "cannot make the OSMesa context current");
    }
    OSMesaPixelStore(OSMESA_Y_UP, 1);
  }
  ~OffscreenContext() { OSMesaDestroyContext(m_context); }
  OffscreenContext(const OffscreenContext&) = delete;
  OffscreenContext& operator=(const OffscreenContext&) = delete;
  [[nodiscard]] int width() const { return m_width; }
  [[nodiscard]] int height() const { return m_height; }

 private:
  int m_width, m_height;
  std::vector<unsigned char> m_buffer;
  OSMesaContext m_context{nullptr};
};

}  // namespace fsm::examples
