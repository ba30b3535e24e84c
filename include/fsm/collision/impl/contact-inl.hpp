#pragma once

// Definitions of ContactSolver; included at the bottom of fsm/collision/contact.hpp.

#include <algorithm>
#include <cmath>
#include <limits>

#include "fsm/error.hpp"

namespace fsm::collision {

template <typename Scalar>
ContactSolver<Scalar>::ContactSolver(const SphereModel<Scalar>& model,
                                     const ContactOptions<Scalar>& options)
    : m_options(options) {
  const auto& o = m_options;
  if (!(o.stiffness_ratio > 0) || !std::isfinite(o.stiffness_ratio) ||
      !(o.part_stiffness_ratio > 0) || !std::isfinite(o.part_stiffness_ratio) ||
      !(o.damping_ratio >= 0) || !std::isfinite(o.damping_ratio) || !(o.friction_speed > 0) ||
      !(o.part_friction >= 0) || !(o.part_contact_onset >= 0) || !(o.part_contact_onset < 1) ||
      o.max_contacts < 1 || !(o.verlet_skin >= 0) || !std::isfinite(o.verlet_skin) ||
      !(o.face_sample_spacing > 0) || !std::isfinite(o.face_sample_spacing) ||
      !(o.detection_margin >= 0) || !std::isfinite(o.detection_margin))
    throw Error("", "contact options",
                "stiffness_ratio, part_stiffness_ratio, face_sample_spacing and friction_speed "
                "must be positive, "
                "damping_ratio and "
                "part_friction non-negative, part_contact_onset in [0, 1), verlet_skin and "
                "detection_margin finite and non-negative, max_contacts at least 1");
  refresh(model);
}

template <typename Scalar>
void ContactSolver<Scalar>::refresh(const SphereModel<Scalar>& model) {
  model.validate();
  const Index n = model.num_nodes();
  m_max_radius = n > 0 ? model.radii().maxCoeff() : Scalar(0);
  m_cell = std::max(Scalar(2) * m_max_radius, Scalar(1e-6));
  std::uint32_t size = 64;
  while (size < 2u * std::uint32_t(std::max<Index>(n, 1))) size <<= 1;
  m_mask = size - 1;
  m_head.assign(size, -1);
  m_next.assign(std::size_t(n), -1);
  m_prev.assign(std::size_t(n), -1);
  m_cell_of.assign(std::size_t(n), Eigen::Vector3i::Zero());
  m_slot_of.assign(std::size_t(n), 0);
  m_hashed = false;
  // Link adjacency, to leave linked pairs (which are held by their links) out of part contact.
  m_adj_start.assign(std::size_t(n) + 1, 0);
  const auto links = model.links();
  for (Index l = 0; l < model.num_links(); ++l) {
    ++m_adj_start[std::size_t(links(l, 0)) + 1];
    ++m_adj_start[std::size_t(links(l, 1)) + 1];
  }
  for (std::size_t i = 0; i < std::size_t(n); ++i) m_adj_start[i + 1] += m_adj_start[i];
  m_adj.assign(std::size_t(m_adj_start.back()), 0);
  std::vector<Index> fill(m_adj_start.begin(), m_adj_start.end() - 1);
  for (Index l = 0; l < model.num_links(); ++l) {
    m_adj[std::size_t(fill[std::size_t(links(l, 0))]++)] = links(l, 1);
    m_adj[std::size_t(fill[std::size_t(links(l, 1))]++)] = links(l, 0);
  }
  // Contact stiffness: stiffness_ratio times the sphere's own tissue stiffness (links and
  // elements, as the force model sees them); a sphere with none (a loose one) gets its weight in
  // a 1 ms step's terms, m / (1 ms)^2.
  const std::vector<Scalar> tissue = ForceModel<Scalar>(model).node_stiffness(model);
  m_k.resize(std::size_t(n));
  m_contact_radius.resize(std::size_t(n));
  std::vector<std::uint8_t> in_element(std::size_t(n), 0);
  for (Index t = 0; t < model.num_tetrahedra(); ++t)
    for (int c = 0; c < 4; ++c) in_element[std::size_t(model.tetrahedra()(t, c))] = 1;
  std::vector<Index> count(std::size_t(model.num_regions()), 0);
  for (Index i = 0; i < n; ++i) {
    const Scalar k = tissue[std::size_t(i)] > Scalar(0) ? tissue[std::size_t(i)]
                                                        : model.masses()[i] / Scalar(1e-6);
    m_k[std::size_t(i)] = m_options.stiffness_ratio * k;
    m_contact_radius[std::size_t(i)] =
        m_options.tetrahedral_surface && in_element[std::size_t(i)] ? Scalar(0) : model.radii()[i];
    ++count[std::size_t(model.node_regions()[i])];
  }
  m_dominant_region =
      count.empty() ? -1 : Index(std::max_element(count.begin(), count.end()) - count.begin());
  build_faces(model);
  m_contacts.assign(std::size_t(m_options.max_contacts), Contact<Scalar>{});
  m_pairs.clear();
  m_pairs.reserve(32 * std::size_t(std::max<Index>(n, 1)));
  m_list_x.resize(n, 3);
  m_list_valid = false;
  // Per-region bounds of the list's validity (list_holds), for models with few regions.
  const Index R = model.num_regions();
  m_region_move.assign(R <= k_max_list_regions ? std::size_t(R) : 0, Scalar(0));
  m_region_threshold.assign(m_region_move.size() * m_region_move.size(), Scalar(0));
  m_region_box.assign(2 * m_region_move.size(), Vector3<Scalar>::Zero());
  m_region_radius.assign(m_region_move.size(), Scalar(0));
  for (Index i = 0; i < n && !m_region_radius.empty(); ++i) {
    Scalar& r = m_region_radius[std::size_t(model.node_regions()[i])];
    r = std::max(r, model.radii()[i]);
  }
  m_num_contacts = 0;
  m_wrenches.assign(m_instruments.size(), Wrench<Scalar>{});
}

template <typename Scalar>
void ContactSolver<Scalar>::build_faces(const SphereModel<Scalar>& model) {
  const Index n = model.num_nodes();
  m_faces.clear();
  m_face_tet.clear();
  m_face_div.clear();
  m_on_faces.assign(std::size_t(n), 0);
  m_kappa.assign(std::size_t(n), Scalar(0));
  m_node_face_start.assign(std::size_t(n) + 1, 0);
  m_node_faces.clear();
  m_face_acc.assign(11 * std::size_t(n), Scalar(0));
  m_touched.clear();
  m_touched.reserve(std::size_t(n));
  m_max_face_edge = Scalar(0);
  m_face_stamp.clear();
  m_stamp = 0;
  if (!m_options.tetrahedral_surface || !m_options.face_contact) return;
  // A face of exactly one intact tetrahedron is on the boundary.
  struct Key {
    std::array<Index, 3> sorted, face;
    Index tet;
  };
  static constexpr int k_face[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  const auto tets = model.tetrahedra();
  const auto intact = model.tetrahedron_intact();
  std::vector<Key> keys;
  keys.reserve(4 * std::size_t(model.num_tetrahedra()));
  for (Index t = 0; t < model.num_tetrahedra(); ++t) {
    if (!intact[t]) continue;
    for (const auto& f : k_face) {
      Key key{{}, {tets(t, f[0]), tets(t, f[1]), tets(t, f[2])}, t};
      key.sorted = key.face;
      std::sort(key.sorted.begin(), key.sorted.end());
      keys.push_back(key);
    }
  }
  std::sort(keys.begin(), keys.end(),
            [](const Key& a, const Key& b) { return a.sorted < b.sorted; });
  const auto rest = model.rest_positions();
  std::vector<Scalar> area(std::size_t(n), Scalar(0));
  for (std::size_t a = 0; a < keys.size();) {
    std::size_t b = a + 1;
    while (b < keys.size() && keys[b].sorted == keys[a].sorted) ++b;
    if (b == a + 1) {
      const auto& f = keys[a].face;
      const Vector3<Scalar> p0 = rest.row(f[0]).transpose(), p1 = rest.row(f[1]).transpose(),
                            p2 = rest.row(f[2]).transpose();
      const Scalar edge = std::max({(p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()});
      const Scalar A = Scalar(0.5) * (p1 - p0).cross(p2 - p0).norm();
      if (A > Scalar(0) && std::isfinite(A)) {
        m_faces.push_back(f);
        m_face_tet.push_back(keys[a].tet);
        const Scalar div = std::ceil(edge / m_options.face_sample_spacing);
        m_face_div.push_back(std::uint8_t(std::clamp(div, Scalar(1), Scalar(8))));
        m_max_face_edge = std::max(m_max_face_edge, edge);
        for (const Index v : f) {
          area[std::size_t(v)] += A / Scalar(3);
          ++m_node_face_start[std::size_t(v) + 1];
        }
      }
    }
    a = b;
  }
  for (std::size_t i = 0; i < std::size_t(n); ++i) m_node_face_start[i + 1] += m_node_face_start[i];
  m_node_faces.assign(std::size_t(m_node_face_start.back()), 0);
  std::vector<Index> fill(m_node_face_start.begin(), m_node_face_start.end() - 1);
  for (std::size_t f = 0; f < m_faces.size(); ++f)
    for (const Index v : m_faces[f]) m_node_faces[std::size_t(fill[std::size_t(v)]++)] = Index(f);
  for (Index i = 0; i < n; ++i) {
    if (!(area[std::size_t(i)] > Scalar(0))) continue;
    m_on_faces[std::size_t(i)] = 1;
    m_kappa[std::size_t(i)] = m_k[std::size_t(i)] / area[std::size_t(i)];
  }
  m_face_stamp.assign(m_faces.size(), 0);
}

template <typename Scalar>
void ContactSolver<Scalar>::sample_face(const SphereModel<Scalar>& model,
                                        const Instrument<Scalar>& ins, Index f,
                                        const Vector3<Scalar>& lo,
                                        const Vector3<Scalar>& hi) noexcept {
  if (!model.tetrahedron_intact()[m_face_tet[std::size_t(f)]]) return;  // cut away since
  const auto& v = m_faces[std::size_t(f)];
  const auto x = model.positions();
  const Vector3<Scalar> p0 = x.row(v[0]).transpose(), p1 = x.row(v[1]).transpose(),
                        p2 = x.row(v[2]).transpose();
  const Vector3<Scalar> fmin = p0.cwiseMin(p1).cwiseMin(p2), fmax = p0.cwiseMax(p1).cwiseMax(p2);
  if ((fmax.array() < lo.array()).any() || (fmin.array() > hi.array()).any()) return;
  {  // the face's bounding sphere must meet the instrument before its samples are tested
    const Vector3<Scalar> c = (p0 + p1 + p2) / Scalar(3);
    const Scalar r = std::sqrt(
        std::max({(p0 - c).squaredNorm(), (p1 - c).squaredNorm(), (p2 - c).squaredNorm()}));
    ++m_narrow_tests;
    if (!contact(ins.shape, ins.pose, c, r)) return;
  }
  const int m = m_face_div[std::size_t(f)];
  const Scalar share = Scalar(0.5) * (p1 - p0).cross(p2 - p0).norm() / Scalar(m * m);
  const Scalar kappa[3] = {m_kappa[std::size_t(v[0])], m_kappa[std::size_t(v[1])],
                           m_kappa[std::size_t(v[2])]};
  auto sample = [&](Scalar u, Scalar w) {  // barycentric (1 - u - w, u, w)
    const Scalar b[3] = {Scalar(1) - u - w, u, w};
    const Vector3<Scalar> q = b[0] * p0 + b[1] * p1 + b[2] * p2;
    ++m_narrow_tests;
    const auto hit = contact(ins.shape, ins.pose, q, Scalar(0));
    if (!hit || !(hit->depth > Scalar(0)) || !hit->normal.allFinite() || !hit->point.allFinite())
      return;
    const Scalar kq = share * (b[0] * kappa[0] + b[1] * kappa[1] + b[2] * kappa[2]);
    const Vector3<Scalar> vs =
        ins.linear_velocity + ins.angular_velocity.cross(hit->point - ins.pose.position);
    for (int c = 0; c < 3; ++c) {
      const Scalar k = b[c] * kq;
      if (!(k > Scalar(0))) continue;
      Scalar* a = m_face_acc.data() + 11 * std::ptrdiff_t(v[std::size_t(c)]);
      if (a[0] == Scalar(0)) m_touched.push_back(v[std::size_t(c)]);
      const Scalar kd = k * hit->depth;
      a[0] += k;
      for (int d = 0; d < 3; ++d) {
        a[1 + d] += kd * hit->normal[d];
        a[5 + d] += kd * hit->point[d];
        a[8 + d] += kd * vs[d];
      }
      a[4] += kd;
    }
  };
  // The centroids of the m x m split: upright sub-triangles, then the inverted ones.
  const Scalar h = Scalar(1) / Scalar(m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; i + j < m; ++j)
      sample((Scalar(i) + Scalar(1) / 3) * h, (Scalar(j) + Scalar(1) / 3) * h);
  for (int i = 0; i + 1 < m; ++i)
    for (int j = 0; i + j + 1 < m; ++j)
      sample((Scalar(i) + Scalar(2) / 3) * h, (Scalar(j) + Scalar(2) / 3) * h);
}

template <typename Scalar>
Index ContactSolver<Scalar>::add_instrument(const Instrument<Scalar>& instrument) {
  const std::string what = "instrument '" + instrument.name + "'";
  validate(instrument.shape, what);
  if (!instrument.pose.position.allFinite() || !instrument.pose.orientation.coeffs().allFinite())
    throw Error("", what, "pose is not finite");
  if (!(instrument.friction >= 0)) throw Error("", what, "friction must be non-negative");
  m_instruments.push_back(instrument);
  m_instruments.back().pose.orientation.normalize();
  m_wrenches.emplace_back();
  return Index(m_instruments.size() - 1);
}

namespace detail {
/// floor(a) for a in [-2^28, 2^28], without a call into libm (the baseline x86-64 build has no
/// rounding instruction): truncate, then step down for a negative non-integer.
inline int floor_to_int(double a) noexcept {
  const int t = static_cast<int>(a);
  return t - (a < double(t) ? 1 : 0);
}

/// The hash cell of a point: floor(p / cell), clamped to +-2^28 so that converting to int (and
/// differences of cells) stays defined for any coordinate (a NaN gives the lowest cell).
template <typename Derived, typename Scalar>
Eigen::Vector3i hash_cell(const Eigen::MatrixBase<Derived>& p, Scalar inverse_cell) noexcept {
  constexpr double k_limit = double(1 << 28);
  auto cell = [](double a) {
    return floor_to_int(a > -k_limit ? (a < k_limit ? a : k_limit) : -k_limit);
  };
  const double inv = double(inverse_cell);
  return Eigen::Vector3i(cell(double(p(0)) * inv), cell(double(p(1)) * inv),
                         cell(double(p(2)) * inv));
}
}  // namespace detail

template <typename Scalar>
std::uint32_t ContactSolver<Scalar>::slot(const Eigen::Vector3i& c) const noexcept {
  const std::uint32_t h = std::uint32_t(c.x()) * 73856093u ^ std::uint32_t(c.y()) * 19349663u ^
                          std::uint32_t(c.z()) * 83492791u;
  return h & m_mask;
}

template <typename Scalar>
void ContactSolver<Scalar>::update_hash(const SphereModel<Scalar>& model) noexcept {
  const Scalar* x = model.positions().data();
  const Scalar inv = Scalar(1) / m_cell;
  for (Index i = 0; i < model.num_nodes(); ++i) {
    const Eigen::Map<const Vector3<Scalar>> p(x + 3 * std::ptrdiff_t(i));
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])))
      continue;  // keep the old cell; such a state is never stepped
    const Eigen::Vector3i c = detail::hash_cell(p, inv);
    const std::size_t k = std::size_t(i);
    if (m_hashed && c == m_cell_of[k]) continue;
    if (m_hashed) {  // unlink from the old slot
      if (m_prev[k] >= 0)
        m_next[std::size_t(m_prev[k])] = m_next[k];
      else
        m_head[m_slot_of[k]] = m_next[k];
      if (m_next[k] >= 0) m_prev[std::size_t(m_next[k])] = m_prev[k];
    }
    const std::uint32_t s = slot(c);
    m_cell_of[k] = c;
    m_slot_of[k] = s;
    m_prev[k] = -1;
    m_next[k] = m_head[s];
    if (m_head[s] >= 0) m_prev[std::size_t(m_head[s])] = i;
    m_head[s] = i;
  }
  m_hashed = true;
}

