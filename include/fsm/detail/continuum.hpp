#pragma once

// The continuum law's element term (docs/physics.md section 11), owned by ForceModel: neo-Hookean
// elasticity on the tetrahedra of the regions that use ForceLaw::continuum,
//
//   E = sum_T V_T W_dev(F_T) + sum_a V_a U(J_a),
//   W_dev = C10 (I1 g(J) - 3)             (g = J^-2/3, extended below J_min; bilinear: below),
//   U(J) = (K / 2) (J - 1)^2,             J_a = v_a / V_a, v_a = sum_{T at a} v_T / 4,
//
// (CalculiX's NEO HOOKE with C10 = mu / 2 and D1 = 2 / K: the deviatoric part per element, the
// volumetric part on nodal-averaged volume ratios, Bonet and Burton 1998, so that nearly
// incompressible tissue does not lock), with Voigt viscosity on the strain rate: a viscous
// pressure tau K dJ_a/dt and, for the deviatoric part, dashpots tau k_e along the element edges.
//
// The implicit solve's tangent is positive semi-definite by construction. Deviatoric part: springs
// k_e along the current edges (k_e = (5/2) mu sum V_T / l_e^2, the network whose shear modulus is
// mu), each element's share scaled by its state (bilinear stiffening, g(J), pressure); an element
// too poorly shaped for springs along its edges to stand for it (a sliver: its apex moves across
// its base, which no edge resists), or too strongly strained, gets instead the exact-shape
// corotated element tangent c V |sym(Q^T dF)|^2 (Q the rotation of F). Volumetric part: the
// Gauss-Newton term sum_a (K / V_a) grad v_a grad v_a^T; the indefinite term with U' d2v (the
// pressure's geometric stiffness) is represented by its size alone, in the element's deviatoric
// share. The forces are exact; only the tangent approximates. Nothing here allocates after
// refresh(), and nothing throws in the per-step functions.

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "fsm/detail/parallel.hpp"
#include "fsm/detail/reserved_vector.hpp"
#include "fsm/detail/simd_links.hpp"
#include "fsm/detail/simd_tets.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/types.hpp"

namespace fsm {

/// How the continuum law measures the deviatoric strain (docs/physics.md section 11).
enum class StrainSmoothing : std::uint8_t {
  /// Each tetrahedron's own F (the linear tetrahedron: too stiff in bending and shear at the
  /// spacings a real-time model can afford).
  element,
  /// F averaged, by rest volume, over the two tetrahedra at each interior face (face-based strain
  /// smoothing, Nguyen-Thoi et al. 2009): the deviatoric energy lives on the faces' domains, each
  /// a quarter of its two elements, so every element couples to its four neighbours' strains. The
  /// same nodes, the same number of unknowns; softer and closer to the continuum.
  face,
  /// F averaged over the tetrahedra around each edge, on a sixth of each (edge-based smoothing,
  /// ES-FEM-T4): softer than face.
  edge,
  /// F averaged over the tetrahedra around each node, on a quarter of each (node-based smoothing,
  /// NS-FEM, as the volumetric part already is): the softest; alone it has soft local modes that
  /// a point load finds, which the element share (ForceModel::Options::smoothing_element_share)
  /// stabilises.
  node,
};

/// @brief Name of a StrainSmoothing ("element", "face", "edge", "node").
[[nodiscard]] inline const char* to_string(StrainSmoothing s) noexcept {
  switch (s) {
    case StrainSmoothing::face:
      return "face";
    case StrainSmoothing::edge:
      return "edge";
    case StrainSmoothing::node:
      return "node";
    default:
      return "element";
  }
}

}  // namespace fsm

namespace fsm::detail {

/// x^{-2/3} for a positive, finite, normal x. For double: a seed from the exponent bits, three
/// Newton steps on y^{-3} = x and one on g^{-3} = x^2 (quadratic convergence; within 1e-15 of
/// 1 / cbrt(x^2) over 1e-3 to 1e3 and exact at 1, tested), about half the cost of libm's cbrt and
/// a division, which took a tenth of the continuum law's step. Other types use std::cbrt.
template <typename Scalar>
inline Scalar inverse_cbrt_squared(Scalar x) noexcept {
  if constexpr (std::is_same_v<Scalar, double>) {
    // Halving-and-thirding the exponent: the bits of x^{-1/3} are about K - bits(x) / 3.
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    bits = std::uint64_t(0x553ef0ff289dd796ULL) - bits / 3;
    double y;
    std::memcpy(&y, &bits, sizeof y);
    for (int k = 0; k < 3; ++k) y *= (4.0 - x * y * y * y) * (1.0 / 3.0);
    // A last step on g = y^2 itself (g^3 x^2 = 1), as a small correction: exact at x = 1, so an
    // element at rest has exactly zero energy.
    const double g = y * y;
    return g + g * (1.0 - x * x * g * g * g) * (1.0 / 3.0);
  } else {
    return Scalar(1) / std::cbrt(x * x);
  }
}

/// g(J) = J^{-2/3} for J >= J_min and its second-order Taylor extension below, which is positive
/// for every J (its discriminant is negative): the energy stays finite and keeps pushing an
/// inverted element back. Returns g and dg/dJ.
template <typename Scalar>
inline void volume_factor(Scalar J, Scalar j_min, Scalar& g, Scalar& dg) noexcept {
  if (J >= j_min) {
    g = inverse_cbrt_squared(J);
    dg = Scalar(-2) / Scalar(3) * g / J;
    return;
  }
  const Scalar g0 = inverse_cbrt_squared(j_min);
  const Scalar g1 = Scalar(-2) / Scalar(3) * g0 / j_min;
  const Scalar g2 = Scalar(10) / Scalar(9) * g0 / (j_min * j_min);
  const Scalar t = J - j_min;
  g = g0 + t * (g1 + Scalar(0.5) * g2 * t);
  dg = g1 + g2 * t;
}

/// The cofactor matrix of F (J F^{-T}, defined for any F).
template <typename Scalar>
inline Matrix3<Scalar> cofactor(const Matrix3<Scalar>& F) noexcept {
  Matrix3<Scalar> c;
  c.col(0) = F.col(1).cross(F.col(2));
  c.col(1) = F.col(2).cross(F.col(0));
  c.col(2) = F.col(0).cross(F.col(1));
  return c;
}

/// The rotation of F for a tangent: two Newton steps of the polar decomposition
/// (X <- (X + X^-T) / 2, X^-T = cof(X) / det X) from F. Each step keeps F's singular vectors and
/// takes its singular values s to (s + 1/s) / 2, so after two they are within 3 % of 1 for s in
/// [0.5, 2] (exact rotations are not needed by a tangent; a reflection for an inverted element is
/// fine). The identity for a degenerate F.
template <typename Scalar>
inline Matrix3<Scalar> tangent_rotation(const Matrix3<Scalar>& F) noexcept {
  Matrix3<Scalar> X = F;
  for (int k = 0; k < 2; ++k) {
    const Matrix3<Scalar> c = cofactor(X);
    const Scalar det = X.col(0).dot(c.col(0));
    if (!(std::abs(det) > std::numeric_limits<Scalar>::min()) || !std::isfinite(det))
      return Matrix3<Scalar>::Identity();
    X = Scalar(0.5) * (X + c / det);
  }
  return X.allFinite() ? X : Matrix3<Scalar>::Identity();
}

/// Deviatoric energy density and its first Piola-Kirchhoff stress for one element.
/// c10: C10 (Pa); c10_large: C10 beyond the switch (0 = linear); q_switch: I1bar - 3 at the
/// switch. The bilinear pair as the link law has it (force continuous, stiffness E then E_L):
/// with s = sqrt(q / 3), about the uniaxial strain (q ~ 3 eps^2),
///   W = C10 q + 3 (C10_L - C10) (s - s_switch)^2   beyond the switch,
/// whose stress is continuous and whose uniaxial stiffness goes from E to E_L at the switch.
/// `stiffening` gets the ratio of the incremental stiffness to the small-strain one (C10_L / C10
/// beyond the switch, else 1), for the implicit tangent.
template <typename Scalar>
inline Scalar deviatoric(const Matrix3<Scalar>& F, Scalar c10, Scalar c10_large, Scalar q_switch,
                         Scalar j_min, Matrix3<Scalar>* P, Scalar* stiffening = nullptr,
                         Scalar* volume_factor_out = nullptr,
                         Scalar* distortion_out = nullptr) noexcept {
  const Matrix3<Scalar> cof = cofactor(F);
  const Scalar J = F.col(0).dot(cof.col(0));
  const Scalar I1 = F.squaredNorm();
  Scalar g, dg;
  volume_factor(J, j_min, g, dg);
  if (volume_factor_out) *volume_factor_out = g;
  const Scalar q = I1 * g - Scalar(3);
  if (distortion_out) *distortion_out = q;
  Scalar W, slope;  // slope = dW/dq
  if (c10_large > Scalar(0) && q > q_switch) {
    const Scalar s = std::sqrt(q / Scalar(3)), ss = std::sqrt(q_switch / Scalar(3));
    W = c10 * q + Scalar(3) * (c10_large - c10) * (s - ss) * (s - ss);
    slope = c10 + (c10_large - c10) * (Scalar(1) - ss / s);
    if (stiffening) *stiffening = c10_large / c10;
  } else {
    W = c10 * q;
    slope = c10;
    if (stiffening) *stiffening = Scalar(1);
  }
  // d(I1 g)/dF = 2 g F + I1 g' dJ/dF, dJ/dF = cof(F).
  if (P) *P = slope * (Scalar(2) * g * F + I1 * dg * cof);
  return W;
}

/// Copies n nodes' rows of 3 into rows of 4 (the SIMD kernels' layout; the fourth entry is left
/// as it is).
template <typename Scalar>
inline void pad_rows4(const Scalar* a, Index n, Scalar* a4) noexcept {
  for (Index i = 0; i < n; ++i)  // (one 16- and one 8-byte move a node, not three of 8)
    std::memcpy(a4 + 4 * std::ptrdiff_t(i), a + 3 * std::ptrdiff_t(i), 3 * sizeof(Scalar));
}

/// The element term: rest data, per-step scratch, forces, energy and the implicit tangent.
template <typename Scalar>
class ContinuumTerm {
 public:
  /// The implicit tangent's edge springs are this many times the network whose shear modulus is
  /// mu (their damping is exact). The springs approximate the deviatoric Hessian, which is stiffer
  /// than them in some modes (under large strain, near a stiff contact); the linearised step of a
  /// mode of true stiffness k with tangent k_t is stable only while h^2 k / m < 4 + 2 h^2 k_t / m,
  /// so a tangent at least half the true stiffness keeps every step stable. Measured: a 5 mm ball
  /// pressed 1 mm into a 1 mm lattice diverges at h = 2 ms with a margin of 1 and is stable to
  /// 5 ms with 2 (docs/physics.md section 11). The equilibrium does not depend on it: the forces
  /// are exact.
  static constexpr Scalar tangent_margin = Scalar(2);
  /// Below this volume ratio an element's deviatoric energy uses the extension of J^{-2/3}.
  static constexpr double j_min = 0.2;
  /// Default of element_tangent_quality(): elements of shape quality below this get the element
  /// tangent (about 1 % of the elements Mesh_3 makes, docs/physics.md section 11).
  static constexpr double default_element_tangent_quality = 0.3;
  /// An element strained past this also gets the element tangent for the step: I1bar - 3 (0.5 in
  /// an isochoric stretch of 1.55 or a compression to 0.61) or |J - 1|. Springs along the edges of
  /// a strongly distorted element miss much of its stiffness (an ovary hanging by a ligament chain
  /// is stretched 2-4.5 times next to the attachment). A trade measured on 2026-11-25
  /// (docs/physics.md section 11): at 0.2 the sagging VHF pelvis needs 22 solver iterations a step
  /// (at 1.0: 38) but the validation's bonded compression twice as many as without it.
  static constexpr double element_tangent_strain = 0.5;
  /// An element whose volume ratio J moves by more than this from one implicit step to the next,
  /// in alternating directions over three successive steps (two reversals), is fluttering: its
  /// edge springs let the step overshoot a mode they do not carry, and the step swings it back
  /// and forth at the step's own frequency, which a stable implicit step never produces. Such an
  /// element gets the element tangent from then on (until refresh()). Found on the VHF left
  /// adnexa: one element of shape quality 0.465 (the threshold is 0.3) seeded a period-2 swing of
  /// J between 0.96 and 1.0 in about 50 elements, held for as long as the run lasted and taking
  /// 2.4 times the solver iterations (docs/physics.md section 11).
  static constexpr double flutter_change = 1e-3;
  /// Default of set_smoothing()'s element share.
  static constexpr double default_element_share = 0.1;

