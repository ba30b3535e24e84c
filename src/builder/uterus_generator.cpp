/// @file uterus_generator.cpp
/// @brief The default data set: a procedural uterus (pear-shaped body with a subserosal fibroid,
/// ovaries, ovarian ligaments and fallopian tubes), each part an implicit function meshed by
/// CGAL Mesh_3 into a closed, manifold, outward triangle surface; and its scene file.

#include "fsm/builder/uterus_generator.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_domain_with_polyline_features_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/facets_in_complex_3_to_triangle_mesh.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/refine_mesh_3.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <utility>

#include "cgal_mesh.hpp"
#include "fsm/error.hpp"

namespace fsm::build {
namespace {

using Vec = Eigen::Vector3d;
using Field = std::function<double(const Vec&)>;
using Polyline = std::vector<Vec>;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// Implicit functions: negative inside, zero on the surface, about the distance to it nearby.
// ---------------------------------------------------------------------------------------------

/// @brief The uterine body's pear: an ellipsoid whose cross-section shrinks linearly from the
/// fundus (scale 1) to the cervical end (scale `taper`), centred at the origin, axis z.
struct Pear {
  double half_length{0}, half_width{0}, half_depth{0}, taper{1};

  /// Builds the pear whose largest width and depth are `width` and `depth`.
  Pear(double length, double width, double depth, double taper_) : taper(taper_) {
    half_length = length / 2;
    // The widest cross-section of the tapered ellipsoid is above the centre and narrower than
    // the untapered one; scale the semi-axes so the largest width and depth are the given ones.
    double widest = 0;
    for (int i = 0; i <= 2000; ++i) {
      const double u = -1.0 + 2.0 * i / 2000;
      widest = std::max(widest, scale(u) * std::sqrt(std::max(0.0, 1 - u * u)));
    }
    half_width = width / 2 / widest;
    half_depth = depth / 2 / widest;
  }
  [[nodiscard]] double scale(double u) const {
    const double uc = std::clamp(u, -1.0, 1.0);
    return taper + (1 - taper) * (1 + uc) / 2;
  }
  /// Gauge (1 on the surface, homogeneous-like).
  [[nodiscard]] double gauge(const Vec& p) const {
    const double u = p.z() / half_length;
    const double s = scale(u);
    const double x = p.x() / (half_width * s), y = p.y() / (half_depth * s);
    return std::sqrt(x * x + y * y + u * u);
  }
  /// Distance-like: (gauge - 1) times the smallest semi-axis (a lower bound of the distance far
  /// from the tapered end, exact in sign).
  [[nodiscard]] double operator()(const Vec& p) const {
    return (gauge(p) - 1) * std::min({half_length, half_width * taper, half_depth * taper});
  }
};

/// @brief An axis-aligned ellipsoid.
struct Ellipsoid {
  Vec centre, semi_axes;
  [[nodiscard]] double operator()(const Vec& p) const {
    const double g = (p - centre).cwiseQuotient(semi_axes).norm();
    return (g - 1) * semi_axes.minCoeff();
  }
};

/// @brief Distance from `p` to segment `ab`.
double segment_distance(const Vec& p, const Vec& a, const Vec& b) {
  const Vec ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

/// @brief A round tube with hemispherical caps around a polyline: distance to it minus the radius.
struct Tube {
  Polyline axis;
  double radius{0};
  [[nodiscard]] double operator()(const Vec& p) const {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i + 1 < axis.size(); ++i) {
      // Cheap reject: the segment's nearest point is at least |p - a| - |b - a| away.
      const double lower = (p - axis[i]).norm() - (axis[i + 1] - axis[i]).norm();
      if (lower >= best) continue;
      best = std::min(best, segment_distance(p, axis[i], axis[i + 1]));
    }
    return best - radius;
  }
};

/// @brief The point where the ray `origin + t dir` (t > 0) leaves the region `f < 0` for the
/// first time, by stepping and bisection; `origin` must be inside.
Vec ray_exit(const Field& f, const Vec& origin, const Vec& dir, double max_t) {
  const Vec d = dir.normalized();
  if (!(f(origin) < 0) || !(f(origin + max_t * d) >= 0))
    throw Error("", "uterus", "the shape's parts do not fit together (a ray from the body misses)");
  const int steps = 400;
  double lo = 0, hi = max_t;
  for (int i = 1; i <= steps; ++i) {
    const double t = max_t * i / steps;
    if (f(origin + t * d) >= 0) {
      hi = t;
      break;
    }
    lo = t;
  }
  for (int i = 0; i < 100; ++i) {
    const double mid = (lo + hi) / 2;
    (f(origin + mid * d) < 0 ? lo : hi) = mid;
  }
  return origin + (lo + hi) / 2 * d;
}

/// @brief Outward unit normal of `f`'s level set at `p` (central differences).
Vec gradient_direction(const Field& f, const Vec& p) {
  const double h = 1e-6;
  Vec g;
  for (int k = 0; k < 3; ++k) {
    Vec e = Vec::Zero();
    e[k] = h;
    g[k] = f(p + e) - f(p - e);
  }
  return g.normalized();
}

/// @brief Centripetal Catmull-Rom spline through `points` (with mirrored end tangents),
/// resampled at arc-length `spacing` and cut at arc length `length` (or its end).
Polyline catmull_rom(const std::vector<Vec>& points, double spacing, double length) {
  std::vector<Vec> p;
  p.push_back(2 * points.front() - points[1]);
  p.insert(p.end(), points.begin(), points.end());
  p.push_back(2 * points.back() - points[points.size() - 2]);
  // Dense samples.
  Polyline dense;
  const int per_segment = 200;
  for (std::size_t i = 1; i + 2 < p.size(); ++i) {
    const Vec &p0 = p[i - 1], &p1 = p[i], &p2 = p[i + 1], &p3 = p[i + 2];
    const double t0 = 0, t1 = t0 + std::sqrt((p1 - p0).norm()),
                 t2 = t1 + std::sqrt((p2 - p1).norm()), t3 = t2 + std::sqrt((p3 - p2).norm());
    for (int k = 0; k < per_segment; ++k) {
      const double t = t1 + (t2 - t1) * k / per_segment;
      const Vec a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1;
      const Vec a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2;
      const Vec a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3;
      const Vec b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2;
      const Vec b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3;
      dense.push_back((t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2);
    }
  }
  dense.push_back(points.back());
  // Resample uniformly by arc length (along the dense samples) up to `length`.
  std::vector<double> arc(dense.size(), 0.0);
  for (std::size_t i = 0; i + 1 < dense.size(); ++i)
    arc[i + 1] = arc[i] + (dense[i + 1] - dense[i]).norm();
  if (arc.back() < length)
    throw Error("", "tube",
                "tube_length " + std::to_string(length) + " m is longer than the tube's path (" +
                    std::to_string(arc.back()) + " m)");
  const int n = std::max(1, int(std::ceil(length / spacing)));
  Polyline out;
  std::size_t j = 0;
  for (int k = 0; k <= n; ++k) {
    const double at = length * k / n;
    while (j + 2 < dense.size() && arc[j + 1] < at) ++j;
    const double t = (at - arc[j]) / (arc[j + 1] - arc[j]);
    out.push_back(dense[j] + t * (dense[j + 1] - dense[j]));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Meshing.
// ---------------------------------------------------------------------------------------------

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Implicit_domain = CGAL::Labeled_mesh_domain_3<K>;
using Domain = CGAL::Mesh_domain_with_polyline_features_3<Implicit_domain>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr, Domain::Corner_index, Domain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;
using Surface = cgal::SurfaceMesh;

/// @brief Meshes the surface `f = 0` inside the ball (`centre`, `radius`) with triangles of about
/// `size`, keeping the closed polylines `features` (sharp creases) as mesh edges.
TriangleMesh<double> mesh_surface(const Field& f, const Vec& centre, double radius, double size,
                                  const std::vector<Polyline>& features, unsigned seed,
                                  const std::string& name) {
  namespace params = CGAL::parameters;
  CGAL::Random rng(seed);
  const auto function = [&f](const Point& p) { return f(Vec(p.x(), p.y(), p.z())); };
  Domain domain = Implicit_domain::create_implicit_mesh_domain(
      function, K::Sphere_3(Point(centre.x(), centre.y(), centre.z()), radius * radius),
      params::relative_error_bound = 1e-7, params::p_rng = &rng);
  if (!features.empty()) {
    std::vector<std::vector<Point>> lines;
    for (const Polyline& line : features) {
      std::vector<Point> pts;
      for (const Vec& v : line) pts.emplace_back(v.x(), v.y(), v.z());
      lines.push_back(std::move(pts));
    }
    domain.add_features(lines.begin(), lines.end());
  }
  const Criteria criteria(params::edge_size = size, params::facet_angle = 30,
                          params::facet_size = size, params::facet_distance = size / 20);
  // Protect the creases first (make_mesh_3 with edge criteria only), then seed the surface with
  // the domain's random initial points (make_mesh_3 alone skips them once the creases give some
  // restricted facets, and may then miss the rest of the surface), then refine.
  C3t3 c3t3;
  if (!features.empty())
    c3t3 = CGAL::make_mesh_3<C3t3>(domain, Criteria(params::edge_size = size), params::features(),
                                   params::no_perturb(), params::no_exude());
  std::vector<std::pair<Point, Domain::Index>> seeds;
  domain.construct_initial_points_object()(std::back_inserter(seeds));
  auto& tr = c3t3.triangulation();
  const auto weighted = tr.geom_traits().construct_weighted_point_3_object();
  for (const auto& [p, index] : seeds) {
    const auto v = tr.insert(weighted(p));
    if (v == Tr::Vertex_handle()) continue;  // hidden by a crease's protecting ball
    c3t3.set_dimension(v, 2);
    c3t3.set_index(v, index);
  }
  CGAL::refine_mesh_3(c3t3, domain, criteria, params::no_perturb(), params::no_exude(),
                      params::no_reset_c3t3(), params::manifold());
  Surface surface;
  CGAL::facets_in_complex_3_to_triangle_mesh(c3t3, surface);
  if (surface.number_of_faces() == 0) throw Error("", name, "meshing produced no surface");

  TriangleMesh<double> mesh = cgal::from_cgal(surface);
  if (mesh.volume() < 0) mesh.faces.col(1).swap(mesh.faces.col(2));
  return mesh;
}

/// @brief The mirror image of `mesh` in the plane x = 0 (faces reversed to stay outward).
TriangleMesh<double> mirror_x(const TriangleMesh<double>& mesh) {
  TriangleMesh<double> out = mesh;
  out.vertices.col(0) *= -1;
  out.faces.col(1).swap(out.faces.col(2));
  return out;
}

// ---------------------------------------------------------------------------------------------
// The anatomy.
// ---------------------------------------------------------------------------------------------

/// @brief Throws fsm::Error naming the first UterusShape field that cannot make a uterus.
void check(const UterusShape& s) {
  const std::vector<std::pair<const char*, double>> positive{
      {"body_length", s.body_length},         {"body_width", s.body_width},
      {"body_depth", s.body_depth},           {"body_taper", s.body_taper},
      {"fibroid_radius", s.fibroid_radius},   {"ovary_size.x", s.ovary_size.x()},
      {"ovary_size.y", s.ovary_size.y()},     {"ovary_size.z", s.ovary_size.z()},
      {"ligament_radius", s.ligament_radius}, {"tube_radius", s.tube_radius},
      {"tube_length", s.tube_length},         {"mesh_size", s.mesh_size}};
  for (const auto& [name, value] : positive)
    if (!(value > 0) || !std::isfinite(value))
      throw Error("", std::string("UterusShape::") + name, "must be positive and finite");
  if (!(s.body_taper <= 1)) throw Error("", "UterusShape::body_taper", "must be in (0, 1]");
  if (!(s.fibroid_protrusion > 0 && s.fibroid_protrusion < 1))
    throw Error("", "UterusShape::fibroid_protrusion", "must be in (0, 1)");
  if (!(s.fibroid_direction.norm() > 0))
    throw Error("", "UterusShape::fibroid_direction", "must not be zero");
}

/// @brief Every derived position of the procedural uterus (m), for the left side (+x); the right
/// side is the mirror image.
struct Layout {
  Pear pear;
  Vec fibroid_centre, fibroid_axis;  ///< axis: outward normal of the body at the fibroid
  double fibroid_radius{0};
  Polyline crease;  ///< closed polyline where the fibroid's ball cuts the pear
  Ellipsoid ovary;
  Polyline ligament, tube;

  explicit Layout(const UterusShape& s)
      : pear(s.body_length, s.body_width, s.body_depth, s.body_taper) {
    const Field pear_f = [this](const Vec& p) { return pear(p); };
    const double reach = s.body_length;

    // Fibroid: a ball centred so that `fibroid_protrusion` of its diameter lies outside the
    // body wall, along the wall's normal.
    fibroid_radius = s.fibroid_radius;
    const Vec attach = ray_exit(pear_f, Vec::Zero(), s.fibroid_direction, reach);
    fibroid_axis = gradient_direction(pear_f, attach);
    fibroid_centre = attach + fibroid_axis * fibroid_radius * (2 * s.fibroid_protrusion - 1);
    // The crease: on each meridian of the ball (inner pole inside the pear, outer pole outside),
    // the point where it leaves the pear.
    const Vec e1 = fibroid_axis.unitOrthogonal(), e2 = fibroid_axis.cross(e1);
    const int n = 360;
    for (int k = 0; k < n; ++k) {
      const double phi = 2 * kPi * k / n;
      const Vec side = std::cos(phi) * e1 + std::sin(phi) * e2;
      const auto on_ball = [&](double theta) {
        return Vec(fibroid_centre +
                   fibroid_radius * (-std::cos(theta) * fibroid_axis + std::sin(theta) * side));
      };
      double lo = 0, hi = kPi;
      for (int i = 0; i < 100; ++i) {
        const double mid = (lo + hi) / 2;
        (pear(on_ball(mid)) < 0 ? lo : hi) = mid;
      }
      crease.push_back(on_ball((lo + hi) / 2));
    }
    crease.push_back(crease.front());

    // Left ovary.
    ovary.centre = Vec(s.ovary_offset, s.ovary_y, s.ovary_height);
    ovary.semi_axes = s.ovary_size / 2;
    const Vec& o = ovary.centre;
    const double ax = ovary.semi_axes.x(), ay = ovary.semi_axes.y(), az = ovary.semi_axes.z();

    // Ovarian ligament: straight, from the cornu (below the tube's insertion, on the level of
    // the ovary's posterior half) to the ovary's medial pole; each end `attachment_depth` inside.
    const Vec lig_origin(0, s.ovary_y, s.cornu_height - s.ligament_drop);
    const Vec lig_body = ray_exit(pear_f, lig_origin, Vec(1, 0, 0), reach);
    const Vec medial_pole = o - Vec(ax, 0, 0);
    const Vec lig_dir = (medial_pole - lig_body).normalized();
    ligament = {lig_body - s.attachment_depth * lig_dir,
                medial_pole + s.attachment_depth * lig_dir};

    // Fallopian tube: from inside the cornu, laterally over the ovary, down past its lateral
    // pole and back medially behind it (the fimbriated end lies posterior to the ovary).
    const Vec cornu = ray_exit(pear_f, Vec(0, 0, s.cornu_height), Vec(1, 0, 0), reach);
    const Vec cornu_normal = gradient_direction(pear_f, cornu);
    const double g = s.tube_clearance;  // offset of the path around the ovary
    const double cm = 0.01;
    const std::vector<Vec> controls{
        cornu - s.tube_insertion * cornu_normal,
        cornu + 0.8 * cm * cornu_normal,
        o + Vec(-1.0 * cm, 0.4 * cm, az + g + 0.5 * cm),  // arching over the ovary
        o + Vec(0.6 * cm, 0.2 * cm, az + g + 0.6 * cm),
        o + Vec(ax + g + 0.4 * cm, -0.2 * cm, az + 0.3 * cm),  // down past the lateral pole
        o + Vec(ax + g + 0.2 * cm, -1.0 * cm, -az - 0.4 * cm),
        o + Vec(0.2 * cm, -(ay + g + 0.1 * cm), -az - 0.3 * cm),  // back behind the ovary
        o + Vec(-0.8 * cm, -(ay + g + 0.1 * cm), 0.0),
        o + Vec(-1.6 * cm, -(ay + g + 0.2 * cm), 0.4 * cm),
    };
    tube = catmull_rom(controls, 0.0005, s.tube_length);
  }
};

void write_obj(const std::string& path, const TriangleMesh<double>& mesh, double scale,
               const std::string& name) {
  std::ofstream out(path);
  if (!out) throw Error(path, name, "cannot open the file for writing");
  out << "# fsm procedural uterus: " << name << " (units: cm)\n";
  out << "o " << name << "\n";
  out << std::fixed << std::setprecision(6);
  for (Index v = 0; v < mesh.num_vertices(); ++v)
    out << "v " << mesh.vertices(v, 0) * scale << ' ' << mesh.vertices(v, 1) * scale << ' '
        << mesh.vertices(v, 2) * scale << '\n';
  for (Index f = 0; f < mesh.num_faces(); ++f)
    out << "f " << mesh.faces(f, 0) + 1 << ' ' << mesh.faces(f, 1) + 1 << ' '
        << mesh.faces(f, 2) + 1 << '\n';
  if (!out) throw Error(path, name, "writing failed");
}

/// Rounds a length in cm to 1e-4 cm (1 um) for the scene file.
double round_cm(double metres) {
  return std::round(metres * 100 * 1e4) / 1e4;
}

}  // namespace

UterusMeshes generate_uterus(const UterusShape& shape) {
  check(shape);
  const Layout layout(shape);
  const double size = shape.mesh_size;
  UterusMeshes out;
  const auto add = [&out](const std::string& name, TriangleMesh<double> mesh) {
    out.names.push_back(name);
    out.meshes.push_back(std::move(mesh));
  };

  // Body: the pear minus the fibroid's ball; the crease where they meet is kept as mesh edges.
  const Pear& pear = layout.pear;
  const Vec fc = layout.fibroid_centre;
  const double fr = layout.fibroid_radius;
  const Field body = [&pear, fc, fr](const Vec& p) {
    return std::max(pear(p), fr - (p - fc).norm());
  };
  const double body_reach = pear.half_length + 2 * fr + 0.01;
  add("body",
      mesh_surface(body, Vec::Zero(), body_reach, size, {layout.crease}, shape.seed, "body"));

  const Field fibroid = [fc, fr](const Vec& p) { return (p - fc).norm() - fr; };
  add("fibroid",
      mesh_surface(fibroid, fc, fr * 1.3, std::min(size, fr / 3), {}, shape.seed, "fibroid"));

  const Ellipsoid ovary = layout.ovary;
  const TriangleMesh<double> ovary_left =
      mesh_surface([ovary](const Vec& p) { return ovary(p); }, ovary.centre,
                   ovary.semi_axes.maxCoeff() * 1.3, size, {}, shape.seed, "ovary_left");

  const auto tube_mesh = [&](const Polyline& axis, double radius, const std::string& name) {
    Vec lo = axis.front(), hi = axis.front();
    for (const Vec& p : axis) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const Tube tube{axis, radius};
    return mesh_surface([tube](const Vec& p) { return tube(p); }, (lo + hi) / 2,
                        (hi - lo).norm() / 2 + 2 * radius, std::min(size, 0.8 * radius), {},
                        shape.seed, name);
  };
  const TriangleMesh<double> ligament_left =
      tube_mesh(layout.ligament, shape.ligament_radius, "ligament_left");
  const TriangleMesh<double> tube_left = tube_mesh(layout.tube, shape.tube_radius, "tube_left");

  add("ovary_left", ovary_left);
  add("ovary_right", mirror_x(ovary_left));
  add("ligament_left", ligament_left);
  add("ligament_right", mirror_x(ligament_left));
  add("tube_left", tube_left);
  add("tube_right", mirror_x(tube_left));
  return out;
}

std::string write_uterus_scene(const std::string& directory, const UterusShape& shape) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) throw Error(directory, "", "cannot create the directory: " + ec.message());

  const UterusMeshes meshes = generate_uterus(shape);
  for (std::size_t i = 0; i < meshes.names.size(); ++i)
    write_obj((fs::path(directory) / (meshes.names[i] + ".obj")).string(), meshes.meshes[i], 100.0,
              meshes.names[i]);

  using Json = nlohmann::ordered_json;
  const Json material = {{"density", 1050},
                         {"youngs_modulus", 13150},
                         {"viscosity", 10.26},
                         {"large_strain_modulus", 68380},
                         {"switch_strain", 0.1}};
  // Table 1 of the paper: topology and sphere radius (cm) per part.
  const std::vector<std::pair<std::string, std::pair<std::string, double>>> table{
      {"body", {"tetrahedral", 0.50}},       {"fibroid", {"tetrahedral", 0.30}},
      {"ovary_left", {"tetrahedral", 0.40}}, {"ovary_right", {"tetrahedral", 0.40}},
      {"ligament_left", {"axis", 0.25}},     {"ligament_right", {"axis", 0.25}},
      {"tube_left", {"axis", 0.33}},         {"tube_right", {"axis", 0.33}}};
  Json parts = Json::array();
  for (const auto& [name, spec] : table) {
    Json part = {{"name", name},
                 {"mesh", name + ".obj"},
                 {"topology", spec.first},
                 {"radius", spec.second},
                 {"material", material}};
    if (spec.first == "tetrahedral") {
      part["metric"] = {{"type", "isotropic"}};
      part["optimiser"] = "odt";
    }
    parts.push_back(part);
  }
  Json attachments = Json::array();
  for (const auto& [a, b] :
       std::vector<std::pair<std::string, std::string>>{{"body", "fibroid"},
                                                        {"body", "ligament_left"},
                                                        {"body", "ligament_right"},
                                                        {"ovary_left", "ligament_left"},
                                                        {"ovary_right", "ligament_right"},
                                                        {"body", "tube_left"},
                                                        {"body", "tube_right"}})
    attachments.push_back({{"parts", {a, b}}, {"tolerance", 0.3}, {"stiffness_scale", 1.0}});

  // Fixed: the cervical end of the body (its lowest centimetre) and each ovary's lateral pole
  // (standing in for the suspensory ligament to the pelvic wall).
  const double bottom = -shape.body_length / 2;
  const double hx = shape.body_width / 2 + 0.01, hy = shape.body_depth / 2 + 0.01;
  const Vec ovary_semi = shape.ovary_size / 2;
  const double lateral = shape.ovary_offset + 0.6 * ovary_semi.x();
  Json fixed = Json::array();
  fixed.push_back({{"part", "body"},
                   {"box",
                    {{"min", {round_cm(-hx), round_cm(-hy), round_cm(bottom - 0.01)}},
                     {"max", {round_cm(hx), round_cm(hy), round_cm(bottom + 0.01)}}}}});
  fixed.push_back(
      {{"part", "ovary_left"},
       {"plane",
        {{"point", {round_cm(lateral), round_cm(shape.ovary_y), round_cm(shape.ovary_height)}},
         {"normal", {-1, 0, 0}}}}});
  fixed.push_back(
      {{"part", "ovary_right"},
       {"plane",
        {{"point", {round_cm(-lateral), round_cm(shape.ovary_y), round_cm(shape.ovary_height)}},
         {"normal", {1, 0, 0}}}}});

  const Json scene = {
      {"format", "fsm-scene"}, {"version", 1},   {"name", "uterus"},           {"units", "cm"},
      {"mesh_units", "cm"},    {"parts", parts}, {"attachments", attachments}, {"fixed", fixed}};
  const std::string path = (fs::path(directory) / "uterus.json").string();
  std::ofstream out(path);
  if (!out) throw Error(path, "", "cannot open the file for writing");
  out << scene.dump(2) << '\n';
  if (!out) throw Error(path, "", "writing failed");
  return path;
}

}  // namespace fsm::build
