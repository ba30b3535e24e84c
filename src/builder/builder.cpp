// HybridTopologyBuilder: per part, read and check the surface, fill it, then join the parts,
// fix anchors, bind the render surface and report.

#include "fsm/builder/builder.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>

#include "fidelity.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm/error.hpp"
#include "skin_binding.hpp"

namespace fsm::build {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

// What a part contributes before it is placed in the model.
struct PartOutcome {
  PartReport report;
  TriangleMesh<double> surface;              // the closed surface that was filled
  std::vector<TriangleMesh<double>> render;  // the input meshes, rendered as given
  // Exactly one of these is used, by topology.
  TetraFilling tetra;
  AxisFilling axis;
  GridFilling grid;
  PackingFilling packing;
};

// ---- The resource budget (docs/builder.md, "Resource budget") ---------------------------------
//
// Cost models, calibrated on this machine's builds (docs/builder.md gives the measurements): a
// Mesh_3 filling at size h makes about V/h^3 + A/(2 h^2) vertices (interior plus surface), up to
// 5 tetrahedra and 7 links per vertex, and peaks at about kTetraBytesPerSphere per vertex; an
// alpha wrap makes about 4 A/alpha^2 faces at kWrapBytesPerFace each.
constexpr double kTetraBytesPerSphere = 4e3;
constexpr double kWrapBytesPerFace = 2e3;
constexpr double kSphereBytes = 2e3;  // chains, grids, packings: nodes, links, search structures

double surface_area(const TriangleMesh<double>& m) {
  double a = 0;
  for (Index f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d p = m.vertices.row(m.faces(f, 0)).transpose();
    const Eigen::Vector3d q = m.vertices.row(m.faces(f, 1)).transpose();
    const Eigen::Vector3d r = m.vertices.row(m.faces(f, 2)).transpose();
    a += 0.5 * (q - p).cross(r - p).norm();
  }
  return a;
}

std::string si(double value, const char* unit, double scale, int digits = 3) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g %s", digits, value / scale, unit);
  return buf;
}

// The vertex density sqrt(det M) (1/m^3) and the smallest size (m) of a metric over a box: exact
// for a constant metric, else the mean and minimum over a 16^3 sample grid.
std::pair<double, double> metric_density(const MetricField& metric, const Eigen::Vector3d& lo,
                                         const Eigen::Vector3d& hi) {
  auto density = [&](const Eigen::Vector3d& x) {
    const double d = metric.metric(x).determinant();
    return d > 0 ? std::sqrt(d) : 0.0;
  };
  if (metric.is_constant()) return {density(lo), metric.size(lo)};
  constexpr int n = 16;
  double sum = 0, smallest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const Eigen::Vector3d t((i + 0.5) / n, (j + 0.5) / n, (k + 0.5) / n);
        const Eigen::Vector3d x = lo + t.cwiseProduct(hi - lo);
        sum += density(x);
        smallest = std::min(smallest, metric.size(x));
      }
  return {sum / (n * n * n), smallest};
}

// What filling `surface` by `spec` will cost.
WorkEstimate estimate_filling(const PartSpec& spec, const TriangleMesh<double>& surface) {
  WorkEstimate e;
  const double volume = std::abs(surface.volume());
  const double area = surface_area(surface);
  const Eigen::Vector3d lo = surface.vertices.colwise().minCoeff().transpose();
  const Eigen::Vector3d hi = surface.vertices.colwise().maxCoeff().transpose();
  const std::string shape =
      "volume " + si(volume, "cm^3", 1e-6) + ", area " + si(area, "cm^2", 1e-4);
  switch (spec.topology) {
    case Topology::tetrahedral: {
      const auto metric = spec.metric ? spec.metric : isotropic_metric(spec.radius);
      const auto [density, h] = metric_density(*metric, lo, hi);
      e.spheres = volume * density + 0.5 * area / (h * h);
      e.elements = 12 * e.spheres;  // 5 tetrahedra + 7 links per sphere
      e.memory_bytes = kTetraBytesPerSphere * e.spheres;
      e.basis = shape +
                (metric->is_constant() ? " at element size " : " at element sizes down to ") +
                si(h, "mm", 1e-3) + (metric->is_constant() ? "" : " (sampled)");
      break;
    }
    case Topology::axis: {
      const double spacing = spec.axis.spacing > 0 ? spec.axis.spacing : spec.radius;
      const double r = spec.axis.radius_min > 0 ? spec.axis.radius_min : 0.5 * spec.radius;
      // A tube of radius r and length L has area 2 pi r L: the longest axis the surface allows.
      e.spheres = area / (2 * M_PI * r) / spacing + 1;
      e.elements = 2 * e.spheres;
      e.memory_bytes = kSphereBytes * e.spheres + 4e3 * double(surface.num_faces());
      e.basis = shape + ", spheres every " + si(spacing, "mm", 1e-3);
      break;
    }
    case Topology::grid: {
      const double s = spec.grid.spacing > 0 ? spec.grid.spacing : 2 * spec.radius;
      const Eigen::Vector3d cells = (hi - lo) / s;
      e.spheres = std::min(volume / (s * s * s), (cells.array() + 1).prod());
      e.elements = e.spheres * spec.grid.neighbours / 2;
      e.memory_bytes = kSphereBytes * e.spheres;
      e.basis = shape + " at spacing " + si(s, "mm", 1e-3);
      break;
    }
    case Topology::packing: {
      const double r = spec.packing.radius_min > 0 ? spec.packing.radius_min : 0.5 * spec.radius;
      e.spheres = volume / (r * r * r);
      e.elements = 6 * e.spheres;
      e.memory_bytes = kSphereBytes * e.spheres;
      e.basis = shape + " down to radius " + si(r, "mm", 1e-3);
      break;
    }
  }
  return e;
}

