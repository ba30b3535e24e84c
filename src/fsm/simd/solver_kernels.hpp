#pragma once

// The CG kernels' body (simd_solver.hpp), instantiated per instruction set by
// solver_kernels_<isa>.cpp, each compiled with that set's flags (and no FMA contraction: each
// operation rounds as the integrator's scalar loops do, which stay the reference). Four nodes a
// batch: their rows (x, y, z and the next node's x) are loaded and transposed, as in the link
// kernels, so the 3 x 3 preconditioner works on one lane per node.

#include <xsimd/xsimd.hpp>

#include "fsm/detail/simd_solver.hpp"
#include "link_kernels.hpp"  // transpose4

namespace fsm::detail::simd {

// Node i's entry c in the grouped preconditioner (Arch only names the instantiation apart).
template <class Arch>
inline std::int64_t grouped(std::int32_t i, int c) noexcept {
  return 6 * std::int64_t(i & ~3) + 4 * c + (i & 3);
}

// One node of precondition(), scalar: the batches' remainder.
template <class Arch>
inline void precondition_one(std::int32_t i, const double* blocks, const double* diag,
                             double* inv) noexcept {
  const double* d = diag + 3 * std::int64_t(i);
  double out[6] = {1 / d[0], 1 / d[1], 1 / d[2], 0, 0, 0};
  if (blocks) {
    const double* B = blocks + 6 * std::int64_t(i);
    const double a = B[0], b = B[1], c = B[2], e3 = B[3], e4 = B[4], f = B[5];
    const double c00 = b * c - f * f, c01 = e4 * f - e3 * c, c02 = e3 * f - b * e4;
    const double det = a * c00 + e3 * c01 + e4 * c02;
    const double m2 = a * b - e3 * e3;
    if (det > 0 && a > 0 && m2 > 0 && det - det == 0) {
      const double s = 1 / det;
      out[0] = c00 * s;
      out[1] = (a * c - e4 * e4) * s;
      out[2] = m2 * s;
      out[3] = c01 * s;
      out[4] = c02 * s;
      out[5] = (e3 * e4 - a * f) * s;
    }
  }
  for (int c = 0; c < 6; ++c) inv[grouped<Arch>(i, c)] = out[c];
}

template <class Arch>
void precondition(std::int32_t n, const double* blocks, const double* diag, double* inv) noexcept {
  using B = xsimd::batch<double, Arch>;
  static_assert(B::size == 4, "four nodes a batch");
  const B zero(0.0), one(1.0);
  std::int32_t g = 0;
  for (; g + 4 < n; g += 4) {  // (node g + 3's row reads node g + 4's x)
    const double* D = diag + 3 * std::int64_t(g);
    B dx, dy, dz;
    load_transposed<Arch>(D, D + 3, D + 6, D + 9, dx, dy, dz);
    B out[6] = {one / dx, one / dy, one / dz, zero, zero, zero};
    if (blocks) {
      const double* K = blocks + 6 * std::int64_t(g);
      B a, b, c, e3, unused, e4, f;
      load_transposed4<Arch>(K, K + 6, K + 12, K + 18, a, b, c, e3);
      load_transposed4<Arch>(K + 2, K + 8, K + 14, K + 20, unused, unused, e4, f);
      const B c00 = b * c - f * f, c01 = e4 * f - e3 * c, c02 = e3 * f - b * e4;
      const B det = a * c00 + e3 * c01 + e4 * c02;
      const B m2 = a * b - e3 * e3;
      const auto ok = (det > zero) & (a > zero) & (m2 > zero) & ((det - det) == zero);
      const B s = one / det;
      out[0] = xsimd::select(ok, c00 * s, out[0]);
      out[1] = xsimd::select(ok, (a * c - e4 * e4) * s, out[1]);
      out[2] = xsimd::select(ok, m2 * s, out[2]);
      out[3] = xsimd::select(ok, c01 * s, zero);
      out[4] = xsimd::select(ok, c02 * s, zero);
      out[5] = xsimd::select(ok, (e3 * e4 - a * f) * s, zero);
    }
    double* I = inv + 6 * std::int64_t(g);
    for (int c = 0; c < 6; ++c) out[c].store_unaligned(I + 4 * c);
  }
  for (; g < n; ++g) precondition_one<Arch>(g, blocks, diag, inv);
}

// z = P r for node i, scalar; returns its r^T z.
template <class Arch>
inline double apply_one(std::int32_t i, const double* r, const double* inv, double* z) noexcept {
  const double* ri = r + 3 * std::int64_t(i);
  double* zi = z + 3 * std::int64_t(i);
  const double* I = inv + grouped<Arch>(i, 0);  // entry c at I[4 c]
  zi[0] = I[0] * ri[0] + I[12] * ri[1] + I[16] * ri[2];
  zi[1] = I[12] * ri[0] + I[4] * ri[1] + I[20] * ri[2];
  zi[2] = I[16] * ri[0] + I[20] * ri[1] + I[8] * ri[2];
  return ri[0] * zi[0] + ri[1] * zi[1] + ri[2] * zi[2];
}

template <class Arch>
double cg_update(std::int32_t n, double alpha, const double* p, const double* q, double* dv,
                 double* r, const double* inv, double* z) noexcept {
  using B = xsimd::batch<double, Arch>;
  const B a(alpha), zero(0.0);
  B acc(0.0);
  std::int32_t g = 0;
  for (; g + 4 < n; g += 4) {  // (node g + 3's row reads node g + 4's x)
    const std::int64_t o = 3 * std::int64_t(g);
    // The rows of the updated r, loaded before this batch's stores (node g + 4's x, in the last
    // row's fourth lane, is not used).
    B row[4];
    for (int k = 0; k < 4; ++k) {
      row[k] = B::load_unaligned(r + o + 3 * k);
      if (p) row[k] = row[k] - a * B::load_unaligned(q + o + 3 * k);
    }
    if (p) {
      for (int m = 0; m < 3; ++m) {  // the 12 doubles of the four nodes
        const std::int64_t f = o + 4 * m;
        (B::load_unaligned(dv + f) + a * B::load_unaligned(p + f)).store_unaligned(dv + f);
        (B::load_unaligned(r + f) - a * B::load_unaligned(q + f)).store_unaligned(r + f);
      }
    }
    B rx, ry, rz, unused;
    transpose4<Arch>(row[0], row[1], row[2], row[3], rx, ry, rz, unused);
    const double* I = inv + 6 * std::int64_t(g);
    const B i0 = B::load_unaligned(I), i1 = B::load_unaligned(I + 4), i2 = B::load_unaligned(I + 8),
            i3 = B::load_unaligned(I + 12), i4 = B::load_unaligned(I + 16),
            i5 = B::load_unaligned(I + 20);
    const B zx = i0 * rx + i3 * ry + i4 * rz;
    const B zy = i3 * rx + i1 * ry + i5 * rz;
    const B zz = i4 * rx + i5 * ry + i2 * rz;
    acc += rx * zx + ry * zy + rz * zz;
    // Back to rows, stored in order: each row's fourth lane (zero) lands on the next node's x,
    // which the next row, batch or remainder overwrites.
    transpose4<Arch>(zx, zy, zz, zero, row[0], row[1], row[2], row[3]);
    for (int k = 0; k < 4; ++k) row[k].store_unaligned(z + o + 3 * k);
  }
  double s = xsimd::hadd(acc);
  for (; g < n; ++g) {
    if (p) {
      for (std::int64_t f = 3 * std::int64_t(g); f < 3 * std::int64_t(g) + 3; ++f) {
        dv[f] = dv[f] + alpha * p[f];
        r[f] = r[f] - alpha * q[f];
      }
    }
    s += apply_one<Arch>(g, r, inv, z);
  }
  return s;
}

template <class Arch>
void cg_direction(std::int64_t count, double beta, const double* z, double* p) noexcept {
  using B = xsimd::batch<double, Arch>;
  const B b(beta);
  std::int64_t k = 0;
  for (; k + 4 <= count; k += 4)
    (B::load_unaligned(z + k) + b * B::load_unaligned(p + k)).store_unaligned(p + k);
  for (; k < count; ++k) p[k] = z[k] + beta * p[k];
}

template <class Arch>
double dot(std::int64_t count, const double* a, const double* b) noexcept {
  using B = xsimd::batch<double, Arch>;
  B s0(0.0), s1(0.0);  // two chains: the adds' latency
  std::int64_t k = 0;
  for (; k + 8 <= count; k += 8) {
    s0 += B::load_unaligned(a + k) * B::load_unaligned(b + k);
    s1 += B::load_unaligned(a + k + 4) * B::load_unaligned(b + k + 4);
  }
  for (; k + 4 <= count; k += 4) s0 += B::load_unaligned(a + k) * B::load_unaligned(b + k);
  double s = xsimd::hadd(s0 + s1);
  for (; k < count; ++k) s += a[k] * b[k];
  return s;
}

// The getters dispatch.cpp calls, for instruction set `isa` on xsimd architecture `Arch`.
#define FSM_SIMD_SOLVER_GETTERS(isa, Arch)                  \
  PreconditionKernel isa##_precondition_kernel() noexcept { \
    return &precondition<Arch>;                             \
  }                                                         \
  CgUpdateKernel isa##_cg_update_kernel() noexcept {        \
    return &cg_update<Arch>;                                \
  }                                                         \
  CgDirectionKernel isa##_cg_direction_kernel() noexcept {  \
    return &cg_direction<Arch>;                             \
  }                                                         \
  DotKernel isa##_dot_kernel() noexcept {                   \
    return &dot<Arch>;                                      \
  }

}  // namespace fsm::detail::simd
