#pragma once

// The element kernels' body (simd_tets.hpp), instantiated per instruction set by
// tet_kernels_<isa>.cpp. The same formulas as detail::deviatoric, detail::volume_factor,
// ContinuumTerm::add_forces's two passes, its volumetric product and prepare_implicit's volumetric
// blocks, four elements per batch.

#include <xsimd/xsimd.hpp>

#include "fsm/detail/simd_tets.hpp"
#include "link_kernels.hpp"

namespace fsm::detail::simd {

// x^{-2/3} for x > 0 as detail::inverse_cbrt_squared, for N batches at once: a seed from the
// exponent bits, three Newton steps on y^-3 = x and a last one on g = y^2. The seed divides only
// the high word of the bits by 3 (in doubles: AVX2 has no 64-bit integer division), which moves it
// by about 2^-20 relative; the Newton steps take it to the same value. Each batch's steps are one
// chain of about 20 dependent products: the N chains side by side keep the core busy while each
// waits (one chain per element batch left a tenth of the force kernel waiting on it).
template <class Arch, int N>
inline void inverse_cbrt_squared(const xsimd::batch<double, Arch>* x,
                                 xsimd::batch<double, Arch>* out) noexcept {
  using B = xsimd::batch<double, Arch>;
  using U = xsimd::batch<std::uint64_t, Arch>;
  B y[N];
  for (int i = 0; i < N; ++i) {
    const U bits = xsimd::bitwise_cast<U>(x[i]);
    const B high = xsimd::batch_cast<double>(U(bits >> 32));  // exact: below 2^32
    const B seed_high = B(double(0x553ef0ffULL)) - xsimd::floor(high / B(3.0));
    // An integer-valued double below 2^52 plus 2^52 holds that integer in its low 52 bits.
    const U seed_bits = (xsimd::bitwise_cast<U>(seed_high + B(4503599627370496.0)) &
                         U(std::uint64_t(0xFFFFFFFFFFFFFULL)))
                        << 32;
    y[i] = xsimd::bitwise_cast<B>(seed_bits);
  }
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < N; ++i) y[i] *= (B(4.0) - x[i] * y[i] * y[i] * y[i]) * B(1.0 / 3.0);
  for (int i = 0; i < N; ++i) {
    const B g = y[i] * y[i];
    out[i] = g + g * (B(1.0) - x[i] * x[i] * g * g * g) * B(1.0 / 3.0);
  }
}

// One batch of elements: everything the kernels share, from the positions.
template <class Arch>
struct TetBatch {
  using B = xsimd::batch<double, Arch>;
  B d[3][3];  // edge vectors d[k][axis] = corner k+1 - corner 0
  B F[3][3];  // F[r][c]
  B J, I1, g, dg, q, W, slope, stiffening;

  // Each lane's edge rows (corner k+1 - corner 0) subtracted first, then one transpose per edge:
  // the same subtractions lane by lane as transposing the four corners (identical results).
  inline void load(const std::int32_t* nodes, const double* x4) noexcept {
    B origin[4], unused;
    for (int l = 0; l < 4; ++l) origin[l] = B::load_unaligned(x4 + 4 * std::int64_t(nodes[l]));
    for (int k = 0; k < 3; ++k) {
      const std::int32_t* n = nodes + 4 * (k + 1);
      B row[4];
      for (int l = 0; l < 4; ++l)
        row[l] = B::load_unaligned(x4 + 4 * std::int64_t(n[l])) - origin[l];
      transpose4<Arch>(row[0], row[1], row[2], row[3], d[k][0], d[k][1], d[k][2], unused);
    }
  }

