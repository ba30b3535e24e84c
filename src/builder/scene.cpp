// Scene files: JSON (nlohmann) to fsm::build::Scene, strictly checked, in SI units.

#include "fsm/builder/scene.hpp"

#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;
constexpr int kSceneVersion = 1;

class Reader {
 public:
  explicit Reader(std::string file) : m_file(std::move(file)) {}

  [[noreturn]] void fail(const std::string& part, const std::string& reason) const {
    throw Error(m_file, part, reason);
  }

  void keys(const json& j, const std::set<std::string>& allowed, const std::string& where) const {
    if (!j.is_object()) fail(where, "must be a JSON object");
    for (const auto& [k, v] : j.items()) {
      (void)v;
      if (!allowed.count(k)) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(where, "unknown key '" + k + "' (allowed: " + list + ")");
      }
    }
  }

  double number(const json& j, const char* key, const std::string& where) const {
    if (!j.contains(key)) fail(where, std::string("missing '") + key + "'");
    return number_value(j.at(key), std::string(key), where);
  }

  double number_or(const json& j, const char* key, double fallback,
                   const std::string& where) const {
    return j.contains(key) ? number_value(j.at(key), key, where) : fallback;
  }

  /// An integer in [lo, hi], read without wrapping (JSON integers can be 64-bit, signed or not).
  long long integer(const json& v, const std::string& key, const std::string& where, long long lo,
                    long long hi) const {
    const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    if (!v.is_number_integer()) fail(where, "'" + key + "' must be an integer in " + range);
    if (v.is_number_unsigned() && v.get<unsigned long long>() > static_cast<unsigned long long>(hi))
      fail(where, "'" + key + "' is " + std::to_string(v.get<unsigned long long>()) + ", outside " +
                      range);
    const long long x = v.get<long long>();
    if (x < lo || x > hi)
      fail(where, "'" + key + "' is " + std::to_string(x) + ", outside " + range);
    return x;
  }

  double number_value(const json& v, const std::string& key, const std::string& where) const {
    if (!v.is_number()) fail(where, "'" + key + "' must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(where, "'" + key + "' is not finite");
    return d;
  }

  Eigen::Vector3d vec3(const json& j, const char* key, const std::string& where) const {
    if (!j.contains(key)) fail(where, std::string("missing '") + key + "'");
    const json& v = j.at(key);
    if (!v.is_array() || v.size() != 3) fail(where, std::string("'") + key + "' must be [x, y, z]");
    Eigen::Vector3d out;
    for (int i = 0; i < 3; ++i) out[i] = number_value(v[std::size_t(i)], key, where);
    return out;
  }

  std::string string(const json& j, const char* key, const std::string& where) const {
    if (!j.contains(key)) fail(where, std::string("missing '") + key + "'");
    if (!j.at(key).is_string()) fail(where, std::string("'") + key + "' must be a string");
    return j.at(key).get<std::string>();
  }

  void require_part(const std::set<std::string>& names, const std::string& name,
                    const std::string& where) const {
    if (!names.count(name)) fail(where, "names part '" + name + "', which the scene does not have");
  }

  double unit(const json& j, const char* key, double fallback, const std::string& where) const {
    if (!j.contains(key)) return fallback;
    const std::string u = string(j, key, where);
    if (u == "m") return 1.0;
    if (u == "cm") return 0.01;
    if (u == "mm") return 0.001;
    fail(where, "'" + std::string(key) + "' must be \"m\", \"cm\" or \"mm\", not \"" + u + "\"");
  }

 private:
  std::string m_file;
};

Material<double> read_material(const Reader& r, const json& j, const std::string& where) {
  r.keys(j,
         {"density", "youngs_modulus", "viscosity", "large_strain_modulus", "switch_strain",
          "poisson_ratio", "tear_strain"},
         where + " material");
  Material<double> m;
  m.density = r.number(j, "density", where);
  m.youngs_modulus = r.number(j, "youngs_modulus", where);
  m.viscosity = r.number_or(j, "viscosity", 0.0, where);
  m.large_strain_modulus = r.number_or(j, "large_strain_modulus", 0.0, where);
  m.switch_strain = r.number_or(j, "switch_strain", 0.0, where);
  m.poisson_ratio = r.number_or(j, "poisson_ratio", m.poisson_ratio, where);
  m.tear_strain = r.number_or(j, "tear_strain", m.tear_strain, where);
  try {
    m.validate(where);
  } catch (const Error& e) {
    r.fail(e.part(), e.reason());
  }
  return m;
}