  /// The cube of a tetrahedron's root-mean-square edge length, from its edge matrix.
  [[nodiscard]] static Scalar rms_edge_cubed(const Matrix3<Scalar>& Dm) noexcept {
    const Scalar l2 =
        (Dm.col(0).squaredNorm() + Dm.col(1).squaredNorm() + Dm.col(2).squaredNorm() +
         (Dm.col(1) - Dm.col(0)).squaredNorm() + (Dm.col(2) - Dm.col(0)).squaredNorm() +
         (Dm.col(2) - Dm.col(1)).squaredNorm()) /
        Scalar(6);
    return l2 * std::sqrt(l2);
  }
  /// The shape quality of a tetrahedron: 6 sqrt(2) V / l_rms^3 (1 for a regular one, 0 for a
  /// flat one; negative when inverted).
  [[nodiscard]] static Scalar shape_quality(const Matrix3<Scalar>& Dm) noexcept {
    const Scalar l3 = rms_edge_cubed(Dm);
    return l3 > Scalar(0) ? Scalar(std::sqrt(2.0)) * Dm.determinant() / l3 : Scalar(0);
  }

  /// The edge spring of the tangent (before tangent_margin): the network whose shear modulus is
  /// mu, each element's share scaled by its state at the last add_forces() (m_state_factor and
  /// its pressure), and without the elements that have the element tangent.
  [[nodiscard]] Scalar edge_stiffness(std::size_t e) const noexcept {
    Scalar k(0);
    for (Index s = m_edge_part_start[e]; s < m_edge_part_start[e + 1]; ++s)
      k += m_edge_factor[std::size_t(m_edge_part_element[std::size_t(s)])] *
           m_edge_part_k[std::size_t(s)];
    return k;
  }

  /// Elements whose shape quality (shape_quality()) is below `q` get the exact-shape element
  /// tangent instead of edge springs: 0 = none, above 1 = all (each costs about five times its
  /// edge springs per iteration). Allocates; not real-time.
  void set_element_tangent_quality(Scalar q) {
    ++m_generation;
    m_element_tangent_quality = q;
    const std::size_t nt = m_quality.size();
    m_poor_shape.assign(nt, 0);
    for (std::size_t t = 0; t < nt; ++t) m_poor_shape[t] = m_quality[t] < q ? 1 : 0;
    // Which elements have it is decided at every add_forces() (poor shape, strain or flutter):
    // room for all.
    m_element_tangent = m_poor_shape;
    // (refresh() sizes the per-element state before it calls this.)
    m_edge_factor.assign(nt, Scalar(0));
    for (std::size_t t = 0; t < nt; ++t)
      if (!m_element_tangent[t] && !m_removed[t])
        m_edge_factor[t] =
            m_state_factor[t] + m_pressure_share[t] * std::abs(m_pressure[t]) / m_c10[t];
    m_dense.clear();
    m_dense.reserve(nt);
    m_dense_rotation.assign(9 * nt, Scalar(0));
    m_dense_coefficient.assign(nt, Scalar(0));
  }
  [[nodiscard]] Scalar element_tangent_quality() const noexcept {
    return m_element_tangent_quality;
  }
  /// The elements that have the element tangent at the last add_forces(): those of poor shape,
  /// those strained past element_tangent_strain and those found fluttering (flutter_change).
  [[nodiscard]] std::size_t num_element_tangents() const noexcept { return m_dense.size(); }
  /// Whether apply_implicit() runs the volumetric product on the pair kernels (given p padded to
  /// four): the CPU has them and the pairs are those of the last prepare_implicit().
  [[nodiscard]] bool pair_product_ready() const noexcept {
    if constexpr (std::is_same_v<Scalar, double>)
      return !empty() && simd_active() && m_pair_generation == m_generation &&
             simd::pair_spread_kernel() && simd::pair_gather_kernel();
    return false;
  }
  /// The elements found fluttering (flutter_change) since the last refresh(): they keep the
  /// element tangent.
  [[nodiscard]] std::size_t num_fluttered() const noexcept { return m_num_fluttered; }
  /// Makes the next add_forces() watch each element's J for flutter (flutter_change): the
  /// implicit step calls it once per step, before its first force evaluation. No allocation.
  void watch_next_forces() noexcept { m_watch = m_flutter_guard; }
  /// Saves the flutter watch's state (each element's last watched J, its change, the reversals in
  /// a row and the flags) for restore_watch(): a watched force evaluation at a state that may not
  /// start a step (ForceModel::elastic_energy_keeping_forces) must leave no trace if it does not.
  /// No allocation.
  void save_watch() noexcept {
    m_saved_step_j = m_step_j;  // the same sizes: no allocation
    m_saved_step_dj = m_step_dj;
    m_saved_reversals = m_reversals;
    m_saved_fluttered = m_fluttered;
    m_saved_num_fluttered = m_num_fluttered;
  }
  /// Puts back what save_watch() saved (the next add_forces() sees the flags as they were).
  void restore_watch() noexcept {
    ++m_generation;
    m_step_j = m_saved_step_j;
    m_step_dj = m_saved_step_dj;
    m_reversals = m_saved_reversals;
    m_fluttered = m_saved_fluttered;
    m_num_fluttered = m_saved_num_fluttered;
  }
  /// Whether watch_next_forces() watches (default true). Off also forgets the elements found
  /// fluttering. No allocation.
  void set_flutter_guard(bool on) noexcept {
    ++m_generation;
    m_flutter_guard = on;
    if (on) return;
    std::fill(m_fluttered.begin(), m_fluttered.end(), std::uint8_t(0));
    std::fill(m_reversals.begin(), m_reversals.end(), std::uint8_t(0));
    m_num_fluttered = 0;
    m_watch = false;
  }

  /// Rebuilds everything from the model's continuum regions (allocates; not real-time).
  void refresh(const SphereModel<Scalar>& model) {
    ++m_generation;
    m_tets.clear();
    m_dm_inv.clear();
    m_volume.clear();
    m_quality.clear();
    m_pressure_share.clear();
    m_c10.clear();
    m_c10_large.clear();
    m_q_switch.clear();
    m_element_tet.clear();
    const Index n = model.num_nodes();
    m_num_nodes = n;
    m_node_volume.assign(std::size_t(n), Scalar(0));
    m_node_bulk.assign(std::size_t(n), Scalar(0));
    m_node_tau.assign(std::size_t(n), Scalar(0));
    const auto x = model.rest_positions();
    const auto tets = model.tetrahedra();
    const auto region = model.node_regions();
    // (i, j, V / l^2, region, element)
    std::vector<std::tuple<Index, Index, Scalar, Index, Index>> edges;
    for (Index t = 0; t < model.num_tetrahedra(); ++t) {
      const Index r = region[tets(t, 0)];
      const Region<Scalar>& reg = model.region(r);
      if (reg.law != ForceLaw::continuum) continue;
      const Material<Scalar>& mat = reg.material;
      Matrix3<Scalar> Dm;
      for (int k = 0; k < 3; ++k)
        Dm.col(k) = (x.row(tets(t, k + 1)) - x.row(tets(t, 0))).transpose();
      const Scalar V = Dm.determinant() / Scalar(6);
      const Matrix3<Scalar> inv = Dm.inverse();
      for (int k = 0; k < 4; ++k) m_tets.push_back(tets(t, k));
      m_element_tet.push_back(t);
      for (int k = 0; k < 9; ++k) m_dm_inv.push_back(inv(k % 3, k / 3));  // column-major
      m_volume.push_back(V);
      m_quality.push_back(shape_quality(Dm));
      // The pressure's geometric stiffness p d2v_T against the element's edge springs: d2v_T has
      // entries of about l / 6, a share (5/2) mu V / l^2 (edge_stiffness(): p l^3 / (30 C10 V)).
      m_pressure_share.push_back(rms_edge_cubed(Dm) / (Scalar(30) * V));
      const Scalar mu = mat.shear_modulus();
      m_c10.push_back(mu / Scalar(2));
      const Index element = Index(m_volume.size()) - 1;
      if (mat.is_bilinear()) {
        // The bilinear pair as a stiffening of the deviatoric energy (deviatoric()): E_L / E times
        // larger where I1bar - 3 passes its value in uniaxial stretch at the switch strain.
        const Scalar s = Scalar(1) + mat.switch_strain;
        m_c10_large.push_back(mu / Scalar(2) * mat.large_strain_modulus / mat.youngs_modulus);
        m_q_switch.push_back(s * s + Scalar(2) / s - Scalar(3));
      } else {
        m_c10_large.push_back(Scalar(0));
        m_q_switch.push_back(Scalar(0));
      }
      for (int k = 0; k < 4; ++k) {
        const auto a = std::size_t(tets(t, k));
        m_node_volume[a] += V / Scalar(4);
        m_node_bulk[a] = mat.bulk_modulus();
        m_node_tau[a] = mat.retardation_time();
      }
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) {
          Index p = tets(t, a), q = tets(t, b);
          if (p > q) std::swap(p, q);
          const Scalar l2 = (x.row(q) - x.row(p)).squaredNorm();
          edges.emplace_back(p, q, V / l2, r, element);
        }
    }
    std::sort(edges.begin(), edges.end(), [](const auto& u, const auto& w) {
      return std::tie(std::get<0>(u), std::get<1>(u)) < std::tie(std::get<0>(w), std::get<1>(w));
    });
    m_edges.clear();
    m_edge_k.clear();
    m_edge_tau.clear();
    m_edge_part_start.assign(1, 0);
    m_edge_part_element.clear();
    m_edge_part_k.clear();
    for (std::size_t k = 0; k < edges.size();) {
      const auto [p, q, w0, r, t0] = edges[k];
      const Material<Scalar>& pm = model.region(r).material;
      Scalar w(0);
      for (; k < edges.size() && std::get<0>(edges[k]) == p && std::get<1>(edges[k]) == q; ++k) {
        w += std::get<2>(edges[k]);
        m_edge_part_element.push_back(std::get<4>(edges[k]));
        m_edge_part_k.push_back(Scalar(2.5) * pm.shear_modulus() * std::get<2>(edges[k]));
      }
      m_edge_part_start.push_back(Index(m_edge_part_element.size()));
      (void)w0;
      (void)t0;
      const Material<Scalar>& mat = model.region(r).material;
      m_edges.push_back(p);
      m_edges.push_back(q);
      m_edge_k.push_back(Scalar(2.5) * mat.shear_modulus() * w);
      m_edge_tau.push_back(mat.retardation_time());
    }
    const std::size_t nt = m_volume.size();
    m_edge_k_whole = m_edge_k;
    m_removed.assign(nt, 0);
    m_state_factor.assign(nt, Scalar(1));
    m_pressure.assign(nt, Scalar(0));
    m_step_j.assign(nt, Scalar(1));
    m_step_dj.assign(nt, Scalar(0));
    m_reversals.assign(nt, 0);
    m_fluttered.assign(nt, 0);
    m_num_fluttered = 0;
    save_watch();  // sizes the saved copy
    m_watch = false;
    set_element_tangent_quality(m_element_tangent_quality);
    m_edge_block.assign(std::size_t(edge_block_size) * num_edges(), Scalar(0));
    m_edge_rate.assign(num_edges(), Scalar(0));
    m_edge_weight.assign(num_edges(), Scalar(0));
    m_node_coefficient.assign(std::size_t(n), Scalar(0));
    m_node_rate.assign(std::size_t(n), Scalar(0));
    m_node_blocks.assign(6 * std::size_t(n), Scalar(0));
    m_node_scratch.assign(std::size_t(n), Scalar(0));
    m_energy_scratch.assign(std::size_t(n), Scalar(0));  // energy() reuses it without growing
    m_node_volume_whole = m_node_volume;
    // Each element's six (edge, share) pairs and each model tetrahedron's element, for remove().
    m_tet_element.assign(std::size_t(model.num_tetrahedra()), -1);
    for (std::size_t t = 0; t < nt; ++t) m_tet_element[std::size_t(m_element_tet[t])] = Index(t);
    m_element_edge.assign(12 * nt, 0);
    {
      std::vector<int> filled(nt, 0);
      for (std::size_t e = 0; e < num_edges(); ++e)
        for (Index p = m_edge_part_start[e]; p < m_edge_part_start[e + 1]; ++p) {
          const auto t = std::size_t(m_edge_part_element[std::size_t(p)]);
          const std::size_t slot = 12 * t + 2 * std::size_t(filled[t]++);
          m_element_edge[slot] = Index(e);
          m_element_edge[slot + 1] = p;
        }
    }
    m_node_count.assign(std::size_t(n), 0);
    m_edge_count.assign(num_edges(), 0);
    apply_topology(model.tetrahedron_intact().data());
    build_batches();
    build_domains();
    build_pairs();
  }

