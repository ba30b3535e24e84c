#pragma once

// Definitions of ForceModel's members; included at the bottom of fsm/force_model.hpp.

#include <algorithm>
#include <cmath>

#include "fsm/detail/parallel.hpp"

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

}  // namespace detail

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
  m_inverse_mass.resize(n);
  // Worst case: every other link active.
  m_ranges.reserve(std::size_t(model.num_links()) / 2 + 2);
  update_mobility(model);
  resize_scratch();
}

template <typename Scalar>
void ForceModel<Scalar>::update_mobility(const SphereModel<Scalar>& model) noexcept {
  const auto mass = model.masses();
  const auto fixed = model.fixed();
  for (Index i = 0; i < m_num_nodes; ++i) {
    m_immobile[std::size_t(i)] = (fixed[i] || m_asleep[std::size_t(i)]) ? 1 : 0;
    m_inverse_mass[i] = m_immobile[std::size_t(i)] ? Scalar(0) : Scalar(1) / mass[i];
  }
  m_ranges.clear();
  const auto links = model.links();
  const Index L = model.num_links();
  for (Index l = 0; l < L;) {
    while (l < L && m_immobile[std::size_t(links(l, 0))] && m_immobile[std::size_t(links(l, 1))])
      ++l;
    const Index begin = l;
    while (l < L && !(m_immobile[std::size_t(links(l, 0))] && m_immobile[std::size_t(links(l, 1))]))
      ++l;
    if (l > begin) m_ranges.emplace_back(begin, l);
  }
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
  m_options = options;
  resize_scratch();
}

template <typename Scalar>
void ForceModel<Scalar>::resize_scratch() {
  const int extra = std::max(0, std::min(m_options.threads, detail::max_threads()) - 1);
  m_scratch.resize(std::size_t(extra));
  for (auto& s : m_scratch) s.assign(3 * std::size_t(m_num_nodes), Scalar(0));
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
  auto kernel_range = [&](Index begin, Index end, Scalar* out) {
    using DM = DampingModel;
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
  detail::scatter_links(m_options.threads, model.num_nodes(), model.num_links(), f.data(),
                        m_scratch, init, kernel);
}

template <typename Scalar>
Scalar ForceModel<Scalar>::elastic_energy(const SphereModel<Scalar>& model,
                                          const ConstPositionsRef& x) const noexcept {
  const detail::LinkData<Scalar> L(model);
  const Scalar* p = x.data();
  Scalar sum(0);
  for (Index l = 0; l < model.num_links(); ++l) {
    const std::ptrdiff_t i = 3 * std::ptrdiff_t(L.ij[2 * l]);
    const std::ptrdiff_t j = 3 * std::ptrdiff_t(L.ij[2 * l + 1]);
    const Scalar dx = p[j] - p[i], dy = p[j + 1] - p[i + 1], dz = p[j + 2] - p[i + 2];
    sum += L.law(l).energy(std::sqrt(dx * dx + dy * dy + dz * dz) - L.rest[l]);
  }
  return sum;
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
void ForceModel<Scalar>::prepare_implicit(const SphereModel<Scalar>& model, Scalar h,
                                          JacobianForm form, Scalar* blocks, PositionsRef rhs,
                                          PositionsRef diagonal) noexcept {
  const detail::LinkData<Scalar> L(model);
  const Scalar* mass = model.masses().data();
  const Scalar* ext = m_external.data();
  const Scalar* x = model.positions().data();
  const Scalar* v = model.velocities().data();
  const Vector3<Scalar> g = m_options.gravity;
  const DampingModel dm = m_options.damping;
  const Scalar h2 = h * h;
  m_implicit_h = h;  // apply_implicit() needs it for the drag term
  // rhs = h F + h^2 K v, and the per-link blocks B = h D + h^2 K = a n n^T + b I.
  const Scalar drag = m_options.drag;
  auto init = [&](Index i, Scalar* out) {
    const std::ptrdiff_t k = 3 * std::ptrdiff_t(i);
    for (int c = 0; c < 3; ++c) out[c] = h * (mass[i] * (g[c] - drag * v[k + c]) + ext[k + c]);
  };
  auto kernel = [&](Index begin, Index end, Scalar* out) {
    for (Index l = begin; l < end; ++l) {
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
  detail::scatter_links(m_options.threads, model.num_nodes(), model.num_links(), rhs.data(),
                        m_scratch, init, kernel);
  // Jacobi diagonal: m_i + sum over links of diag(B_l), on both ends.
  // The drag's Jacobian -gamma m I joins the mass: M (1 + h gamma).
  auto init_diag = [&](Index i, Scalar* out) {
    out[0] = out[1] = out[2] = mass[i] * (1 + h * drag);
  };
  auto kernel_diag = [&](Index begin, Index end, Scalar* out) {
    for (Index l = begin; l < end; ++l) {
      const Scalar* B = blocks + std::ptrdiff_t(implicit_block_size) * l;
      const std::ptrdiff_t i = 3 * std::ptrdiff_t(L.ij[2 * l]);
      const std::ptrdiff_t j = 3 * std::ptrdiff_t(L.ij[2 * l + 1]);
      for (int c = 0; c < 3; ++c) {
        const Scalar d = B[3] * B[c] * B[c] + B[4];
        out[i + c] += d;
        out[j + c] += d;
      }
    }
  };
  detail::scatter_links(m_options.threads, model.num_nodes(), model.num_links(), diagonal.data(),
                        m_scratch, init_diag, kernel_diag);
  for (Index i = 0; i < model.num_nodes(); ++i) {
    if (m_immobile[std::size_t(i)]) {
      rhs.row(i).setZero();
      diagonal.row(i).setOnes();
    }
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
  auto kernel = [&](Index begin, Index end, Scalar* out) {
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
  detail::scatter_links(m_options.threads, model.num_nodes(), model.num_links(), y.data(),
                        m_scratch, init, kernel);
  for (Index i = 0; i < model.num_nodes(); ++i)
    if (m_immobile[std::size_t(i)]) y.row(i).setZero();
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
  SparseMatrix D(3 * n, 3 * n);
  D.setFromTriplets(trip.begin(), trip.end());
  return D;
}

}  // namespace fsm