// The part's topology-specific options ("metric", "optimiser", "axis", "grid", "packing").
void read_topology_options(const Reader& r, const json& p, double units, PartSpec& part,
                           const std::string& where) {
  const bool tetra = part.topology == Topology::tetrahedral;
  if (p.contains("metric")) {
    if (!tetra) r.fail(where, "'metric' applies to tetrahedral parts only");
    const json& m = p["metric"];
    const std::string type = r.string(m, "type", where + " metric");
    if (type == "isotropic") {
      r.keys(m, {"type", "size"}, where + " metric");
      part.metric = isotropic_metric(r.number_or(m, "size", part.radius / units, where) * units);
    } else if (type == "anisotropic") {
      r.keys(m, {"type", "sizes", "axes"}, where + " metric");
      const Eigen::Vector3d sizes = r.vec3(m, "sizes", where) * units;
      Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
      if (m.contains("axes")) {
        if (!m["axes"].is_array() || m["axes"].size() != 3)
          r.fail(where, "'metric.axes' must be three [x, y, z] vectors");
        for (int i = 0; i < 3; ++i) {
          const json row = json{{"v", m["axes"][std::size_t(i)]}};
          axes.col(i) = r.vec3(row, "v", where + " metric axes");
        }
      }
      try {
        part.metric = anisotropic_metric(sizes, axes);
      } catch (const Error& e) {
        r.fail(where, e.reason());
      }
    } else if (type == "graded") {
      r.keys(m, {"type", "size_min", "size_max", "centre", "distance", "plateau_radius"},
             where + " metric");
      try {
        part.metric = graded_metric(
            r.number(m, "size_min", where) * units, r.number(m, "size_max", where) * units,
            r.vec3(m, "centre", where) * units, r.number(m, "distance", where) * units,
            r.number_or(m, "plateau_radius", 0.0, where) * units);
      } catch (const Error& e) {
        r.fail(where, e.reason());
      }
    } else {
      r.fail(where, "unknown metric type '" + type + "' (isotropic, anisotropic, graded)");
    }
  }
  if (p.contains("optimiser")) {
    if (!tetra) r.fail(where, "'optimiser' applies to tetrahedral parts only");
    part.optimiser = r.string(p, "optimiser", where);
    const std::set<std::string> ok{"odt", "odt_perturb", "lloyd", "perturb", "exude", "none"};
    if (!ok.count(part.optimiser))
      r.fail(where,
             "unknown optimiser '" + part.optimiser + "' (odt, lloyd, perturb, exude, none)");
  }
  if (p.contains("axis")) {
    if (part.topology != Topology::axis) r.fail(where, "'axis' applies to axis parts only");
    const json& a = p["axis"];
    r.keys(a, {"spacing", "radius_min", "radius_max", "bending"}, where + " axis");
    part.axis.spacing = r.number_or(a, "spacing", 0.0, where) * units;
    part.axis.radius_min = r.number_or(a, "radius_min", 0.0, where) * units;
    part.axis.radius_max = r.number_or(a, "radius_max", 0.0, where) * units;
    if (a.contains("bending")) {
      if (!a["bending"].is_boolean()) r.fail(where, "'axis.bending' must be true or false");
      part.axis.bending = a["bending"].get<bool>();
    }
    if (part.axis.spacing < 0 || part.axis.radius_min < 0 || part.axis.radius_max < 0)
      r.fail(where, "axis lengths must not be negative");
  }
  if (p.contains("grid")) {
    if (part.topology != Topology::grid) r.fail(where, "'grid' applies to grid parts only");
    const json& g = p["grid"];
    r.keys(g, {"neighbours", "spacing"}, where + " grid");
    if (g.contains("neighbours")) {
      const double n = r.number(g, "neighbours", where);
      if (n != 6 && n != 18 && n != 26) r.fail(where, "'grid.neighbours' must be 6, 18 or 26");
      part.grid.neighbours = int(n);
    }
    part.grid.spacing = r.number_or(g, "spacing", 0.0, where) * units;
    if (part.grid.spacing < 0) r.fail(where, "'grid.spacing' must not be negative");
  }
  if (p.contains("packing")) {
    if (part.topology != Topology::packing)
      r.fail(where, "'packing' applies to packing parts only");
    const json& k = p["packing"];
    r.keys(k, {"radius_min", "radius_max"}, where + " packing");
    part.packing.radius_min = r.number_or(k, "radius_min", 0.0, where) * units;
    part.packing.radius_max = r.number_or(k, "radius_max", 0.0, where) * units;
    if (part.packing.radius_min < 0 || part.packing.radius_max < 0)
      r.fail(where, "packing radii must not be negative");
  }
}