  // F = Ds D_m^-1, J and I1.
  inline void deformation(const double* rest) noexcept {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        B s = d[0][r] * B::load_unaligned(rest + 4 * (0 + 3 * c));
        s += d[1][r] * B::load_unaligned(rest + 4 * (1 + 3 * c));
        s += d[2][r] * B::load_unaligned(rest + 4 * (2 + 3 * c));
        F[r][c] = s;
      }
    // J = F_0 . (F_1 x F_2) with F_c the columns.
    const B c0x = F[1][1] * F[2][2] - F[2][1] * F[1][2];
    const B c0y = F[2][1] * F[0][2] - F[0][1] * F[2][2];
    const B c0z = F[0][1] * F[1][2] - F[1][1] * F[0][2];
    J = F[0][0] * c0x + F[1][0] * c0y + F[2][0] * c0z;
    I1 = B(0.0);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) I1 += F[r][c] * F[r][c];
  }

  // The argument of J^-2/3 (J, or j_min below it).
  inline B clamped_j(double j_min) const noexcept { return xsimd::max(J, B(j_min)); }

  // After deformation(): the deviatoric energy density and its slope dW/dq, with ga =
  // clamped_j()^-2/3.
  inline void deviatoric(const double* rest, double j_min, const B& ga) noexcept {
    // volume_factor: J^-2/3 above j_min, its Taylor extension below.
    const double g0s = 1.0 / __builtin_cbrt(j_min * j_min);
    const double g1s = -2.0 / 3.0 * g0s / j_min;
    const double g2s = 10.0 / 9.0 * g0s / (j_min * j_min);
    const auto above = J >= B(j_min);
    const B Ja = clamped_j(j_min);
    const B t = J - B(j_min);
    g = xsimd::select(above, ga, B(g0s) + t * (B(g1s) + B(0.5 * g2s) * t));
    dg = xsimd::select(above, B(-2.0 / 3.0) * ga / Ja, B(g1s) + B(g2s) * t);
    q = I1 * g - B(3.0);
    const B c10 = B::load_unaligned(rest + tet_rest_c10);
    const B c10l = B::load_unaligned(rest + tet_rest_c10_large);
    const B qs = B::load_unaligned(rest + tet_rest_q_switch);
    const auto large = (c10l > B(0.0)) && (q > qs);
    W = c10 * q;
    slope = c10;
    stiffening = B(1.0);
    if (xsimd::any(large)) {
      const B s = xsimd::sqrt(xsimd::max(q, qs) / B(3.0)), ss = xsimd::sqrt(qs / B(3.0));
      const B safe = xsimd::select(large, s, B(1.0));
      W = xsimd::select(large, W + B(3.0) * (c10l - c10) * (s - ss) * (s - ss), W);
      slope = xsimd::select(large, c10 + (c10l - c10) * (B(1.0) - ss / safe), slope);
      stiffening = xsimd::select(large, c10l / c10, stiffening);
    }
  }
};