  /// How the deviatoric strain is measured (StrainSmoothing; default element) and, when it is
  /// smoothed, the share `element_share` in [0, 1] of the deviatoric energy kept on each
  /// element's own strain: W = (1 - share) sum_d V_d W(F_d) + share sum_T V_T W(F_T). The
  /// element's share stabilises the smoothed strains' soft local modes (node smoothing alone
  /// lets a point load through: docs/physics.md section 11). Allocates (the domains); not
  /// real-time.
  void set_smoothing(StrainSmoothing s, Scalar element_share = Scalar(default_element_share)) {
    ++m_generation;
    m_element_share = std::clamp(element_share, Scalar(0), Scalar(1));
    if (s == m_smoothing) return;
    m_smoothing = s;
    build_domains();
  }
  [[nodiscard]] StrainSmoothing smoothing() const noexcept { return m_smoothing; }
  [[nodiscard]] Scalar smoothing_element_share() const noexcept { return m_element_share; }
  /// The smoothing domains: per face, edge or node (StrainSmoothing), the elements of one
  /// material around it; none for StrainSmoothing::element.
  [[nodiscard]] std::size_t num_domains() const noexcept { return m_domain_start.size() - 1; }

  /// Whether add_forces() and energy() run the element kernels on SIMD registers where the CPU
  /// has them (default true; the scalar loops are the reference).
  void set_simd(bool on) noexcept {
    m_simd = on;
    ++m_generation;
  }
  /// Whether the next add_forces() and energy() run the element kernels.
  [[nodiscard]] bool simd_active() const noexcept {
    if constexpr (std::is_same_v<Scalar, double>)
      return m_simd && !m_batch_rest.empty() && simd::tet_force_kernel() != nullptr;
    return false;
  }

  /// Takes the given model tetrahedra out (those of continuum regions not out already), updating
  /// the nodes' volumes and the edges' springs by what each removes: O(removed), no allocation.
  void remove(const Index* tets, std::size_t count) noexcept {
    ++m_generation;
    for (std::size_t k = 0; k < count; ++k) {
      const Index t = tets[k];
      if (t < 0 || std::size_t(t) >= m_tet_element.size()) continue;
      const Index e = m_tet_element[std::size_t(t)];
      if (e >= 0) remove_element(std::size_t(e));
    }
  }

  /// Makes the elements what the model says (`intact`: per model tetrahedron, 0 = removed): from
  /// the whole term, every removed one taken out as remove() does. A removed element carries no
  /// force, its volume leaves its nodes' volumes and its share leaves its edges' springs and
  /// dashpots. No allocation.
  void apply_topology(const std::uint8_t* intact) noexcept {
    ++m_generation;
    std::fill(m_removed.begin(), m_removed.end(), std::uint8_t(0));
    std::copy(m_node_volume_whole.begin(), m_node_volume_whole.end(), m_node_volume.begin());
    std::copy(m_edge_k_whole.begin(), m_edge_k_whole.end(), m_edge_k.begin());
    std::fill(m_node_count.begin(), m_node_count.end(), Index(0));
    for (const Index a : m_tets) ++m_node_count[std::size_t(a)];
    for (std::size_t e = 0; e < num_edges(); ++e)
      m_edge_count[e] = m_edge_part_start[e + 1] - m_edge_part_start[e];
    for (std::size_t t = 0; t < m_volume.size(); ++t)
      if (!intact[m_element_tet[t]]) remove_element(t);
  }

  [[nodiscard]] bool empty() const noexcept { return m_volume.empty(); }
  /// sum over elements of 6 C10 V (about E V, J): the energy scale of a unit strain.
  [[nodiscard]] Scalar energy_scale() const noexcept {
    Scalar s(0);
    for (std::size_t t = 0; t < m_volume.size(); ++t)
      if (!m_removed[t]) s += Scalar(6) * m_c10[t] * m_volume[t];
    return s;
  }
  [[nodiscard]] Index num_elements() const noexcept { return Index(m_volume.size()); }
  [[nodiscard]] std::size_t num_edges() const noexcept { return m_edge_k.size(); }

  /// Adds the elastic and (unless `viscous` is false) viscous forces at (x, v) (N) to f (all
  /// `|V| x 3`, row-major). Keeps the elements' volume gradients at x for apply_implicit().
  /// `x4`, `v4`: x and v already padded to four per node (the caller's, for the SIMD kernels;
  /// optional: else the term pads its own copies).
  void add_forces(const Scalar* x, const Scalar* v, Scalar* f, bool viscous = true,
                  const Scalar* x4 = nullptr, const Scalar* v4 = nullptr) noexcept {
    ++m_generation;
    if (empty()) {
      m_forces_energy = Scalar(0);
      m_forces_inverted = 0;
      return;
    }
    Scalar* volume_now = m_node_scratch.data();  // current nodal volumes, then pressures
    Scalar* rate = m_node_rate.data();           // d(nodal volume)/dt
    std::fill(volume_now, volume_now + m_num_nodes, Scalar(0));
    std::fill(rate, rate + m_num_nodes, Scalar(0));
    const std::size_t nt = m_volume.size();
    m_dense.clear();
    // x and v padded to four per node for the kernels (the edges' kernel needs them even where the
    // element kernel does not run), unless the caller gave them padded.
    if constexpr (std::is_same_v<Scalar, double>)
      if (simd_active()) {
        if (!x4) {
          pad_rows4(x, m_num_nodes, m_x4.data());
          x4 = m_x4.data();
        }
        if (viscous && !v4) {
          pad_rows4(v, m_num_nodes, m_v4.data());
          v4 = m_v4.data();
        }
      }
    // Pass 1: deviatoric forces; current volumes and their rates scattered to the nodes. The
    // per-element work on the SIMD kernel where there is one (into m_batch_out and m_batch_grad),
    // else here.
    bool kernel;
    if (m_smoothing != StrainSmoothing::element) {
      // The element share's forces, the gradients, volumes and rates on the kernel where there is
      // one; the smoothed part added to its outputs.
      const bool element_kernel =
          m_element_share > Scalar(0) && run_force_kernel(x4, viscous ? v4 : nullptr);
      smoothed_pass(x, viscous ? v : nullptr, element_kernel);
      kernel = true;
    } else {
      kernel = run_force_kernel(x4, viscous ? v4 : nullptr);
    }
    // The elastic energy and the inverted elements at x, as energy() and inverted() give them
    // (the same sums in the same order), for the element strain: ForceModel reuses a force
    // evaluation at the end of a step for its energy check.
    const bool by_products = m_smoothing == StrainSmoothing::element;
    Scalar energy(0);
    Index inverted = 0;
    for (std::size_t t = 0; t < nt; ++t) {
      if (m_removed[t]) {  // zero gradients and H: the later passes add nothing for it
        Scalar* g = grad(t);
        for (int k = 0; k < 12; ++k) g[4 * k] = Scalar(0);
        Scalar* o = &m_batch_out[std::size_t(simd::tet_out_stride) * (t / 4) + t % 4];
        for (int k = 0; k < 9; ++k) o[4 * k] = Scalar(0);
        m_element_tangent[t] = 0;
        m_state_factor[t] = Scalar(1);
        continue;
      }
      const Index* id = &m_tets[4 * t];
      Matrix3<Scalar> H, F;
      Scalar vt, dvt(0), distortion(0);
      bool have_f = false;
      if (kernel) {
        const Scalar* o = &m_batch_out[std::size_t(simd::tet_out_stride) * (t / 4) + t % 4];
        for (int k = 0; k < 9; ++k) H(k % 3, k / 3) = o[4 * k];
        vt = o[simd::tet_out_volume];
        dvt = o[simd::tet_out_rate];
        m_state_factor[t] = o[simd::tet_out_state];
        distortion = o[simd::tet_out_distortion];
        energy += o[simd::tet_out_energy];
      } else {
        Matrix3<Scalar> Ds;
        Vector3<Scalar> g[4];
        load_edges(x, id, Ds);
        volume_gradient(Ds, g);
        Scalar* gt = grad(t);
        for (int k = 0; k < 4; ++k)
          for (int c = 0; c < 3; ++c) gt[4 * (3 * k + c)] = g[k][c];
        F = Ds * dm_inv(t);
        have_f = true;
        Matrix3<Scalar> P;
        Scalar stiffening(1), gj(1);
        energy += m_volume[t] * deviatoric(F, m_c10[t], m_c10_large[t], m_q_switch[t],
                                           Scalar(j_min), &P, &stiffening, &gj, &distortion);
        // The I1 curvature of the energy is 2 C10 g(J): stiffer in compression.
        m_state_factor[t] = stiffening * std::max(Scalar(1), gj);
        H = -m_volume[t] * P * dm_inv(t).transpose();
        vt = Ds.col(0).dot(Ds.col(1).cross(Ds.col(2))) / Scalar(6);
        if (viscous)
          for (int k = 0; k < 4; ++k) dvt += g[k].dot(row(v, id[k]));
      }
      if (!(vt > Scalar(0))) ++inverted;
      if (!kernel) {  // H where pass 2 reads it (the kernel left it there)
        Scalar* o = &m_batch_out[std::size_t(simd::tet_out_stride) * (t / 4) + t % 4];
        for (int k = 0; k < 9; ++k) o[4 * k] = H(k % 3, k / 3);
      }
      const bool strained = distortion > Scalar(element_tangent_strain) ||
                            std::abs(vt / m_volume[t] - Scalar(1)) > Scalar(element_tangent_strain);
      if (m_watch) watch_flutter(t, vt / m_volume[t]);
      m_element_tangent[t] = std::uint8_t(m_poor_shape[t] || strained || m_fluttered[t]);
      if (m_element_tangent[t]) {
        if (!have_f) {
          Matrix3<Scalar> Ds;
          load_edges(x, id, Ds);
          F = Ds * dm_inv(t);
        }
        // Its F, for prepare_implicit() to turn into its rotation (the slot holds that after).
        Eigen::Map<Matrix3<Scalar>> slot(&m_dense_rotation[9 * m_dense.size()]);
        slot = F;
        m_dense.push_back(Index(t));  // within its capacity
      }
      for (int k = 0; k < 4; ++k) {
        volume_now[id[k]] += vt / Scalar(4);
        rate[id[k]] += dvt / Scalar(4);
      }
    }
    m_watch = false;
    // Pass 2 on the SIMD kernel where there is one: it takes the pressures negated.
    simd::TetForceScatterKernel scatter = nullptr;
    if constexpr (std::is_same_v<Scalar, double>)
      if (simd_active()) scatter = simd::tet_force_scatter_kernel();
    // Nodal pressures: p_a = K (J_a - 1) + tau K dJ_a/dt, J_a = v_a / V_a.
    for (Index a = 0; a < m_num_nodes; ++a) {
      const Scalar V = m_node_volume[std::size_t(a)];
      if (!(V > Scalar(0))) {  // no pressure (its volume sum is 0 unless V rounded to 0)
        volume_now[a] = Scalar(0);
        continue;
      }
      const Scalar K = m_node_bulk[std::size_t(a)];
      const Scalar d = volume_now[a] / V - Scalar(1);
      energy += Scalar(0.5) * V * K * d * d;
      const Scalar p =
          K * ((volume_now[a] / V - Scalar(1)) + m_node_tau[std::size_t(a)] * rate[a] / V);
      volume_now[a] = scatter ? -p : p;
    }
    m_forces_energy = by_products ? energy : std::numeric_limits<Scalar>::quiet_NaN();
    m_forces_inverted = by_products ? inverted : Index(-1);
    // Pass 2: f = sum_T (H_T - pbar_T grad v_T), pbar_T the mean of its nodal pressures, in one
    // scatter (H's columns are the forces on corners 1-3, corner 0 gets minus their sum).
    // On the kernel, it leaves -pbar_T in m_pressure; a removed element's zero H and gradients
    // add nothing (while its corners' pressures are finite: a non-finite one fails the step).
    if constexpr (std::is_same_v<Scalar, double>)
      if (scatter)
        scatter(m_batch_nodes.data(), m_batch_out.data(), m_batch_grad.data(), volume_now, f,
                m_pressure.data(), 0, std::int32_t(m_batch_nodes.size() / 16), std::int32_t(nt));
    for (std::size_t t = 0; t < nt; ++t) {
      const Index* id = &m_tets[4 * t];
      if (m_removed[t]) {
        m_pressure[t] = m_edge_factor[t] = Scalar(0);
        continue;
      }
      const Scalar p =
          scatter
              ? -m_pressure[t]
              : (volume_now[id[0]] + volume_now[id[1]] + volume_now[id[2]] + volume_now[id[3]]) /
                    Scalar(4);
      m_pressure[t] = p;
      m_edge_factor[t] = m_element_tangent[t]
                             ? Scalar(0)
                             : m_state_factor[t] + m_pressure_share[t] * std::abs(p) / m_c10[t];
      if (scatter) continue;
      const Scalar* g = grad(t);
      const Scalar* o = &m_batch_out[std::size_t(simd::tet_out_stride) * (t / 4) + t % 4];
      Scalar h0[3] = {0, 0, 0};
      for (int k = 1; k < 4; ++k) {
        Scalar* q = f + 3 * std::ptrdiff_t(id[k]);
        for (int c = 0; c < 3; ++c) {
          const Scalar hk = o[4 * (c + 3 * (k - 1))];
          h0[c] -= hk;
          q[c] += hk - p * g[4 * (3 * k + c)];
        }
      }
      Scalar* q = f + 3 * std::ptrdiff_t(id[0]);
      for (int c = 0; c < 3; ++c) q[c] += h0[c] - p * g[4 * c];
    }
    if (!viscous) return;
    // Deviatoric viscosity: dashpots tau k_e along the edges. Each edge's direction and rate of
    // extension are kept for prepare_implicit() at this state (m_edge_block, m_edge_rate). On the
    // edge kernel where there is one (the same formulas).
    m_rate_generation = m_generation;
    if constexpr (std::is_same_v<Scalar, double>)
      if (simd_active() && v4)
        if (const auto dashpots = simd::edge_dashpot_kernel()) {
          dashpots(m_edges.data(), m_edge_tau.data(), m_edge_k.data(), x4, v4, m_edge_block.data(),
                   m_edge_rate.data(), f, 0, std::int32_t(num_edges()));
          return;
        }
    for (std::size_t e = 0; e < num_edges(); ++e) {
      const Index i = m_edges[2 * e], j = m_edges[2 * e + 1];
      const Vector3<Scalar> d = row(x, j) - row(x, i);
      const Scalar l = d.norm();
      Scalar* B = &m_edge_block[std::size_t(edge_block_size) * e];
      if (!(l > Scalar(0))) {
        B[0] = B[1] = B[2] = m_edge_rate[e] = Scalar(0);
        continue;
      }
      const Vector3<Scalar> n = d / l;
      const Scalar extension_rate = n.dot(row(v, j) - row(v, i));
      B[0] = n[0];
      B[1] = n[1];
      B[2] = n[2];
      m_edge_rate[e] = extension_rate;
      const Vector3<Scalar> F = m_edge_tau[e] * m_edge_k[e] * extension_rate * n;
      add(f, i, F);
      add(f, j, -F);
    }
  }