template <typename Scalar>
template <typename Visit>
void ContactSolver<Scalar>::for_each_in_box(const Vector3<Scalar>& lo, const Vector3<Scalar>& hi,
                                            Visit&& visit) const {
  if (!lo.allFinite() || !hi.allFinite()) return;
  const Scalar inv = Scalar(1) / m_cell;
  const Eigen::Vector3i a = detail::hash_cell(lo.transpose(), inv);
  const Eigen::Vector3i b = detail::hash_cell(hi.transpose(), inv);
  const double cells =
      double(b.x() - a.x() + 1) * double(b.y() - a.y() + 1) * double(b.z() - a.z() + 1);
  if (!m_options.spatial_hash) {  // brute force: every sphere
    for (Index j = 0; j < Index(m_next.size()); ++j) visit(j);
    return;
  }
  if (cells > double(m_next.size())) {  // a box larger than the model: scan every sphere once
    for (Index j = 0; j < Index(m_next.size()); ++j) {
      const Eigen::Vector3i& c = m_cell_of[std::size_t(j)];
      if ((c.array() >= a.array()).all() && (c.array() <= b.array()).all()) visit(j);
    }
    return;
  }
  for (int z = a.z(); z <= b.z(); ++z)
    for (int y = a.y(); y <= b.y(); ++y)
      for (int x = a.x(); x <= b.x(); ++x) {
        const Eigen::Vector3i c(x, y, z);
        for (Index j = m_head[slot(c)]; j >= 0; j = m_next[std::size_t(j)])
          if (m_cell_of[std::size_t(j)] == c) visit(j);
      }
}

