#pragma once

// Definitions of ForceModel's members; included at the bottom of fsm/force_model.hpp.

#include <algorithm>
#include <cmath>
#include <type_traits>

#include "fsm/detail/parallel.hpp"
#include "fsm/detail/simd_links.hpp"

namespace fsm {

namespace detail {

// Raw views of the link arrays, so the hot loops index plain pointers.
template <typename Scalar>
struct LinkData {
  const Index* ij;
  const Scalar *rest, *ks, *kd, *kl, *es;
  explicit LinkData(const SphereModel<Scalar>& m)
      : ij(m.links().data()),
        rest(m.rest_lengths().data()),
        ks(m.stiffness().data()),
        kd(m.damping().data()),
        kl(m.large_stiffness().data()),
        es(m.switch_strain().data()) {}
  VoigtLink<Scalar> law(Index l) const noexcept { return {rest[l], ks[l], kd[l], kl[l], es[l]}; }
};

// Accumulates the Voigt forces of links [begin, end) into f (F_i += F, F_j -= F). Links that
// share their first node in a row (add_tetrahedral_part sorts them so) keep that node's state and
// force in registers: the force of a run is stored once, which removes the store-to-load chain
// through f[i] that otherwise serialises the loop. Unsorted links are still correct (runs of one).
template <typename Scalar, bool Bilinear, DampingModel Damping>
void accumulate_link_forces(const LinkData<Scalar>& L, const Scalar* x, const Scalar* v, Scalar* f,
                            Index begin, Index end) noexcept {
  Index l = begin;
  while (l < end) {
    const Index node = L.ij[2 * l];
    const std::ptrdiff_t i = 3 * std::ptrdiff_t(node);
    const Scalar xi = x[i], yi = x[i + 1], zi = x[i + 2];
    const Scalar vxi = v[i], vyi = v[i + 1], vzi = v[i + 2];
    Scalar fx(0), fy(0), fz(0);
    for (; l < end && L.ij[2 * l] == node; ++l) {
      const std::ptrdiff_t j = 3 * std::ptrdiff_t(L.ij[2 * l + 1]);
      const Scalar dx = x[j] - xi, dy = x[j + 1] - yi, dz = x[j + 2] - zi;
      const Scalar l2 = dx * dx + dy * dy + dz * dz;
      // One square root and one division give both 1/l and l = l^2 / l.
      const Scalar inv = l2 > Scalar(0) ? Scalar(1) / std::sqrt(l2) : Scalar(0);
      const Scalar len = l2 * inv;
      const Scalar ux = v[j] - vxi, uy = v[j + 1] - vyi, uz = v[j + 2] - vzi;
      const Scalar e = len - L.rest[l];
      const Scalar fe = Bilinear ? L.law(l).elastic_force(e) : L.ks[l] * e;
      Scalar Fx, Fy, Fz;
      if constexpr (Damping == DampingModel::along_link) {
        // s n with n = d / l: the scalar force times 1/l, applied to d.
        const Scalar s = (fe + L.kd[l] * (ux * dx + uy * dy + uz * dz) * inv) * inv;
        Fx = s * dx;
        Fy = s * dy;
        Fz = s * dz;
      } else {
        const Scalar s = fe * inv;
        Fx = s * dx + L.kd[l] * ux;
        Fy = s * dy + L.kd[l] * uy;
        Fz = s * dz + L.kd[l] * uz;
      }
      fx += Fx;
      fy += Fy;
      fz += Fz;
      f[j] -= Fx;
      f[j + 1] -= Fy;
      f[j + 2] -= Fz;
    }
    f[i] += fx;
    f[i + 1] += fy;
    f[i + 2] += fz;
  }
}

// Geometry of one link for the Jacobian forms: direction, length, scalar forces, tangent.
template <typename Scalar>
struct LinkState {
  Vector3<Scalar> n, u;
  Scalar length, elastic, total, tangent;
};

template <typename Scalar>
LinkState<Scalar> link_state(const LinkData<Scalar>& L, Index l, const Scalar* x, const Scalar* v,
                             DampingModel damping) noexcept {
  const std::ptrdiff_t i = 3 * std::ptrdiff_t(L.ij[2 * l]);
  const std::ptrdiff_t j = 3 * std::ptrdiff_t(L.ij[2 * l + 1]);
  LinkState<Scalar> s;
  const Vector3<Scalar> d(x[j] - x[i], x[j + 1] - x[i + 1], x[j + 2] - x[i + 2]);
  s.u = Vector3<Scalar>(v[j] - v[i], v[j + 1] - v[i + 1], v[j + 2] - v[i + 2]);
  s.length = d.norm();
  s.n = s.length > Scalar(0) ? Vector3<Scalar>(d / s.length) : Vector3<Scalar>::Zero();
  const VoigtLink<Scalar> law = L.law(l);
  const Scalar e = s.length - L.rest[l];
  s.elastic = law.elastic_force(e);
  s.tangent = law.tangent_stiffness(e);
  s.total = damping == DampingModel::along_link ? s.elastic + L.kd[l] * s.u.dot(s.n) : s.elastic;
  return s;
}

// K_l = alpha n n^T + beta I for the symmetric and definite forms (dF_i/dx_j).
template <typename Scalar>
void symmetric_stiffness(const LinkState<Scalar>& s, JacobianForm form, Scalar& alpha,
                         Scalar& beta) noexcept {
  if (!(s.length > Scalar(0))) {
    alpha = beta = Scalar(0);
    return;
  }
  const Scalar f = form == JacobianForm::definite ? std::max(s.total, Scalar(0)) : s.total;
  beta = f / s.length;
  alpha = s.tangent - beta;
}

// A penalty contact's relative velocity (of `node` against the instrument surface or `other`) and
// displacement since detection.
template <typename Scalar>
void contact_kinematics(const PenaltyContact<Scalar>& c, const Scalar* x, const Scalar* v,
                        Vector3<Scalar>& displacement, Vector3<Scalar>& velocity) noexcept {
  const std::ptrdiff_t i = 3 * std::ptrdiff_t(c.node);
  displacement = Vector3<Scalar>(x[i], x[i + 1], x[i + 2]) - c.node_start;
  velocity = Vector3<Scalar>(v[i], v[i + 1], v[i + 2]);
  if (c.other >= 0) {
    const std::ptrdiff_t j = 3 * std::ptrdiff_t(c.other);
    displacement -= Vector3<Scalar>(x[j], x[j + 1], x[j + 2]) - c.other_start;
    velocity -= Vector3<Scalar>(v[j], v[j + 1], v[j + 2]);
  } else {
    velocity -= c.surface_velocity;
  }
}

// The penetration (m) of `node` at x in the tangent-plane model, the instrument moved by
// `extra_depth` along the normal.
template <typename Scalar>
Scalar contact_depth(const PenaltyContact<Scalar>& c, const Scalar* x,
                     Scalar extra_depth) noexcept {
  const std::ptrdiff_t i = 3 * std::ptrdiff_t(c.node);
  Vector3<Scalar> d = Vector3<Scalar>(x[i], x[i + 1], x[i + 2]) - c.node_start;
  if (c.other >= 0) {
    const std::ptrdiff_t j = 3 * std::ptrdiff_t(c.other);
    d -= Vector3<Scalar>(x[j], x[j + 1], x[j + 2]) - c.other_start;
  }
  return c.depth - c.normal.dot(d) + extra_depth;
}

// The onset of a contact's normal law at penetration `depth`: s(depth), with its slope s'. Without
// an onset (0) the plain penalty s = depth, s' = 1 (for any depth: the linear law the implicit
// step takes may be evaluated where it no longer penetrates).
template <typename Scalar>
Scalar contact_onset(Scalar depth, Scalar onset, Scalar& slope) noexcept {
  if (!(onset > Scalar(0))) {
    slope = Scalar(1);
    return depth;
  }
  if (!(depth > Scalar(0))) {
    slope = Scalar(0);
    return Scalar(0);
  }
  if (depth < onset) {
    slope = depth / onset;
    return Scalar(0.5) * depth * slope;
  }
  slope = Scalar(1);
  return depth - Scalar(0.5) * onset;
}

// The regularised Coulomb friction's force per unit slip speed, mu f_n / sqrt(|slip|^2 + eps^2)
// (0 without friction: the frictionless part contacts skip the square root).
template <typename Scalar>
Scalar friction_slope(const PenaltyContact<Scalar>& c, Scalar fn,
                      const Vector3<Scalar>& slip) noexcept {
  if (c.friction == Scalar(0)) return Scalar(0);
  return c.friction * fn / std::sqrt(slip.squaredNorm() + c.friction_speed * c.friction_speed);
}

// The force on `node` at (x, v) in the tangent-plane model, the instrument moved by
// `extra_depth` along the normal; fn gets the normal force, slip the tangential relative velocity.
// Clamped, the normal force never pulls (k s(depth) - c s'(depth) v_n below zero gives zero).
// Unclamped, it is the law the implicit step takes for a contact that penetrates at the step's
// start: linear, linearised at `solve_depth` (the plain penalty is linear already; its damping
// may pull for that step); the friction always uses the clamped normal force.
template <typename Scalar>
Vector3<Scalar> contact_force(const PenaltyContact<Scalar>& c, const Scalar* x, const Scalar* v,
                              Scalar extra_depth, Scalar& fn, Vector3<Scalar>& slip,
                              bool clamp = true) noexcept {
  Vector3<Scalar> d, u;
  contact_kinematics(c, x, v, d, u);
  const Scalar depth = c.depth - c.normal.dot(d) + extra_depth;
  const Scalar vn = c.normal.dot(u);
  Scalar slope;
  const Scalar s = contact_onset(depth, c.onset, slope);
  const Scalar law = c.stiffness * s - c.damping * slope * vn;
  // No force before the sphere touches (a near contact, or one the step carried out), however
  // fast it approaches: the damping acts only in contact.
  fn = depth >= Scalar(0) ? std::max(Scalar(0), law) : Scalar(0);
  Scalar linear = law;
  if (!clamp && c.onset > Scalar(0)) {
    Scalar slope0;
    const Scalar s0 = contact_onset(c.solve_depth, c.onset, slope0);
    linear = c.stiffness * (s0 + slope0 * (depth - c.solve_depth)) - c.damping * slope0 * vn;
  }
  slip = u - vn * c.normal;
  const Vector3<Scalar> F = (clamp ? fn : linear) * c.normal - friction_slope(c, fn, slip) * slip;
  return F.allFinite() ? F : Vector3<Scalar>::Zero();
}

// The slope s' of the onset at `depth` (1 for the plain penalty).
template <typename Scalar>
Scalar contact_slope(const PenaltyContact<Scalar>& c, Scalar depth) noexcept {
  Scalar slope;
  (void)contact_onset(depth, c.onset, slope);
  return slope;
}

// How far an instrument contact's surface has advanced along its normal after time t.
template <typename Scalar>
Scalar surface_advance(const PenaltyContact<Scalar>& c, Scalar t) noexcept {
  return c.other < 0 ? t * c.normal.dot(c.surface_velocity) : Scalar(0);
}

}  // namespace detail

template <typename Scalar>
void ForceModel<Scalar>::reserve_contacts(Index capacity) {
  // (Defined before refresh() uses it.)
  if (capacity < 0) throw Error("", "contacts", "capacity must be non-negative");
  if (Index(m_contacts.size()) < capacity) {
    m_contacts.resize(std::size_t(capacity));
    m_contact_forces_before.resize(std::size_t(capacity));
  }
}

template <typename Scalar>
bool ForceModel<Scalar>::add_contact(const PenaltyContact<Scalar>& contact) noexcept {
  if (m_num_contacts >= Index(m_contacts.size())) return false;
  m_contacts[std::size_t(m_num_contacts++)] = contact;
  return true;
}

template <typename Scalar>
void ForceModel<Scalar>::reserve_held(Index capacity) {
  if (capacity > Index(m_held.size())) {
    m_held.resize(std::size_t(capacity));
    m_held_forces_before.resize(std::size_t(capacity));
  }
}

template <typename Scalar>
bool ForceModel<Scalar>::add_held(const HeldNode<Scalar>& held) noexcept {
  if (m_num_held >= Index(m_held.size())) return false;
  if (held.node < 0 || held.node >= m_num_nodes || !(held.stiffness > Scalar(0)) ||
      !std::isfinite(held.stiffness) || !(held.damping >= Scalar(0)) ||
      !std::isfinite(held.damping) || !held.target.allFinite() || !held.target_velocity.allFinite())
    return false;
  m_held[std::size_t(m_num_held++)] = held;
  return true;
}

template <typename Scalar>
void ForceModel<Scalar>::start_contacts(const SphereModel<Scalar>& model,
                                        bool start_forces) noexcept {
  const Scalar* x = model.positions().data();
  const Scalar* v = model.velocities().data();
  m_contacts_linearised = false;
  m_base_h = Scalar(-1);  // a new step: prepare_implicit recomputes everything
  for (Index k = 0; k < m_num_contacts; ++k) {
    PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    Scalar fn;
    Vector3<Scalar> slip;
    c.start_force =
        start_forces
            ? detail::contact_force(c, x, v, detail::surface_advance(c, m_contact_time), fn, slip)
            : Vector3<Scalar>::Zero();
    c.in_solve = false;
    m_contact_forces_before[std::size_t(k)] = c.force;
  }
  for (Index k = 0; k < m_num_held; ++k)
    m_held_forces_before[std::size_t(k)] = m_held[std::size_t(k)].force;
}

template <typename Scalar>
void ForceModel<Scalar>::reject_contacts() noexcept {
  for (Index k = 0; k < m_num_contacts; ++k)
    m_contacts[std::size_t(k)].force = m_contact_forces_before[std::size_t(k)];
  for (Index k = 0; k < m_num_held; ++k)
    m_held[std::size_t(k)].force = m_held_forces_before[std::size_t(k)];
}

template <typename Scalar>
void ForceModel<Scalar>::finish_contacts(const SphereModel<Scalar>& model) noexcept {
  const Scalar* x = model.positions().data();
  const Scalar* v = model.velocities().data();
  for (Index k = 0; k < m_num_contacts; ++k) {
    PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    Scalar fn;
    Vector3<Scalar> slip;
    // After an implicit step, a contact outside its last solve reports what the step applied
    // through it: nothing. (A sphere the last contact pass carried in is pushed out by the next
    // step; its penalty at this state would be a one-step spike in the instrument's wrench.)
    c.force =
        m_contacts_linearised && !c.in_solve
            ? Vector3<Scalar>::Zero()
            : detail::contact_force(c, x, v, detail::surface_advance(c, m_contact_time), fn, slip);
  }
  for (Index k = 0; k < m_num_held; ++k) {
    HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    hn.force = hn.force_at(x, v, m_contact_time);
  }
}

template <typename Scalar>
Index ForceModel<Scalar>::limit_contact_stiffness(const SphereModel<Scalar>& model,
                                                  Scalar h) noexcept {
  const auto mass = model.masses();
  Index softened = 0;
  // At most m / (2 h^2) for a spring on a mass m, the damping scaled to keep its ratio.
  // (A near contact, not touching yet, is softened too but not counted: it is not a contact.)
  auto soften = [&](Scalar& stiffness, Scalar& damping, Scalar m, bool count = true) {
    const Scalar cap = Scalar(0.5) * m / (h * h);
    if (!(stiffness > cap)) return;
    damping *= std::sqrt(cap / stiffness);
    stiffness = cap;
    softened += count ? 1 : 0;
  };
  for (Index k = 0; k < m_num_contacts; ++k) {
    PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    soften(
        c.stiffness, c.damping,
        c.other < 0 ? mass[c.node] : mass[c.node] * mass[c.other] / (mass[c.node] + mass[c.other]),
        c.depth > Scalar(0) || c.other >= 0);
  }
  for (Index k = 0; k < m_num_held; ++k) {
    HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    soften(hn.stiffness, hn.damping, mass[hn.node]);
  }
  return softened;
}

template <typename Scalar>
void ForceModel<Scalar>::add_contact_linearisation(const SphereModel<Scalar>& model, Scalar h,
                                                   Scalar* rhs) noexcept {
  const Scalar* x = model.positions().data();
  const Scalar* v = model.velocities().data();
  m_contacts_linearised = true;
  for (Index k = 0; k < m_num_contacts; ++k) {
    PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    const Scalar adv = detail::surface_advance(c, m_contact_time);
    c.solve_depth = detail::contact_depth(c, x, adv);
    c.in_solve = c.solve_depth > Scalar(0);
    if (!c.in_solve) continue;
    Scalar fn;
    Vector3<Scalar> slip;
    // h (F_linear - F_clamped): evaluate() clamped the force the rhs holds.
    Vector3<Scalar> r = h * (detail::contact_force(c, x, v, adv, fn, slip, false) -
                             detail::contact_force(c, x, v, adv, fn, slip));
    const Scalar kt = c.stiffness * detail::contact_slope(c, c.solve_depth);
    if (c.other < 0) r += h * h * kt * c.normal.dot(c.surface_velocity) * c.normal;
    for (int a = 0; a < 3; ++a) {
      if (!m_immobile[std::size_t(c.node)]) rhs[3 * c.node + a] += r[a];
      if (c.other >= 0 && !m_immobile[std::size_t(c.other)]) rhs[3 * c.other + a] -= r[a];
    }
  }
  // Held nodes: the point's motion over the step (their force and Jacobians are in the rest).
  for (Index k = 0; k < m_num_held; ++k) {
    const HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    if (m_immobile[std::size_t(hn.node)]) continue;
    for (int a = 0; a < 3; ++a)
      rhs[3 * hn.node + a] += h * h * hn.stiffness * hn.target_velocity[a];
  }
}

template <typename Scalar>
Scalar ForceModel<Scalar>::contact_work(const SphereModel<Scalar>& model,
                                        const ConstPositionsRef& x_before) const noexcept {
  const auto x = model.positions();
  const Scalar* xp = x.data();
  const Scalar* vp = model.velocities().data();
  Scalar w(0);
  for (Index k = 0; k < m_num_contacts; ++k) {
    const PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    Vector3<Scalar> d = (x.row(c.node) - x_before.row(c.node)).transpose();
    if (c.other >= 0) d -= (x.row(c.other) - x_before.row(c.other)).transpose();
    Vector3<Scalar> F;
    if (m_contacts_linearised) {
      // Backward Euler applies the end-of-step force of its linear law to contacts that
      // penetrated at the start, and nothing to the others.
      Scalar fn;
      Vector3<Scalar> slip;
      F = c.in_solve ? detail::contact_force(c, xp, vp, detail::surface_advance(c, m_contact_time),
                                             fn, slip, false)
                     : Vector3<Scalar>::Zero();
    } else {
      F = Scalar(0.5) * (c.start_force + c.force);  // trapezoid: exact for a linear spring
    }
    w += F.dot(d);
  }
  // Held nodes: backward Euler applies their end-of-step force (so does an explicit step's end
  // force bound the work of a spring being stretched).
  for (Index k = 0; k < m_num_held; ++k) {
    const HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    const Vector3<Scalar> d = (x.row(hn.node) - x_before.row(hn.node)).transpose();
    w += hn.force_at(xp, vp, m_contact_time).dot(d);
  }
  return w;
}

template <typename Scalar>
std::vector<Scalar> ForceModel<Scalar>::node_stiffness(const SphereModel<Scalar>& model) const {
  std::vector<Scalar> k(std::size_t(model.num_nodes()), Scalar(0));
  const auto links = model.links();
  for (Index l = 0; l < model.num_links(); ++l) {
    if (!m_force_link[std::size_t(l)]) continue;
    const Scalar s = std::max(model.stiffness()[l], model.large_stiffness()[l]);
    k[std::size_t(links(l, 0))] += s;
    k[std::size_t(links(l, 1))] += s;
  }
  m_continuum.add_node_stiffness(model, k.data());
  return k;
}

template <typename Scalar>
ForceModel<Scalar>::ForceModel(const SphereModel<Scalar>& model, const Options& options) {
  set_options(options);
  refresh(model);
}

template <typename Scalar>
void ForceModel<Scalar>::refresh(const SphereModel<Scalar>& model) {
  const Index n = model.num_nodes();
  if (n != m_num_nodes) {
    m_external.assign(3 * std::size_t(n), Scalar(0));
    m_num_nodes = n;
  }
  if (m_asleep.size() != std::size_t(n)) m_asleep.assign(std::size_t(n), 0);
  m_immobile.resize(std::size_t(n));
  m_immobile_nodes.reserve(std::size_t(n));
  m_inverse_mass.resize(n);
  m_force_link.assign(std::size_t(model.num_links()), 1);
  // Links inside a continuum region carry no force: the region's elements do.
  m_continuum_link.assign(std::size_t(model.num_links()), 0);
  {
    const auto links = model.links();
    const auto region = model.node_regions();
    for (Index l = 0; l < model.num_links(); ++l) {
      const Index r = region[links(l, 0)];
      m_continuum_link[std::size_t(l)] =
          r == region[links(l, 1)] && model.region(r).law == ForceLaw::continuum;
    }
  }
  // Worst case: every other link active.
  m_force_ranges.clear();
  m_force_ranges.reserve(std::size_t(model.num_links()) / 2 + 2);
  m_ranges.reserve(std::size_t(model.num_links()) / 2 + 2);
  m_continuum.refresh(model);
  m_continuum.set_simd(m_options.simd);
  m_continuum.set_smoothing(m_options.strain_smoothing, m_options.smoothing_element_share);
  update_topology(model);
  m_element_force.assign(m_continuum.empty() ? 0 : 3 * std::size_t(n), Scalar(0));
  m_base_rhs.assign(3 * std::size_t(n), Scalar(0));
  m_base_diagonal.assign(3 * std::size_t(n), Scalar(0));
  m_link_node_blocks.assign(6 * std::size_t(n), Scalar(0));
  if constexpr (std::is_same_v<Scalar, double>) {
    m_x4.assign(4 * std::size_t(n), 0.0);
    m_v4.assign(4 * std::size_t(n), 0.0);
  }
  m_base_h = Scalar(-1);
  // Contacts name nodes of the old model: forget them; keep (at least 1024 of) the capacity.
  clear_contacts();
  reserve_contacts(1024);
  clear_held();
  reserve_held(256);
  resize_scratch();
  // Accepted while its longest path (a thread's links, then the bands on one thread) is at most
  // an eighth of the links longer than an even share: the buffers' passes cost about that.
  m_partition = detail::partition_links(model.links().data(), model.num_links(), n,
                                        m_pool.threads(), model.num_links() / 8);
}

template <typename Scalar>
void ForceModel<Scalar>::update_topology(const SphereModel<Scalar>& model) noexcept {
  // Links inside a continuum region carry no force (the region's elements do), nor do broken ones.
  const Index L = model.num_links();
  if (Index(m_force_link.size()) != L) return;  // refresh() first
  const std::uint8_t* intact = model.link_intact().data();
  for (std::size_t l = 0; l < std::size_t(L); ++l)
    m_force_link[l] = std::uint8_t(intact[l] & (m_continuum_link[l] ^ 1));
  m_continuum.apply_topology(model.tetrahedron_intact().data());
  m_base_h = Scalar(-1);   // the kept rhs and diagonal of prepare_implicit() are stale
  update_mobility(model);  // and the ranges
}

template <typename Scalar>
void ForceModel<Scalar>::update_topology(const SphereModel<Scalar>& model,
                                         const std::vector<Index>& broken_links,
                                         const std::vector<Index>& removed_tetrahedra) noexcept {
  const Index L = model.num_links();
  if (Index(m_force_link.size()) != L) return;  // refresh() first
  for (const Index l : broken_links)
    if (l >= 0 && l < L) m_force_link[std::size_t(l)] = 0;
  m_continuum.remove(removed_tetrahedra.data(), removed_tetrahedra.size());
  m_base_h = Scalar(-1);
  update_ranges(model);
}

template <typename Scalar>
void ForceModel<Scalar>::update_mobility(const SphereModel<Scalar>& model) noexcept {
  const auto mass = model.masses();
  const auto fixed = model.fixed();
  m_immobile_nodes.clear();
  for (Index i = 0; i < m_num_nodes; ++i) {
    m_immobile[std::size_t(i)] = (fixed[i] || m_asleep[std::size_t(i)]) ? 1 : 0;
    m_inverse_mass[i] = m_immobile[std::size_t(i)] ? Scalar(0) : Scalar(1) / mass[i];
    if (m_immobile[std::size_t(i)]) m_immobile_nodes.push_back(i);
  }
  update_ranges(model);
}

// The force links' ranges and the active ones' (carries force and has a mobile end), in one pass
// and within the capacity refresh() reserved.
template <typename Scalar>
void ForceModel<Scalar>::update_ranges(const SphereModel<Scalar>& model) noexcept {
  m_force_ranges.clear();
  m_ranges.clear();
  const Index* ij = model.links().data();
  const Index L = model.num_links();
  Index force_begin = -1, active_begin = -1;
  for (Index l = 0; l < L; ++l) {
    const bool force = m_force_link[std::size_t(l)] != 0;
    const bool active =
        force && !(m_immobile[std::size_t(ij[2 * l])] && m_immobile[std::size_t(ij[2 * l + 1])]);
    if (force && force_begin < 0) force_begin = l;
    if (!force && force_begin >= 0) {
      m_force_ranges.emplace_back(force_begin, l);
      force_begin = -1;
    }
    if (active && active_begin < 0) active_begin = l;
    if (!active && active_begin >= 0) {
      m_ranges.emplace_back(active_begin, l);
      active_begin = -1;
    }
  }
  if (force_begin >= 0) m_force_ranges.emplace_back(force_begin, L);
  if (active_begin >= 0) m_ranges.emplace_back(active_begin, L);
}

template <typename Scalar>
bool ForceModel<Scalar>::set_asleep(const std::vector<std::uint8_t>& asleep,
                                    const SphereModel<Scalar>& model) noexcept {
  if (asleep.size() != m_asleep.size() || model.num_nodes() != m_num_nodes) return false;
  std::copy(asleep.begin(), asleep.end(), m_asleep.begin());
  update_mobility(model);
  return true;
}

template <typename Scalar>
void ForceModel<Scalar>::set_options(const Options& options) {
  if (options.threads < 1)
    throw Error("", "threads", std::to_string(options.threads) + " must be at least 1");
  if (!options.gravity.allFinite()) throw Error("", "gravity", "is not finite");
  if (!(std::isfinite(options.drag) && options.drag >= 0))
    throw Error("", "drag", "must be non-negative and finite (1/s)");
  if (!(std::isfinite(options.element_tangent_quality) && options.element_tangent_quality >= 0))
    throw Error("", "element_tangent_quality", "must be non-negative and finite");
  if (!(options.smoothing_element_share >= 0 && options.smoothing_element_share <= 1))
    throw Error("", "smoothing_element_share", "must be in [0, 1]");
  m_options = options;
  if (m_continuum.element_tangent_quality() != options.element_tangent_quality)
    m_continuum.set_element_tangent_quality(options.element_tangent_quality);
  m_continuum.set_simd(options.simd);
  m_continuum.set_flutter_guard(options.flutter_guard);
  m_continuum.set_smoothing(options.strain_smoothing, options.smoothing_element_share);
  resize_scratch();
}

template <typename Scalar>
bool ForceModel<Scalar>::simd_ready(Index n) const noexcept {
  return m_options.simd && m_x4.size() == 4 * std::size_t(n);
}

template <typename Scalar>
void ForceModel<Scalar>::pad_states(const Scalar* x, const Scalar* v, Index n) noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    // On the pool for a large model: on one thread the other spun through it, 9 % of a two-thread
    // evaluation of 952k links (docs/benchmarks.md). The size is a cautious choice, not measured:
    // it keeps the extra dispatch away from the models a real-time step runs (a few thousand).
    constexpr Index kPoolNodes = 16384;
    if (detail::WorkerPool* pool = n >= kPoolNodes ? m_pool.get() : nullptr) {  // (2+ threads)
      auto pad = [&](int t, int T) {
        const auto [begin, end] = detail::share(n, t, T);
        pad_state_rows(x, v, begin, end);
      };
      pool->run(pad);
      return;
    }
  }
  pad_state_rows(x, v, 0, n);
}

