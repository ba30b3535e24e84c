// Geometric fidelity of a tetrahedral filling (docs/builder.md, "Geometric fidelity").

#include "fidelity.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

namespace fsm::build::detail {

namespace {

using Vec = Eigen::Vector3d;

double triangle_area(const Vec& p, const Vec& q, const Vec& r) {
  return 0.5 * (q - p).cross(r - p).norm();
}

double total_area(const TriangleMesh<double>& m) {
  double a = 0;
  for (Index f = 0; f < m.num_faces(); ++f)
    a += triangle_area(m.vertices.row(m.faces(f, 0)).transpose(),
                       m.vertices.row(m.faces(f, 1)).transpose(),
                       m.vertices.row(m.faces(f, 2)).transpose());
  return a;
}

// A half-space n . x <= d.
struct HalfSpace {
  Vec n;
  double d;
};

// The region as half-spaces grown by `tol`; empty for regions that are not geometric.
std::vector<HalfSpace> half_spaces(const FixedSpec& r, double tol) {
  std::vector<HalfSpace> h;
  switch (r.kind) {
    case FixedSpec::Kind::box:
      for (int k = 0; k < 3; ++k) {
        h.push_back({Vec::Unit(k), r.max[k] + tol});
        h.push_back({-Vec::Unit(k), -r.min[k] + tol});
      }
      break;
    case FixedSpec::Kind::plane: {
      const Vec n = r.normal.normalized();
      h.push_back({n, n.dot(r.point) + tol});
      break;
    }
    default:
      break;
  }
  return h;
}

// Area of a convex polygon (fan from its first vertex).
double polygon_area(const std::vector<Vec>& p) {
  Vec twice = Vec::Zero();
  for (std::size_t i = 1; i + 1 < p.size(); ++i) twice += (p[i] - p[0]).cross(p[i + 1] - p[0]);
  return 0.5 * twice.norm();
}

// Sutherland-Hodgman: the part of the triangle inside every half-space.
double clipped_area(const Vec& a, const Vec& b, const Vec& c, const std::vector<HalfSpace>& hs) {
  std::vector<Vec> poly{a, b, c}, next;
  for (const HalfSpace& h : hs) {
    next.clear();
    for (std::size_t i = 0; i < poly.size(); ++i) {
      const Vec& p = poly[i];
      const Vec& q = poly[(i + 1) % poly.size()];
      const double sp = h.n.dot(p) - h.d, sq = h.n.dot(q) - h.d;
      if (sp <= 0) next.push_back(p);
      if ((sp < 0 && sq > 0) || (sp > 0 && sq < 0)) next.push_back(p + (sp / (sp - sq)) * (q - p));
    }
    poly.swap(next);
    if (poly.size() < 3) return 0;
  }
  return polygon_area(poly);
}

double relative(double value, double reference) {
  return reference != 0 ? value / reference - 1 : 0;
}

std::string percent(double d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%+.1f %%", 100 * d);
  return buf;
}

}  // namespace

TriangleMesh<double> boundary_surface(const TetrahedralMesh<double>& mesh) {
  // Each face as (sorted vertices, the face as seen from outside its tetrahedron); a face of two
  // tetrahedra appears twice.
  static const int opposite[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  struct Face {
    std::array<Index, 3> key, face;
  };
  std::vector<Face> faces;
  faces.reserve(std::size_t(4 * mesh.tetrahedra.rows()));
  for (Index t = 0; t < mesh.tetrahedra.rows(); ++t)
    for (const auto& o : opposite) {
      Face f;
      for (int k = 0; k < 3; ++k) f.face[std::size_t(k)] = mesh.tetrahedra(t, o[k]);
      f.key = f.face;
      std::sort(f.key.begin(), f.key.end());
      faces.push_back(f);
    }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.key < b.key; });
  std::vector<std::array<Index, 3>> boundary;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].key == faces[i].key) ++j;
    if (j == i + 1) boundary.push_back(faces[i].face);
    i = j;
  }
  TriangleMesh<double> out;
  out.vertices = mesh.vertices;
  out.faces.resize(Index(boundary.size()), 3);
  for (std::size_t f = 0; f < boundary.size(); ++f)
    for (int k = 0; k < 3; ++k) out.faces(Index(f), k) = boundary[f][std::size_t(k)];
  return out;
}

double area_in_region(const TriangleMesh<double>& mesh, const FixedSpec& region, double tolerance) {
  const std::vector<HalfSpace> hs = half_spaces(region, tolerance);
  if (hs.empty()) return 0;
  double a = 0;
  for (Index f = 0; f < mesh.num_faces(); ++f)
    a += clipped_area(mesh.vertices.row(mesh.faces(f, 0)).transpose(),
                      mesh.vertices.row(mesh.faces(f, 1)).transpose(),
                      mesh.vertices.row(mesh.faces(f, 2)).transpose(), hs);
  return a;
}

FidelityReport measure_fidelity(const TriangleMesh<double>& surface,
                                const TetrahedralMesh<double>& filling,
                                const std::vector<FixedSpec>& regions,
                                const std::vector<std::string>& names) {
  FidelityReport r;
  const TriangleMesh<double> boundary = boundary_surface(filling);
  r.input_volume = std::abs(surface.volume());
  r.filled_volume = filling.volume();
  r.input_area = total_area(surface);
  r.filled_area = total_area(boundary);
  r.volume_difference = relative(r.filled_volume, r.input_volume);
  r.area_difference = relative(r.filled_area, r.input_area);
  // A face on a region's boundary plane counts whole: the tolerance is far below any element
  // (1e-9 of the part's size) and far above the round-off of the filling's mapped vertices.
  const double size =
      (surface.vertices.colwise().maxCoeff() - surface.vertices.colwise().minCoeff()).norm();
  const double tol = 1e-9 * size;
  for (std::size_t k = 0; k < regions.size(); ++k) {
    RegionFidelity f;
    f.region = names[k];
    f.input_area = area_in_region(surface, regions[k], tol);
    f.filled_area = area_in_region(boundary, regions[k], tol);
    f.difference = relative(f.filled_area, f.input_area);
    r.regions.push_back(f);
  }
  return r;
}

std::vector<std::string> fidelity_warnings(const FidelityReport& f, double radius) {
  std::vector<std::string> w;
  char buf[512];
  if (std::abs(f.volume_difference) > kFidelityTolerance ||
      std::abs(f.area_difference) > kFidelityTolerance) {
    std::snprintf(buf, sizeof buf,
                  "the tetrahedral filling differs from its surface by more than 1 %%: volume "
                  "%.4g of %.4g cm^3 (%s), boundary area %.4g of %.4g cm^2 (%s); a curved surface "
                  "is followed more closely at a smaller radius than %.3g mm",
                  f.filled_volume * 1e6, f.input_volume * 1e6, percent(f.volume_difference).c_str(),
                  f.filled_area * 1e4, f.input_area * 1e4, percent(f.area_difference).c_str(),
                  radius * 1e3);
    w.push_back(buf);
  }
  for (const RegionFidelity& r : f.regions) {
    if (r.input_area > 0 ? std::abs(r.difference) <= kFidelityTolerance : r.filled_area == 0)
      continue;
    std::snprintf(buf, sizeof buf,
                  "%s: the filling's boundary covers %.4g mm^2 of the surface's %.4g mm^2 there "
                  "(%s)",
                  r.region.c_str(), r.filled_area * 1e6, r.input_area * 1e6,
                  r.input_area > 0 ? percent(r.difference).c_str() : "the surface has none");
    w.push_back(buf);
  }
  return w;
}

}  // namespace fsm::build::detail