// Refuses, naming the estimate and how to raise the limit, when `total` passes a limit.
void check_budget(const WorkEstimate& part, const WorkEstimate& total, const BuildLimits& limits,
                  const std::string& file, const std::string& part_name, const char* what) {
  auto over = [&](double used, double limit, const char* quantity, const char* key,
                  const char* flag) {
    if (std::isfinite(used) && used <= limit) return;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "%s would need about %.3g %s (%s), and the build %.3g in all: more than the "
                  "limit of %.3g; if this is meant, raise it with \"limits\": {\"%s\": N} in "
                  "the scene or %s N",
                  what,
                  std::strcmp(quantity, "bytes of memory") == 0 ? part.memory_bytes
                  : std::strcmp(quantity, "spheres") == 0       ? part.spheres
                                                                : part.elements,
                  quantity, part.basis.c_str(), used, limit, key, flag);
    throw Error(file, part_name, buf);
  };
  over(total.spheres, limits.spheres, "spheres", "spheres", "--max-spheres");
  over(total.elements, limits.elements, "elements", "elements", "--max-elements");
  over(total.memory_bytes, limits.memory_bytes, "bytes of memory", "memory_gb",
       "--max-memory-gb (GB)");
}

// Reads the part's meshes, reports their defects, applies the requested repairs and returns the
// closed surface to fill; fsm::Error naming file, part and defect otherwise. An alpha wrap is
// estimated against the budget before it runs.
TriangleMesh<double> prepare_surface(const PartSpec& spec, PartOutcome& out,
                                     const BuildLimits& limits, const WorkEstimate& so_far,
                                     const std::string& scene_file) {
  for (std::size_t k = 0; k < spec.meshes.size(); ++k) {
    const std::string& path = spec.meshes[k];
    const std::vector<std::string> nodes =
        k < spec.mesh_nodes.size() ? spec.mesh_nodes[k] : std::vector<std::string>{};
    TriangleMesh<double> m = read_mesh(path, spec.mesh_scale, nodes);
    std::string label = path;  // a glTF's chosen nodes follow its path: "pelvis.glb#uterus,cervix"
    for (std::size_t n = 0; n < nodes.size(); ++n) label += (n == 0 ? "#" : ",") + nodes[n];
    out.report.meshes.push_back(inspect_mesh(m, label));
    out.render.push_back(std::move(m));
  }
  if (spec.wrap) {
    double area = 0;
    for (const auto& m : out.render) area += surface_area(m);
    WorkEstimate wrap;
    wrap.elements = 4 * area / (spec.wrap->alpha * spec.wrap->alpha);
    wrap.memory_bytes = kWrapBytesPerFace * wrap.elements;
    wrap.basis =
        "input area " + si(area, "cm^2", 1e-4) + " at alpha " + si(spec.wrap->alpha, "mm", 1e-3);
    WorkEstimate total = so_far;
    total.elements += wrap.elements;
    total.memory_bytes = std::max(total.memory_bytes, wrap.memory_bytes);
    check_budget(wrap, total, limits, scene_file, spec.name, "the alpha wrap");
    TriangleMesh<double> wrapped = alpha_wrap(out.render, spec.wrap->alpha, spec.wrap->offset);
    MeshReport r = inspect_mesh(wrapped, "alpha wrap");
    char buf[160];
    std::snprintf(buf, sizeof buf, "alpha wrap of %zu mesh(es), alpha %.3g mm, offset %.3g mm",
                  out.render.size(), spec.wrap->alpha * 1e3, spec.wrap->offset * 1e3);
    r.repairs.push_back(buf);
    if (!r.bounds_a_volume())
      throw Error(spec.meshes.front(), spec.name,
                  "the alpha wrap does not bound a volume: " + join(r.defects(), ", "));
    out.report.meshes.push_back(r);
    return wrapped;
  }
  if (out.render.size() > 1)
    throw Error(
        spec.meshes[1], spec.name,
        "a part filled from " + std::to_string(out.render.size()) +
            " meshes needs \"repair\": {\"alpha_wrap\": ...} to join them into one surface");
  TriangleMesh<double> surface = out.render.front();
  MeshReport& r = out.report.meshes.front();
  if (spec.orient && !r.outward_oriented && r.closed() && r.manifold()) {
    surface = orient_outward(surface, spec.meshes.front());
    r = inspect_mesh(surface, spec.meshes.front());
    r.repairs.push_back("faces reoriented outward");
    out.render.front() = surface;
  }
  if (!r.bounds_a_volume()) {
    std::string hint =
        r.closed() && r.manifold() && r.self_intersections == 0 && !r.outward_oriented
            ? "; add \"repair\": {\"orient\": true}"
            : "; add \"repair\": {\"alpha_wrap\": {...}} to wrap it";
    throw Error(spec.meshes.front(), spec.name,
                "the mesh does not bound a volume: " + join(r.defects(), ", ") + hint);
  }
  return surface;
}