template <typename Scalar>
void ForceModel<Scalar>::pad_state_rows(const Scalar* x, const Scalar* v, Index begin,
                                        Index end) noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    const std::ptrdiff_t b = begin;
    detail::pad_rows4(x + 3 * b, end - begin, m_x4.data() + 4 * b);
    if (v) detail::pad_rows4(v + 3 * b, end - begin, m_v4.data() + 4 * b);
  } else {
    (void)x, (void)v, (void)begin, (void)end;
  }
}

template <typename Scalar>
void ForceModel<Scalar>::resize_scratch() {
  const int threads = std::max(1, std::min(m_options.threads, detail::max_threads()));
  m_pool.reset(threads);
  m_scratch.resize(threads > 1 ? std::size_t(threads) : 0);
  for (auto& s : m_scratch) s.assign(3 * std::size_t(m_num_nodes), Scalar(0));
  m_node_scratch.resize(m_scratch.size());
  for (auto& s : m_node_scratch) s.assign(std::size_t(m_num_nodes), Scalar(0));
  m_block_scratch.resize(m_scratch.size());
  for (auto& s : m_block_scratch) s.assign(6 * std::size_t(m_num_nodes), Scalar(0));
}

template <typename Scalar>
void ForceModel<Scalar>::clear_external_forces() noexcept {
  std::fill(m_external.begin(), m_external.end(), Scalar(0));
}

