#pragma once

// Drawing the tissue, the instrument and plots with legacy (compatibility-profile) OpenGL, shared
// by fsm-demo (offscreen, OSMesa) and the viewer (GLFW). Example code: not part of the library.

#include <string>
#include <vector>

#include "fsm/collision/shapes.hpp"
#include "fsm/tissue_model.hpp"

namespace fsm::examples {

/// An orbiting camera around `target` (m): yaw about z, pitch above the xy plane, distance.
struct OrbitCamera {
  Vector3<double> target{Vector3<double>::Zero()};
  double distance{0.25}, yaw{-0.6}, pitch{0.45}, fov_deg{40};
  [[nodiscard]] Vector3<double> eye() const;
};

/// What to draw in one frame.
struct SceneFrame {
  const TissueModel<double>* model{nullptr};
  const Positions<double>* surface{nullptr};  ///< skinned vertices (the skin's |S| x 3), or rest
  const Positions<double>* spheres{nullptr};  ///< optional: the spheres (drawn as points)
  bool show_spheres{true};                    ///< with `spheres`: draw them as points
  bool show_surface{true};                    ///< draw the render surface
  /// Optional: the skin's faces to draw instead of its rest faces (CutSurface::skin_faces(),
  /// degenerate faces skipped).
  const FaceArray* faces{nullptr};
  /// Optional, with `spheres`: the first `num_walls` rows are wound walls over the spheres
  /// (CutSurface::wall_faces()), drawn in the wound's colour.
  const FaceArray* walls{nullptr};
  Index num_walls{0};
  bool show_links{false};  ///< with `spheres`: draw the model's links between them as lines
  bool has_instrument{false};
  collision::Pose<double> instrument;
  double instrument_radius{0.003}, instrument_half_length{0.02};  ///< drawn as a capsule
  Vector3<double> force{
      Vector3<double>::Zero()};  ///< force on the instrument (N), drawn as an arrow
  double arrow_scale{0.05};      ///< m per N
  std::string caption;
};

/// A colour per part (by index), RGB in [0, 1].
[[nodiscard]] Vector3<float> part_colour(std::size_t part);

/// Frames the model: a camera looking at the centre of its rest surface from far enough to see it.
[[nodiscard]] OrbitCamera frame_model(const TissueModel<double>& model);

/// Draws the scene into the current GL context's viewport of `width` x `height` pixels.
void draw_scene(const SceneFrame& frame, const OrbitCamera& camera, int width, int height);

/// A line plot: y against x for each series, axes with tick labels, a title and axis names.
struct PlotSeries {
  std::vector<double> x, y;
  Vector3<float> colour{0.1f, 0.3f, 0.8f};
  std::string label;
};
void draw_plot(const std::vector<PlotSeries>& series, const std::string& title,
               const std::string& x_label, const std::string& y_label, int width, int height,
               bool log_y = false);

/// Text in pixels from the top-left corner (stb_easy_font), `scale` x its 7-pixel glyphs.
void draw_text(const std::string& text, float x, float y, float scale, const Vector3<float>& colour,
               int width, int height);

/// Reads the current framebuffer (RGBA, top row first).
[[nodiscard]] std::vector<unsigned char> read_pixels(int width, int height);
/// Writes RGBA pixels (top row first) as a PNG; fsm::Error naming the path if it cannot.
void write_png(const std::string& path, const std::vector<unsigned char>& rgba, int width,
               int height);
/// Fraction of pixels that differ from the top-left pixel (a blank image gives 0).
[[nodiscard]] double non_background_fraction(const std::vector<unsigned char>& rgba, int width,
                                             int height);

}  // namespace fsm::examples
