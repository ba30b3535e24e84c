#pragma once

// Definitions of SphereModel's members; included at the bottom of fsm/sphere_model.hpp.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <unordered_set>

namespace fsm {

namespace detail {
inline std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}
}  // namespace detail

template <typename Scalar>
Index SphereModel<Scalar>::add_region(std::string name, const Material<Scalar>& material,
                                      ForceLaw law) {
  if (name.empty()) throw Error("", "region " + std::to_string(m_regions.size()), "name is empty");
  for (const auto& r : m_regions)
    if (r.name == name) throw Error("", "region '" + name + "'", "a region of that name exists");
  material.validate("region '" + name + "'");
  if (law != ForceLaw::links && law != ForceLaw::continuum)
    throw Error("", "region '" + name + "'", "unknown force law " + std::to_string(int(law)));
  m_regions.push_back({std::move(name), material, law});
  return static_cast<Index>(m_regions.size() - 1);
}

template <typename Scalar>
void SphereModel<Scalar>::set_region_law(Index region, ForceLaw law) {
  if (region < 0 || region >= num_regions())
    throw Error("", "region " + std::to_string(region), "index out of range");
  if (law != ForceLaw::links && law != ForceLaw::continuum)
    throw Error("", "region '" + m_regions[std::size_t(region)].name + "'",
                "unknown force law " + std::to_string(int(law)));
  m_regions[std::size_t(region)].law = law;
}

template <typename Scalar>
void SphereModel<Scalar>::set_region_material(Index region, const Material<Scalar>& material) {
  if (region < 0 || region >= num_regions())
    throw Error("", "region " + std::to_string(region), "index out of range");
  material.validate("region '" + m_regions[std::size_t(region)].name + "'");
  m_regions[std::size_t(region)].material = material;
}

template <typename Scalar>
Index SphereModel<Scalar>::add_tetrahedron(Index a, Index b, Index c, Index d) {
  const Index t = num_tetrahedra();
  m_tetrahedron.insert(m_tetrahedron.end(), {a, b, c, d});
  try {
    check_tetrahedron(t);
  } catch (...) {
    m_tetrahedron.resize(4 * std::size_t(t));
    throw;
  }
  m_tetrahedron_intact.push_back(1);
  return t;
}

template <typename Scalar>
Index SphereModel<Scalar>::num_broken_links() const noexcept {
  return Index(std::count(m_link_intact.begin(), m_link_intact.end(), std::uint8_t(0)));
}

template <typename Scalar>
Index SphereModel<Scalar>::num_removed_tetrahedra() const noexcept {
  return Index(
      std::count(m_tetrahedron_intact.begin(), m_tetrahedron_intact.end(), std::uint8_t(0)));
}

template <typename Scalar>
void SphereModel<Scalar>::restore_topology() noexcept {
  std::fill(m_link_intact.begin(), m_link_intact.end(), std::uint8_t(1));
  std::fill(m_tetrahedron_intact.begin(), m_tetrahedron_intact.end(), std::uint8_t(1));
}

template <typename Scalar>
bool SphereModel<Scalar>::has_continuum() const noexcept {
  return std::any_of(m_regions.begin(), m_regions.end(),
                     [](const Region<Scalar>& r) { return r.law == ForceLaw::continuum; });
}

template <typename Scalar>
Index SphereModel<Scalar>::add_node(const Vector3<Scalar>& rest_position, Scalar radius,
                                    Scalar mass, Index region) {
  const Index i = num_nodes();
  for (int c = 0; c < 3; ++c) {
    m_position.push_back(rest_position[c]);
    m_rest_position.push_back(rest_position[c]);
    m_velocity.push_back(Scalar(0));
  }
  m_mass.push_back(mass);
  m_radius.push_back(radius);
  m_node_region.push_back(region);
  m_fixed.push_back(0);
  try {
    check_node(i);
  } catch (...) {  // leave the model as it was
    m_position.resize(3 * std::size_t(i));
    m_rest_position.resize(3 * std::size_t(i));
    m_velocity.resize(3 * std::size_t(i));
    m_mass.pop_back();
    m_radius.pop_back();
    m_node_region.pop_back();
    m_fixed.pop_back();
    throw;
  }
  return i;
}

template <typename Scalar>
Index SphereModel<Scalar>::add_link(Index i, Index j, const VoigtLink<Scalar>& law) {
  const Index l = num_links();
  m_link.push_back(i);
  m_link.push_back(j);
  m_rest_length.push_back(law.rest_length);
  m_stiffness.push_back(law.stiffness);
  m_damping.push_back(law.damping);
  m_large_stiffness.push_back(law.large_stiffness);
  m_switch_strain.push_back(law.switch_strain);
  m_tear_strain.push_back(std::numeric_limits<Scalar>::infinity());
  m_link_intact.push_back(1);
  try {
    check_link(l);
  } catch (...) {
    m_link.resize(2 * std::size_t(l));
    m_rest_length.pop_back();
    m_stiffness.pop_back();
    m_damping.pop_back();
    m_large_stiffness.pop_back();
    m_switch_strain.pop_back();
    m_tear_strain.pop_back();
    m_link_intact.pop_back();
    throw;
  }
  return l;
}