template <typename Scalar>
void ForceModel<Scalar>::evaluate(const SphereModel<Scalar>& model, const ConstPositionsRef& x,
                                  const ConstPositionsRef& v, PositionsRef f) noexcept {
  const detail::LinkData<Scalar> L(model);
  const Scalar* mass = model.masses().data();
  const Scalar* ext = m_external.data();
  const Vector3<Scalar> g = m_options.gravity;
  const Scalar drag = m_options.drag;
  const Scalar* xp = x.data();
  const Scalar* vp = v.data();
  auto init = [&](Index i, Scalar* out) {
    const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
    out[0] = mass[i] * (g[0] - drag * vp[k]) + ext[k];
    out[1] = mass[i] * (g[1] - drag * vp[k + 1]) + ext[k + 1];
    out[2] = mass[i] * (g[2] - drag * vp[k + 2]) + ext[k + 2];
  };
  const bool bilinear = model.has_bilinear_links();
  const DampingModel dm = m_options.damping;
  // On the pool, with the links shared so that no two threads meet at a node (refresh()): one
  // dispatch, no buffers. Otherwise each thread its own buffer, then their sum.
  detail::WorkerPool* pool = m_pool.get();
  const bool partitioned = links_partitioned();
  detail::simd::LinkForceKernel simd_kernel = nullptr;
  detail::simd::LinkArrays simd_links{};
  if constexpr (std::is_same_v<Scalar, double>) {
    if (simd_ready(model.num_nodes()))
      simd_kernel = detail::simd::link_force_kernel(bilinear, dm == DampingModel::along_link);
    if (simd_kernel) {  // one load per node: x, y, z padded to four
      simd_links = {L.ij, L.rest, L.ks, L.kd, L.kl, L.es};
      if (!partitioned) pad_states(xp, vp, model.num_nodes());  // (else each thread its nodes)
    }
  }
  auto kernel_range = [&](Index begin, Index end, Scalar* out) {
    using DM = DampingModel;
    if constexpr (std::is_same_v<Scalar, double>) {
      if (simd_kernel) {
        simd_kernel(simd_links, m_x4.data(), m_v4.data(), out, begin, end);
        return;
      }
    }
    if (bilinear) {
      if (dm == DM::along_link)
        detail::accumulate_link_forces<Scalar, true, DM::along_link>(L, xp, vp, out, begin, end);
      else
        detail::accumulate_link_forces<Scalar, true, DM::full_relative_velocity>(L, xp, vp, out,
                                                                                 begin, end);
    } else {
      if (dm == DM::along_link)
        detail::accumulate_link_forces<Scalar, false, DM::along_link>(L, xp, vp, out, begin, end);
      else
        detail::accumulate_link_forces<Scalar, false, DM::full_relative_velocity>(L, xp, vp, out,
                                                                                  begin, end);
    }
  };
  // Only the links with a mobile end (all of them unless nodes are fixed or asleep).
  const auto& ranges = m_ranges;
  auto kernel = [&](Index begin, Index end, Scalar* out) {
    for (const auto& [a, b] : ranges) {
      const Index lo = std::max(a, begin), hi = std::min(b, end);
      if (lo < hi) kernel_range(lo, hi, out);
    }
  };
  if (partitioned) {
    auto nodes = [&](Index begin, Index end) {
      if (simd_kernel) pad_state_rows(xp, vp, begin, end);  // the states its links read
      for (Index i = begin; i < end; ++i) init(i, f.data() + 3 * std::ptrdiff_t(i));
    };
    detail::scatter_links(*pool, m_partition, f.data(), nodes, kernel);
  } else {
    detail::scatter_links(pool, model.num_nodes(), model.num_links(), f.data(), m_scratch, init,
                          kernel);
  }
  {
    // (The states padded for the link kernel serve the element kernels too.)
    const Scalar *x4 = nullptr, *v4 = nullptr;
    if constexpr (std::is_same_v<Scalar, double>)
      if (simd_kernel) x4 = m_x4.data(), v4 = m_v4.data();
    m_continuum.add_forces(xp, vp, f.data(), true, x4, v4);
  }
  for (Index k = 0; k < m_num_contacts; ++k) {
    const PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    Scalar fn;
    Vector3<Scalar> slip;
    const Vector3<Scalar> F =
        detail::contact_force(c, xp, vp, detail::surface_advance(c, m_contact_time), fn, slip);
    f.row(c.node) += F.transpose();
    if (c.other >= 0) f.row(c.other) -= F.transpose();
  }
  for (Index k = 0; k < m_num_held; ++k) {
    const HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    f.row(hn.node) += hn.force_at(xp, vp, m_contact_time).transpose();
  }
}