// The part's "repair" options.
void read_repair(const Reader& r, const json& rep, double units, PartSpec& part,
                 const std::string& where) {
  r.keys(rep, {"orient", "alpha_wrap"}, where + " repair");
  if (rep.contains("orient")) {
    if (!rep["orient"].is_boolean()) r.fail(where, "'repair.orient' must be true or false");
    part.orient = rep["orient"].get<bool>();
  }
  if (rep.contains("alpha_wrap")) {
    const json& w = rep["alpha_wrap"];
    r.keys(w, {"alpha", "offset"}, where + " alpha_wrap");
    AlphaWrapSpec spec{r.number(w, "alpha", where) * units, r.number(w, "offset", where) * units};
    if (!(spec.alpha > 0) || !(spec.offset > 0))
      r.fail(where, "alpha_wrap 'alpha' and 'offset' must be positive");
    part.wrap = spec;
  }
}

// One entry of "parts"; `names` collects the names seen so far.
PartSpec read_part(const Reader& r, const json& p, std::size_t index, double units,
                   double mesh_units, const std::string& base_dir, std::set<std::string>& names) {
  const std::string name = p.is_object() && p.contains("name") && p["name"].is_string()
                               ? p["name"].get<std::string>()
                               : std::string();
  const std::string where = name.empty() ? "part " + std::to_string(index) : "part '" + name + "'";
  r.keys(p,
         {"name", "mesh", "meshes", "mesh_units", "topology", "radius", "material", "law", "repair",
          "metric", "optimiser", "axis", "grid", "packing"},
         where);
  if (name.empty()) r.fail(where, "'name' must be a non-empty string");
  if (!names.insert(name).second) r.fail(where, "a part of that name already exists");
  PartSpec part;
  part.name = name;
  std::vector<std::string> meshes;
  if (p.contains("mesh") == p.contains("meshes"))
    r.fail(where, "give exactly one of 'mesh' and 'meshes'");
  // A mesh is a path, or {"file": path, "nodes": [names]} to take some nodes of a glTF file.
  auto mesh_entry = [&](const json& m, const std::string& key) {
    if (m.is_string()) {
      meshes.push_back(m.get<std::string>());
      part.mesh_nodes.emplace_back();
      return;
    }
    if (!m.is_object()) r.fail(where, "'" + key + "' must be a path or {\"file\", \"nodes\"}");
    r.keys(m, {"file", "nodes"}, where + " " + key);
    meshes.push_back(r.string(m, "file", where + " " + key));
    std::vector<std::string> nodes;
    if (m.contains("nodes")) {
      if (!m["nodes"].is_array() || m["nodes"].empty())
        r.fail(where, "'nodes' must be a non-empty list of node names");
      for (const json& n : m["nodes"]) {
        if (!n.is_string() || n.get<std::string>().empty())
          r.fail(where, "'nodes' must be a list of non-empty node names");
        nodes.push_back(n.get<std::string>());
      }
    }
    part.mesh_nodes.push_back(std::move(nodes));
  };
  if (p.contains("mesh")) {
    mesh_entry(p["mesh"], "mesh");
  } else {
    if (!p["meshes"].is_array() || p["meshes"].empty())
      r.fail(where, "'meshes' must be a non-empty list of paths");
    for (const json& m : p["meshes"]) mesh_entry(m, "meshes");
  }
  for (const std::string& m : meshes) {
    const fs::path path = fs::path(m).is_absolute() ? fs::path(m) : fs::path(base_dir) / m;
    std::error_code ec;
    if (!fs::exists(path, ec)) r.fail(where, "mesh file '" + path.string() + "' does not exist");
    if (!fs::is_regular_file(path, ec))
      r.fail(where, "mesh file '" + path.string() + "' is not a regular file");
    const fs::path canonical = fs::weakly_canonical(path, ec);
    part.meshes.push_back(ec ? path.string() : canonical.string());
  }
  part.mesh_scale = r.unit(p, "mesh_units", mesh_units, where);
  const std::string topo = r.string(p, "topology", where);
  if (topo == "tetrahedral")
    part.topology = Topology::tetrahedral;
  else if (topo == "axis")
    part.topology = Topology::axis;
  else if (topo == "grid")
    part.topology = Topology::grid;
  else if (topo == "packing")
    part.topology = Topology::packing;
  else
    r.fail(where, "unknown topology '" + topo + "' (tetrahedral, axis, grid, packing)");
  part.radius = r.number(p, "radius", where) * units;
  if (!(part.radius > 0)) r.fail(where, "'radius' must be positive");
  if (!p.contains("material")) r.fail(where, "missing 'material'");
  part.material = read_material(r, p["material"], where);
  if (p.contains("law")) {
    const std::string law = r.string(p, "law", where);
    if (law == "links")
      part.law = ForceLaw::links;
    else if (law == "continuum")
      part.law = ForceLaw::continuum;
    else
      r.fail(where, "unknown law '" + law + "' (links, continuum)");
    if (part.law == ForceLaw::continuum && part.topology != Topology::tetrahedral)
      r.fail(where, "the continuum law needs a tetrahedral part (it acts on tetrahedra)");
  }
  if (p.contains("repair")) read_repair(r, p["repair"], units, part, where);
  read_topology_options(r, p, units, part, where);
  return part;
}