// Links of the grid baseline: E-to-k per neighbour set (docs/builder.md).
double grid_factor(int neighbours, std::uint8_t kind) {
  if (neighbours == 6) return 1.0;              // bar: k = E s^2 / s
  if (neighbours == 18) return 0.4;             // isotropic: k1 = k2 = 2 E s / 5
  return kind == 0 ? 22.0 / 35.0 : 6.0 / 35.0;  // 26, isotropic with k2 = k3
}

}  // namespace

HybridTopologyBuilder::HybridTopologyBuilder(Scene scene)
    : m_scene(std::move(scene)), m_limits(m_scene.limits) {
  if (m_scene.parts.empty()) throw Error(m_scene.file, "scene", "has no parts");
}

void HybridTopologyBuilder::set_limits(const BuildLimits& limits) {
  if (!(limits.spheres > 0) || !(limits.elements > 0) || !(limits.memory_bytes > 0))
    throw Error(m_scene.file, "limits", "every limit must be positive");
  m_limits = limits;
}

namespace {

// The state the stages of one build share.
// Progress only moves forward: filling takes the first 80 % of the bar (by part), linking the next
// 10 %, binding the render surfaces the rest.
constexpr double k_fill_share = 0.8, k_link_share = 0.1;

struct Build {
  const Scene& scene;
  const HybridTopologyBuilder::Progress& progress;
  TissueModel<double> model;
  std::vector<PartOutcome> outcomes;
  std::map<std::string, std::size_t> part_index;
  std::vector<std::vector<std::size_t>> joined;  // per part: the parts attached to it
  const BuildLimits& limits;
  WorkEstimate total;  // estimated so far: spheres and elements add up, memory is the peak

  void report_progress(const std::string& part, const std::string& stage, double f) const {
    if (progress) progress(part, stage, f);
  }
};

// Stage 1: read, check and fill every part.
void fill_parts(Build& b) {
  const std::size_t np = b.scene.parts.size();
  b.outcomes.resize(np);
  for (std::size_t p = 0; p < np; ++p) {
    const PartSpec& spec = b.scene.parts[p];
    b.part_index[spec.name] = p;
    PartOutcome& out = b.outcomes[p];
    const auto t0 = Clock::now();
    out.report.name = spec.name;
    out.report.topology = spec.topology;
    out.report.radius = spec.radius;
    b.report_progress(spec.name, "reading meshes", k_fill_share * double(p) / double(np));
    try {
      out.surface = prepare_surface(spec, out, b.limits, b.total, b.scene.file);
    } catch (const Error& e) {
      if (e.part().empty()) throw Error(e.file(), spec.name, e.reason());
      throw;
    }
    out.report.volume = out.surface.volume();
    // The budget, before any filling work.
    out.report.estimate = estimate_filling(spec, out.surface);
    b.total.spheres += out.report.estimate.spheres;
    b.total.elements += out.report.estimate.elements;
    b.total.memory_bytes = std::max(b.total.memory_bytes, out.report.estimate.memory_bytes);
    check_budget(out.report.estimate, b.total, b.limits, b.scene.file, spec.name,
                 (std::string("the ") + to_string(spec.topology) + " filling").c_str());
    // A sphere larger than the part cannot fill it: the filling would be a few spheres at best.
    const double equivalent = std::cbrt(std::abs(out.report.volume));
    if (spec.radius > 0.5 * equivalent) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "the sphere radius %.3g mm is larger than half the part's size (%.3g mm, the "
                    "cube root of its volume): the filling will have very few spheres",
                    spec.radius * 1e3, equivalent * 1e3);
      out.report.warnings.push_back(buf);
    }
    b.report_progress(spec.name, std::string("filling (") + to_string(spec.topology) + ")",
                      k_fill_share * (double(p) + 0.3) / double(np));
    switch (spec.topology) {
      case Topology::tetrahedral: {
        const auto metric = spec.metric ? spec.metric : isotropic_metric(spec.radius);
        // Sharp edges are protected, except on an alpha wrap: it rounds convex edges by its
        // offset, so its creases are its own facets at alpha, not the organ's edges.
        out.tetra = fill_tetrahedral(out.surface, *metric, spec.optimiser, spec.name,
                                     spec.wrap ? 0.0 : kFeatureAngleDeg);
        out.report.quality = out.tetra.quality;
        out.report.metric = metric->describe();
        out.report.optimiser = out.tetra.optimiser;
        // Geometric fidelity: volume, area, and the area inside the part's fixed boxes and
        // half-spaces (the scene's only regions defined by geometry).
        std::vector<FixedSpec> regions;
        std::vector<std::string> names;
        for (std::size_t k = 0; k < b.scene.fixed.size(); ++k) {
          const FixedSpec& f = b.scene.fixed[k];
          if (f.part != spec.name ||
              (f.kind != FixedSpec::Kind::box && f.kind != FixedSpec::Kind::plane))
            continue;
          regions.push_back(f);
          names.push_back("fixed region " + std::to_string(k) +
                          (f.kind == FixedSpec::Kind::box ? " (box)" : " (plane)"));
        }
        FidelityReport& fid = out.report.fidelity;
        fid = detail::measure_fidelity(out.surface, out.tetra.mesh, regions, names);
        fid.feature_angle_deg = out.tetra.feature_angle_deg;
        fid.feature_edges = out.tetra.feature_edges;
        fid.feature_corners = out.tetra.feature_corners;
        fid.dropped_cells = out.tetra.dropped_cells;
        fid.dropped_volume = out.tetra.dropped_volume;
        for (std::string& w : detail::fidelity_warnings(fid, spec.radius))
          out.report.warnings.push_back(std::move(w));
        break;
      }
      case Topology::axis:
        out.axis = fill_axis(out.surface, spec.axis, spec.radius, spec.name);
        break;
      case Topology::grid: {
        const double s = spec.grid.spacing > 0 ? spec.grid.spacing : 2 * spec.radius;
        out.grid = fill_grid(out.surface, s, spec.grid.neighbours, spec.name);
        break;
      }
      case Topology::packing: {
        const double rmin =
            spec.packing.radius_min > 0 ? spec.packing.radius_min : 0.5 * spec.radius;
        const double rmax =
            spec.packing.radius_max > 0 ? spec.packing.radius_max : 2.0 * spec.radius;
        if (rmin > rmax)
          throw Error(b.scene.file, spec.name, "packing radius_min exceeds radius_max");
        out.packing = fill_packing(out.surface, rmin, rmax, spec.name);
        break;
      }
    }
    out.report.seconds = since(t0);
  }
}