template <typename Scalar>
Index SphereModel<Scalar>::add_link(Index i, Index j, Scalar stiffness, Scalar damping) {
  const Index n = num_nodes();
  if (i < 0 || i >= n || j < 0 || j >= n) {
    throw Error("",
                "link " + std::to_string(num_links()) + " (nodes " + std::to_string(i) + "-" +
                    std::to_string(j) + ")",
                "node index out of range [0, " + std::to_string(n) + ")");
  }
  const Scalar l0 = (rest_positions().row(j) - rest_positions().row(i)).norm();
  return add_link(i, j, VoigtLink<Scalar>::linear(l0, stiffness, damping));
}

template <typename Scalar>
void SphereModel<Scalar>::set_fixed(Index node, bool fixed_flag) {
  if (node < 0 || node >= num_nodes())
    throw Error("", "node " + std::to_string(node),
                "index out of range [0, " + std::to_string(num_nodes()) + ")");
  m_fixed[std::size_t(node)] = fixed_flag ? 1 : 0;
  if (fixed_flag) velocities().row(node).setZero();
}

template <typename Scalar>
void SphereModel<Scalar>::reserve(Index nodes, Index links) {
  const auto n = std::size_t(std::max<Index>(nodes, 0));
  const auto l = std::size_t(std::max<Index>(links, 0));
  m_position.reserve(3 * n);
  m_velocity.reserve(3 * n);
  m_rest_position.reserve(3 * n);
  m_mass.reserve(n);
  m_radius.reserve(n);
  m_node_region.reserve(n);
  m_fixed.reserve(n);
  m_link.reserve(2 * l);
  m_rest_length.reserve(l);
  m_stiffness.reserve(l);
  m_damping.reserve(l);
  m_large_stiffness.reserve(l);
  m_switch_strain.reserve(l);
  m_link_intact.reserve(l);
  m_tear_strain.reserve(l);
}

template <typename Scalar>
Index SphereModel<Scalar>::num_fixed() const noexcept {
  return static_cast<Index>(std::count(m_fixed.begin(), m_fixed.end(), std::uint8_t(1)));
}

template <typename Scalar>
VoigtLink<Scalar> SphereModel<Scalar>::link(Index l) const {
  const auto k = std::size_t(l);
  return {m_rest_length.at(k), m_stiffness[k], m_damping[k], m_large_stiffness[k],
          m_switch_strain[k]};
}

template <typename Scalar>
void SphereModel<Scalar>::set_link(Index l, const VoigtLink<Scalar>& law) {
  if (l < 0 || l >= num_links()) throw Error("", "link " + std::to_string(l), "index out of range");
  const VoigtLink<Scalar> old = link(l);
  const auto k = std::size_t(l);
  auto assign = [&](const VoigtLink<Scalar>& v) {
    m_rest_length[k] = v.rest_length;
    m_stiffness[k] = v.stiffness;
    m_damping[k] = v.damping;
    m_large_stiffness[k] = v.large_stiffness;
    m_switch_strain[k] = v.switch_strain;
  };
  assign(law);
  try {
    check_link(l);
  } catch (...) {
    assign(old);
    throw;
  }
}

template <typename Scalar>
bool SphereModel<Scalar>::has_bilinear_links() const noexcept {
  return std::any_of(m_switch_strain.begin(), m_switch_strain.end(),
                     [](Scalar s) { return std::isfinite(s); });
}

template <typename Scalar>
Index SphereModel<Scalar>::region_index(const std::string& name) const {
  std::string names;
  for (std::size_t r = 0; r < m_regions.size(); ++r) {
    if (m_regions[r].name == name) return static_cast<Index>(r);
    names += (r ? ", '" : "'") + m_regions[r].name + "'";
  }
  throw Error("", "region '" + name + "'",
              "no such region; the model has " + (names.empty() ? std::string("none") : names));
}

template <typename Scalar>
void SphereModel<Scalar>::reset_to_rest() noexcept {
  m_position = m_rest_position;
  std::fill(m_velocity.begin(), m_velocity.end(), Scalar(0));
}

template <typename Scalar>
Scalar SphereModel<Scalar>::total_mass() const noexcept {
  return std::accumulate(m_mass.begin(), m_mass.end(), Scalar(0));
}