template <typename Scalar>
Scalar ForceModel<Scalar>::link_energy(const SphereModel<Scalar>& model,
                                       const Scalar* p) const noexcept {
  const detail::LinkData<Scalar> L(model);
  // The force links in [begin, end).
  auto range_energy = [&](Index begin, Index end) {
    Scalar sum(0);
    if constexpr (std::is_same_v<Scalar, double>) {
      if (m_options.simd)
        if (const auto kernel = detail::simd::link_energy_kernel()) {
          const detail::simd::LinkArrays links{L.ij, L.rest, L.ks, L.kd, L.kl, L.es};
          for (const auto& [a, b] : m_force_ranges) {
            const Index lo = std::max(a, begin), hi = std::min(b, end);
            if (lo < hi)
              sum += kernel(links, p, std::int32_t(model.num_nodes()), std::int32_t(lo),
                            std::int32_t(hi));
          }
          return sum;
        }
    }
    for (const auto& [a, b] : m_force_ranges)  // (every link in them carries force)
      for (Index l = std::max(a, begin); l < std::min(b, end); ++l) {
        const std::ptrdiff_t i = 3 * std::ptrdiff_t(L.ij[2 * l]);
        const std::ptrdiff_t j = 3 * std::ptrdiff_t(L.ij[2 * l + 1]);
        const Scalar dx = p[j] - p[i], dy = p[j + 1] - p[i + 1], dz = p[j + 2] - p[i + 2];
        sum += L.law(l).energy(std::sqrt(dx * dx + dy * dy + dz * dz) - L.rest[l]);
      }
    return sum;
  };
  // On the pool: each thread its share of the links (at most kMaxShares partial sums).
  constexpr int kMaxShares = 16;
  detail::WorkerPool* pool = m_pool.get();
  const int T = pool ? std::min(pool->size(), kMaxShares) : 1;
  if (T < 2) return range_energy(0, model.num_links());
  Scalar partial[kMaxShares] = {};
  auto job = [&](int t, int) {
    if (t >= T) return;
    const auto [begin, end] = detail::share(model.num_links(), t, T);
    partial[t] = range_energy(begin, end);
  };
  pool->run(job);
  Scalar sum(0);
  for (int t = 0; t < T; ++t) sum += partial[t];
  return sum;
}