void read_attachments(const Reader& r, const json& list, double units,
                      const std::set<std::string>& names, Scene& scene) {
  if (!list.is_array()) r.fail("attachments", "must be a list");
  int k = 0;
  for (const json& a : list) {
    const std::string where = "attachment " + std::to_string(k++);
    r.keys(a, {"parts", "tolerance", "stiffness_scale", "tear_strain"}, where);
    if (!a.contains("parts") || !a["parts"].is_array() || a["parts"].size() != 2 ||
        !a["parts"][0].is_string() || !a["parts"][1].is_string())
      r.fail(where, "'parts' must be two part names");
    AttachmentSpec spec;
    spec.a = a["parts"][0].get<std::string>();
    spec.b = a["parts"][1].get<std::string>();
    r.require_part(names, spec.a, where);
    r.require_part(names, spec.b, where);
    if (spec.a == spec.b) r.fail(where, "attaches part '" + spec.a + "' to itself");
    spec.tolerance = r.number(a, "tolerance", where) * units;
    spec.stiffness_scale = r.number_or(a, "stiffness_scale", 1.0, where);
    if (!(spec.tolerance >= 0) || !(spec.stiffness_scale > 0))
      r.fail(where, "'tolerance' must be >= 0 and 'stiffness_scale' > 0");
    spec.tear_strain = r.number_or(a, "tear_strain", spec.tear_strain, where);
    if (!(spec.tear_strain > 0))
      r.fail(where, "'tear_strain' must be positive (leave it out: the parts' materials decide)");
    scene.attachments.push_back(spec);
  }
}

void read_fixed(const Reader& r, const json& list, double units, const std::set<std::string>& names,
                Scene& scene) {
  if (!list.is_array()) r.fail("fixed", "must be a list");
  int k = 0;
  for (const json& f : list) {
    const std::string where = "fixed region " + std::to_string(k++);
    r.keys(f, {"part", "box", "plane", "vertices", "chain_end"}, where);
    FixedSpec spec;
    spec.part = r.string(f, "part", where);
    r.require_part(names, spec.part, where);
    const int kinds = int(f.contains("box")) + int(f.contains("plane")) +
                      int(f.contains("vertices")) + int(f.contains("chain_end"));
    if (kinds != 1) r.fail(where, "give exactly one of 'box', 'plane', 'vertices', 'chain_end'");
    if (f.contains("box")) {
      r.keys(f["box"], {"min", "max"}, where + " box");
      spec.kind = FixedSpec::Kind::box;
      spec.min = r.vec3(f["box"], "min", where) * units;
      spec.max = r.vec3(f["box"], "max", where) * units;
      if ((spec.max.array() < spec.min.array()).any()) r.fail(where, "box 'max' is below 'min'");
    } else if (f.contains("plane")) {
      r.keys(f["plane"], {"point", "normal"}, where + " plane");
      spec.kind = FixedSpec::Kind::plane;
      spec.point = r.vec3(f["plane"], "point", where) * units;
      spec.normal = r.vec3(f["plane"], "normal", where);
      if (!(spec.normal.norm() > 0)) r.fail(where, "plane 'normal' is zero");
      spec.normal.normalize();
    } else if (f.contains("vertices")) {
      spec.kind = FixedSpec::Kind::vertices;
      if (!f["vertices"].is_array() || f["vertices"].empty())
        r.fail(where, "'vertices' must be a non-empty list of indices");
      for (const json& v : f["vertices"]) {
        spec.vertices.push_back(
            Index(r.integer(v, "vertices", where, 0, std::numeric_limits<Index>::max())));
      }
    } else {
      spec.kind = FixedSpec::Kind::chain_end;
      const std::string end = r.string(f, "chain_end", where);
      if (end != "first" && end != "last")
        r.fail(where, "'chain_end' must be \"first\" or \"last\"");
      spec.last = end == "last";
    }
    scene.fixed.push_back(spec);
  }
}

}  // namespace

