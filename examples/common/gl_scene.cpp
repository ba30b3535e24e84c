// Legacy OpenGL drawing for the demo and the viewer.

#include "gl_scene.hpp"

#include <GL/gl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_easy_font.h>
#include <stb/stb_image_write.h>

#include "fsm/triangle_mesh.hpp"

namespace fsm::examples {

namespace {

constexpr double kPi = 3.14159265358979323846;

void perspective(double fov_deg, double aspect, double znear, double zfar) {
  const double f = 1.0 / std::tan(fov_deg * kPi / 360.0);
  const double m[16] = {f / aspect,
                        0,
                        0,
                        0,
                        0,
                        f,
                        0,
                        0,
                        0,
                        0,
                        (zfar + znear) / (znear - zfar),
                        -1,
                        0,
                        0,
                        2 * zfar * znear / (znear - zfar),
                        0};
  glMatrixMode(GL_PROJECTION);
  glLoadMatrixd(m);
}

void look_at(const Vector3<double>& eye, const Vector3<double>& target, const Vector3<double>& up) {
  const Vector3<double> f = (target - eye).normalized();
  const Vector3<double> s = f.cross(up).normalized();
  const Vector3<double> u = s.cross(f);
  const double m[16] = {s.x(), u.x(), -f.x(), 0, s.y(),       u.y(),       -f.y(),     0,
                        s.z(), u.z(), -f.z(), 0, -s.dot(eye), -u.dot(eye), f.dot(eye), 1};
  glMatrixMode(GL_MODELVIEW);
  glLoadMatrixd(m);
}

void draw_capsule(const collision::Pose<double>& pose, double r, double half) {
  const int seg = 16;
  const Eigen::Matrix3d R = pose.orientation.toRotationMatrix();
  auto world = [&](const Vector3<double>& p) { return Vector3<double>(pose.position + R * p); };
  glColor3f(0.75f, 0.75f, 0.8f);
  // The strips below wind clockwise seen from outside, so with two-sided lighting GL would light
  // the outside with the flipped (inward) normals and the capsule would come out almost black.
  // Light one-sided: the normals given are the outward ones whatever the winding.
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_FALSE);
  glBegin(GL_QUAD_STRIP);
  for (int i = 0; i <= seg; ++i) {
    const double a = 2 * kPi * i / seg;
    const Vector3<double> n(std::cos(a), std::sin(a), 0);
    const Vector3<double> wn = R * n;
    glNormal3d(wn.x(), wn.y(), wn.z());
    for (double z : {-half, half}) {
      const Vector3<double> p = world(Vector3<double>(r * n.x(), r * n.y(), z));
      glVertex3d(p.x(), p.y(), p.z());
    }
  }
  glEnd();
  // Hemispherical ends.
  for (double sign : {-1.0, 1.0}) {
    for (int j = 0; j < seg / 2; ++j) {
      const double b0 = kPi / 2 * j / (seg / 2), b1 = kPi / 2 * (j + 1) / (seg / 2);
      glBegin(GL_QUAD_STRIP);
      for (int i = 0; i <= seg; ++i) {
        const double a = 2 * kPi * i / seg;
        for (double b : {b0, b1}) {
          const Vector3<double> n(std::cos(a) * std::cos(b), std::sin(a) * std::cos(b),
                                  sign * std::sin(b));
          const Vector3<double> wn = R * n;
          const Vector3<double> p = world(Vector3<double>(0, 0, sign * half) + r * n);
          glNormal3d(wn.x(), wn.y(), wn.z());
          glVertex3d(p.x(), p.y(), p.z());
        }
      }
      glEnd();
    }
  }
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
}

void draw_arrow(const Vector3<double>& from, const Vector3<double>& vec) {
  const double len = vec.norm();
  if (!(len > 1e-6)) return;
  // On top: the arrow starts at the instrument's centre, and a push along the shaft (the usual
  // probe force) would otherwise be hidden inside the capsule.
  glDisable(GL_LIGHTING);
  glDisable(GL_DEPTH_TEST);
  glLineWidth(3.0f);
  glColor3f(1.0f, 0.85f, 0.1f);
  const Vector3<double> to = from + vec;
  const Vector3<double> d = vec / len;
  Vector3<double> side = d.cross(Vector3<double>::UnitZ());
  if (side.norm() < 1e-3) side = d.cross(Vector3<double>::UnitX());
  side = side.normalized() * 0.25 * len;
  const Vector3<double> back = to - 0.3 * vec;
  glBegin(GL_LINES);
  for (const auto& [a, b] : {std::pair{from, to}, std::pair{to, Vector3<double>(back + side)},
                             std::pair{to, Vector3<double>(back - side)}}) {
    glVertex3d(a.x(), a.y(), a.z());
    glVertex3d(b.x(), b.y(), b.z());
  }
  glEnd();
  glEnable(GL_DEPTH_TEST);
  glEnable(GL_LIGHTING);
}

void begin_2d(int width, int height) {
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glOrtho(0, width, height, 0, -1, 1);
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  glDisable(GL_LIGHTING);
  glDisable(GL_DEPTH_TEST);
}

std::string format_tick(double v) {
  char buf[32];
  if (std::abs(v) >= 1000 || (std::abs(v) < 0.01 && v != 0))
    std::snprintf(buf, sizeof buf, "%.0e", v);
  else if (std::abs(v - std::round(v)) < 1e-9)
    std::snprintf(buf, sizeof buf, "%.0f", v);
  else
    std::snprintf(buf, sizeof buf, "%.2g", v);
  return buf;
}

}  // namespace