  /// The elastic energy (J) and the number of inverted elements at the x of the last add_forces(),
  /// as energy() and inverted() give them; NaN and -1 with smoothed strains (not computed).
  [[nodiscard]] Scalar forces_energy() const noexcept { return m_forces_energy; }
  [[nodiscard]] Index forces_inverted() const noexcept { return m_forces_inverted; }
  /// Element t's mean nodal pressure (Pa; negative in compression) at the last add_forces(), 0 for
  /// a removed one.
  [[nodiscard]] Scalar pressure(std::size_t t) const noexcept { return m_pressure[t]; }
  /// Changes with every add_forces() and every change to the term: the per-step state that
  /// prepare_implicit() reads is the one of the add_forces() call that left this value.
  [[nodiscard]] std::uint64_t generation() const noexcept { return m_generation; }

  /// Elastic energy (J) at x.
  [[nodiscard]] Scalar energy(const Scalar* x) const noexcept {
    if (empty()) return Scalar(0);
    std::vector<Scalar>& volume_now = m_energy_scratch;
    volume_now.assign(std::size_t(m_num_nodes), Scalar(0));  // reserved by refresh: no growth
    Scalar e(0);
    const bool smoothed = m_smoothing != StrainSmoothing::element;
    const bool kernel = (!smoothed || m_element_share > Scalar(0)) && run_energy_kernel(x);
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      if (m_removed[t]) continue;
      const Index* id = &m_tets[4 * t];
      Scalar vt;
      if (kernel) {
        const Scalar* o = &m_energy_out[std::size_t(simd::tet_energy_stride) * (t / 4) + t % 4];
        e += (smoothed ? m_element_share : Scalar(1)) * o[0];
        vt = o[4];
        if (smoothed) {
          Matrix3<Scalar> Ds;
          load_edges(x, id, Ds);
          Eigen::Map<Matrix3<Scalar>>{&m_element_F[9 * t]} = Ds * dm_inv(t);
        }
      } else {
        Matrix3<Scalar> Ds;
        load_edges(x, id, Ds);
        const Matrix3<Scalar> F = Ds * dm_inv(t);
        if (smoothed) Eigen::Map<Matrix3<Scalar>>{&m_element_F[9 * t]} = F;
        if (!smoothed || m_element_share > Scalar(0))
          e += (smoothed ? m_element_share : Scalar(1)) * m_volume[t] *
               deviatoric<Scalar>(F, m_c10[t], m_c10_large[t], m_q_switch[t], Scalar(j_min),
                                  nullptr);
        vt = Ds.col(0).dot(Ds.col(1).cross(Ds.col(2))) / Scalar(6);
      }
      for (int k = 0; k < 4; ++k) volume_now[std::size_t(id[k])] += vt / Scalar(4);
    }
    if (smoothed)
      for (std::size_t d = 0; d < num_domains(); ++d) {
        Matrix3<Scalar> F;
        Scalar V;
        std::size_t t = 0;
        if (!domain_strain(d, F, V, t)) continue;
        e += (Scalar(1) - m_element_share) * V *
             deviatoric<Scalar>(F, m_c10[t], m_c10_large[t], m_q_switch[t], Scalar(j_min), nullptr);
      }
    for (Index a = 0; a < m_num_nodes; ++a) {
      const Scalar V = m_node_volume[std::size_t(a)];
      if (!(V > Scalar(0))) continue;
      const Scalar d = volume_now[std::size_t(a)] / V - Scalar(1);
      e += Scalar(0.5) * V * m_node_bulk[std::size_t(a)] * d * d;
    }
    return e;
  }

  /// Elements with J <= 0 at x.
  [[nodiscard]] Index inverted(const Scalar* x) const noexcept {
    Index count = 0;
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      if (m_removed[t]) continue;
      Matrix3<Scalar> Ds;
      load_edges(x, &m_tets[4 * t], Ds);
      // (The triple product, as add_forces() computes the volume: the same sign.)
      if (!(Ds.col(0).dot(Ds.col(1).cross(Ds.col(2))) > Scalar(0))) ++count;
    }
    return count;
  }

  /// Prepares the implicit tangent at x for a step h, after add_forces() at the same x (its
  /// volume gradients are reused): the edge springs' blocks and the nodal coefficients; adds
  /// - h^2 H v to rhs (H the tangent, so that rhs = h F + h^2 dF/dx v with the forces added by the
  /// caller) and diag(A) contributions to `diagonal`.
  /// `v4`: v padded to four per node (the caller's, optional).
  void prepare_implicit(const Scalar* x, const Scalar* v, Scalar h, Scalar* rhs, Scalar* diagonal,
                        const Scalar* v4 = nullptr) noexcept {
    if (empty()) return;
    const Scalar h2 = h * h;
    // The diagonal blocks (add_diagonal_blocks()) in the same passes; diag(A) from them at the end.
    std::fill(m_node_blocks.begin(), m_node_blocks.end(), Scalar(0));
    simd::LinkNodeBlocksKernel edge_blocks = nullptr;
    if constexpr (std::is_same_v<Scalar, double>)
      if (simd_active()) {
        edge_blocks = simd::link_node_blocks_kernel();
      }
    // The edges' directions and rates of extension, and the nodal volumes' rates: kept by a
    // viscous add_forces() at this x, v.
    const bool kept = m_rate_generation == m_generation;
    // With the kept directions and rates and the edge kernels, the springs' tangents here and the
    // right-hand side on the scatter kernel (the same products).
    simd::EdgeScatterKernel edge_rhs = nullptr;
    if constexpr (std::is_same_v<Scalar, double>)
      if (kept && edge_blocks) edge_rhs = simd::edge_scatter_kernel();
    if (edge_rhs) {
      for (std::size_t e = 0; e < num_edges(); ++e) {
        const Scalar k = tangent_margin * edge_stiffness(e);
        m_edge_block[std::size_t(edge_block_size) * e + 3] =
            h2 * k + h * m_edge_tau[e] * m_edge_k[e];
        m_edge_weight[e] = h2 * k;
      }
      if constexpr (std::is_same_v<Scalar, double>)
        edge_rhs(m_edges.data(), m_edge_block.data(), m_edge_rate.data(), m_edge_weight.data(), rhs,
                 0, std::int32_t(num_edges()));
    }
    for (std::size_t e = 0; e < (edge_rhs ? 0 : num_edges()); ++e) {
      const Index i = m_edges[2 * e], j = m_edges[2 * e + 1];
      Scalar* B = &m_edge_block[std::size_t(edge_block_size) * e];
      if (!kept) {
        const Vector3<Scalar> d = row(x, j) - row(x, i);
        const Scalar l = d.norm();
        const Vector3<Scalar> n = l > Scalar(0) ? Vector3<Scalar>(d / l) : Vector3<Scalar>::Zero();
        B[0] = n[0];
        B[1] = n[1];
        B[2] = n[2];
        m_edge_rate[e] = n.dot(row(v, j) - row(v, i));
      }
      const Vector3<Scalar> n(B[0], B[1], B[2]);
      const Scalar k = tangent_margin * edge_stiffness(e);
      B[3] = h2 * k + h * m_edge_tau[e] * m_edge_k[e];
      // rhs: the stiffness part only (damping is in the forces): -h^2 k n n^T (v_i - v_j) on i.
      const Vector3<Scalar> r = h2 * k * m_edge_rate[e] * n;
      add(rhs, i, r);
      add(rhs, j, -r);
      if (!edge_blocks) {
        add_block(i, n[0], n[1], n[2], B[3]);
        add_block(j, n[0], n[1], n[2], B[3]);
      }
    }
    // The edges' blocks on the links' kernel where there is one: an edge's block (n, a, 0) is a
    // link's (simd_links.hpp).
    if constexpr (std::is_same_v<Scalar, double>)
      if (edge_blocks)
        edge_blocks(m_edges.data(), m_edge_block.data(), m_node_blocks.data(), 0,
                    std::int32_t(num_edges()));
    ++m_generation;  // the F slots below become rotations: the state is this call's now
    if (kept) m_rate_generation = m_generation;
    // The element tangents: h^2 c V |sym(Q^T dF)|^2 at this x (add_forces() left F in the slot).
    for (std::size_t k = 0; k < m_dense.size(); ++k) {
      const auto t = std::size_t(m_dense[k]);
      Eigen::Map<Matrix3<Scalar>> slot(&m_dense_rotation[9 * k]);
      const Matrix3<Scalar> F = slot;
      slot = tangent_rotation(F);
      m_dense_coefficient[k] = h2 * element_coefficient(t, F);
      apply_element(k, v, rhs, -m_dense_coefficient[k]);
      const Matrix3<Scalar> QQt = slot * slot.transpose();
      for (int a = 0; a < 4; ++a) {
        const Matrix3<Scalar> B = element_block(k, a, QQt);
        Scalar* o = &m_node_blocks[6 * std::size_t(m_tets[4 * t + std::size_t(a)])];
        o[0] += B(0, 0);
        o[1] += B(1, 1);
        o[2] += B(2, 2);
        o[3] += B(0, 1);
        o[4] += B(0, 2);
        o[5] += B(1, 2);
      }
    }
    // The Gauss-Newton coefficients (h^2 + h tau) K / V_a.
    for (Index a = 0; a < m_num_nodes; ++a) {
      const Scalar V = m_node_volume[std::size_t(a)];
      m_node_coefficient[std::size_t(a)] =
          V > Scalar(0) ? (h2 + h * m_node_tau[std::size_t(a)]) * m_node_bulk[std::size_t(a)] / V
                        : Scalar(0);
    }
    // rhs -= h^2 H_vol v: the stiffness part of the coefficient.
    if constexpr (std::is_same_v<Scalar, double>) {
      if (simd_active() && !v4) {
        pad_rows4(v, m_num_nodes, m_v4.data());
        v4 = m_v4.data();
      }
    }
    if (!simd_active()) v4 = nullptr;
    pair_gradients();  // the volumetric product's pairs at this x
    // (grad v_a . v is the nodal volume's rate add_forces() kept: no first pass then.)
    apply_volumetric(
        v, rhs,
        [&](Index a) {
          const Scalar V = m_node_volume[std::size_t(a)];
          return V > Scalar(0) ? -h2 * m_node_bulk[std::size_t(a)] / V : Scalar(0);
        },
        v4, kept ? m_node_rate.data() : nullptr);
    // The volumetric part's diagonal blocks, exactly: sum_a c_a G_ab G_ab^T at each node b, row b
    // of the transposed pairs.
    bool blocks_done = false;
    if constexpr (std::is_same_v<Scalar, double>) {
      if (simd_active())
        if (const auto blocks = simd::pair_blocks_kernel()) {
          blocks(m_pair_start.data(), m_pair_node.data(), m_pair_grad_t.data(),
                 m_node_coefficient.data(), m_node_blocks.data(), 0, std::int32_t(m_num_nodes));
          blocks_done = true;
        }
    }
    for (Index b = 0; b < (blocks_done ? 0 : m_num_nodes); ++b)
      for (std::int32_t k = m_pair_start[std::size_t(b)]; k < m_pair_start[std::size_t(b) + 1];
           ++k) {
        const Scalar* H = &m_pair_grad_t[4 * std::size_t(k)];
        add_block(b, H[0], H[1], H[2],
                  m_node_coefficient[std::size_t(m_pair_node[std::size_t(k)])]);
      }
    for (Index a = 0; a < m_num_nodes; ++a)
      for (int c = 0; c < 3; ++c)
        diagonal[3 * std::ptrdiff_t(a) + c] += m_node_blocks[6 * std::size_t(a) + std::size_t(c)];
  }

  /// Adds the 3 x 3 diagonal blocks of the tangent prepared by prepare_implicit() (6 scalars per
  /// node: xx, yy, zz, xy, xz, yz), the volumetric part's summed over the node's pairs.
  void add_diagonal_blocks(Scalar* out) const noexcept {
    if (empty()) return;
    for (std::size_t k = 0; k < m_node_blocks.size(); ++k) out[k] += m_node_blocks[k];
  }

  /// y += A_continuum p for the tangent prepared by prepare_implicit(). `p4`: p padded to 4 per
  /// node, for the SIMD kernels (optional).
  void apply_implicit(const Scalar* p, Scalar* y, const Scalar* p4 = nullptr) noexcept {
    if (empty()) return;
    apply_edges(0, num_edges(), p, y, p4);
    apply_volumetric(
        p, y, [&](Index a) { return m_node_coefficient[std::size_t(a)]; }, p4);
    for (std::size_t k = 0; k < m_dense.size(); ++k) apply_element(k, p, y, m_dense_coefficient[k]);
  }

  /// apply_implicit() on T threads, in three phases with a barrier between them (the caller's
  /// pool runs): phase 1, share t: the edges' and element tangents' share into y_t and the
  /// volumetric first pass into s_t (both zeroed by the caller); phase 2, nodes [begin, end):
  /// the nodal sums of the T buffers s, scaled by the nodes' coefficients; phase 3, share t: the
  /// volumetric second pass into y_t. The caller then adds the y_t. Same products as
  /// apply_implicit(), summed in another order.
  void apply_implicit_phase1(const Scalar* p, Scalar* y_t, Scalar* s_t, int t, int T,
                             const Scalar* p4 = nullptr) const noexcept {
    if (empty()) return;
    const auto [e0, e1] = share(num_edges(), t, T);
    apply_edges(e0, e1, p, y_t, p4);
    bool done = false;
    if constexpr (std::is_same_v<Scalar, double>) {
      if (p4 && pair_product_ready()) {
        const auto [a0, a1] = share(std::size_t(m_num_nodes), t, T);
        simd::pair_spread_kernel()(m_pair_start.data(), m_pair_node.data(), m_pair_grad.data(), p4,
                                   s_t, std::int32_t(a0), std::int32_t(a1));
        done = true;
      }
    }
    if (!done) {
      const auto [t0, t1] = share(m_volume.size(), t, T);
      volumetric_spread(t0, t1, p, s_t);
    }
    const auto [k0, k1] = share(m_dense.size(), t, T);
    for (std::size_t k = k0; k < k1; ++k) apply_element(k, p, y_t, m_dense_coefficient[k]);
  }
  /// Phase 2 of apply_implicit_phase1(): `s` holds the T threads' buffers.
  void apply_implicit_phase2(const std::vector<std::vector<Scalar>>& s, int T, Index begin,
                             Index end) noexcept {
    if (empty()) return;
    for (Index a = begin; a < end; ++a) {
      Scalar sum(0);
      for (int b = 0; b < T; ++b) sum += s[std::size_t(b)][std::size_t(a)];
      m_node_scratch[std::size_t(a)] = sum * m_node_coefficient[std::size_t(a)];
    }
  }
  /// Phase 3 of apply_implicit_phase1() (`p4` as there: the kernels run if it is given).
  void apply_implicit_phase3(Scalar* y_t, int t, int T, const Scalar* p4 = nullptr) const noexcept {
    if (empty()) return;
    if constexpr (std::is_same_v<Scalar, double>) {
      if (p4 && pair_product_ready()) {
        const auto [a0, a1] = share(std::size_t(m_num_nodes), t, T);
        simd::pair_gather_kernel()(m_pair_start.data(), m_pair_node.data(), m_pair_grad_t.data(),
                                   m_node_scratch.data(), y_t, std::int32_t(a0), std::int32_t(a1));
        return;
      }
    }
    (void)p4;
    const auto [t0, t1] = share(m_volume.size(), t, T);
    volumetric_gather(t0, t1, m_node_scratch.data(), y_t);
  }

  /// Conservative bound of the element term's stiffness per node (N/m): Gershgorin row sums of
  /// the rest tangent (for stable time steps and contact stiffness).
  void add_node_stiffness(const SphereModel<Scalar>& model, Scalar* k) const {
    if (empty()) return;
    const auto x = model.rest_positions();
    for (std::size_t e = 0; e < num_edges(); ++e) {
      // At its stiffest: each element's share at its large-strain C10 (bilinear materials), as
      // the link law takes the larger of its two stiffnesses.
      Scalar ke(0);
      for (Index s = m_edge_part_start[e]; s < m_edge_part_start[e + 1]; ++s) {
        const auto t = std::size_t(m_edge_part_element[std::size_t(s)]);
        if (m_removed[t]) continue;
        ke += std::max(Scalar(1), m_c10_large[t] / m_c10[t]) * m_edge_part_k[std::size_t(s)];
      }
      k[m_edges[2 * e]] += Scalar(2) * ke;
      k[m_edges[2 * e + 1]] += Scalar(2) * ke;
    }
    // Volumetric: row sum of sum_a (K / V_a) |grad_i v_a| |grad_j v_a| over j.
    std::vector<Scalar> ring(std::size_t(m_num_nodes), Scalar(0));
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      if (m_removed[t]) continue;
      Matrix3<Scalar> Ds;
      Vector3<Scalar> g[4];
      load_edges(x.data(), &m_tets[4 * t], Ds);
      volume_gradient(Ds, g);
      Scalar s(0);
      for (int j = 0; j < 4; ++j) s += g[j].norm() / Scalar(4);
      for (int a = 0; a < 4; ++a) ring[std::size_t(m_tets[4 * t + std::size_t(a)])] += s;
    }
    // Element tangents at rest (F = I): row sums of 2 C10_max V (|g_a| |g_b| + |g_a . g_b|) <=
    // 4 C10_max V |g_a| |g_b|, at the stiffer C10 of a bilinear material.
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      if (!m_poor_shape[t] || m_removed[t]) continue;
      const Scalar c10 = std::max(m_c10[t], m_c10_large[t]);
      Scalar sum(0);
      for (int b = 0; b < 4; ++b) sum += shape_gradient(t, b).norm();
      for (int a = 0; a < 4; ++a)
        k[m_tets[4 * t + std::size_t(a)]] +=
            tangent_margin * Scalar(4) * c10 * m_volume[t] * shape_gradient(t, a).norm() * sum;
    }
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      if (m_removed[t]) continue;
      Matrix3<Scalar> Ds;
      Vector3<Scalar> g[4];
      load_edges(x.data(), &m_tets[4 * t], Ds);
      volume_gradient(Ds, g);
      for (int a = 0; a < 4; ++a) {
        const auto na = std::size_t(m_tets[4 * t + std::size_t(a)]);
        const Scalar c = m_node_bulk[na] / m_node_volume[na] * ring[na];
        for (int i = 0; i < 4; ++i)
          k[m_tets[4 * t + std::size_t(i)]] += c * g[i].norm() / Scalar(4);
      }
    }
  }

  /// Per node a, the gradient of its nodal volume v_a at x: (node i, d v_a / d x_i) pairs, from
  /// the elements at a (offline: the assembled tangent and damping matrices).
  [[nodiscard]] std::vector<std::vector<std::pair<Index, Vector3<Scalar>>>> nodal_volume_gradients(
      const Scalar* x) const {
    std::vector<std::vector<std::pair<Index, Vector3<Scalar>>>> grad(
        static_cast<std::size_t>(m_num_nodes));
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      if (m_removed[t]) continue;
      const Index* id = &m_tets[4 * t];
      Matrix3<Scalar> Ds;
      Vector3<Scalar> g[4];
      load_edges(x, id, Ds);
      volume_gradient(Ds, g);
      for (int a = 0; a < 4; ++a)
        for (int k = 0; k < 4; ++k) grad[std::size_t(id[a])].emplace_back(id[k], g[k] / Scalar(4));
    }
    return grad;
  }

  /// The retardation time of node a's region (s), 0 outside continuum regions.
  [[nodiscard]] Scalar node_tau(Index a) const noexcept { return m_node_tau[std::size_t(a)]; }

  /// Triplets of the tangent H (the positive semi-definite approximation of -dF/dx the solve uses)
  /// at x.
  template <typename Triplets>
  void tangent_triplets(const Scalar* x, Triplets& trip) const {
    for (std::size_t e = 0; e < num_edges(); ++e) {
      const Index i = m_edges[2 * e], j = m_edges[2 * e + 1];
      const Vector3<Scalar> d = row(x, j) - row(x, i);
      const Scalar l = d.norm();
      if (!(l > Scalar(0))) continue;
      const Matrix3<Scalar> K = tangent_margin * edge_stiffness(e) * (d / l) * (d / l).transpose();
      push_pair(trip, i, j, K);
    }
    // Element tangents: 2 c V G^T Q sym(Q^T G .), column by column.
    for (const Index te : m_dense) {
      const auto t = std::size_t(te);
      const Index* id = &m_tets[4 * t];
      Matrix3<Scalar> Ds;
      load_edges(x, id, Ds);
      const Matrix3<Scalar> F = Ds * dm_inv(t);
      const Matrix3<Scalar> Q = tangent_rotation(F);
      const Scalar c = element_coefficient(t, F);
      for (int b = 0; b < 4; ++b)
        for (int cb = 0; cb < 3; ++cb) {
          Matrix3<Scalar> dF = Matrix3<Scalar>::Zero();
          dF.row(cb) = shape_gradient(t, b).transpose();
          const Matrix3<Scalar> A = Q.transpose() * dF;
          const Matrix3<Scalar> B = Scalar(2) * c * Q * (Scalar(0.5) * (A + A.transpose()));
          for (int a = 0; a < 4; ++a) {
            const Vector3<Scalar> col = B * shape_gradient(t, a);
            for (int r = 0; r < 3; ++r) trip.emplace_back(3 * id[a] + r, 3 * id[b] + cb, col[r]);
          }
        }
    }
    // sum_a (K / V_a) grad v_a grad v_a^T, grad v_a = sum_{T at a} grad v_T / 4.
    const auto grad = nodal_volume_gradients(x);
    for (Index a = 0; a < m_num_nodes; ++a) {
      const Scalar V = m_node_volume[std::size_t(a)];
      if (!(V > Scalar(0))) continue;
      const Scalar c = m_node_bulk[std::size_t(a)] / V;
      for (const auto& [i, gi] : grad[std::size_t(a)])
        for (const auto& [j, gj] : grad[std::size_t(a)]) {
          const Matrix3<Scalar> B = c * gi * gj.transpose();
          for (int r = 0; r < 3; ++r)
            for (int s = 0; s < 3; ++s) trip.emplace_back(3 * i + r, 3 * j + s, B(r, s));
        }
    }
  }

  /// Triplets of the exact Jacobian dF/dx of the elastic element forces at x, by central
  /// differences of the exact forces (offline: for the direct solvers and for analysis).
  template <typename Triplets>
  void exact_stiffness_triplets(const Scalar* x, Triplets& trip) {
    std::vector<Scalar> xp(x, x + 3 * std::size_t(m_num_nodes));
    const std::vector<Scalar> zero(xp.size(), Scalar(0));
    std::vector<Scalar> fp(xp.size()), fm(xp.size());
    // Columns j: perturb x_j; forces on every node (the volumetric term reaches the 2-ring).
    for (Index j = 0; j < m_num_nodes; ++j) {
      if (!(m_node_volume[std::size_t(j)] > Scalar(0))) continue;
      for (int c = 0; c < 3; ++c) {
        const std::size_t k = 3 * std::size_t(j) + std::size_t(c);
        const Scalar step = std::sqrt(std::numeric_limits<Scalar>::epsilon()) *
                            std::max(Scalar(1e-3), std::abs(xp[k]));
        std::fill(fp.begin(), fp.end(), Scalar(0));
        std::fill(fm.begin(), fm.end(), Scalar(0));
        xp[k] += step;
        add_forces(xp.data(), zero.data(), fp.data(), false);
        xp[k] -= 2 * step;
        add_forces(xp.data(), zero.data(), fm.data(), false);
        xp[k] += step;
        for (Index i = 0; i < m_num_nodes; ++i)
          for (int r = 0; r < 3; ++r) {
            const Scalar d = (fp[3 * std::size_t(i) + std::size_t(r)] -
                              fm[3 * std::size_t(i) + std::size_t(r)]) /
                             (2 * step);
            if (d != Scalar(0)) trip.emplace_back(3 * i + r, 3 * j + c, d);
          }
      }
    }
  }

  /// Triplets of the element term's damping matrix D = -dF/dv (positive semi-definite; exact: the
  /// forces are linear in v).
  template <typename Triplets>
  void damping_triplets(const Scalar* x, Triplets& trip) const {
    for (std::size_t e = 0; e < num_edges(); ++e) {
      const Index i = m_edges[2 * e], j = m_edges[2 * e + 1];
      const Vector3<Scalar> d = row(x, j) - row(x, i);
      const Scalar l = d.norm();
      if (!(l > Scalar(0))) continue;
      const Matrix3<Scalar> D = m_edge_tau[e] * m_edge_k[e] * (d / l) * (d / l).transpose();
      push_pair(trip, i, j, D);
    }
    const auto grad = nodal_volume_gradients(x);
    for (Index a = 0; a < m_num_nodes; ++a) {
      const Scalar V = m_node_volume[std::size_t(a)];
      if (!(V > Scalar(0))) continue;
      const Scalar c = m_node_tau[std::size_t(a)] * m_node_bulk[std::size_t(a)] / V;
      for (const auto& [i, gi] : grad[std::size_t(a)])
        for (const auto& [j, gj] : grad[std::size_t(a)]) {
          const Matrix3<Scalar> B = c * gi * gj.transpose();
          for (int r = 0; r < 3; ++r)
            for (int s = 0; s < 3; ++s) trip.emplace_back(3 * i + r, 3 * j + s, B(r, s));
        }
    }
  }

 private:
  // Element t's volume gradients at the step's x (corner k, axis c at [4 (3 k + c)]): kept in the
  // element kernel's layout (simd_tets.hpp) whichever loop computed them.
  [[nodiscard]] Scalar* grad(std::size_t t) noexcept {
    return &m_batch_grad[std::size_t(simd::tet_grad_stride) * (t / 4) + t % 4];
  }
  [[nodiscard]] const Scalar* grad(std::size_t t) const noexcept {
    return &m_batch_grad[std::size_t(simd::tet_grad_stride) * (t / 4) + t % 4];
  }
  // The element kernels' inputs in batches of four (simd_tets.hpp), the last batch filled with
  // copies of the last element (its extra lanes are computed and never read), their outputs, and
  // the states padded to four per node.
  void build_batches() {
    m_batch_nodes.clear();
    m_batch_rest.clear();
    m_batch_out.clear();
    m_energy_out.clear();
    m_x4.clear();
    m_v4.clear();
    const std::size_t nt = m_volume.size(), nb = (nt + 3) / 4;
    m_batch_grad.assign(std::size_t(simd::tet_grad_stride) * nb, Scalar(0));
    // (The face-smoothed pass writes the force kernel's outputs for any Scalar.)
    m_batch_out.assign(std::size_t(simd::tet_out_stride) * nb, Scalar(0));
    if constexpr (std::is_same_v<Scalar, double>) {
      if (nt == 0) return;
      m_batch_nodes.assign(16 * nb, 0);
      m_batch_rest.assign(std::size_t(simd::tet_rest_stride) * nb, 0.0);
      for (std::size_t b = 0; b < nb; ++b)
        for (std::size_t l = 0; l < 4; ++l) {
          const std::size_t t = std::min(4 * b + l, nt - 1);
          for (std::size_t c = 0; c < 4; ++c) m_batch_nodes[16 * b + 4 * c + l] = m_tets[4 * t + c];
          double* R = &m_batch_rest[std::size_t(simd::tet_rest_stride) * b + l];
          for (std::size_t k = 0; k < 9; ++k) R[4 * k] = m_dm_inv[9 * t + k];
          R[simd::tet_rest_c10] = m_c10[t];
          R[simd::tet_rest_c10_large] = m_c10_large[t];
          R[simd::tet_rest_q_switch] = m_q_switch[t];
          R[simd::tet_rest_volume] = m_volume[t];
        }
      m_energy_out.assign(std::size_t(simd::tet_energy_stride) * nb, 0.0);
      m_x4.assign(4 * std::size_t(m_num_nodes), 0.0);
      m_v4.assign(4 * std::size_t(m_num_nodes), 0.0);
    }
  }
  // The volumetric product's node pairs (apply_volumetric()): per node a, the nodes b it shares
  // an element with, a itself included (CSR, sorted), and per element the pair of each of its
  // corner pairs (corner i's row, corner j's column: 16 per element; those with i == j are not
  // read: pair_gradients() sets the diagonal pairs from their rows).
  void build_pairs() {
    const std::size_t n = std::size_t(m_num_nodes), nt = m_volume.size();
    m_pair_start.assign(n + 1, 0);
    m_pair_node.clear();
    m_pair_slot.clear();
    m_pair_grad.clear();
    m_pair_grad_t.clear();
    m_pair_transpose.clear();
    m_pair_diagonal.assign(n, -1);
    m_pair_generation = ~std::uint64_t(0);
    if (nt == 0) return;
    std::vector<std::vector<std::int32_t>> rows(n);
    for (std::size_t t = 0; t < nt; ++t)
      for (std::size_t i = 0; i < 4; ++i)
        for (std::size_t j = 0; j < 4; ++j)
          rows[std::size_t(m_tets[4 * t + i])].push_back(std::int32_t(m_tets[4 * t + j]));
    for (std::size_t a = 0; a < n; ++a) {
      auto& r = rows[a];
      std::sort(r.begin(), r.end());
      r.erase(std::unique(r.begin(), r.end()), r.end());
      m_pair_start[a + 1] = m_pair_start[a] + std::int32_t(r.size());
      m_pair_node.insert(m_pair_node.end(), r.begin(), r.end());
    }
    m_pair_slot.assign(16 * nt, 0);
    for (std::size_t t = 0; t < nt; ++t)
      for (std::size_t i = 0; i < 4; ++i) {
        const auto a = std::size_t(m_tets[4 * t + i]);
        const auto first = m_pair_node.begin() + m_pair_start[a];
        const auto last = m_pair_node.begin() + m_pair_start[a + 1];
        for (std::size_t j = 0; j < 4; ++j)
          m_pair_slot[16 * t + 4 * i + j] = std::int32_t(
              std::lower_bound(first, last, std::int32_t(m_tets[4 * t + j])) - m_pair_node.begin());
      }
    m_pair_grad.assign(4 * m_pair_node.size(), Scalar(0));
    m_pair_grad_t.assign(4 * m_pair_node.size(), Scalar(0));
    m_pair_transpose.assign(m_pair_node.size(), 0);
    for (std::size_t a = 0; a < n; ++a)
      for (std::int32_t k = m_pair_start[a]; k < m_pair_start[a + 1]; ++k) {
        const auto b = std::size_t(m_pair_node[std::size_t(k)]);
        const auto first = m_pair_node.begin() + m_pair_start[b];
        const auto last = m_pair_node.begin() + m_pair_start[b + 1];
        m_pair_transpose[std::size_t(k)] =
            std::int32_t(std::lower_bound(first, last, std::int32_t(a)) - m_pair_node.begin());
        if (b == a) m_pair_diagonal[a] = k;
      }
  }
  // G_ab = d(nodal volume a) / d x_b = sum over the elements at a and b of grad_b v_T / 4 (4
  // scalars per pair, the fourth 0), and its transpose, from the volume gradients at hand: the
  // pairs off the diagonal summed over the elements, each diagonal pair minus the sum of its
  // row's others (an element's volume gradients sum to zero). On the pair kernels where the CPU
  // has them.
  void pair_gradients() noexcept {
    std::fill(m_pair_grad.begin(), m_pair_grad.end(), Scalar(0));
    m_pair_generation = m_generation;
    if constexpr (std::is_same_v<Scalar, double>) {
      const auto build = simd::pair_build_kernel();
      const auto finish = simd::pair_finish_kernel();
      if (simd_active() && build && finish) {
        build(m_batch_grad.data(), m_pair_slot.data(), m_pair_grad.data(),
              std::int32_t(m_volume.size()));
        finish(m_pair_start.data(), m_pair_diagonal.data(), m_pair_transpose.data(),
               m_pair_grad.data(), m_pair_grad_t.data(), 0, std::int32_t(m_num_nodes));
        return;
      }
    }
    for (std::size_t t = 0; t < m_volume.size(); ++t) {
      const Scalar* g = grad(t);
      for (std::size_t j = 0; j < 4; ++j)
        for (std::size_t i = 0; i < 4; ++i) {
          if (i == j) continue;
          Scalar* o = &m_pair_grad[4 * std::size_t(m_pair_slot[16 * t + 4 * i + j])];
          for (std::size_t c = 0; c < 3; ++c) o[c] += Scalar(0.25) * g[4 * (3 * j + c)];
        }
    }
    for (std::size_t a = 0; a < std::size_t(m_num_nodes); ++a) {
      const std::int32_t d = m_pair_diagonal[a];
      if (d < 0) continue;
      Scalar* o = &m_pair_grad[4 * std::size_t(d)];
      for (std::int32_t k = m_pair_start[a]; k < m_pair_start[a + 1]; ++k)
        for (std::size_t c = 0; c < 3 && k != d; ++c) o[c] -= m_pair_grad[4 * std::size_t(k) + c];
      for (std::int32_t k = m_pair_start[a]; k < m_pair_start[a + 1]; ++k)
        std::copy_n(&m_pair_grad[4 * std::size_t(m_pair_transpose[std::size_t(k)])], 4,
                    &m_pair_grad_t[4 * std::size_t(k)]);
    }
  }
  // The smoothing domains (StrainSmoothing): per face, edge or node of the elements, the
  // elements of one material around it (CSR); each element is in m_domain_share^-1 of them.
  void build_domains() {
    const std::size_t nt = m_volume.size();
    m_domain_start.assign(1, 0);
    m_domain_elements.clear();
    m_element_F.assign(9 * nt, Scalar(0));
    m_element_P.assign(9 * nt, Scalar(0));
    if (m_smoothing == StrainSmoothing::element) return;
    // (sorted node key, material, element)
    using Key = std::array<Index, 3>;
    std::vector<std::tuple<Key, Scalar, Scalar, Scalar, Index>> items;
    auto push = [&](std::size_t t, Key k) {
      std::sort(k.begin(), k.end());
      items.emplace_back(k, m_c10[t], m_c10_large[t], m_q_switch[t], Index(t));
    };
    for (std::size_t t = 0; t < nt; ++t) {
      const Index* id = &m_tets[4 * t];
      if (m_smoothing == StrainSmoothing::face) {
        push(t, {id[1], id[2], id[3]});
        push(t, {id[0], id[2], id[3]});
        push(t, {id[0], id[1], id[3]});
        push(t, {id[0], id[1], id[2]});
      } else if (m_smoothing == StrainSmoothing::edge) {
        for (int a = 0; a < 4; ++a)
          for (int b = a + 1; b < 4; ++b) push(t, {-1, id[a], id[b]});
      } else {
        for (int a = 0; a < 4; ++a) push(t, {-1, -1, id[a]});
      }
    }
    std::sort(items.begin(), items.end());
    for (std::size_t k = 0; k < items.size(); ++k) {
      if (k > 0 && (std::get<0>(items[k]) != std::get<0>(items[k - 1]) ||
                    std::get<1>(items[k]) != std::get<1>(items[k - 1]) ||
                    std::get<2>(items[k]) != std::get<2>(items[k - 1]) ||
                    std::get<3>(items[k]) != std::get<3>(items[k - 1])))
        m_domain_start.push_back(Index(k));
      m_domain_elements.push_back(std::get<4>(items[k]));
    }
    if (!items.empty()) m_domain_start.push_back(Index(items.size()));
    m_domain_share = m_smoothing == StrainSmoothing::face   ? Scalar(1) / Scalar(4)
                     : m_smoothing == StrainSmoothing::edge ? Scalar(1) / Scalar(6)
                                                            : Scalar(1) / Scalar(4);
  }
  // Domain d's smoothed F from m_element_F (its intact elements' rest-volume average), its rest
  // volume (its share of theirs) and an element for its material; false if all are removed.
  bool domain_strain(std::size_t d, Matrix3<Scalar>& F, Scalar& V, std::size_t& t) const noexcept {
    F.setZero();
    V = Scalar(0);
    for (Index k = m_domain_start[d]; k < m_domain_start[d + 1]; ++k) {
      const auto e = std::size_t(m_domain_elements[std::size_t(k)]);
      if (m_removed[e]) continue;
      F += m_volume[e] * Eigen::Map<const Matrix3<Scalar>>(&m_element_F[9 * e]);
      V += m_volume[e];
      t = e;
    }
    if (!(V > Scalar(0))) return false;
    F /= V;
    V *= m_domain_share;
    return true;
  }
  // The force kernel's work with smoothed strains, scalar, into its outputs (m_batch_out,
  // m_batch_grad): each element's F, volume and rate; each domain's stress; each element's force
  // H = -V_T Pbar_T D_m^-T with Pbar_T = (1 - a) s sum_{d at T} P(F_d) + a P(F_T) (the gradient
  // of the smoothed energy: dF_d/dF_T = V_T / sum_{T' in d} V_T' and V_d = s sum V_T', so each
  // domain's share in dE/dF_T is s V_T P(F_d)); its state factor and distortion the largest of its
  // domains' and its own. `element_kernel`: the force kernel has run, so the element share's
  // forces, the gradients, volumes, rates and the element's own state and distortion are in its
  // outputs already.
  void smoothed_pass(const Scalar* x, const Scalar* v, bool element_kernel) noexcept {
    const std::size_t nt = m_volume.size();
    auto out = [&](std::size_t t) {
      return &m_batch_out[std::size_t(simd::tet_out_stride) * (t / 4) + t % 4];
    };
    for (std::size_t t = 0; t < nt; ++t) {
      if (m_removed[t]) continue;
      const Index* id = &m_tets[4 * t];
      Matrix3<Scalar> Ds;
      load_edges(x, id, Ds);
      Eigen::Map<Matrix3<Scalar>>{&m_element_F[9 * t]} = Ds * dm_inv(t);
      Eigen::Map<Matrix3<Scalar>>{&m_element_P[9 * t]}.setZero();
      if (element_kernel) continue;
      Vector3<Scalar> g[4];
      volume_gradient(Ds, g);
      Scalar* gt = grad(t);
      for (int k = 0; k < 4; ++k)
        for (int c = 0; c < 3; ++c) gt[4 * (3 * k + c)] = g[k][c];
      Scalar* o = out(t);
      o[simd::tet_out_volume] = Ds.col(0).dot(Ds.col(1).cross(Ds.col(2))) / Scalar(6);
      Scalar dvt(0);
      if (v)
        for (int k = 0; k < 4; ++k) dvt += g[k].dot(row(v, id[k]));
      o[simd::tet_out_rate] = dvt;
      o[simd::tet_out_state] = Scalar(1);
      o[simd::tet_out_distortion] = -std::numeric_limits<Scalar>::infinity();
    }
    for (std::size_t d = 0; d < num_domains(); ++d) {
      Matrix3<Scalar> F, P;
      Scalar V;
      std::size_t t = 0;
      if (!domain_strain(d, F, V, t)) continue;
      Scalar stiffening(1), gj(1), distortion(0);
      deviatoric(F, m_c10[t], m_c10_large[t], m_q_switch[t], Scalar(j_min), &P, &stiffening, &gj,
                 &distortion);
      const Scalar state = stiffening * std::max(Scalar(1), gj);
      for (Index k = m_domain_start[d]; k < m_domain_start[d + 1]; ++k) {
        const Index e = m_domain_elements[std::size_t(k)];
        if (m_removed[std::size_t(e)]) continue;
        Eigen::Map<Matrix3<Scalar>>{&m_element_P[9 * std::size_t(e)]} += m_domain_share * P;
        Scalar* o = out(std::size_t(e));
        o[simd::tet_out_state] = std::max(o[simd::tet_out_state], state);
        o[simd::tet_out_distortion] = std::max(o[simd::tet_out_distortion], distortion);
      }
    }
    const Scalar alpha = m_element_share;
    for (std::size_t t = 0; t < nt; ++t) {
      if (m_removed[t]) continue;
      Matrix3<Scalar> Pt =
          (Scalar(1) - alpha) * Eigen::Map<const Matrix3<Scalar>>(&m_element_P[9 * t]);
      if (element_kernel) {  // H = alpha H_element (the kernel's) - V Pt D_m^-T
        const Matrix3<Scalar> H = -m_volume[t] * Pt * dm_inv(t).transpose();
        Scalar* o = out(t);
        for (int k = 0; k < 9; ++k) o[4 * k] = alpha * o[4 * k] + H(k % 3, k / 3);
        continue;
      }
      if (alpha > Scalar(0)) {
        Matrix3<Scalar> P;
        Scalar stiffening(1), gj(1), distortion(0);
        deviatoric(Matrix3<Scalar>(Eigen::Map<const Matrix3<Scalar>>(&m_element_F[9 * t])),
                   m_c10[t], m_c10_large[t], m_q_switch[t], Scalar(j_min), &P, &stiffening, &gj,
                   &distortion);
        Pt += alpha * P;
        Scalar* o = out(t);
        o[simd::tet_out_state] =
            std::max(o[simd::tet_out_state], stiffening * std::max(Scalar(1), gj));
        o[simd::tet_out_distortion] = std::max(o[simd::tet_out_distortion], distortion);
      }
      const Matrix3<Scalar> H = -m_volume[t] * Pt * dm_inv(t).transpose();
      Scalar* o = out(t);
      for (int k = 0; k < 9; ++k) o[4 * k] = H(k % 3, k / 3);
    }
  }
  // Runs the force kernel on every batch at (x4, v4), the positions and velocities padded to four
  // per node (add_forces() pads them; v4 null: no rates); false where it does not run.
  bool run_force_kernel(const Scalar* x4, const Scalar* v4) noexcept {
    if constexpr (std::is_same_v<Scalar, double>) {
      if (!simd_active()) return false;
      simd::tet_force_kernel()(m_batch_nodes.data(), m_batch_rest.data(), x4, v4, j_min,
                               m_batch_out.data(), m_batch_grad.data(), 0,
                               std::int32_t(m_batch_nodes.size() / 16));
      return true;
    }
    (void)x4, (void)v4;
    return false;
  }
  bool run_energy_kernel(const Scalar* x) const noexcept {
    if constexpr (std::is_same_v<Scalar, double>) {
      if (!simd_active()) return false;  // (which implies the energy kernel)
      pad_rows4(x, m_num_nodes, m_x4.data());
      simd::tet_energy_kernel()(m_batch_nodes.data(), m_batch_rest.data(), m_x4.data(), j_min,
                                m_energy_out.data(), 0, std::int32_t(m_batch_nodes.size() / 16));
      return true;
    }
    (void)x;
    return false;
  }

  static Vector3<Scalar> row(const Scalar* a, Index i) noexcept {
    const Scalar* p = a + 3 * std::ptrdiff_t(i);
    return {p[0], p[1], p[2]};
  }
  static void add(Scalar* a, Index i, const Vector3<Scalar>& v) noexcept {
    Scalar* p = a + 3 * std::ptrdiff_t(i);
    p[0] += v[0];
    p[1] += v[1];
    p[2] += v[2];
  }
  // Takes element e out (nothing if it is out already): its volume from its nodes, its share from
  // its edges; a node or an edge left with no element gets exactly 0.
  void remove_element(std::size_t e) noexcept {
    if (m_removed[e]) return;
    m_removed[e] = 1;
    m_edge_factor[e] = Scalar(0);
    for (std::size_t c = 0; c < 4; ++c) {
      const auto a = std::size_t(m_tets[4 * e + c]);
      m_node_volume[a] = --m_node_count[a] > 0 ? m_node_volume[a] - m_volume[e] / 4 : Scalar(0);
    }
    for (std::size_t c = 0; c < 6; ++c) {
      const auto edge = std::size_t(m_element_edge[12 * e + 2 * c]);
      const auto part = std::size_t(m_element_edge[12 * e + 2 * c + 1]);
      m_edge_k[edge] = --m_edge_count[edge] > 0 ? m_edge_k[edge] - m_edge_part_k[part] : Scalar(0);
    }
  }
  /// The rest shape gradient of node a (0-3) of element t: dF = sum_a x_a g_a^T.
  [[nodiscard]] Vector3<Scalar> shape_gradient(std::size_t t, int a) const noexcept {
    const auto D = dm_inv(t);
    if (a > 0) return D.row(a - 1).transpose();
    return -(D.row(0) + D.row(1) + D.row(2)).transpose();
  }
  /// c V of element t's tangent at F: tangent_margin times its I1 curvature 2 C10 (stiffened as in
  /// add_forces()), plus the size of its pressure's geometric stiffness |p| |F| / sqrt(3).
  [[nodiscard]] Scalar element_coefficient(std::size_t t, const Matrix3<Scalar>& F) const noexcept {
    return m_volume[t] * (tangent_margin * Scalar(2) * m_c10[t] * m_state_factor[t] +
                          std::abs(m_pressure[t]) * F.norm() / std::sqrt(Scalar(3)));
  }
  /// The k-th element tangent's diagonal block on its node a, as apply_element() applies it:
  /// h^2 c V (|g_a|^2 Q Q^T + (Q g_a)(Q g_a)^T). (Q Q^T, not I: tangent_rotation()'s two Newton
  /// steps leave Q short of orthogonal where the element is stretched far, and those are the
  /// elements that get this tangent.) `QQt`: Q Q^T, the same for the element's four nodes.
  [[nodiscard]] Matrix3<Scalar> element_block(std::size_t k, int a,
                                              const Matrix3<Scalar>& QQt) const noexcept {
    const Eigen::Map<const Matrix3<Scalar>> Q(&m_dense_rotation[9 * k]);
    const Vector3<Scalar> g = shape_gradient(std::size_t(m_dense[k]), a), qg = Q * g;
    return m_dense_coefficient[k] * (g.squaredNorm() * QQt + qg * qg.transpose());
  }
  /// y += 2 coef G^T Q sym(Q^T G p) for the k-th element tangent (Q its stored rotation).
  void apply_element(std::size_t k, const Scalar* p, Scalar* y, Scalar coef) const noexcept {
    const auto t = std::size_t(m_dense[k]);
    const Index* id = &m_tets[4 * t];
    const Eigen::Map<const Matrix3<Scalar>> Q(&m_dense_rotation[9 * k]);
    Matrix3<Scalar> Dp;
    load_edges(p, id, Dp);
    const Matrix3<Scalar> A = Q.transpose() * (Dp * dm_inv(t));
    const Matrix3<Scalar> B = coef * Q * (A + A.transpose());  // 2 coef Q sym(A)
    const Matrix3<Scalar> H = B * dm_inv(t).transpose();
    Vector3<Scalar> f0 = Vector3<Scalar>::Zero();
    for (int c = 0; c < 3; ++c) {
      add(y, id[c + 1], H.col(c));
      f0 -= H.col(c);
    }
    add(y, id[0], f0);
  }
  FSM_ALWAYS_INLINE static void load_edges(const Scalar* x, const Index* id,
                                           Matrix3<Scalar>& Ds) noexcept {
    const Vector3<Scalar> o = row(x, id[0]);
    for (int k = 0; k < 3; ++k) Ds.col(k) = row(x, id[k + 1]) - o;
  }
  /// d(volume)/dx of the four nodes: (1/6) e2 x e3, e3 x e1, e1 x e2, and minus their sum.
  FSM_ALWAYS_INLINE static void volume_gradient(const Matrix3<Scalar>& Ds,
                                                Vector3<Scalar> g[4]) noexcept {
    g[1] = Ds.col(1).cross(Ds.col(2)) / Scalar(6);
    g[2] = Ds.col(2).cross(Ds.col(0)) / Scalar(6);
    g[3] = Ds.col(0).cross(Ds.col(1)) / Scalar(6);
    g[0] = -(g[1] + g[2] + g[3]);
  }
  [[nodiscard]] Eigen::Map<const Matrix3<Scalar>> dm_inv(std::size_t t) const noexcept {
    return Eigen::Map<const Matrix3<Scalar>>(&m_dm_inv[9 * t]);
  }
  template <typename Triplets>
  static void push_pair(Triplets& trip, Index i, Index j, const Matrix3<Scalar>& K) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        trip.emplace_back(3 * i + r, 3 * i + c, K(r, c));
        trip.emplace_back(3 * j + r, 3 * j + c, K(r, c));
        trip.emplace_back(3 * i + r, 3 * j + c, -K(r, c));
        trip.emplace_back(3 * j + r, 3 * i + c, -K(r, c));
      }
  }

  // The edge springs of [begin, end): y += B (p_j - p_i) on j, minus on i. On the links' SIMD
  // apply kernel when `p4` (p padded to 4 per node) is given and the CPU has it: an edge's block
  // is a link's with no isotropic part.
  void apply_edges(std::size_t begin, std::size_t end, const Scalar* p, Scalar* y,
                   const Scalar* p4) const noexcept {
    if constexpr (std::is_same_v<Scalar, double>) {
      if (p4 && m_simd) {
        if (const auto kernel = simd::link_apply_kernel()) {
          kernel(m_edges.data(), m_edge_block.data(), p4, y, std::int32_t(begin),
                 std::int32_t(end));
          return;
        }
      }
    }
    (void)p4;
    for (std::size_t e = begin; e < end; ++e) {
      const Scalar* B = &m_edge_block[std::size_t(edge_block_size) * e];
      const std::ptrdiff_t a = 3 * std::ptrdiff_t(m_edges[2 * e]);
      const std::ptrdiff_t b = 3 * std::ptrdiff_t(m_edges[2 * e + 1]);
      const Scalar s = B[3] * (B[0] * (p[b] - p[a]) + B[1] * (p[b + 1] - p[a + 1]) +
                               B[2] * (p[b + 2] - p[a + 2]));
      for (int c = 0; c < 3; ++c) {
        y[a + c] -= s * B[c];
        y[b + c] += s * B[c];
      }
    }
  }
  // Volumetric first pass over the elements [begin, end): s_a += (grad v_T . p) / 4 at each of
  // their nodes a (grad v_a . p, summed over a's elements, once every share is in).
  void volumetric_spread(std::size_t begin, std::size_t end, const Scalar* p,
                         Scalar* s) const noexcept {
    for (std::size_t t = begin; t < end; ++t) {
      const Index* id = &m_tets[4 * t];
      const Scalar* g = grad(t);
      Scalar d(0);
      for (int k = 0; k < 4; ++k) {
        const Scalar* q = p + 3 * std::ptrdiff_t(id[k]);
        d += g[4 * (3 * k)] * q[0] + g[4 * (3 * k + 1)] * q[1] + g[4 * (3 * k + 2)] * q[2];
      }
      d *= Scalar(0.25);
      for (int k = 0; k < 4; ++k) s[id[k]] += d;
    }
  }
  // Volumetric second pass over [begin, end): y += (mean of s over the element's nodes) grad v_T.
  void volumetric_gather(std::size_t begin, std::size_t end, const Scalar* s,
                         Scalar* y) const noexcept {
    for (std::size_t t = begin; t < end; ++t) {
      const Index* id = &m_tets[4 * t];
      const Scalar* g = grad(t);
      const Scalar c = Scalar(0.25) * (s[id[0]] + s[id[1]] + s[id[2]] + s[id[3]]);
      for (int k = 0; k < 4; ++k) {
        Scalar* q = y + 3 * std::ptrdiff_t(id[k]);
        q[0] += c * g[4 * (3 * k)];
        q[1] += c * g[4 * (3 * k + 1)];
        q[2] += c * g[4 * (3 * k + 2)];
      }
    }
  }

  /// Adds a g g^T to node i's diagonal block (m_node_blocks).
  void add_block(Index i, Scalar g0, Scalar g1, Scalar g2, Scalar a) noexcept {
    Scalar* o = &m_node_blocks[6 * std::size_t(i)];
    o[0] += a * g0 * g0;
    o[1] += a * g1 * g1;
    o[2] += a * g2 * g2;
    o[3] += a * g0 * g1;
    o[4] += a * g0 * g2;
    o[5] += a * g1 * g2;
  }

  /// One step's J of element t (flutter_change): two reversals in a row of a change larger than
  /// flutter_change mark it.
  void watch_flutter(std::size_t t, Scalar j) noexcept {
    const Scalar d = j - m_step_j[t];
    const auto limit = Scalar(flutter_change);
    const bool reversal =
        d * m_step_dj[t] < Scalar(0) && std::abs(d) > limit && std::abs(m_step_dj[t]) > limit;
    m_reversals[t] = reversal ? std::uint8_t(std::min(2, m_reversals[t] + 1)) : std::uint8_t(0);
    if (m_reversals[t] >= 2 && !m_fluttered[t]) {
      m_fluttered[t] = 1;
      ++m_num_fluttered;
    }
    m_step_j[t] = j;
    m_step_dj[t] = d;
  }

  // y += sum_a coefficient(a) (grad v_a . p) grad v_a, with the gradients of prepare_implicit().
  // On the SIMD kernels when `p4` (p padded to 4 per node) is given and the CPU has them.
  // `spread`: grad v_a . p for every node a, known already (then the first pass is skipped).
  template <typename Coefficient>
  void apply_volumetric(const Scalar* p, Scalar* y, Coefficient coefficient,
                        const Scalar* p4 = nullptr, const Scalar* spread_s = nullptr) noexcept {
    Scalar* s = m_node_scratch.data();
    if (spread_s)
      std::copy(spread_s, spread_s + m_num_nodes, s);
    else
      std::fill(s, s + m_num_nodes, Scalar(0));
    if constexpr (std::is_same_v<Scalar, double>) {
      if (p4 && pair_product_ready()) {
        const auto n = std::int32_t(m_num_nodes);
        if (!spread_s)
          simd::pair_spread_kernel()(m_pair_start.data(), m_pair_node.data(), m_pair_grad.data(),
                                     p4, s, 0, n);
        for (Index a = 0; a < m_num_nodes; ++a) s[a] *= coefficient(a);
        simd::pair_gather_kernel()(m_pair_start.data(), m_pair_node.data(), m_pair_grad_t.data(), s,
                                   y, 0, n);
        return;
      }
    }
    (void)p4;
    if (!spread_s) volumetric_spread(0, m_volume.size(), p, s);
    for (Index a = 0; a < m_num_nodes; ++a) s[a] *= coefficient(a);
    volumetric_gather(0, m_volume.size(), s, y);
  }

  Index m_num_nodes{0};
  std::vector<Index> m_tets;            // 4 per element
  std::vector<Index> m_element_tet;     // per element: its tetrahedron in the model
  std::vector<std::uint8_t> m_removed;  // per element: cut or torn (carries nothing)
  std::vector<Scalar> m_node_volume_whole, m_edge_k_whole;  // before any removal
  std::vector<Index> m_tet_element;   // per model tetrahedron: its element, or -1
  std::vector<Index> m_element_edge;  // 12 per element: (edge, share in the edge's CSR) x 6
  std::vector<Index> m_node_count, m_edge_count;       // intact elements at each node, on each edge
  std::vector<Scalar> m_dm_inv;                        // 9 per element, column-major D_m^-1
  std::vector<Scalar> m_volume;                        // rest volume per element (m^3)
  std::vector<Scalar> m_c10, m_c10_large, m_q_switch;  // per element
  std::vector<Scalar> m_node_volume, m_node_bulk, m_node_tau;  // per node
  std::vector<Index> m_edges;                                  // 2 per edge
  std::vector<Scalar> m_edge_k, m_edge_tau;                    // per edge (N/m, s)
  // Each edge's spring as the sum of its elements' shares (CSR), so that an element's state
  // (m_state_factor and its pressure, set by add_forces()) stiffens the tangent of its edges: a
  // tangent far softer than the forces would make the step unstable.
  std::vector<Index> m_edge_part_start, m_edge_part_element;
  std::vector<Scalar> m_edge_part_k;
  // Per element at the last add_forces(): its current C10 over its small-strain C10 (bilinear
  // stiffening) times max(1, g(J)), and its mean nodal pressure.
  std::vector<Scalar> m_state_factor, m_pressure;
  // Per element: its share's factor in edge_stiffness() (0 with the element tangent or removed).
  std::vector<Scalar> m_edge_factor;
  std::vector<Scalar> m_quality;         // per element: shape_quality() at rest
  std::vector<Scalar> m_pressure_share;  // per element: l_rms^3 / (30 V)
  // The element tangents (set_element_tangent_quality(), add_forces()): which elements, their F
  // from add_forces() turned into their rotations by prepare_implicit() (9, column-major), and
  // h^2 c V at the last prepare_implicit().
  Scalar m_element_tangent_quality{Scalar(default_element_tangent_quality)};
  std::vector<std::uint8_t> m_poor_shape;       // per element: quality below the threshold
  std::vector<std::uint8_t> m_element_tangent;  // per element, at the last add_forces()
  ReservedVector<Index> m_dense;  // refilled by add_forces() within refresh()'s capacity
  std::vector<Scalar> m_dense_rotation, m_dense_coefficient;
  // Per-step scratch (sized by refresh).
  // edge_block_size per edge: n, (h^2 + h tau) k and 0 (a link's block, simd_links.hpp).
  static constexpr int edge_block_size = 5;
  std::vector<Scalar> m_edge_block;
  std::vector<Scalar> m_edge_rate;    // per edge: n . (v_j - v_i) at the last viscous add_forces()
  std::vector<Scalar> m_node_rate;    // per node: d(nodal volume)/dt, the same
  std::vector<Scalar> m_edge_weight;  // per edge: h^2 k at the last prepare_implicit() (scratch)
  std::uint64_t m_rate_generation{~std::uint64_t(0)};  // m_generation when they were kept
  std::vector<Scalar> m_node_coefficient;              // per node
  // The tangent's 3 x 3 diagonal blocks per node (xx yy zz xy xz yz), from prepare_implicit().
  std::vector<Scalar> m_node_blocks;
  std::vector<Scalar> m_node_scratch;  // per node
  mutable std::vector<Scalar> m_energy_scratch;
  // The element kernels (build_batches()): inputs, outputs, and the states padded to 4 per node.
  bool m_simd{true};
  // The flutter watch (flutter_change): per element, J at the last watched step, its change then,
  // reversals in a row, and whether it has fluttered.
  std::vector<Scalar> m_step_j, m_step_dj;
  std::vector<std::uint8_t> m_reversals, m_fluttered;
  std::size_t m_num_fluttered{0};
  bool m_watch{false}, m_flutter_guard{true};
  // save_watch()'s copy.
  std::vector<Scalar> m_saved_step_j, m_saved_step_dj;
  std::vector<std::uint8_t> m_saved_reversals, m_saved_fluttered;
  std::size_t m_saved_num_fluttered{0};
  // add_forces()'s by-products and the term's generation (generation()).
  Scalar m_forces_energy{0};
  Index m_forces_inverted{0};
  std::uint64_t m_generation{0};
  std::vector<std::int32_t> m_batch_nodes;
  // The volumetric product's node pairs (build_pairs(), pair_gradients()).
  std::vector<std::int32_t> m_pair_start, m_pair_node, m_pair_slot, m_pair_transpose,
      m_pair_diagonal;
  std::vector<Scalar> m_pair_grad, m_pair_grad_t;
  std::uint64_t m_pair_generation{~std::uint64_t(0)};
  std::vector<Scalar> m_batch_rest, m_batch_out, m_batch_grad, m_v4;
  mutable std::vector<Scalar> m_x4, m_energy_out;
  // Smoothed strains (build_domains()): each domain's elements (CSR), the share s of their rest
  // volume a domain has, a (m_element_share); per-step scratch: each element's F and the sum of
  // its domains' stresses.
  StrainSmoothing m_smoothing{StrainSmoothing::element};
  std::vector<Index> m_domain_start{0}, m_domain_elements;
  Scalar m_domain_share{1};
  Scalar m_element_share{
      Scalar(default_element_share)};  // the element strain's share (set_smoothing())
  mutable std::vector<Scalar> m_element_F;
  std::vector<Scalar> m_element_P;
};

}  // namespace fsm::detail