template <typename Scalar>
bool ContactSolver<Scalar>::linked(Index i, Index j) const noexcept {
  for (Index k = m_adj_start[std::size_t(i)]; k < m_adj_start[std::size_t(i) + 1]; ++k)
    if (m_adj[std::size_t(k)] == j) return true;
  return false;
}

template <typename Scalar>
void ContactSolver<Scalar>::record(const Contact<Scalar>& c) noexcept {
  if (m_num_contacts < Index(m_contacts.size()))
    m_contacts[std::size_t(m_num_contacts++)] = c;
  else
    m_overflow = true;
}

template <typename Scalar>
void ContactSolver<Scalar>::record_and_add(const PenaltyContact<Scalar>& c) noexcept {
  // A near contact (ContactOptions::detection_margin) that does not push is not a contact yet.
  if (!(c.depth > Scalar(0)) && c.force.squaredNorm() == Scalar(0)) return;
  record({c.node, c.instrument, c.other, c.normal, c.depth, c.point, c.force});
  if (c.instrument >= 0) {
    Wrench<Scalar>& w = m_wrenches[std::size_t(c.instrument)];
    w.force -= c.force;
    w.torque -= (c.point - m_instruments[std::size_t(c.instrument)].pose.position).cross(c.force);
    if (c.force.dot(c.normal) > Scalar(0)) {  // pushing: its normal stiffness and damping count
      const Matrix3<Scalar> nn = c.normal * c.normal.transpose();
      const Scalar slope = fsm::detail::contact_slope(c, c.depth);
      w.stiffness += slope * c.stiffness * nn;
      w.damping += slope * c.damping * nn;
    }
  }
}