// Stage 2: place the parts in one SphereModel, a region per part; a tetrahedral part keeps its
// tetrahedra.
void place_parts(Build& b) {
  SphereModel<double>& spheres = b.model.spheres;
  for (std::size_t p = 0; p < b.scene.parts.size(); ++p) {
    const PartSpec& spec = b.scene.parts[p];
    PartOutcome& out = b.outcomes[p];
    const auto t0 = Clock::now();
    b.report_progress(spec.name, "linking",
                      k_fill_share + k_link_share * double(p) / double(b.scene.parts.size()));
    Part part;
    part.name = spec.name;
    part.topology = spec.topology;
    part.radius = spec.radius;
    part.region = spheres.add_region(spec.name, spec.material, spec.law);
    part.first_node = spheres.num_nodes();
    part.first_link = spheres.num_links();
    part.first_tetrahedron = spheres.num_tetrahedra();
    const Material<double>& mat = spec.material;
    const double volume = std::abs(out.report.volume);
    auto add_nodes = [&](const Positions<double>& c, const Eigen::VectorXd& radii,
                         const Eigen::VectorXd& weight) {
      const double total = weight.sum();
      for (Index i = 0; i < Index(c.rows()); ++i)
        spheres.add_node(c.row(i).transpose(), radii[i], mat.density * volume * weight[i] / total,
                         part.region);
    };
    switch (spec.topology) {
      case Topology::tetrahedral: {
        add_tetrahedral_part(spheres, out.tetra.mesh, part.region, spec.radius);
        // Lumped masses add up to rho times the filling's volume, which misses a thin shell of
        // the surface (the boundary is within h/4 of it): scale them to the organ's rho V.
        const Index n = spheres.num_nodes() - part.first_node;
        spheres.masses().segment(part.first_node, n) *= volume / out.tetra.mesh.volume();
        break;
      }
      case Topology::axis: {
        const auto& a = out.axis;
        // Mass in proportion to r^2 times the chain length each sphere stands for; total rho V.
        Eigen::VectorXd share = Eigen::VectorXd::Zero(a.radii.size());
        for (const auto& [i, j] : a.chain_links) {
          const double half = 0.5 * (a.centres.row(i) - a.centres.row(j)).norm();
          share[i] += half;
          share[j] += half;
        }
        if (share.sum() == 0) share.setOnes();
        add_nodes(a.centres, a.radii, share.cwiseProduct(a.radii.cwiseAbs2()));
        auto rod = [&](Index i, Index j) {
          const double r = 0.5 * (a.radii[i] + a.radii[j]);
          const double l = (a.centres.row(i) - a.centres.row(j)).norm();
          spheres.add_link(part.first_node + i, part.first_node + j,
                           rod_link(mat, M_PI * r * r, l));
        };
        for (const auto& [i, j] : a.chain_links) rod(i, j);
        for (const auto& [i, j] : a.bending_links) rod(i, j);
        break;
      }
      case Topology::grid: {
        const auto& g = out.grid;
        const Eigen::VectorXd r = Eigen::VectorXd::Constant(g.centres.rows(), 0.5 * g.spacing);
        add_nodes(g.centres, r, Eigen::VectorXd::Ones(g.centres.rows()));
        for (std::size_t l = 0; l < g.links.size(); ++l) {
          const auto [i, j] = g.links[l];
          const double len = (g.centres.row(i) - g.centres.row(j)).norm();
          const double f = grid_factor(spec.grid.neighbours, g.link_kind[l]);
          // k = f E s and k_d = f eta s, written as a rod of area f s len.
          spheres.add_link(part.first_node + i, part.first_node + j,
                           rod_link(mat, f * g.spacing * len, len));
        }
        break;
      }
      case Topology::packing: {
        const auto& k = out.packing;
        add_nodes(k.centres, k.radii, k.radii.array().cube().matrix());
        for (const auto& [i, j] : k.links) {
          const double r = std::min(k.radii[i], k.radii[j]);
          const double l = (k.centres.row(i) - k.centres.row(j)).norm();
          spheres.add_link(part.first_node + i, part.first_node + j,
                           rod_link(mat, M_PI * r * r, l));
        }
        break;
      }
    }
    part.num_nodes = spheres.num_nodes() - part.first_node;
    part.num_links = spheres.num_links() - part.first_link;
    part.num_tetrahedra = spheres.num_tetrahedra() - part.first_tetrahedron;
    out.report.spheres = part.num_nodes;
    out.report.links = part.num_links;
    out.report.mass = spheres.masses().segment(part.first_node, part.num_nodes).sum();
    b.model.parts.push_back(part);
    out.report.seconds += since(t0);
  }
}