template <typename Scalar>
void SphereModel<Scalar>::distribute_region_mass(Index region, Scalar volume) {
  if (region < 0 || region >= num_regions())
    throw Error("", "region " + std::to_string(region), "index out of range");
  if (!(std::isfinite(volume) && volume > 0))
    throw Error("", "region '" + m_regions[std::size_t(region)].name + "'",
                "volume " + detail::format_number(double(volume)) + " m^3 must be positive");
  const auto count = std::count(m_node_region.begin(), m_node_region.end(), region);
  if (count == 0)
    throw Error("", "region '" + m_regions[std::size_t(region)].name + "'", "has no nodes");
  const Scalar m = m_regions[std::size_t(region)].material.density * volume / Scalar(count);
  for (std::size_t i = 0; i < m_mass.size(); ++i)
    if (m_node_region[i] == region) m_mass[i] = m;
}

template <typename Scalar>
std::string SphereModel<Scalar>::describe_node(Index i) const {
  const Index r = m_node_region[std::size_t(i)];
  std::string s = "node " + std::to_string(i);
  if (r >= 0 && r < num_regions()) s += " (region '" + m_regions[std::size_t(r)].name + "')";
  return s;
}

template <typename Scalar>
std::string SphereModel<Scalar>::describe_link(Index l) const {
  return "link " + std::to_string(l) + " (nodes " + std::to_string(m_link[2 * std::size_t(l)]) +
         "-" + std::to_string(m_link[2 * std::size_t(l) + 1]) + ")";
}

template <typename Scalar>
void SphereModel<Scalar>::check_node(Index i) const {
  const auto k = std::size_t(i);
  const Index r = m_node_region[k];
  if (r < 0 || r >= num_regions())
    throw Error("", describe_node(i),
                "region index " + std::to_string(r) + " out of range [0, " +
                    std::to_string(num_regions()) + ")");
  auto fail = [&](const std::string& why) { throw Error("", describe_node(i), why); };
  if (!detail::all_finite(&m_rest_position[3 * k], 3)) fail("rest position is not finite");
  if (!detail::all_finite(&m_position[3 * k], 3)) fail("position is not finite");
  if (!detail::all_finite(&m_velocity[3 * k], 3)) fail("velocity is not finite");
  if (!(std::isfinite(m_radius[k]) && m_radius[k] > 0))
    fail("radius " + detail::format_number(double(m_radius[k])) + " m must be positive");
  if (!(std::isfinite(m_mass[k]) && m_mass[k] > 0))
    fail("mass " + detail::format_number(double(m_mass[k])) + " kg must be positive");
}

template <typename Scalar>
void SphereModel<Scalar>::check_tetrahedron(Index t) const {
  const auto k = 4 * std::size_t(t);
  const Index n = num_nodes();
  const Index* v = &m_tetrahedron[k];
  auto fail = [&](const std::string& why) {
    throw Error("",
                "tetrahedron " + std::to_string(t) + " (nodes " + std::to_string(v[0]) + " " +
                    std::to_string(v[1]) + " " + std::to_string(v[2]) + " " + std::to_string(v[3]) +
                    ")",
                why);
  };
  for (int a = 0; a < 4; ++a) {
    if (v[a] < 0 || v[a] >= n) fail("node index out of range [0, " + std::to_string(n) + ")");
    for (int b = 0; b < a; ++b)
      if (v[a] == v[b]) fail("repeats a node");
  }
  const Index r = m_node_region[std::size_t(v[0])];
  for (int a = 1; a < 4; ++a)
    if (m_node_region[std::size_t(v[a])] != r) fail("its nodes belong to different regions");
  const auto x = rest_positions();
  const Vector3<Scalar> o = x.row(v[0]).transpose();
  const Vector3<Scalar> e1 = x.row(v[1]).transpose() - o, e2 = x.row(v[2]).transpose() - o,
                        e3 = x.row(v[3]).transpose() - o;
  const Scalar six_v = e1.dot(e2.cross(e3));
  const Scalar edge = std::max({e1.norm(), e2.norm(), e3.norm()});
  // |V| at least 1e-12 of the longest edge cubed, as TetrahedralMesh::validate.
  if (!(six_v > Scalar(6e-12) * edge * edge * edge))
    fail("is inverted or degenerate at rest (6V = " + detail::format_number(double(six_v)) +
         " m^3)");
}