template <typename Scalar>
bool ContactSolver<Scalar>::compute(const SphereModel<Scalar>& model,
                                    ForceModel<Scalar>& forces) noexcept {
  forces.clear_contacts();
  m_num_contacts = 0;
  m_overflow = false;
  m_candidates = m_narrow_tests = 0;
  for (auto& w : m_wrenches) w = Wrench<Scalar>{};
  if (num_nodes() != model.num_nodes()) return false;
  detect(model, [&](const PenaltyContact<Scalar>& c) {
    if (!forces.add_contact(c)) {
      m_overflow = true;  // beyond the force model's capacity: not integrated, not recorded
      return;
    }
    record_and_add(c);
  });
  m_filled = &forces;
  return true;
}

template <typename Scalar>
bool ContactSolver<Scalar>::collect(const ForceModel<Scalar>& forces) noexcept {
  if (m_filled != &forces) return false;
  m_num_contacts = 0;
  for (auto& w : m_wrenches) w = Wrench<Scalar>{};
  const PenaltyContact<Scalar>* c = forces.contacts();
  for (Index k = 0; k < forces.num_contacts(); ++k) record_and_add(c[k]);
  return true;
}

template <typename Scalar>
bool ContactSolver<Scalar>::compute(const SphereModel<Scalar>& model,
                                    Eigen::Ref<Positions<Scalar>> forces) noexcept {
  m_num_contacts = 0;
  m_overflow = false;
  m_candidates = m_narrow_tests = 0;
  m_filled = nullptr;
  for (auto& w : m_wrenches) w = Wrench<Scalar>{};
  if (num_nodes() != model.num_nodes() || forces.rows() != model.num_nodes()) return false;
  detect(model, [&](const PenaltyContact<Scalar>& c) {
    forces.row(c.node) += c.force.transpose();
    if (c.other >= 0) forces.row(c.other) -= c.force.transpose();
    record_and_add(c);
  });
  return true;
}