Scene parse_scene(const std::string& text, const std::string& base_dir, const std::string& file) {
  const Reader r(file);
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {  // a syntax error, or a number out of range (1e999)
    r.fail("", std::string("not valid JSON: ") + e.what());
  }
  r.keys(root,
         {"format", "version", "name", "units", "mesh_units", "parts", "attachments", "fixed",
          "limits"},
         "scene");
  if (!root.contains("format") || root["format"] != "fsm-scene")
    r.fail("scene", "'format' must be \"fsm-scene\"");
  if (!root.contains("version")) r.fail("scene", "missing 'version'");
  if (!root["version"].is_number_integer()) r.fail("scene", "'version' must be an integer");
  // Newer first: a later builder's scene gets the message that says so.
  if (root["version"].is_number_unsigned() &&
      root["version"].get<unsigned long long>() > static_cast<unsigned long long>(kSceneVersion))
    r.fail("scene", "scene version " + std::to_string(root["version"].get<unsigned long long>()) +
                        " is newer than this builder (" + std::to_string(kSceneVersion) + ")");
  r.integer(root["version"], "version", "scene", 1, kSceneVersion);

  Scene scene;
  scene.file = file;
  scene.name = root.contains("name") ? r.string(root, "name", "scene")
                                     : fs::path(file.empty() ? "scene" : file).stem().string();
  const double units = r.unit(root, "units", 1.0, "scene");
  const double mesh_units = r.unit(root, "mesh_units", units, "scene");

  if (!root.contains("parts") || !root["parts"].is_array() || root["parts"].empty())
    r.fail("scene", "'parts' must be a non-empty list");
  std::set<std::string> names;
  for (const json& p : root["parts"])
    scene.parts.push_back(read_part(r, p, scene.parts.size(), units, mesh_units, base_dir, names));
  if (root.contains("attachments")) read_attachments(r, root["attachments"], units, names, scene);
  if (root.contains("fixed")) read_fixed(r, root["fixed"], units, names, scene);
  if (root.contains("limits")) {
    const json& l = root["limits"];
    r.keys(l, {"spheres", "elements", "memory_gb"}, "limits");
    scene.limits.spheres = r.number_or(l, "spheres", scene.limits.spheres, "limits");
    scene.limits.elements = r.number_or(l, "elements", scene.limits.elements, "limits");
    scene.limits.memory_bytes =
        r.number_or(l, "memory_gb", scene.limits.memory_bytes / 1e9, "limits") * 1e9;
    if (!(scene.limits.spheres > 0) || !(scene.limits.elements > 0) ||
        !(scene.limits.memory_bytes > 0))
      r.fail("limits", "'spheres', 'elements' and 'memory_gb' must be positive");
  }
  return scene;
}

Scene load_scene(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(path, "", "cannot open the scene file: it does not exist");
  if (!fs::is_regular_file(path, ec))
    throw Error(path, "", "cannot open the scene file: not a regular file");
  // A scene is a few kilobytes; a file far larger is not one (and is not read into memory).
  constexpr std::uintmax_t k_max_scene_bytes = 16u << 20;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (!ec && size > k_max_scene_bytes)
    throw Error(path, "",
                "the scene file has " + std::to_string(size) + " bytes; a scene is at most 16 MiB");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path, "", "cannot open the scene file");
  std::stringstream text;
  text << in.rdbuf();
  const fs::path p = fs::absolute(path, ec);
  return parse_scene(text.str(), (ec ? fs::path(path) : p).parent_path().string(), path);
}

}  // namespace fsm::build