template <typename Scalar>
Scalar ForceModel<Scalar>::elastic_energy(const SphereModel<Scalar>& model,
                                          const ConstPositionsRef& x) const noexcept {
  const Scalar* p = x.data();
  return m_continuum.energy(p) + link_energy(model, p);
}

template <typename Scalar>
Scalar ForceModel<Scalar>::elastic_energy_keeping_forces(
    const SphereModel<Scalar>& model) noexcept {
  drop_kept_forces();
  const Scalar* x = model.positions().data();
  if (m_continuum.empty() || !m_options.reuse_end_forces ||
      m_options.strain_smoothing != StrainSmoothing::element ||
      m_element_force.size() != 3 * std::size_t(model.num_nodes()))
    return elastic_energy(model, model.positions());
  const Scalar* v = model.velocities().data();
  const Scalar *x4 = nullptr, *v4 = nullptr;
  if constexpr (std::is_same_v<Scalar, double>) {
    if (simd_ready(model.num_nodes())) {
      pad_states(x, v, model.num_nodes());
      x4 = m_x4.data();
      v4 = m_v4.data();
    }
  }
  // As prepare_implicit()'s first pass of a step evaluates them, its flutter watch included:
  // saved first, and undone if the state does not start a step (drop_kept_forces()).
  std::fill(m_element_force.begin(), m_element_force.end(), Scalar(0));
  m_kept_watched = m_options.flutter_guard;
  if (m_kept_watched) m_continuum.save_watch();
  m_continuum.watch_next_forces();
  m_continuum.add_forces(x, v, m_element_force.data(), true, x4, v4);
  m_kept = true;
  m_kept_generation = m_continuum.generation();
  return m_continuum.forces_energy() + link_energy(model, x);
}

template <typename Scalar>
Scalar ForceModel<Scalar>::kinetic_energy(const SphereModel<Scalar>& model,
                                          const ConstPositionsRef& v) const noexcept {
  return Scalar(0.5) * model.masses().dot(v.rowwise().squaredNorm());
}

template <typename Scalar>
Scalar ForceModel<Scalar>::gravity_energy(const SphereModel<Scalar>& model,
                                          const ConstPositionsRef& x) const noexcept {
  const auto rest = model.rest_positions();
  const auto mass = model.masses();
  const Vector3<Scalar> g = m_options.gravity;
  Scalar sum(0);
  for (Index i = 0; i < model.num_nodes(); ++i)
    sum -= mass[i] * (g[0] * (x(i, 0) - rest(i, 0)) + g[1] * (x(i, 1) - rest(i, 1)) +
                      g[2] * (x(i, 2) - rest(i, 2)));
  return sum;
}

template <typename Scalar>
bool ForceModel<Scalar>::update_contact_set(const SphereModel<Scalar>& model, const Scalar* x_end,
                                            Scalar h) noexcept {
  bool changed = false;
  for (Index k = 0; k < m_num_contacts; ++k) {
    PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    if (m_immobile[std::size_t(c.node)] && (c.other < 0 || m_immobile[std::size_t(c.other)]))
      continue;
    if (c.other >= 0) continue;  // part contacts keep the start's set (see the header)
    // A contact that did not penetrate at the step's start (a near contact) and joined a pass
    // stays for the rest of the step: its linear law, damping included, stops the sphere short of
    // the surface, and dropping it again would let the next pass carry the sphere in. So does any
    // contact marked stays_in_solve: a face contact's vertex, whose law sums samples that switch
    // on and off along its faces; when those could leave between passes, the last pass was often
    // solved with a set that threw the surface; and, with face contact on, a tetrahedral node
    // that is not a face vertex (docs/physics.md section 8).
    const bool joined = c.in_solve && (c.stays_in_solve || !(c.solve_depth > Scalar(0)));
    const bool in =
        joined ||
        detail::contact_depth(c, x_end, detail::surface_advance(c, m_contact_time + h)) > Scalar(0);
    changed = changed || in != c.in_solve;
    c.in_solve = in;
  }
  (void)model;
  return changed;
}