// Stage 3: attachments. Each sphere of one part within the tolerance of the other part's spheres
// is linked to its nearest one there (both ways; no pair twice). Rod rule with the softer
// material and the smaller sphere's cross-section, times the scene's stiffness_scale.
void attach_parts(Build& b) {
  SphereModel<double>& spheres = b.model.spheres;
  b.model.first_attachment_link = spheres.num_links();
  b.joined.assign(b.scene.parts.size(), {});
  for (const AttachmentSpec& att : b.scene.attachments) {
    const std::size_t pa = b.part_index.at(att.a), pb = b.part_index.at(att.b);
    const Part &A = b.model.parts[pa], &B = b.model.parts[pb];
    const auto x = spheres.rest_positions();
    const auto r = spheres.radii();
    const Material<double>& soft =
        b.scene.parts[pa].material.youngs_modulus <= b.scene.parts[pb].material.youngs_modulus
            ? b.scene.parts[pa].material
            : b.scene.parts[pb].material;
    std::map<std::pair<Index, Index>, bool> done;
    double closest = std::numeric_limits<double>::infinity();
    Index added = 0;
    auto link_from = [&](const Part& P, const Part& Q) {
      for (Index i = P.first_node; i < P.first_node + P.num_nodes; ++i) {
        Index best = -1;
        double best_gap = std::numeric_limits<double>::infinity();
        for (Index j = Q.first_node; j < Q.first_node + Q.num_nodes; ++j) {
          const double gap = (x.row(i) - x.row(j)).norm() - r[i] - r[j];
          if (gap < best_gap) {
            best_gap = gap;
            best = j;
          }
        }
        closest = std::min(closest, best_gap);
        if (best < 0 || best_gap > att.tolerance) continue;
        const auto key = std::minmax(i, best);
        const double len = (x.row(i) - x.row(best)).norm();
        if (done[key] || len < 1e-9) continue;  // coincident centres cannot carry a rest length
        done[key] = true;
        const double rr = std::min(r[i], r[best]);
        // A bar no shorter than the smaller radius: nearly coincident spheres would otherwise get
        // arbitrarily stiff links (k = E A / l), which set the highest eigenfrequency.
        VoigtLink<double> law = rod_link(soft, M_PI * rr * rr, std::max(len, rr));
        law.rest_length = len;
        law.stiffness *= att.stiffness_scale;
        law.damping *= att.stiffness_scale;
        law.large_stiffness *= att.stiffness_scale;
        const Index l = spheres.add_link(key.first, key.second, law);
        spheres.tear_strain()[l] = att.tear_strain;
        ++added;
      }
    };
    link_from(A, B);
    link_from(B, A);
    if (added == 0) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "no spheres within the tolerance of %.3g mm; the closest sphere surfaces are "
                    "%.3g mm apart",
                    att.tolerance * 1e3, closest * 1e3);
      throw Error(b.scene.file, "attachment '" + att.a + "'-'" + att.b + "'", buf);
    }
    b.joined[pa].push_back(pb);
    b.joined[pb].push_back(pa);
  }
  b.model.num_attachment_links = spheres.num_links() - b.model.first_attachment_link;
}