template <typename Scalar>
void SphereModel<Scalar>::check_link(Index l) const {
  const auto k = std::size_t(l);
  const Index i = m_link[2 * k], j = m_link[2 * k + 1];
  auto fail = [&](const std::string& why) { throw Error("", describe_link(l), why); };
  const Index n = num_nodes();
  if (i < 0 || i >= n || j < 0 || j >= n)
    fail("node index out of range [0, " + std::to_string(n) + ")");
  if (i == j) fail("links a node to itself");
  auto num = [](Scalar v) { return detail::format_number(double(v)); };
  if (!(std::isfinite(m_rest_length[k]) && m_rest_length[k] > 0))
    fail("rest length " + num(m_rest_length[k]) + " m must be positive");
  if (!(std::isfinite(m_stiffness[k]) && m_stiffness[k] > 0))
    fail("stiffness " + num(m_stiffness[k]) + " N/m must be positive");
  if (!(std::isfinite(m_damping[k]) && m_damping[k] >= 0))
    fail("damping " + num(m_damping[k]) + " N s/m must be non-negative");
  if (!(std::isfinite(m_large_stiffness[k]) && m_large_stiffness[k] > 0))
    fail("large-strain stiffness " + num(m_large_stiffness[k]) + " N/m must be positive");
  if (std::isnan(m_switch_strain[k]) || !(m_switch_strain[k] > 0))
    fail("switch strain " + num(m_switch_strain[k]) + " must be positive (infinity = linear)");
  if (!(m_tear_strain[k] > 0))
    fail("tear strain " + num(m_tear_strain[k]) + " must be positive (infinity = never tears)");
  if (m_link_intact[k] > 1) fail("intact flag must be 0 or 1");
}

template <typename Scalar>
void SphereModel<Scalar>::validate() const {
  for (std::size_t r = 0; r < m_regions.size(); ++r) {
    if (m_regions[r].name.empty()) throw Error("", "region " + std::to_string(r), "name is empty");
    m_regions[r].material.validate("region '" + m_regions[r].name + "'");
  }
  for (Index i = 0; i < num_nodes(); ++i) {
    check_node(i);
    if (m_fixed[std::size_t(i)] > 1) throw Error("", describe_node(i), "fixed flag must be 0 or 1");
  }
  std::unordered_set<std::uint64_t> seen;
  seen.reserve(m_rest_length.size());
  for (Index l = 0; l < num_links(); ++l) {
    check_link(l);
    auto a = std::uint64_t(std::uint32_t(m_link[2 * std::size_t(l)]));
    auto b = std::uint64_t(std::uint32_t(m_link[2 * std::size_t(l) + 1]));
    if (a > b) std::swap(a, b);
    if (!seen.insert((a << 32) | b).second)
      throw Error("", describe_link(l), "duplicates an earlier link between the same nodes");
  }
  // Tetrahedra: each checked; a region with the continuum law needs every node in one (a node
  // in no element would carry no force).
  std::vector<std::uint8_t> in_element(m_mass.size(), 0);
  for (Index t = 0; t < num_tetrahedra(); ++t) {
    check_tetrahedron(t);
    for (int k = 0; k < 4; ++k) in_element[std::size_t(m_tetrahedron[4 * std::size_t(t) + k])] = 1;
  }
  for (Index i = 0; i < num_nodes(); ++i) {
    const Region<Scalar>& r = m_regions[std::size_t(m_node_region[std::size_t(i)])];
    if (r.law == ForceLaw::continuum && !in_element[std::size_t(i)])
      throw Error("", describe_node(i),
                  "is in no tetrahedron, but region '" + r.name +
                      "' uses the continuum law (which acts on tetrahedra)");
  }
}

template <typename Scalar>
template <typename Other>
SphereModel<Other> SphereModel<Scalar>::cast() const {
  SphereModel<Other> out;
  for (const auto& r : m_regions) {
    const auto& m = r.material;
    out.m_regions.push_back(
        {r.name,
         Material<Other>{Other(m.density), Other(m.youngs_modulus), Other(m.viscosity),
                         Other(m.large_strain_modulus), Other(m.switch_strain),
                         Other(m.poisson_ratio), Other(m.tear_strain)},
         r.law});
  }
  auto conv = [](const std::vector<Scalar>& v) { return std::vector<Other>(v.begin(), v.end()); };
  out.m_position = conv(m_position);
  out.m_velocity = conv(m_velocity);
  out.m_rest_position = conv(m_rest_position);
  out.m_mass = conv(m_mass);
  out.m_radius = conv(m_radius);
  out.m_node_region = m_node_region;
  out.m_fixed = m_fixed;
  out.m_link = m_link;
  out.m_rest_length = conv(m_rest_length);
  out.m_stiffness = conv(m_stiffness);
  out.m_damping = conv(m_damping);
  out.m_large_stiffness = conv(m_large_stiffness);
  out.m_switch_strain = conv(m_switch_strain);
  out.m_tetrahedron = m_tetrahedron;
  out.m_link_intact = m_link_intact;
  out.m_tear_strain = conv(m_tear_strain);
  out.m_tetrahedron_intact = m_tetrahedron_intact;
  return out;
}

}  // namespace fsm