template <typename Scalar>
template <typename Emit>
void ContactSolver<Scalar>::detect(const SphereModel<Scalar>& model, Emit&& emit) noexcept {
  update_hash(model);
  const auto x = model.positions();
  const auto v = model.velocities();
  const auto mass = model.masses();
  const auto radii = model.radii();
  const Scalar zeta = m_options.damping_ratio;
  const Scalar* xp = x.data();
  const Scalar* vp = v.data();

  // Instruments against spheres (and the boundary faces of tetrahedral parts: a face that meets
  // the instrument has a vertex within its longest edge of the instrument's box).
  const bool faces = !m_faces.empty();
  for (std::size_t k = 0; k < m_instruments.size(); ++k) {
    const Instrument<Scalar>& ins = m_instruments[k];
    if (!ins.enabled) continue;
    const auto box = bounding_box(ins.shape, ins.pose);  // (not a structured binding: captured)
    const Vector3<Scalar> box_lo = box.first, box_hi = box.second;
    // Spheres reach the box by their radius plus their detection margin; faces by two edges.
    const Scalar reach = (Scalar(1) + m_options.detection_margin) * m_max_radius;
    const Scalar margin = std::max(reach, faces ? Scalar(2) * m_max_face_edge : Scalar(0));
    const Vector3<Scalar> lo = box_lo.array() - margin, hi = box_hi.array() + margin;
    if (faces && ++m_stamp == 0) {  // the stamps wrapped: start again
      std::fill(m_face_stamp.begin(), m_face_stamp.end(), 0u);
      m_stamp = 1;
    }
    for_each_in_box(lo, hi, [&](Index j) {
      ++m_candidates;
      if (faces && m_on_faces[std::size_t(j)]) {
        for (Index q = m_node_face_start[std::size_t(j)]; q < m_node_face_start[std::size_t(j) + 1];
             ++q) {
          const Index f = m_node_faces[std::size_t(q)];
          if (m_face_stamp[std::size_t(f)] == m_stamp) continue;
          m_face_stamp[std::size_t(f)] = m_stamp;
          sample_face(model, ins, f, box_lo, box_hi);
        }
        return;
      }
      if (faces && ((x.row(j).transpose() - box_lo).minCoeff() < -reach ||
                    (box_hi - x.row(j).transpose()).minCoeff() < -reach))
        return;  // only in the margin the faces need
      ++m_narrow_tests;
      const Vector3<Scalar> c = x.row(j).transpose();
      // Within the detection margin outside the instrument: a near contact (depth <= 0, no
      // force until the step carries the sphere in; ContactOptions::detection_margin).
      const Scalar near_margin = m_options.detection_margin * radii[j];
      const auto hit =
          contact(ins.shape, ins.pose, c, m_contact_radius[std::size_t(j)] + near_margin);
      if (!hit) return;
      PenaltyContact<Scalar> pc;
      pc.node = j;
      pc.instrument = Index(k);
      pc.normal = hit->normal;
      pc.point = hit->point;
      pc.depth = hit->depth - near_margin;
      pc.stiffness = m_k[std::size_t(j)];
      pc.damping = Scalar(2) * zeta * std::sqrt(pc.stiffness * mass[j]);
      pc.friction = ins.friction;
      pc.friction_speed = m_options.friction_speed;
      pc.surface_velocity =
          ins.linear_velocity + ins.angular_velocity.cross(hit->point - ins.pose.position);
      pc.node_start = c;
      // With face contact on, a node of a tetrahedral part's elements that is not a face vertex
      // (an interior node the tissue has folded onto the tool, as under a sharp rim; or one a cut
      // exposed since the faces were built) stays in the solve like the face contacts around
      // it: when it could leave between passes, the last pass often threw it out of the tissue
      // (docs/physics.md section 8). (Contact radius 0: a node of an element, with faces on.)
      pc.stays_in_solve = faces && m_contact_radius[std::size_t(j)] == Scalar(0);
      Scalar fn;
      Vector3<Scalar> slip;
      pc.force = fsm::detail::contact_force(pc, xp, vp, Scalar(0), fn, slip);
      if (!pc.normal.allFinite() || !pc.point.allFinite()) return;
      emit(pc);
    });
    // Each face vertex the instrument's samples reached: one contact, the sum of their laws
    // (stiffness sum k, force sum k delta n; its depth and normal are those of that force).
    for (const Index j : m_touched) {
      Scalar* a = m_face_acc.data() + 11 * std::ptrdiff_t(j);
      const Vector3<Scalar> F(a[1], a[2], a[3]);
      const Scalar Fn = F.norm();
      if (Fn > Scalar(0) && a[0] > Scalar(0) && a[4] > Scalar(0)) {
        PenaltyContact<Scalar> pc;
        pc.node = j;
        pc.instrument = Index(k);
        pc.normal = F / Fn;
        pc.depth = Fn / a[0];
        pc.point = Vector3<Scalar>(a[5], a[6], a[7]) / a[4];
        pc.stiffness = a[0];
        pc.damping = Scalar(2) * zeta * std::sqrt(pc.stiffness * mass[j]);
        pc.friction = ins.friction;
        pc.friction_speed = m_options.friction_speed;
        pc.surface_velocity = Vector3<Scalar>(a[8], a[9], a[10]) / a[4];
        pc.node_start = x.row(j).transpose();
        pc.stays_in_solve = true;
        Scalar fn;
        Vector3<Scalar> slip;
        pc.force = fsm::detail::contact_force(pc, xp, vp, Scalar(0), fn, slip);
        if (pc.normal.allFinite() && pc.point.allFinite() && std::isfinite(pc.depth)) emit(pc);
      }
      std::fill(a, a + 11, Scalar(0));
    }
    m_touched.clear();
  }

  // Parts against parts (and folding within a part, when asked).
  if (!m_options.part_contact && !m_options.self_contact) return;
  const Scalar skin = m_options.verlet_skin;
  // A pair's distance test, and its contact when its spheres are closer than its threshold.
  auto test = [&](const PartPair& p) {
    const Scalar* a = xp + 3 * std::ptrdiff_t(p.i);
    const Scalar* b = xp + 3 * std::ptrdiff_t(p.j);
    const Vector3<Scalar> d(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
    const Scalar dist2 = d.squaredNorm();
    if (dist2 < p.threshold * p.threshold) part_contact(model, p, d, dist2, emit);
  };
  bool rebuild = !m_list_valid || !(skin > 0) || !list_holds(model);
  if (rebuild) {
    m_pairs.clear();
    bool fits = true;
    for_each_part_pair(model, skin, [&](Index i, Index j) {
      if (m_pairs.size() < m_pairs.capacity())
        m_pairs.push_back({i, j, pair_threshold(model, i, j)});
      else
        fits = false;
    });
    m_list_x = x;
    m_list_valid = fits && skin > 0;  // a list that did not fit is not kept: scan again next step
    if (m_list_valid) set_region_thresholds(model);
    ++m_rebuilds;
    if (!fits) {  // rare: more candidate pairs than reserved; handle this step by scanning
      for_each_part_pair(model, Scalar(0), [&](Index i, Index j) {
        ++m_candidates;
        test({i, j, pair_threshold(model, i, j)});
      });
      return;
    }
  }
  m_candidates += Index(m_pairs.size());
  for (const PartPair& p : m_pairs) test(p);
}

// Whether part contact can pair regions a and b (a == b: within one region, self contact).
template <typename Scalar>
bool ContactSolver<Scalar>::region_pairs(Index a, Index b) const noexcept {
  return a == b ? m_options.self_contact : m_options.part_contact;
}

// At a list's build: for each pair of regions, how far their spheres may move between them
// (the larger of the skin and the gap between the regions' boxes less their largest radii)
// before a pair of theirs that the list left out could be in reach.
template <typename Scalar>
void ContactSolver<Scalar>::set_region_thresholds(const SphereModel<Scalar>& model) noexcept {
  const std::size_t R = m_region_move.size();
  if (R == 0) return;
  const auto x = model.positions();
  const auto region = model.node_regions();
  const Scalar inf = std::numeric_limits<Scalar>::infinity();
  for (std::size_t r = 0; r < R; ++r) {
    m_region_box[2 * r].setConstant(inf);
    m_region_box[2 * r + 1].setConstant(-inf);
  }
  for (Index q = 0; q < model.num_nodes(); ++q) {
    const std::size_t r = std::size_t(region[q]);
    if (r >= R) continue;  // (a region refresh() did not see: list_holds then uses one bound)
    m_region_box[2 * r] = m_region_box[2 * r].cwiseMin(x.row(q).transpose());
    m_region_box[2 * r + 1] = m_region_box[2 * r + 1].cwiseMax(x.row(q).transpose());
  }
  const Scalar skin = m_options.verlet_skin;
  for (std::size_t a = 0; a < R; ++a)
    for (std::size_t b = a; b < R; ++b) {  // (list_holds reads b >= a)
      // The distance between the boxes (0 when they overlap); an empty region's box is
      // inverted and gives infinity: it has no sphere to pair.
      const Vector3<Scalar> gap = (m_region_box[2 * b] - m_region_box[2 * a + 1])
                                      .cwiseMax(m_region_box[2 * a] - m_region_box[2 * b + 1])
                                      .cwiseMax(Vector3<Scalar>::Zero());
      const Scalar free = gap.norm() - m_region_radius[a] - m_region_radius[b];
      m_region_threshold[a * R + b] = a == b ? skin : std::max(skin, free);
    }
}

// Whether the part-contact list still holds every pair that can be in reach. A pair the list left
// out was farther apart than reach plus the skin (or, across regions, than the regions' threshold
// of set_region_thresholds allows for), so it can be in reach only once its two spheres' moves
// since the build add up to more than that. The moves are bounded per region: the tissue an
// instrument pushes does not make chains elsewhere rescan, and two regions far apart may move
// that far before either's spheres could meet. (Many regions: one bound for all, twice the
// largest move against the skin.) A NaN move rebuilds (a state that Simulation never steps).
template <typename Scalar>
bool ContactSolver<Scalar>::list_holds(const SphereModel<Scalar>& model) noexcept {
  const auto x = model.positions();
  const Scalar* xp = x.data();
  const Scalar* lp = m_list_x.data();
  auto moved2 = [&](Index q) {
    const std::ptrdiff_t k = 3 * std::ptrdiff_t(q);
    const Scalar dx = xp[k] - lp[k], dy = xp[k + 1] - lp[k + 1], dz = xp[k + 2] - lp[k + 2];
    return dx * dx + dy * dy + dz * dz;
  };
  const std::size_t R = m_region_move.size();
  // One bound for all: many regions, or a sphere in a region refresh() did not see (added since,
  // or an index that names no region), which the per-region arrays do not cover.
  auto one_bound = [&] {
    const Scalar limit = Scalar(0.25) * m_options.verlet_skin * m_options.verlet_skin;
    for (Index q = 0; q < model.num_nodes(); ++q)
      if (!(moved2(q) <= limit)) return false;  // (a NaN move rebuilds)
    return true;
  };
  if (R == 0) return one_bound();
  std::fill(m_region_move.begin(), m_region_move.end(), Scalar(0));
  const auto region = model.node_regions();
  bool nan = false;
  // (A region's nodes are usually consecutive: its largest move is kept in a register.)
  for (Index q = 0; q < model.num_nodes();) {
    const Index r = region[q];
    if (r < 0 || std::size_t(r) >= R) return one_bound();
    Scalar m = 0;
    for (; q < model.num_nodes() && region[q] == r; ++q) {
      const Scalar d2 = moved2(q);
      nan = nan || std::isnan(d2);
      m = std::max(m, d2);
    }
    Scalar& M = m_region_move[std::size_t(r)];
    M = std::max(M, m);
  }
  if (nan) return false;  // a NaN move rebuilds, as in the one-bound rule
  for (Scalar& m : m_region_move) m = std::sqrt(m);
  for (std::size_t a = 0; a < R; ++a)
    for (std::size_t b = a; b < R; ++b)
      if (region_pairs(Index(a), Index(b)) &&
          m_region_move[a] + m_region_move[b] > m_region_threshold[a * R + b])
        return false;
  return true;
}

// Every candidate pair (i, j) for part contact whose spheres are within reach + extra, once each.
template <typename Scalar>
template <typename Visit>
void ContactSolver<Scalar>::for_each_part_pair(const SphereModel<Scalar>& model, Scalar extra,
                                               Visit&& visit) const {
  const auto x = model.positions();
  const auto rest = model.rest_positions();
  const auto radius = model.radii();
  const auto region = model.node_regions();
  for (Index i = 0; i < model.num_nodes(); ++i) {
    const Index ri = region[i];
    if (!m_options.self_contact && ri == m_dominant_region) continue;
    const Vector3<Scalar> xi = x.row(i).transpose();
    const Scalar reach = radius[i] + m_max_radius + extra;
    for_each_in_box(xi.array() - reach, xi.array() + reach, [&](Index j) {
      if (j == i) return;
      const Index rj = region[j];
      const bool same = ri == rj;
      if (same && !m_options.self_contact) return;
      if (!same && !m_options.part_contact) return;
      // Each pair once: from its non-dominant side, or from the lower index.
      if (m_options.self_contact ? j < i : (rj != m_dominant_region && j < i)) return;
      const Scalar reach_ij = radius[i] + radius[j] + extra;
      if ((x.row(j).transpose() - xi).squaredNorm() >= reach_ij * reach_ij) return;
      if (same && (rest.row(j) - rest.row(i)).norm() <= Scalar(2) * (radius[i] + radius[j])) return;
      if (linked(i, j)) return;
      visit(i, j);
    });
  }
}

// Spheres i and j of a part-contact pair touch closer than this: their radii's sum, or across
// regions the lesser of that and their rest distance (parts that overlap at rest are at rest in
// contact). Fixed while the model is: the list keeps it.
template <typename Scalar>
Scalar ContactSolver<Scalar>::pair_threshold(const SphereModel<Scalar>& model, Index i,
                                             Index j) const noexcept {
  const Scalar reach = model.radii()[i] + model.radii()[j];
  if (model.node_regions()[i] == model.node_regions()[j]) return reach;
  return std::min(reach, (model.rest_positions().row(j) - model.rest_positions().row(i)).norm());
}

template <typename Scalar>
template <typename Emit>
void ContactSolver<Scalar>::part_contact(const SphereModel<Scalar>& model, const PartPair& pair,
                                         const Vector3<Scalar>& d, Scalar dist2,
                                         Emit&& emit) noexcept {
  ++m_narrow_tests;
  const Index i = pair.i, j = pair.j;
  const auto x = model.positions();
  const auto rest = model.rest_positions();
  const auto radius = model.radii();
  const auto mass = model.masses();
  const Scalar threshold = pair.threshold;
  const Scalar dist = std::sqrt(dist2);
  const Scalar depth = threshold - dist;
  if (!(depth > 0)) return;
  Vector3<Scalar> n = dist > Scalar(0) ? Vector3<Scalar>(d / dist)
                                       : Vector3<Scalar>((rest.row(j) - rest.row(i)).transpose());
  if (!(n.squaredNorm() > 0)) n = Vector3<Scalar>::UnitZ();
  n.normalize();
  // j is pushed along n (away from i), i the other way. The softer sphere yields.
  PenaltyContact<Scalar> pc;
  pc.node = j;
  pc.other = i;
  pc.normal = n;
  pc.depth = depth;
  pc.onset = m_options.part_contact_onset * threshold;
  pc.point = x.row(i).transpose() + (radius[i] - Scalar(0.5) * depth) * n;
  pc.stiffness = std::min(m_k[std::size_t(i)], m_k[std::size_t(j)]) *
                 (m_options.part_stiffness_ratio / m_options.stiffness_ratio);
  const Scalar mu = mass[i] * mass[j] / (mass[i] + mass[j]);
  pc.damping = Scalar(2) * m_options.damping_ratio * std::sqrt(pc.stiffness * mu);
  pc.friction = m_options.part_friction;
  pc.friction_speed = m_options.friction_speed;
  pc.node_start = x.row(j).transpose();
  pc.other_start = x.row(i).transpose();
  Scalar fn;
  Vector3<Scalar> slip;
  pc.force =
      fsm::detail::contact_force(pc, x.data(), model.velocities().data(), Scalar(0), fn, slip);
  if (!pc.point.allFinite()) return;
  emit(pc);
}

template <typename Scalar>
Index ContactSolver<Scalar>::project(SphereModel<Scalar>& model) noexcept {
  if (num_nodes() != model.num_nodes()) return -1;
  update_hash(model);
  auto x = model.positions();
  auto v = model.velocities();
  const auto fixed = model.fixed();
  Index moved = 0;
  for (const Instrument<Scalar>& ins : m_instruments) {
    if (!ins.enabled) continue;
    auto [lo, hi] = bounding_box(ins.shape, ins.pose);
    lo.array() -= m_max_radius;
    hi.array() += m_max_radius;
    for_each_in_box(lo, hi, [&](Index j) {
      if (fixed[j]) return;
      const auto hit = contact(ins.shape, ins.pose, Vector3<Scalar>(x.row(j).transpose()),
                               m_contact_radius[std::size_t(j)]);
      if (!hit) return;
      x.row(j) += (hit->depth * hit->normal).transpose();
      // Keep no velocity into the instrument (relative to its surface).
      const Vector3<Scalar> v_tool =
          ins.linear_velocity + ins.angular_velocity.cross(hit->point - ins.pose.position);
      const Scalar vn = (v.row(j).transpose() - v_tool).dot(hit->normal);
      if (vn < 0) v.row(j) -= (vn * hit->normal).transpose();
      ++moved;
    });
  }
  return moved;
}

}  // namespace fsm::collision