// Stage 4: fixed regions, then the check that every group of attached parts is anchored.
void fix_parts(Build& b) {
  const std::size_t np = b.scene.parts.size();
  SphereModel<double>& spheres = b.model.spheres;
  std::vector<bool> anchored(np, false);
  for (std::size_t k = 0; k < b.scene.fixed.size(); ++k) {
    const FixedSpec& f = b.scene.fixed[k];
    const std::size_t p = b.part_index.at(f.part);
    const Part& P = b.model.parts[p];
    const std::string where = "fixed region " + std::to_string(k) + " (part '" + f.part + "')";
    std::vector<Index> chosen;
    const auto x = spheres.rest_positions();
    switch (f.kind) {
      case FixedSpec::Kind::box:
        for (Index i = P.first_node; i < P.first_node + P.num_nodes; ++i) {
          const Eigen::Vector3d q = x.row(i).transpose();
          if ((q.array() >= f.min.array()).all() && (q.array() <= f.max.array()).all())
            chosen.push_back(i);
        }
        break;
      case FixedSpec::Kind::plane:
        for (Index i = P.first_node; i < P.first_node + P.num_nodes; ++i)
          if ((x.row(i).transpose() - f.point).dot(f.normal) <= 0) chosen.push_back(i);
        break;
      case FixedSpec::Kind::vertices:
        for (Index v : f.vertices) {
          if (v >= P.num_nodes)
            throw Error(b.scene.file, where,
                        "vertex " + std::to_string(v) + " is out of range; the part has " +
                            std::to_string(P.num_nodes) + " spheres");
          chosen.push_back(P.first_node + v);
        }
        break;
      case FixedSpec::Kind::chain_end: {
        if (P.topology != Topology::axis)
          throw Error(b.scene.file, where, "'chain_end' applies to axis parts only");
        const auto& br = b.outcomes[p].axis.branches;
        chosen.push_back(P.first_node + (f.last ? br.back().back() : br.front().front()));
        break;
      }
    }
    if (chosen.empty()) throw Error(b.scene.file, where, "selects no sphere");
    for (Index i : chosen) spheres.set_fixed(i);
    anchored[p] = true;
  }
  std::vector<int> group(np, -1);
  for (std::size_t s = 0; s < np; ++s) {
    if (group[s] >= 0) continue;
    std::vector<std::size_t> stack{s}, members;
    group[s] = int(s);
    bool fixed = false;
    while (!stack.empty()) {
      const std::size_t q = stack.back();
      stack.pop_back();
      members.push_back(q);
      fixed = fixed || anchored[q];
      for (std::size_t w : b.joined[q])
        if (group[w] < 0) {
          group[w] = int(s);
          stack.push_back(w);
        }
    }
    if (!fixed) {
      std::vector<std::string> names;
      for (std::size_t q : members) names.push_back("'" + b.scene.parts[q].name + "'");
      throw Error(b.scene.file, "part " + names.front(),
                  names.size() == 1 ? "is neither fixed nor attached to a fixed part"
                                    : "is attached only to parts that are not fixed either (" +
                                          join(names, ", ") + "): fix one of them");
    }
  }
}