template <typename Scalar>
void ForceModel<Scalar>::prepare_implicit(const SphereModel<Scalar>& model, Scalar h,
                                          JacobianForm form, Scalar* blocks, PositionsRef rhs,
                                          PositionsRef diagonal, bool keep_contact_set) noexcept {
  const detail::LinkData<Scalar> L(model);
  const Scalar* mass = model.masses().data();
  const Scalar* ext = m_external.data();
  const Scalar* x = model.positions().data();
  const Scalar* v = model.velocities().data();
  const Vector3<Scalar> g = m_options.gravity;
  const DampingModel dm = m_options.damping;
  const Scalar h2 = h * h;
  m_implicit_h = h;  // apply_implicit() needs it for the drag term
  const std::size_t n3 = 3 * std::size_t(model.num_nodes());
  const bool reuse = keep_contact_set && m_base_h == h && m_base_rhs.size() == n3;
  if (reuse) {  // a re-solve of the same state: only the contacts change
    std::copy(m_base_rhs.begin(), m_base_rhs.end(), rhs.data());
    std::copy(m_base_diagonal.begin(), m_base_diagonal.end(), diagonal.data());
  } else {
    // rhs = h F + h^2 K v, and the per-link blocks B = h D + h^2 K = a n n^T + b I.
    const Scalar drag = m_options.drag;
    const bool partitioned = links_partitioned();  // (as in evaluate())
    auto init = [&](Index i, Scalar* out) {
      const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
      for (int c = 0; c < 3; ++c) out[c] = h * (mass[i] * (g[c] - drag * v[k + c]) + ext[k + c]);
    };
    detail::simd::LinkPrepareKernel simd_prepare = nullptr;
    detail::simd::LinkArrays simd_links{};
    if constexpr (std::is_same_v<Scalar, double>) {
      if (form != JacobianForm::exact && simd_ready(model.num_nodes()))
        simd_prepare = detail::simd::link_prepare_kernel(model.has_bilinear_links(),
                                                         dm == DampingModel::along_link);
      if (simd_prepare) {
        simd_links = {L.ij, L.rest, L.ks, L.kd, L.kl, L.es};
        if (!partitioned) pad_states(x, v, model.num_nodes());  // (else each thread its nodes)
      }
    }
    auto kernel = [&](Index begin, Index end, Scalar* out) {
      if constexpr (std::is_same_v<Scalar, double>) {
        if (simd_prepare) {  // the force links' ranges on the kernel; the others get zero blocks
          Index l = begin;
          auto zero = [&](Index from, Index to) {
            if (from < to)
              std::fill(blocks + std::ptrdiff_t(implicit_block_size) * from,
                        blocks + std::ptrdiff_t(implicit_block_size) * to, Scalar(0));
          };
          for (const auto& [a, b] : m_force_ranges) {
            const Index lo = std::max(a, begin), hi = std::min(b, end);
            if (lo >= hi) continue;
            zero(l, lo);
            simd_prepare(simd_links, m_x4.data(), m_v4.data(), h, form == JacobianForm::definite,
                         blocks, out, lo, hi);
            l = hi;
          }
          zero(l, end);
          return;
        }
      }
      for (Index l = begin; l < end; ++l) {
        if (!m_force_link[std::size_t(l)]) {  // inside a continuum region: no force, no block
          std::fill_n(blocks + std::ptrdiff_t(implicit_block_size) * l, implicit_block_size,
                      Scalar(0));
          continue;
        }
        const detail::LinkState<Scalar> s = detail::link_state(L, l, x, v, dm);
        Scalar alpha, beta;
        detail::symmetric_stiffness(s, form, alpha, beta);
        // Link force on i, and K_l u with u = v_j - v_i.
        Vector3<Scalar> F = s.total * s.n;
        if (dm == DampingModel::full_relative_velocity) F += L.kd[l] * s.u;
        const Vector3<Scalar> Ku = alpha * s.n.dot(s.u) * s.n + beta * s.u;
        const Vector3<Scalar> r = h * F + h2 * Ku;
        const std::ptrdiff_t i = 3 * std::ptrdiff_t(L.ij[2 * l]);
        const std::ptrdiff_t j = 3 * std::ptrdiff_t(L.ij[2 * l + 1]);
        for (int c = 0; c < 3; ++c) {
          out[i + c] += r[c];
          out[j + c] -= r[c];
        }
        Scalar* B = blocks + std::ptrdiff_t(implicit_block_size) * l;
        B[0] = s.n[0];
        B[1] = s.n[1];
        B[2] = s.n[2];
        const bool along = dm == DampingModel::along_link;
        B[3] = h2 * alpha + (along ? h * L.kd[l] : Scalar(0));
        B[4] = h2 * beta + (along ? Scalar(0) : h * L.kd[l]);
      }
    };
    // The links' 3 x 3 diagonal blocks per node with the mass (the drag's Jacobian -gamma m I
    // joins it: M (1 + h gamma)), kept for implicit_diagonal_blocks(); diag(A) from them. On the
    // pool each thread sums its links' blocks into its own buffer, then its share of the nodes
    // (or, with the links partitioned, straight into the per-node blocks).
    // (m_block_scratch has as many buffers as m_scratch: resize_scratch().)
    const Index n = model.num_nodes();
    auto copy_diagonal = [&](Index begin, Index end) {
      Scalar* d = diagonal.data();
      for (std::ptrdiff_t i = begin; i < end; ++i)
        for (std::ptrdiff_t c = 0; c < 3; ++c) d[3 * i + c] = m_link_node_blocks[6 * i + c];
    };
    auto links_done = [&](int t, Index begin, Index end) {
      std::vector<Scalar>& bb = m_block_scratch[std::size_t(t)];
      std::fill(bb.begin(), bb.end(), Scalar(0));
      add_link_node_blocks(model, blocks, begin, end, bb.data());
    };
    auto nodes_done = [&](Index begin, Index end, int T) {
      init_link_node_blocks(model, h, begin, end, T);
      copy_diagonal(begin, end);
    };
    if (partitioned) {
      // Each thread its nodes (the states its links read, the rhs and the mass blocks), then its
      // links' blocks, rhs and per-node blocks straight into the outputs; then the bands.
      auto nodes = [&](Index begin, Index end) {
        if (simd_prepare) pad_state_rows(x, v, begin, end);
        for (Index i = begin; i < end; ++i) init(i, rhs.data() + 3 * std::ptrdiff_t(i));
        init_link_node_blocks(model, h, begin, end, 0);
      };
      auto links_and_blocks = [&](Index begin, Index end, Scalar* out) {
        kernel(begin, end, out);
        add_link_node_blocks(model, blocks, begin, end, m_link_node_blocks.data());
      };
      detail::scatter_links(*m_pool.get(), m_partition, rhs.data(), nodes, links_and_blocks);
      copy_diagonal(0, n);
    } else if (!detail::scatter_links(m_pool.get(), n, model.num_links(), rhs.data(), m_scratch,
                                      init, kernel, links_done, nodes_done)) {
      init_link_node_blocks(model, h, 0, n, 0);
      add_link_node_blocks(model, blocks, 0, model.num_links(), m_link_node_blocks.data());
      copy_diagonal(0, n);
    }
    if (!m_continuum.empty()) {
      // The elements: h F into the rhs, then their tangent (-h^2 H v into the rhs, diag(A)).
      const Scalar *x4 = nullptr, *v4 = nullptr;  // padded above for the link kernel
      if constexpr (std::is_same_v<Scalar, double>)
        if (simd_prepare) x4 = m_x4.data(), v4 = m_v4.data();
      // The forces kept at the end of the last step, if the caller vouched for the state and
      // nothing has evaluated or changed the elements since (elastic_energy_keeping_forces()).
      const bool kept = m_kept_armed && m_kept && !keep_contact_set &&
                        m_kept_generation == m_continuum.generation();
      if (!kept && !keep_contact_set) drop_kept_forces();  // their watch undone: this one counts
      if (!kept) {
        std::fill(m_element_force.begin(), m_element_force.end(), Scalar(0));
        if (!keep_contact_set) m_continuum.watch_next_forces();  // once per step: its first pass
        m_continuum.add_forces(x, v, m_element_force.data(), true, x4, v4);
      }
      m_kept_reused += kept ? 1 : 0;
      // prepare_implicit() below turns the kept state into its own (their watch stands: this
      // state starts a step).
      m_kept = m_kept_armed = m_kept_watched = false;
      Scalar* r = rhs.data();
      for (std::size_t k = 0; k < m_element_force.size(); ++k) r[k] += h * m_element_force[k];
      m_continuum.prepare_implicit(x, v, h, r, diagonal.data(), v4);
    }
    if (m_base_rhs.size() == n3) {
      std::copy(rhs.data(), rhs.data() + n3, m_base_rhs.begin());
      std::copy(diagonal.data(), diagonal.data() + n3, m_base_diagonal.begin());
      m_base_h = h;
    }
  }  // !reuse
  // Contacts: h F + h^2 dF/dx v (with the instrument's motion over the step) into the rhs, and
  // the blocks B = (h^2 k + h c) n n^T + h c_t (I - n n^T) of those that push at the start.
  // A contact in the solve takes its linear law (unclamped) for the whole step.
  m_contacts_linearised = true;
  for (Index k = 0; k < m_num_contacts; ++k) {
    PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    Scalar fn;
    Vector3<Scalar> slip, d, u;
    const Scalar adv = detail::surface_advance(c, m_contact_time);
    c.solve_depth = detail::contact_depth(c, x, adv);
    if (!keep_contact_set) c.in_solve = c.solve_depth > Scalar(0);
    const bool active = c.in_solve;
    // In the solve: the linear law for the whole step; out of it: the force at the start
    // (clamped: a near contact outside the instrument pulls nothing).
    const Vector3<Scalar> F = detail::contact_force(c, x, v, adv, fn, slip, !active);
    detail::contact_kinematics(c, x, v, d, u);
    // The law's slope at this state (1 for the plain penalty; the onset's s' otherwise).
    const Scalar slope = detail::contact_slope(c, c.solve_depth);
    c.normal_block = active ? slope * (h2 * c.stiffness + h * c.damping) : Scalar(0);
    c.tangent_block = active ? h * detail::friction_slope(c, fn, slip) : Scalar(0);
    Vector3<Scalar> r = h * F;
    if (active) r -= h2 * slope * c.stiffness * c.normal.dot(u) * c.normal;
    rhs.row(c.node) += r.transpose();
    if (c.other >= 0) rhs.row(c.other) -= r.transpose();
    for (int a = 0; a < 3; ++a) {
      const Scalar n2 = c.normal[a] * c.normal[a];
      const Scalar diag = c.tangent_block + (c.normal_block - c.tangent_block) * n2;
      diagonal(c.node, a) += diag;
      if (c.other >= 0) diagonal(c.other, a) += diag;
    }
  }
  // Held nodes: h F + h^2 k (v_p - v) into the rhs, (h^2 k + h c) I into A.
  for (Index k = 0; k < m_num_held; ++k) {
    const HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    const Vector3<Scalar> vi = model.velocities().row(hn.node).transpose();
    const Vector3<Scalar> r =
        h * hn.force_at(x, v, m_contact_time) + h2 * hn.stiffness * (hn.target_velocity - vi);
    rhs.row(hn.node) += r.transpose();
    diagonal.row(hn.node).array() += h2 * hn.stiffness + h * hn.damping;
  }
  for (const Index i : immobile_nodes()) {
    rhs.row(i).setZero();
    diagonal.row(i).setOnes();
  }
}

template <typename Scalar>
void ForceModel<Scalar>::init_link_node_blocks(const SphereModel<Scalar>& model, Scalar h,
                                               Index begin, Index end, int T) noexcept {
  const Scalar* mass = model.masses().data();
  const Scalar md = Scalar(1) + h * m_options.drag;
  Scalar* out = m_link_node_blocks.data();
  for (Index i = begin; i < end; ++i) {
    Scalar* o = out + 6 * std::ptrdiff_t(i);
    o[0] = o[1] = o[2] = md * mass[i];
    o[3] = o[4] = o[5] = Scalar(0);
    for (int t = 0; t < T; ++t) {
      const Scalar* b = m_block_scratch[std::size_t(t)].data() + 6 * std::ptrdiff_t(i);
      for (int c = 0; c < 6; ++c) o[c] += b[c];
    }
  }
}