Vector3<double> OrbitCamera::eye() const {
  return target + distance * Vector3<double>(std::cos(pitch) * std::cos(yaw),
                                             std::cos(pitch) * std::sin(yaw), std::sin(pitch));
}

Vector3<float> part_colour(std::size_t part) {
  static const float table[][3] = {
      {0.86f, 0.45f, 0.45f}, {0.62f, 0.28f, 0.40f}, {0.93f, 0.75f, 0.55f},
      {0.93f, 0.75f, 0.55f}, {0.55f, 0.70f, 0.85f}, {0.55f, 0.70f, 0.85f},
      {0.55f, 0.80f, 0.55f}, {0.55f, 0.80f, 0.55f}, {0.80f, 0.60f, 0.85f}};
  const auto& c = table[part % 9];
  return {c[0], c[1], c[2]};
}

OrbitCamera frame_model(const TissueModel<double>& model) {
  OrbitCamera cam;
  const Positions<double>& v =
      model.skin.num_vertices() > 0 ? model.skin.rest.vertices : model.spheres.rest_positions();
  const Vector3<double> lo = v.colwise().minCoeff().transpose(),
                        hi = v.colwise().maxCoeff().transpose();
  cam.target = 0.5 * (lo + hi);
  cam.distance = 0.5 * (hi - lo).norm() / std::tan(cam.fov_deg * kPi / 360.0) * 1.15;
  return cam;
}