template <class Arch>
void tet_forces(const std::int32_t* nodes, const double* rest, const double* x4, const double* v4,
                double j_min, double* out, double* grad, std::int32_t begin,
                std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  // Two batches' deformations and J^-2/3 side by side (inverse_cbrt_squared), then each batch's
  // forces.
  TetBatch<Arch> pair[2];
  for (std::int32_t b = begin; b < end; ++b) {
    TetBatch<Arch>& e = pair[(b - begin) % 2];
    if ((b - begin) % 2 == 0) {
      const int count = b + 1 < end ? 2 : 1;
      B j[2], ga[2];
      for (int i = 0; i < count; ++i) {
        pair[i].load(nodes + 16 * std::int64_t(b + i), x4);
        pair[i].deformation(rest + tet_rest_stride * std::int64_t(b + i));
        j[i] = pair[i].clamped_j(j_min);
      }
      if (count == 2)
        inverse_cbrt_squared<Arch, 2>(j, ga);
      else
        inverse_cbrt_squared<Arch, 1>(j, ga);
      for (int i = 0; i < count; ++i)
        pair[i].deviatoric(rest + tet_rest_stride * std::int64_t(b + i), j_min, ga[i]);
    }
    const std::int32_t* n = nodes + 16 * std::int64_t(b);
    const double* R = rest + tet_rest_stride * std::int64_t(b);
    double* o = out + tet_out_stride * std::int64_t(b);
    double* og = grad + tet_grad_stride * std::int64_t(b);
    // cof(F) columns: F_1 x F_2, F_2 x F_0, F_0 x F_1.
    const auto& F = e.F;
    B cof[3][3];
    for (int c = 0; c < 3; ++c) {
      const int a = (c + 1) % 3, bb = (c + 2) % 3;
      cof[0][c] = F[1][a] * F[2][bb] - F[2][a] * F[1][bb];
      cof[1][c] = F[2][a] * F[0][bb] - F[0][a] * F[2][bb];
      cof[2][c] = F[0][a] * F[1][bb] - F[1][a] * F[0][bb];
    }
    // P = slope (2 g F + I1 g' cof); H = -V P D_m^-T.
    const B twog = B(2.0) * e.g, i1dg = e.I1 * e.dg;
    B P[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) P[r][c] = e.slope * (twog * F[r][c] + i1dg * cof[r][c]);
    const B V = B::load_unaligned(R + tet_rest_volume);
    const B mV = B(0.0) - V;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        B s = P[r][0] * B::load_unaligned(R + 4 * (c + 0));
        s += P[r][1] * B::load_unaligned(R + 4 * (c + 3));
        s += P[r][2] * B::load_unaligned(R + 4 * (c + 6));
        (mV * s).store_unaligned(o + 4 * (r + 3 * c));
      }
    // Volume gradients: (1/6) d1 x d2, d2 x d0, d0 x d1, and minus their sum; v = d0 . (d1 x d2)
    // / 6.
    const auto& d = e.d;
    B gr[4][3];
    for (int k = 0; k < 3; ++k) {
      const int a = (k + 1) % 3, bb = (k + 2) % 3;
      gr[k + 1][0] = d[a][1] * d[bb][2] - d[a][2] * d[bb][1];
      gr[k + 1][1] = d[a][2] * d[bb][0] - d[a][0] * d[bb][2];
      gr[k + 1][2] = d[a][0] * d[bb][1] - d[a][1] * d[bb][0];
    }
    const B vt = (d[0][0] * gr[1][0] + d[0][1] * gr[1][1] + d[0][2] * gr[1][2]) / B(6.0);
    for (int k = 1; k < 4; ++k)
      for (int a = 0; a < 3; ++a) gr[k][a] = gr[k][a] / B(6.0);
    for (int a = 0; a < 3; ++a) gr[0][a] = B(0.0) - (gr[1][a] + gr[2][a] + gr[3][a]);
    for (int k = 0; k < 4; ++k)
      for (int a = 0; a < 3; ++a) gr[k][a].store_unaligned(og + 4 * (3 * k + a));
    vt.store_unaligned(o + tet_out_volume);
    B rate(0.0);
    if (v4) {
      for (int c = 0; c < 4; ++c) {
        B vx, vy, vz;
        load_transposed<Arch>(v4 + 4 * std::int64_t(n[4 * c]), v4 + 4 * std::int64_t(n[4 * c + 1]),
                              v4 + 4 * std::int64_t(n[4 * c + 2]),
                              v4 + 4 * std::int64_t(n[4 * c + 3]), vx, vy, vz);
        rate += gr[c][0] * vx + gr[c][1] * vy + gr[c][2] * vz;
      }
    }
    rate.store_unaligned(o + tet_out_rate);
    (e.stiffening * xsimd::max(B(1.0), e.g)).store_unaligned(o + tet_out_state);
    e.q.store_unaligned(o + tet_out_distortion);
    (V * e.W).store_unaligned(o + tet_out_energy);
  }
}

template <class Arch>
void tet_energy(const std::int32_t* nodes, const double* rest, const double* x4, double j_min,
                double* out, std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  for (std::int32_t b = begin; b < end; ++b) {
    const double* R = rest + tet_rest_stride * std::int64_t(b);
    double* o = out + tet_energy_stride * std::int64_t(b);
    TetBatch<Arch> e;
    e.load(nodes + 16 * std::int64_t(b), x4);
    e.deformation(R);
    const B j = e.clamped_j(j_min);
    B ga;
    inverse_cbrt_squared<Arch, 1>(&j, &ga);
    e.deviatoric(R, j_min, ga);
    (B::load_unaligned(R + tet_rest_volume) * e.W).store_unaligned(o);
    const auto& d = e.d;
    const B cx = d[1][1] * d[2][2] - d[1][2] * d[2][1];
    const B cy = d[1][2] * d[2][0] - d[1][0] * d[2][2];
    const B cz = d[1][0] * d[2][1] - d[1][1] * d[2][0];
    ((d[0][0] * cx + d[0][1] * cy + d[0][2] * cz) / B(6.0)).store_unaligned(o + 4);
  }
}