// Stage 5: the render surfaces, every input mesh of every part, bound to that part's spheres.
// Axis parts bind to their chains; tetrahedral parts barycentrically to their filling; the
// baselines barycentrically to a Delaunay tetrahedralisation of their sphere centres, or, with
// fewer than four non-coplanar spheres, each vertex to its nearest sphere by a rest offset
// (one-sphere chains: translation only).
void bind_render_surfaces(Build& b) {
  const SphereModel<double>& spheres = b.model.spheres;
  Skin<double>& skin = b.model.skin;
  Index nv = 0, nf = 0;
  for (const auto& out : b.outcomes)
    for (const auto& m : out.render) {
      nv += m.num_vertices();
      nf += m.num_faces();
    }
  skin.rest.vertices.resize(nv, 3);
  skin.rest.faces.resize(nf, 3);
  skin.kind.resize(nv);
  skin.nodes.setConstant(nv, 4, -1);
  skin.weights.setZero(nv, 4);
  skin.offsets.setZero(nv, 3);
  std::vector<Eigen::Matrix<Index, 1, 3>> chain_rows;
  std::vector<Eigen::RowVector3d> tangent_rows;
  Index v0 = 0, f0 = 0;
  for (std::size_t p = 0; p < b.outcomes.size(); ++p) {
    PartOutcome& out = b.outcomes[p];
    Part& part = b.model.parts[p];
    b.report_progress(
        part.name, "binding the render surface",
        k_fill_share + k_link_share +
            (1 - k_fill_share - k_link_share) * double(p) / double(b.outcomes.size()));
    Positions<double> pts(0, 3);
    FaceArray faces(0, 3);
    for (const auto& m : out.render) {
      const Index base = Index(pts.rows());
      pts.conservativeResize(base + m.num_vertices(), 3);
      pts.bottomRows(m.num_vertices()) = m.vertices;
      faces.conservativeResize(faces.rows() + m.num_faces(), 3);
      faces.bottomRows(m.num_faces()) = m.faces.array() + base;
    }
    const Index n = Index(pts.rows());
    skin.rest.vertices.middleRows(v0, n) = pts;
    skin.rest.faces.middleRows(f0, faces.rows()) = faces.array() + v0;
    const auto sphere_pos = spheres.rest_positions().middleRows(part.first_node, part.num_nodes);
    std::vector<std::vector<Index>> branches;
    TetrahedralMesh<double> local;
    if (part.topology == Topology::axis) {
      branches = out.axis.branches;
    } else if (part.topology == Topology::tetrahedral) {
      local = out.tetra.mesh;
    } else {
      try {
        local = tetrahedralise(Positions<double>(sphere_pos));
      } catch (const Error&) {
        for (Index k = 0; k < part.num_nodes; ++k) branches.push_back({k});
      }
    }
    if (!branches.empty()) {
      const detail::ChainBinding cb =
          detail::bind_chain(Positions<double>(sphere_pos), branches, part.first_node, pts);
      const Index base = Index(chain_rows.size());
      for (Index k = 0; k < cb.chain_nodes.rows(); ++k) {
        chain_rows.push_back(cb.chain_nodes.row(k));
        tangent_rows.push_back(cb.tangents.row(k));
      }
      for (Index v = 0; v < n; ++v) {
        skin.kind[v0 + v] = std::uint8_t(SkinKind::chain);
        skin.nodes(v0 + v, 0) = base + cb.entries(v, 0);
        skin.nodes(v0 + v, 1) = base + cb.entries(v, 1);
        skin.weights(v0 + v, 0) = 1 - cb.s[v];
        skin.weights(v0 + v, 1) = cb.s[v];
        skin.offsets.row(v0 + v) = cb.offsets.row(v);
      }
    } else {
      skin.kind.segment(v0, n).setConstant(std::uint8_t(SkinKind::barycentric));
      detail::bind_barycentric(local, part.first_node, pts, skin.nodes.middleRows(v0, n),
                               skin.weights.middleRows(v0, n));
    }
    part.surface = Index(skin.surfaces.size());
    skin.surfaces.push_back({part.name, v0, n, f0, Index(faces.rows())});
    out.report.surface_vertices = n;
    out.report.surface_faces = Index(faces.rows());
    v0 += n;
    f0 += Index(faces.rows());
  }
  skin.chain_nodes.resize(Index(chain_rows.size()), 3);
  skin.chain_rest_tangents.resize(Index(chain_rows.size()), 3);
  for (std::size_t k = 0; k < chain_rows.size(); ++k) {
    skin.chain_nodes.row(Index(k)) = chain_rows[k];
    skin.chain_rest_tangents.row(Index(k)) = tangent_rows[k];
  }
}

// Stage 6: the report.
BuildReport make_report(const Build& b, double seconds) {
  BuildReport report;
  report.scene = b.scene.name;
  for (const auto& out : b.outcomes) report.parts.push_back(out.report);
  report.spheres = b.model.spheres.num_nodes();
  report.links = b.model.spheres.num_links();
  report.attachment_links = b.model.num_attachment_links;
  report.fixed_nodes = b.model.spheres.num_fixed();
  report.seconds = seconds;
  return report;
}

}  // namespace

TissueModel<double> HybridTopologyBuilder::build() {
  const auto t_start = Clock::now();
  Build b{m_scene, m_progress, {}, {}, {}, {}, m_limits, {}};
  b.model.name = m_scene.name;
  fill_parts(b);
  place_parts(b);
  attach_parts(b);
  fix_parts(b);
  bind_render_surfaces(b);
  BuildReport report = make_report(b, since(t_start));
  // The model file keeps a reproducible copy: no wall times, mesh files named relative to the
  // scene's folder (not where this machine keeps it).
  BuildReport stored = report;
  const std::filesystem::path scene_dir = std::filesystem::path(m_scene.file).parent_path();
  for (auto& part : stored.parts)
    for (auto& mesh : part.meshes) {
      const std::filesystem::path file(mesh.file);
      const std::filesystem::path relative = file.lexically_relative(scene_dir);
      const bool inside = !m_scene.file.empty() && !relative.empty() && *relative.begin() != "..";
      mesh.file = (inside ? relative : file.filename()).generic_string();
    }
  b.model.report_json = stored.json(/*wall_times=*/false);
  b.model.validate();
  m_report = std::move(report);
  b.report_progress("", "done", 1.0);
  return std::move(b.model);
}