template <typename Scalar>
void ForceModel<Scalar>::add_link_node_blocks(const SphereModel<Scalar>& model,
                                              const Scalar* blocks, Index begin, Index end,
                                              Scalar* out) const noexcept {
  // a n n^T + b I on both ends of a link. The first node of a run of links that share it (the
  // builder sorts links so) sums in registers. On the SIMD kernel when there is one (the same
  // roundings: ForceModel.SimdLinkNodeBlocksMatchTheScalarLoop).
  const Index* ij = model.links().data();
  if constexpr (std::is_same_v<Scalar, double>) {
    if (m_options.simd) {
      if (const auto simd = detail::simd::link_node_blocks_kernel()) {
        for (const auto& [a, b] : m_force_ranges) {
          const Index lo = std::max(a, begin), hi = std::min(b, end);
          if (lo < hi) simd(ij, blocks, out, lo, hi);
        }
        return;
      }
    }
  }
  for (const auto& [a, b] : m_force_ranges) {
    const Index lo = std::max(a, begin), hi = std::min(b, end);
    for (Index l = lo; l < hi;) {
      const Index i = ij[2 * l];
      Scalar acc[6] = {0, 0, 0, 0, 0, 0};
      for (; l < hi && ij[2 * l] == i; ++l) {
        const Scalar* B = blocks + std::ptrdiff_t(implicit_block_size) * l;
        const Scalar al = B[3], be = B[4];
        const Scalar d[6] = {al * B[0] * B[0] + be, al * B[1] * B[1] + be, al * B[2] * B[2] + be,
                             al * B[0] * B[1],      al * B[0] * B[2],      al * B[1] * B[2]};
        Scalar* o = out + 6 * std::ptrdiff_t(ij[2 * l + 1]);
        for (int c = 0; c < 6; ++c) {
          o[c] += d[c];
          acc[c] += d[c];
        }
      }
      Scalar* o = out + 6 * std::ptrdiff_t(i);
      for (int c = 0; c < 6; ++c) o[c] += acc[c];
    }
  }
}

template <typename Scalar>
void ForceModel<Scalar>::implicit_diagonal_blocks(const SphereModel<Scalar>& model,
                                                  const Scalar* blocks,
                                                  Scalar* out) const noexcept {
  (void)blocks;  // their diagonal blocks were kept by prepare_implicit()
  (void)model;
  std::copy(m_link_node_blocks.begin(), m_link_node_blocks.end(), out);
  // a n n^T + b I on both ends of a contact between parts.
  auto add = [&](Index i, const Scalar* nv, Scalar a, Scalar b) {
    Scalar* o = out + 6 * std::ptrdiff_t(i);
    o[0] += a * nv[0] * nv[0] + b;
    o[1] += a * nv[1] * nv[1] + b;
    o[2] += a * nv[2] * nv[2] + b;
    o[3] += a * nv[0] * nv[1];
    o[4] += a * nv[0] * nv[2];
    o[5] += a * nv[1] * nv[2];
  };
  m_continuum.add_diagonal_blocks(out);
  for (Index k = 0; k < m_num_contacts; ++k) {
    const PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    if (!(c.normal_block > Scalar(0)) && !(c.tangent_block > Scalar(0))) continue;
    const Scalar nv[3] = {c.normal[0], c.normal[1], c.normal[2]};
    add(c.node, nv, c.normal_block - c.tangent_block, c.tangent_block);
    if (c.other >= 0) add(c.other, nv, c.normal_block - c.tangent_block, c.tangent_block);
  }
  const Scalar h = m_implicit_h;
  for (Index k = 0; k < m_num_held; ++k) {
    const HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    const Scalar zero[3] = {0, 0, 0};
    add(hn.node, zero, Scalar(0), h * h * hn.stiffness + h * hn.damping);
  }
  for (const Index i : immobile_nodes()) {
    Scalar* o = out + 6 * std::ptrdiff_t(i);
    o[0] = o[1] = o[2] = Scalar(1);
    o[3] = o[4] = o[5] = Scalar(0);
  }
}

template <typename Scalar>
void ForceModel<Scalar>::apply_implicit(const SphereModel<Scalar>& model, const Scalar* blocks,
                                        const ConstPositionsRef& p, PositionsRef y) noexcept {
  const Index* ij = model.links().data();
  const Scalar* mass = model.masses().data();
  const Scalar* pp = p.data();
  const Scalar md = Scalar(1) + m_implicit_h * m_options.drag;  // drag: M (1 + h gamma)
  auto init = [&](Index i, Scalar* out) {
    const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
    out[0] = md * mass[i] * pp[k];
    out[1] = md * mass[i] * pp[k + 1];
    out[2] = md * mass[i] * pp[k + 2];
  };
  detail::WorkerPool* pool = m_pool.get();
  const int T = pool ? std::min<int>(pool->size(), static_cast<int>(m_scratch.size())) : 1;
  // The link law alone on the pool, its links shared without a common node (as in evaluate()).
  const bool partitioned = T > 1 && m_continuum.empty() && links_partitioned();
  detail::simd::LinkApplyKernel simd_apply = nullptr;
  if constexpr (std::is_same_v<Scalar, double>) {
    if (simd_ready(model.num_nodes())) simd_apply = detail::simd::link_apply_kernel();
    // p into m_x4; on one thread, y = M p in the same pass (scatter_links' init then skipped).
    if (simd_apply && T <= 1) {
      Scalar* p4 = m_x4.data();
      Scalar* out = y.data();
      for (Index i = 0; i < model.num_nodes(); ++i) {
        const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
        const Scalar m = md * mass[i];
        for (int c = 0; c < 3; ++c) {
          p4[4 * std::ptrdiff_t(i) + c] = pp[k + c];
          out[k + c] = m * pp[k + c];
        }
      }
    } else if (simd_apply && !partitioned) {  // (else each thread its nodes)
      pad_states(pp, nullptr, model.num_nodes());
    }
  }
  const Scalar* p4 = nullptr;  // p padded, for the continuum's edges
  if constexpr (std::is_same_v<Scalar, double>) p4 = simd_apply ? m_x4.data() : nullptr;
  auto kernel_range = [&](Index begin, Index end, Scalar* out) {
    if constexpr (std::is_same_v<Scalar, double>) {
      if (simd_apply) {
        simd_apply(ij, blocks, m_x4.data(), out, begin, end);
        return;
      }
    }
    for (Index l = begin; l < end; ++l) {
      const Scalar* B = blocks + std::ptrdiff_t(implicit_block_size) * l;
      const std::ptrdiff_t i = 3 * std::ptrdiff_t(ij[2 * l]);
      const std::ptrdiff_t j = 3 * std::ptrdiff_t(ij[2 * l + 1]);
      const Scalar dx = pp[j] - pp[i], dy = pp[j + 1] - pp[i + 1], dz = pp[j + 2] - pp[i + 2];
      const Scalar s = B[3] * (B[0] * dx + B[1] * dy + B[2] * dz);
      const Scalar gx = s * B[0] + B[4] * dx, gy = s * B[1] + B[4] * dy, gz = s * B[2] + B[4] * dz;
      out[i] -= gx;
      out[i + 1] -= gy;
      out[i + 2] -= gz;
      out[j] += gx;
      out[j + 1] += gy;
      out[j + 2] += gz;
    }
  };
  // The force links only (the others' blocks are zero).
  auto kernel = [&](Index begin, Index end, Scalar* out) {
    for (const auto& [a, b] : m_force_ranges) {
      const Index lo = std::max(a, begin), hi = std::min(b, end);
      if (lo < hi) kernel_range(lo, hi, out);
    }
  };
  if (T > 1 && !m_continuum.empty()) {
    // Links and elements together on the pool (ContinuumTerm::apply_implicit_phase1-3), then
    // each thread sums its share of the nodes: y = M p + the T buffers.
    const Index n = model.num_nodes(), nl = model.num_links();
    const auto n3 = 3 * std::ptrdiff_t(n);
    auto phase1 = [&](int t, int) {
      if (t >= T) return;
      Scalar* buf = m_scratch[std::size_t(t)].data();
      Scalar* s = m_node_scratch[std::size_t(t)].data();
      std::fill(buf, buf + n3, Scalar(0));
      std::fill(s, s + n, Scalar(0));
      const auto [begin, end] = detail::share(nl, t, T);
      kernel(begin, end, buf);
      m_continuum.apply_implicit_phase1(pp, buf, s, t, T, p4);
    };
    pool->run(phase1);
    auto phase2 = [&](int t, int) {
      if (t >= T) return;
      const auto [begin, end] = detail::share(n, t, T);
      m_continuum.apply_implicit_phase2(m_node_scratch, T, begin, end);
    };
    pool->run(phase2);
    auto phase3 = [&](int t, int) {
      if (t < T) m_continuum.apply_implicit_phase3(m_scratch[std::size_t(t)].data(), t, T, p4);
    };
    pool->run(phase3);
    auto sum = [&](int t, int) {
      if (t >= T) return;
      const auto [begin, end] = detail::share(n, t, T);
      detail::sum_buffers(begin, end, y.data(), m_scratch, T, init);
    };
    pool->run(sum);
  } else if (simd_apply && T <= 1) {  // y = M p above
    kernel(0, model.num_links(), y.data());
    m_continuum.apply_implicit(pp, y.data(), p4);
  } else if (partitioned) {  // (no continuum elements)
    auto nodes = [&](Index begin, Index end) {
      if (simd_apply) pad_state_rows(pp, nullptr, begin, end);  // the p its links read
      for (Index i = begin; i < end; ++i) init(i, y.data() + 3 * std::ptrdiff_t(i));
    };
    detail::scatter_links(*pool, m_partition, y.data(), nodes, kernel);
  } else {
    detail::scatter_links(pool, model.num_nodes(), model.num_links(), y.data(), m_scratch, init,
                          kernel);
    m_continuum.apply_implicit(pp, y.data(), p4);
  }
  for (Index k = 0; k < m_num_contacts; ++k) {
    const PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    if (!(c.normal_block > Scalar(0)) && !(c.tangent_block > Scalar(0))) continue;
    Vector3<Scalar> q = p.row(c.node).transpose();
    if (c.other >= 0) q -= p.row(c.other).transpose();
    const Vector3<Scalar> g =
        c.tangent_block * q + (c.normal_block - c.tangent_block) * c.normal.dot(q) * c.normal;
    y.row(c.node) += g.transpose();
    if (c.other >= 0) y.row(c.other) -= g.transpose();
  }
  for (Index k = 0; k < m_num_held; ++k) {
    const HeldNode<Scalar>& hn = m_held[std::size_t(k)];
    const Scalar h = m_implicit_h;
    y.row(hn.node) += (h * h * hn.stiffness + h * hn.damping) * p.row(hn.node);
  }
  for (const Index i : immobile_nodes()) y.row(i).setZero();
}