void draw_scene(const SceneFrame& frame, const OrbitCamera& camera, int width, int height) {
  glViewport(0, 0, width, height);
  glClearColor(0.12f, 0.13f, 0.16f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glEnable(GL_NORMALIZE);
  perspective(camera.fov_deg, double(width) / std::max(height, 1), camera.distance * 0.05,
              camera.distance * 10);
  const Vector3<double> eye = camera.eye();
  look_at(eye, camera.target, Vector3<double>::UnitZ());
  glEnable(GL_LIGHTING);
  glEnable(GL_LIGHT0);
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
  const GLfloat light[4] = {float(eye.x() - camera.target.x()), float(eye.y() - camera.target.y()),
                            float(eye.z() - camera.target.z() + camera.distance), 0.0f};
  glLightfv(GL_LIGHT0, GL_POSITION, light);
  const GLfloat ambient[4] = {0.25f, 0.25f, 0.25f, 1.0f};
  glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
  glEnable(GL_COLOR_MATERIAL);
  glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);

  if (frame.show_surface && frame.model != nullptr && frame.model->skin.num_vertices() > 0) {
    const auto& skin = frame.model->skin;
    const Positions<double>& v = frame.surface != nullptr ? *frame.surface : skin.rest.vertices;
    const FaceArray& faces = frame.faces != nullptr ? *frame.faces : skin.rest.faces;
    Positions<double> n(v.rows(), 3);
    compute_vertex_normals<double>(v, faces, n);
    for (std::size_t p = 0; p < frame.model->parts.size(); ++p) {
      const Index s = frame.model->parts[p].surface;
      if (s < 0) continue;
      const auto& surf = skin.surfaces[std::size_t(s)];
      const Vector3<float> c = part_colour(p);
      glColor3f(c.x(), c.y(), c.z());
      glBegin(GL_TRIANGLES);
      for (Index f = surf.first_face; f < surf.first_face + surf.num_faces; ++f)
        for (int k = 0; k < 3 && faces(f, 0) != faces(f, 1); ++k) {
          const Index i = faces(f, k);
          glNormal3d(n(i, 0), n(i, 1), n(i, 2));
          glVertex3d(v(i, 0), v(i, 1), v(i, 2));
        }
      glEnd();
    }
  }
  if (frame.walls != nullptr && frame.spheres != nullptr && frame.num_walls > 0) {
    const Positions<double>& x = *frame.spheres;
    glColor3f(0.78f, 0.16f, 0.18f);  // the wound
    glBegin(GL_TRIANGLES);
    for (Index w = 0; w < frame.num_walls; ++w) {
      const Vector3<double> a = x.row((*frame.walls)(w, 0)).transpose();
      const Vector3<double> b = x.row((*frame.walls)(w, 1)).transpose();
      const Vector3<double> c = x.row((*frame.walls)(w, 2)).transpose();
      const Vector3<double> nn = (b - a).cross(c - a).normalized();
      glNormal3d(nn.x(), nn.y(), nn.z());
      for (const Vector3<double>* p : {&a, &b, &c}) glVertex3d(p->x(), p->y(), p->z());
    }
    glEnd();
  }
  if (frame.spheres != nullptr && frame.show_links && frame.model != nullptr &&
      frame.model->spheres.num_nodes() == frame.spheres->rows()) {
    glDisable(GL_LIGHTING);
    glLineWidth(1.0f);
    glColor3f(0.95f, 0.85f, 0.3f);
    const auto links = frame.model->spheres.links();
    const Positions<double>& x = *frame.spheres;
    glBegin(GL_LINES);
    for (Index l = 0; l < links.rows(); ++l)
      for (int k = 0; k < 2; ++k)
        glVertex3d(x(links(l, k), 0), x(links(l, k), 1), x(links(l, k), 2));
    glEnd();
    glEnable(GL_LIGHTING);
  }
  if (frame.spheres != nullptr && frame.show_spheres) {
    glDisable(GL_LIGHTING);
    glPointSize(3.0f);
    glColor3f(1, 1, 1);
    glBegin(GL_POINTS);
    for (Index i = 0; i < frame.spheres->rows(); ++i)
      glVertex3d((*frame.spheres)(i, 0), (*frame.spheres)(i, 1), (*frame.spheres)(i, 2));
    glEnd();
    glEnable(GL_LIGHTING);
  }
  if (frame.has_instrument) {
    draw_capsule(frame.instrument, frame.instrument_radius, frame.instrument_half_length);
    draw_arrow(frame.instrument.position, frame.force * frame.arrow_scale);
  }
  if (!frame.caption.empty())
    draw_text(frame.caption, 12, 12, 2.0f, {0.9f, 0.9f, 0.9f}, width, height);
}

void draw_text(const std::string& text, float x, float y, float scale, const Vector3<float>& colour,
               int width, int height) {
  begin_2d(width, height);
  static char buffer[99999];
  const int quads = stb_easy_font_print(0, 0, const_cast<char*>(text.c_str()), nullptr, buffer,
                                        int(sizeof buffer));
  glTranslatef(x, y, 0);
  glScalef(scale, scale, 1);
  glColor3f(colour.x(), colour.y(), colour.z());
  glEnableClientState(GL_VERTEX_ARRAY);
  glVertexPointer(2, GL_FLOAT, 16, buffer);
  glDrawArrays(GL_QUADS, 0, quads * 4);
  glDisableClientState(GL_VERTEX_ARRAY);
}