// The forces' scatter (simd_tets.hpp): per element c_T, the mean of s over its corners, written to
// `mean`, and y[a] += H_a + c_T grad_a v_T, the corners in add_forces's order 1, 2, 3, 0 (H_0 =
// ((0 - H_1) - H_2) - H_3 as there).
template <class Arch>
void tet_force_scatter(const std::int32_t* nodes, const double* h, const double* grad,
                       const double* s, double* y, double* mean, std::int32_t begin,
                       std::int32_t end, std::int32_t nt) noexcept {
  using B = xsimd::batch<double, Arch>;
  for (std::int32_t b = begin; b < end; ++b) {
    const std::int32_t* n = nodes + 16 * std::int64_t(b);
    const double* g = grad + tet_grad_stride * std::int64_t(b);
    const double* o = h + tet_out_stride * std::int64_t(b);
    const int lanes = nt - 4 * b < 4 ? int(nt - 4 * b) : 4;
    double c[4];
    for (int l = 0; l < 4; ++l)
      c[l] = l < lanes ? 0.25 * (s[n[l]] + s[n[4 + l]] + s[n[8 + l]] + s[n[12 + l]]) : 0.0;
    for (int l = 0; l < lanes; ++l) mean[4 * std::int64_t(b) + l] = c[l];
    const B C{c[0], c[1], c[2], c[3]};  // from registers: a load of four scalar stores stalls
    B h0[3];
    for (int a = 0; a < 3; ++a)
      h0[a] = B(0.0) - B::load_unaligned(o + 4 * a) - B::load_unaligned(o + 4 * (a + 3)) -
              B::load_unaligned(o + 4 * (a + 6));
    for (int corner = 0; corner < 4; ++corner) {
      const int k = (corner + 1) % 4;
      B t[3];
      for (int a = 0; a < 3; ++a)
        t[a] = (k == 0 ? h0[a] : B::load_unaligned(o + 4 * (a + 3 * (k - 1)))) +
               C * B::load_unaligned(g + 4 * (3 * k + a));
      B r[4];
      transpose4<Arch>(t[0], t[1], t[2], B(0.0), r[0], r[1], r[2], r[3]);
      alignas(32) double row[4];
      for (int l = 0; l < lanes; ++l) {
        double* q = y + 3 * std::int64_t(n[4 * k + l]);
        r[l].store_aligned(row);
        q[0] += row[0];
        q[1] += row[1];
        q[2] += row[2];
      }
    }
  }
}

// The volumetric product on node pairs (simd_tets.hpp).
template <class Arch>
void pair_build(const double* grad, const std::int32_t* slot, double* G, std::int32_t nt) noexcept {
  using B = xsimd::batch<double, Arch>;
  for (std::int32_t b = 0; 4 * b < nt; ++b) {
    const double* g = grad + tet_grad_stride * std::int64_t(b);
    const int lanes = nt - 4 * b < 4 ? int(nt - 4 * b) : 4;
    for (int j = 0; j < 4; ++j) {
      B r[4];
      transpose4<Arch>(B(0.25) * B::load_unaligned(g + 4 * (3 * j)),
                       B(0.25) * B::load_unaligned(g + 4 * (3 * j + 1)),
                       B(0.25) * B::load_unaligned(g + 4 * (3 * j + 2)), B(0.0), r[0], r[1], r[2],
                       r[3]);
      for (int l = 0; l < lanes; ++l) {
        const std::int32_t* s = slot + 16 * (4 * std::int64_t(b) + l) + j;
        for (int i = 0; i < 4; ++i) {
          if (i == j) continue;
          double* o = G + 4 * std::int64_t(s[4 * i]);
          (B::load_unaligned(o) + r[l]).store_unaligned(o);
        }
      }
    }
  }
}

template <class Arch>
void pair_finish(const std::int32_t* start, const std::int32_t* diagonal,
                 const std::int32_t* transpose, double* G, double* H, std::int32_t begin,
                 std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  for (std::int32_t a = begin; a < end; ++a) {
    const std::int32_t d = diagonal[a];
    if (d < 0) continue;
    B sum(0.0);
    for (std::int32_t k = start[a]; k < start[a + 1]; ++k)
      if (k != d) sum += B::load_unaligned(G + 4 * std::int64_t(k));
    (B(0.0) - sum).store_unaligned(G + 4 * std::int64_t(d));
    for (std::int32_t k = start[a]; k < start[a + 1]; ++k)
      B::load_unaligned(G + 4 * std::int64_t(transpose[k]))
          .store_unaligned(H + 4 * std::int64_t(k));
  }
}