std::string BuildReport::table() const {
  std::ostringstream o;
  char line[256];
  std::snprintf(line, sizeof line, "%-16s %-12s %8s %8s %7s %7s %9s %9s %8s\n", "part", "topology",
                "r (cm)", "spheres", "links", "tets", "Q in 1-3", "min dih.", "time (s)");
  o << line;
  for (const auto& p : parts) {
    const bool tet = p.topology == Topology::tetrahedral;
    char q[16] = "-", d[16] = "-", t[16] = "-";
    if (tet) {
      std::snprintf(q, sizeof q, "%.1f %%", 100 * p.quality.fraction_q_1_3);
      std::snprintf(d, sizeof d, "%.1f deg", p.quality.min_dihedral_deg);
      std::snprintf(t, sizeof t, "%d", p.quality.tetrahedra);
    }
    std::snprintf(line, sizeof line, "%-16s %-12s %8.3f %8d %7d %7s %9s %9s %8.2f\n",
                  p.name.c_str(), to_string(p.topology), p.radius * 100, p.spheres, p.links, t, q,
                  d, p.seconds);
    o << line;
  }
  std::snprintf(line, sizeof line,
                "total: %d spheres, %d links (%d attachment), %d fixed; built in %.2f s\n", spheres,
                links, attachment_links, fixed_nodes, seconds);
  o << line;
  for (const std::string& w : warnings()) o << "warning: " << w << "\n";
  return o.str();
}

std::vector<std::string> BuildReport::warnings() const {
  std::vector<std::string> all;
  for (const auto& p : parts)
    for (const std::string& w : p.warnings) all.push_back("part '" + p.name + "': " + w);
  return all;
}

std::string BuildReport::json(bool wall_times) const {
  nlohmann::json j;
  j["scene"] = scene;
  j["spheres"] = spheres;
  j["links"] = links;
  j["attachment_links"] = attachment_links;
  j["fixed_spheres"] = fixed_nodes;
  if (wall_times) j["seconds"] = seconds;
  j["warnings"] = warnings();
  for (const auto& p : parts) {
    nlohmann::json q;
    q["name"] = p.name;
    q["topology"] = to_string(p.topology);
    q["radius_m"] = p.radius;
    q["spheres"] = p.spheres;
    q["links"] = p.links;
    q["volume_m3"] = p.volume;
    q["mass_kg"] = p.mass;
    if (wall_times) q["seconds"] = p.seconds;
    q["surface_vertices"] = p.surface_vertices;
    q["surface_faces"] = p.surface_faces;
    q["estimate"] = {{"spheres", p.estimate.spheres},
                     {"elements", p.estimate.elements},
                     {"memory_bytes", p.estimate.memory_bytes},
                     {"basis", p.estimate.basis}};
    q["warnings"] = p.warnings;
    if (p.topology == Topology::tetrahedral) {
      q["tetrahedra"] = p.quality.tetrahedra;
      q["quality"] = {{"q_min", p.quality.q_min},
                      {"q_mean", p.quality.q_mean},
                      {"q_max", p.quality.q_max},
                      {"fraction_q_1_3", p.quality.fraction_q_1_3},
                      {"histogram", p.quality.histogram},
                      {"histogram_bins", {"1-1.5", "1.5-2", "2-3", "3-5", "5-10", "10+"}},
                      {"min_dihedral_deg", p.quality.min_dihedral_deg},
                      {"mean_edge_m", p.quality.mean_edge}};
      q["metric"] = p.metric;
      q["optimiser"] = p.optimiser;
      const FidelityReport& f = p.fidelity;
      nlohmann::json regions = nlohmann::json::array();
      for (const RegionFidelity& r : f.regions)
        regions.push_back({{"region", r.region},
                           {"input_area_m2", r.input_area},
                           {"filled_area_m2", r.filled_area},
                           {"difference", r.difference}});
      q["fidelity"] = {{"input_volume_m3", f.input_volume},
                       {"filled_volume_m3", f.filled_volume},
                       {"volume_difference", f.volume_difference},
                       {"input_area_m2", f.input_area},
                       {"filled_area_m2", f.filled_area},
                       {"area_difference", f.area_difference},
                       {"regions", regions},
                       {"tolerance", detail::kFidelityTolerance},
                       {"feature_angle_deg", f.feature_angle_deg},
                       {"feature_edges", f.feature_edges},
                       {"feature_corners", f.feature_corners},
                       {"dropped_cells", f.dropped_cells},
                       {"dropped_volume_m3", f.dropped_volume}};
    }
    for (const auto& m : p.meshes) {
      q["meshes"].push_back({{"file", m.file},
                             {"vertices", m.vertices},
                             {"faces", m.faces},
                             {"components", m.components},
                             {"boundary_edges", m.boundary_edges},
                             {"non_manifold_edges", m.non_manifold_edges},
                             {"non_manifold_vertices", m.non_manifold_vertices},
                             {"degenerate_faces", m.degenerate_faces},
                             {"self_intersections", m.self_intersections},
                             {"outward_oriented", m.outward_oriented},
                             {"volume_m3", m.volume},
                             {"defects", m.defects()},
                             {"repairs", m.repairs}});
    }
    j["parts"].push_back(q);
  }
  return j.dump(2);
}

TissueModel<double> build_model(const std::string& scene_path, BuildReport* report) {
  HybridTopologyBuilder builder(load_scene(scene_path));
  TissueModel<double> model = builder.build();
  if (report) *report = builder.report();
  return model;
}

}  // namespace fsm::build