void draw_plot(const std::vector<PlotSeries>& series, const std::string& title,
               const std::string& x_label, const std::string& y_label, int width, int height,
               bool log_y) {
  glViewport(0, 0, width, height);
  glClearColor(1, 1, 1, 1);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  begin_2d(width, height);
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  auto ty = [&](double y) { return log_y ? std::log10(std::max(y, 1e-12)) : y; };
  for (const auto& s : series)
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      x0 = std::min(x0, s.x[i]);
      x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, ty(s.y[i]));
      y1 = std::max(y1, ty(s.y[i]));
    }
  if (!(x1 > x0)) x1 = x0 + 1;
  if (!(y1 > y0)) y1 = y0 + 1;
  if (!log_y) y0 = std::min(y0, 0.0);
  const double pad = 0.05 * (y1 - y0);
  y1 += pad;
  const float L = 90, R = float(width) - 30, T = 50, B = float(height) - 60;
  auto px = [&](double x) { return float(L + (x - x0) / (x1 - x0) * (R - L)); };
  auto py = [&](double y) { return float(B - (ty(y) - y0) / (y1 - y0) * (B - T)); };
  // Axes and grid.
  glColor3f(0.85f, 0.85f, 0.85f);
  glLineWidth(1.0f);
  const int nt = 5;
  glBegin(GL_LINES);
  for (int i = 0; i <= nt; ++i) {
    const float gx = L + (R - L) * float(i) / nt, gy = T + (B - T) * float(i) / nt;
    glVertex2f(gx, T);
    glVertex2f(gx, B);
    glVertex2f(L, gy);
    glVertex2f(R, gy);
  }
  glEnd();
  glColor3f(0, 0, 0);
  glBegin(GL_LINE_LOOP);
  glVertex2f(L, T);
  glVertex2f(R, T);
  glVertex2f(R, B);
  glVertex2f(L, B);
  glEnd();
  for (const auto& s : series) {
    glColor3f(s.colour.x(), s.colour.y(), s.colour.z());
    glLineWidth(1.5f);
    glBegin(GL_LINE_STRIP);
    for (std::size_t i = 0; i < s.x.size(); ++i) glVertex2f(px(s.x[i]), py(s.y[i]));
    glEnd();
  }
  const Vector3<float> black(0, 0, 0);
  for (int i = 0; i <= nt; ++i) {
    const double xv = x0 + (x1 - x0) * i / nt, yv = y0 + (y1 - y0) * i / nt;
    draw_text(format_tick(xv), L + (R - L) * float(i) / nt - 10, B + 8, 1.5f, black, width, height);
    draw_text(format_tick(log_y ? std::pow(10.0, yv) : yv), 8, B - (B - T) * float(i) / nt - 5,
              1.5f, black, width, height);
  }
  draw_text(title, L, 15, 2.0f, black, width, height);
  draw_text(x_label, (L + R) / 2 - 40, B + 32, 1.8f, black, width, height);
  draw_text(y_label, 8, T - 22, 1.6f, black, width, height);
  float ly = T + 10;
  for (const auto& s : series) {
    if (s.label.empty()) continue;
    draw_text(s.label, R - 260, ly, 1.6f, s.colour, width, height);
    ly += 20;
  }
}

std::vector<unsigned char> read_pixels(int width, int height) {
  std::vector<unsigned char> rgba(std::size_t(width) * std::size_t(height) * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  // GL's first row is the bottom one.
  const std::size_t row = std::size_t(width) * 4;
  for (int y = 0; y < height / 2; ++y)
    std::swap_ranges(rgba.begin() + std::ptrdiff_t(row * std::size_t(y)),
                     rgba.begin() + std::ptrdiff_t(row * std::size_t(y + 1)),
                     rgba.begin() + std::ptrdiff_t(row * std::size_t(height - 1 - y)));
  return rgba;
}

void write_png(const std::string& path, const std::vector<unsigned char>& rgba, int width,
               int height) {
  if (!stbi_write_png(path.c_str(), width, height, 4, rgba.data(), width * 4))
    throw Error(path, "PNG", "cannot write the image");
}

double non_background_fraction(const std::vector<unsigned char>& rgba, int width, int height) {
  if (rgba.size() < 4) return 0;
  std::size_t differ = 0;
  const std::size_t n = std::size_t(width) * std::size_t(height);
  for (std::size_t i = 0; i < n; ++i)
    if (std::abs(int(rgba[4 * i]) - rgba[0]) + std::abs(int(rgba[4 * i + 1]) - rgba[1]) +
            std::abs(int(rgba[4 * i + 2]) - rgba[2]) >
        24)
      ++differ;
  return double(differ) / double(n);
}

}  // namespace fsm::examples