template <class Arch>
void pair_blocks(const std::int32_t* start, const std::int32_t* col, const double* H,
                 const double* coefficient, double* blocks, std::int32_t begin,
                 std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  using Rotate = xsimd::batch_constant<xsimd::batch<std::uint64_t, Arch>, 1, 2, 0, 3>;
  alignas(32) double sq[4], cross[4];
  for (std::int32_t a = begin; a < end; ++a) {
    B square(0.0), product(0.0);
    for (std::int32_t k = start[a]; k < start[a + 1]; ++k) {
      const B h = B::load_unaligned(H + 4 * std::int64_t(k));
      const B ch = B(coefficient[col[k]]) * h;
      square = xsimd::fma(ch, h, square);                              // xx yy zz
      product = xsimd::fma(ch, xsimd::swizzle(h, Rotate()), product);  // xy yz zx
    }
    square.store_aligned(sq);
    product.store_aligned(cross);
    double* o = blocks + 6 * std::int64_t(a);
    o[0] += sq[0];
    o[1] += sq[1];
    o[2] += sq[2];
    o[3] += cross[0];
    o[4] += cross[2];
    o[5] += cross[1];
  }
}

// Over each row a in [begin, end): acc = term(k, acc) summed over the row's pairs k, two pairs in
// flight, then done(a, the four lanes of the sum).
template <class Arch, class Term, class Done>
inline void pair_rows(const std::int32_t* start, std::int32_t begin, std::int32_t end, Term term,
                      Done done) noexcept {
  using B = xsimd::batch<double, Arch>;
  alignas(32) double sum[4];
  for (std::int32_t a = begin; a < end; ++a) {
    B acc0(0.0), acc1(0.0);
    std::int32_t k = start[a];
    const std::int32_t last = start[a + 1];
    for (; k + 1 < last; k += 2) {
      acc0 = term(k, acc0);
      acc1 = term(k + 1, acc1);
    }
    if (k < last) acc0 = term(k, acc0);
    (acc0 + acc1).store_aligned(sum);
    done(a, sum);
  }
}

template <class Arch>
void pair_spread(const std::int32_t* start, const std::int32_t* col, const double* G,
                 const double* p4, double* s, std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  pair_rows<Arch>(
      start, begin, end,
      [&](std::int32_t k, const B& acc) {
        return xsimd::fma(B::load_unaligned(G + 4 * std::int64_t(k)),
                          B::load_unaligned(p4 + 4 * std::int64_t(col[k])), acc);
      },
      // (The fourth lane: G's 0 times whatever p holds there.)
      [&](std::int32_t a, const double* sum) { s[a] = sum[0] + sum[1] + sum[2]; });
}

template <class Arch>
void pair_gather(const std::int32_t* start, const std::int32_t* col, const double* H,
                 const double* s, double* y, std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  pair_rows<Arch>(
      start, begin, end,
      [&](std::int32_t k, const B& acc) {
        return xsimd::fma(B(s[col[k]]), B::load_unaligned(H + 4 * std::int64_t(k)), acc);
      },
      [&](std::int32_t a, const double* sum) {
        double* o = y + 3 * std::int64_t(a);
        o[0] += sum[0];
        o[1] += sum[1];
        o[2] += sum[2];
      });
}

// The getters of one instruction set's element kernels, as FSM_SIMD_LINK_GETTERS.
#define FSM_SIMD_TET_GETTERS(isa, Arch)                             \
  TetForceKernel isa##_tet_force_kernel() noexcept {                \
    return &tet_forces<Arch>;                                       \
  }                                                                 \
  TetEnergyKernel isa##_tet_energy_kernel() noexcept {              \
    return &tet_energy<Arch>;                                       \
  }                                                                 \
  PairBuildKernel isa##_pair_build_kernel() noexcept {              \
    return &pair_build<Arch>;                                       \
  }                                                                 \
  PairFinishKernel isa##_pair_finish_kernel() noexcept {            \
    return &pair_finish<Arch>;                                      \
  }                                                                 \
  PairBlocksKernel isa##_pair_blocks_kernel() noexcept {            \
    return &pair_blocks<Arch>;                                      \
  }                                                                 \
  PairSpreadKernel isa##_pair_spread_kernel() noexcept {            \
    return &pair_spread<Arch>;                                      \
  }                                                                 \
  PairGatherKernel isa##_pair_gather_kernel() noexcept {            \
    return &pair_gather<Arch>;                                      \
  }                                                                 \
  TetForceScatterKernel isa##_tet_force_scatter_kernel() noexcept { \
    return &tet_force_scatter<Arch>;                                \
  }

}  // namespace fsm::detail::simd