template <typename Scalar>
typename ForceModel<Scalar>::SparseMatrix ForceModel<Scalar>::stiffness_matrix(
    const SphereModel<Scalar>& model, JacobianForm form) const {
  const detail::LinkData<Scalar> L(model);
  const Scalar* x = model.positions().data();
  const Scalar* v = model.velocities().data();
  const Index n = model.num_nodes();
  std::vector<Eigen::Triplet<Scalar>> trip;
  trip.reserve(36 * std::size_t(model.num_links()));
  const auto X = model.positions();
  const auto V = model.velocities();
  for (Index l = 0; l < model.num_links(); ++l) {
    if (!m_force_link[std::size_t(l)]) continue;
    const Index i = L.ij[2 * l], j = L.ij[2 * l + 1];
    Matrix3<Scalar> K;
    if (form == JacobianForm::exact) {
      K = L.law(l)
              .jacobian(X.row(i).transpose(), X.row(j).transpose(), V.row(i).transpose(),
                        V.row(j).transpose(), m_options.damping)
              .dx;
    } else {
      const detail::LinkState<Scalar> s = detail::link_state(L, l, x, v, m_options.damping);
      Scalar alpha, beta;
      detail::symmetric_stiffness(s, form, alpha, beta);
      K = alpha * s.n * s.n.transpose() + beta * Matrix3<Scalar>::Identity();
    }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        trip.emplace_back(3 * i + r, 3 * j + c, K(r, c));
        trip.emplace_back(3 * j + r, 3 * i + c, K(r, c));
        trip.emplace_back(3 * i + r, 3 * i + c, -K(r, c));
        trip.emplace_back(3 * j + r, 3 * j + c, -K(r, c));
      }
  }
  // Contacts pushing at this state: -k n n^T between the sphere and the instrument (or the other).
  auto contact_pairs = [&](auto block) {
    for (Index k = 0; k < m_num_contacts; ++k) {
      const PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
      Scalar fn;
      Vector3<Scalar> slip;
      const Scalar adv = detail::surface_advance(c, m_contact_time);
      (void)detail::contact_force(c, x, v, adv, fn, slip);
      if (!(detail::contact_depth(c, x, adv) > Scalar(0))) continue;
      const Matrix3<Scalar> B = block(c, fn, slip);
      for (int r = 0; r < 3; ++r)
        for (int s = 0; s < 3; ++s) {
          trip.emplace_back(3 * c.node + r, 3 * c.node + s, -B(r, s));
          if (c.other >= 0) {
            trip.emplace_back(3 * c.other + r, 3 * c.other + s, -B(r, s));
            trip.emplace_back(3 * c.node + r, 3 * c.other + s, B(r, s));
            trip.emplace_back(3 * c.other + r, 3 * c.node + s, B(r, s));
          }
        }
    }
  };
  contact_pairs([&](const PenaltyContact<Scalar>& c, Scalar, const Vector3<Scalar>&) {
    const Scalar slope = detail::contact_slope(
        c, detail::contact_depth(c, x, detail::surface_advance(c, m_contact_time)));
    return Matrix3<Scalar>(slope * c.stiffness * c.normal * c.normal.transpose());
  });
  for (Index k = 0; k < m_num_held; ++k)
    for (int r = 0; r < 3; ++r)
      trip.emplace_back(3 * m_held[std::size_t(k)].node + r, 3 * m_held[std::size_t(k)].node + r,
                        -m_held[std::size_t(k)].stiffness);
  if (!m_continuum.empty()) {
    detail::ContinuumTerm<Scalar> elements = m_continuum;  // its scratch is used
    {
      // The tangent's state (stiffening, pressures) at this x and v.
      std::vector<Scalar> scratch(3 * std::size_t(n), Scalar(0));
      elements.add_forces(x, model.velocities().data(), scratch.data());
    }
    if (form == JacobianForm::exact) {
      elements.exact_stiffness_triplets(x, trip);
    } else {
      std::vector<Eigen::Triplet<Scalar>> h;
      elements.tangent_triplets(x, h);
      for (const auto& t : h) trip.emplace_back(t.row(), t.col(), -t.value());
    }
  }
  SparseMatrix K(3 * n, 3 * n);
  K.setFromTriplets(trip.begin(), trip.end());
  return K;
}

template <typename Scalar>
typename ForceModel<Scalar>::SparseMatrix ForceModel<Scalar>::damping_matrix(
    const SphereModel<Scalar>& model) const {
  const auto X = model.positions();
  const auto V = model.velocities();
  const auto links = model.links();
  const Index n = model.num_nodes();
  std::vector<Eigen::Triplet<Scalar>> trip;
  trip.reserve(36 * std::size_t(model.num_links()));
  for (Index l = 0; l < model.num_links(); ++l) {
    if (!m_force_link[std::size_t(l)]) continue;
    const Index i = links(l, 0), j = links(l, 1);
    const Matrix3<Scalar> D =
        model.link(l)
            .jacobian(X.row(i).transpose(), X.row(j).transpose(), V.row(i).transpose(),
                      V.row(j).transpose(), m_options.damping)
            .dv;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        trip.emplace_back(3 * i + r, 3 * j + c, D(r, c));
        trip.emplace_back(3 * j + r, 3 * i + c, D(r, c));
        trip.emplace_back(3 * i + r, 3 * i + c, -D(r, c));
        trip.emplace_back(3 * j + r, 3 * j + c, -D(r, c));
      }
  }
  for (Index i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      trip.emplace_back(3 * i + c, 3 * i + c, -m_options.drag * model.masses()[i]);
  if (!m_continuum.empty()) {
    std::vector<Eigen::Triplet<Scalar>> d;
    m_continuum.damping_triplets(model.positions().data(), d);
    for (const auto& t : d) trip.emplace_back(t.row(), t.col(), -t.value());
  }
  // Contacts pushing at this state: -c n n^T - c_t (I - n n^T), c_t the friction's slope at zero
  // slip speed scaled by the regularisation (its linearisation in the implicit step).
  const Scalar* xp = model.positions().data();
  const Scalar* vp = model.velocities().data();
  for (Index k = 0; k < m_num_contacts; ++k) {
    const PenaltyContact<Scalar>& c = m_contacts[std::size_t(k)];
    Scalar fn;
    Vector3<Scalar> slip;
    const Scalar adv = detail::surface_advance(c, m_contact_time);
    (void)detail::contact_force(c, xp, vp, adv, fn, slip);
    if (!(detail::contact_depth(c, xp, adv) > Scalar(0))) continue;
    const Scalar ct = detail::friction_slope(c, fn, slip);
    const Matrix3<Scalar> nn = c.normal * c.normal.transpose();
    const Scalar slope = detail::contact_slope(c, detail::contact_depth(c, xp, adv));
    const Matrix3<Scalar> B = slope * c.damping * nn + ct * (Matrix3<Scalar>::Identity() - nn);
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) {
        trip.emplace_back(3 * c.node + r, 3 * c.node + s, -B(r, s));
        if (c.other >= 0) {
          trip.emplace_back(3 * c.other + r, 3 * c.other + s, -B(r, s));
          trip.emplace_back(3 * c.node + r, 3 * c.other + s, B(r, s));
          trip.emplace_back(3 * c.other + r, 3 * c.node + s, B(r, s));
        }
      }
  }
  for (Index k = 0; k < m_num_held; ++k)
    for (int r = 0; r < 3; ++r)
      trip.emplace_back(3 * m_held[std::size_t(k)].node + r, 3 * m_held[std::size_t(k)].node + r,
                        -m_held[std::size_t(k)].damping);
  SparseMatrix D(3 * n, 3 * n);
  D.setFromTriplets(trip.begin(), trip.end());
  return D;
}

}  // namespace fsm
