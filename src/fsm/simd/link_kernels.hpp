#pragma once

// The link kernels' body, instantiated per instruction set by link_kernels_<isa>.cpp (each compiled
// with that set's flags). Include only xsimd and the plain interface here: anything inline shared
// with the rest of the library could be linked in its wide-instruction version.

#include <xsimd/xsimd.hpp>

#include "fsm/detail/simd_links.hpp"

namespace fsm::detail::simd {

// Four nodes' (x, y, z, _) rows into the batches X, Y, Z (4 lanes: one per node).
template <class Arch>
inline void load_transposed(const double* r0, const double* r1, const double* r2,
                            const double* r3, xsimd::batch<double, Arch>& X,
                            xsimd::batch<double, Arch>& Y, xsimd::batch<double, Arch>& Z) noexcept {
  using B = xsimd::batch<double, Arch>;
  using Swap = xsimd::batch_constant<xsimd::batch<std::uint64_t, Arch>, 2, 3, 0, 1>;
  using High = xsimd::batch_bool_constant<B, false, false, true, true>;
  const B a = B::load_unaligned(r0), b = B::load_unaligned(r1), c = B::load_unaligned(r2),
          d = B::load_unaligned(r3);
  const B t0 = xsimd::zip_lo(a, b), t1 = xsimd::zip_hi(a, b);  // (a0 b0 a2 b2), (a1 b1 a3 b3)
  const B t2 = xsimd::zip_lo(c, d), t3 = xsimd::zip_hi(c, d);
  X = xsimd::select(High{}, xsimd::swizzle(t2, Swap{}), t0);
  Y = xsimd::select(High{}, xsimd::swizzle(t3, Swap{}), t1);
  Z = xsimd::select(High{}, t2, xsimd::swizzle(t0, Swap{}));
}

// One link, scalar: the batch kernel's remainder (the same formula as accumulate_link_forces).
// Arch only names the instantiation apart from other instruction sets' (it is compiled with this
// file's flags).
template <class Arch, bool Bilinear, bool AlongLink>
inline void link_force(const LinkArrays& L, std::int32_t l, const double* x4, const double* v4,
                       double F[3]) noexcept {
  const double* xi = x4 + 4 * std::int64_t(L.ij[2 * l]);
  const double* xj = x4 + 4 * std::int64_t(L.ij[2 * l + 1]);
  const double* vi = v4 + 4 * std::int64_t(L.ij[2 * l]);
  const double* vj = v4 + 4 * std::int64_t(L.ij[2 * l + 1]);
  const double dx = xj[0] - xi[0], dy = xj[1] - xi[1], dz = xj[2] - xi[2];
  const double ux = vj[0] - vi[0], uy = vj[1] - vi[1], uz = vj[2] - vi[2];
  const double l2 = dx * dx + dy * dy + dz * dz;
  const double inv = l2 > 0 ? 1 / __builtin_sqrt(l2) : 0;
  const double e = l2 * inv - L.rest[l];
  double fe = L.ks[l] * e;
  if (Bilinear) {
    const double es = L.es[l] * L.rest[l], a = __builtin_fabs(e);
    if (!(a <= es)) fe = __builtin_copysign(L.ks[l] * es + L.kl[l] * (a - es), e);
  }
  if (AlongLink) {
    const double s = (fe + L.kd[l] * (ux * dx + uy * dy + uz * dz) * inv) * inv;
    F[0] = s * dx;
    F[1] = s * dy;
    F[2] = s * dz;
  } else {
    const double s = fe * inv;
    F[0] = s * dx + L.kd[l] * ux;
    F[1] = s * dy + L.kd[l] * uy;
    F[2] = s * dz + L.kd[l] * uz;
  }
}

// Four links per batch: each link's two nodes are loaded as rows and transposed (no gathers: on
// this machine's AMD cores AVX2 gathers cost more than the arithmetic they feed); the forces go
// back link by link, the first node's summed over a run of links that share it (the builder sorts
// links so), which keeps its force out of memory between links.
template <class Arch, bool Bilinear, bool AlongLink>
void link_forces(const LinkArrays& L, const double* x4, const double* v4, double* out,
                 std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  static_assert(B::size == 4, "the transpose is written for 4 lanes");
  std::int32_t cur = -1;
  double ax = 0, ay = 0, az = 0;
  auto put = [&](std::int32_t i, std::int32_t j, double fx, double fy, double fz) {
    double* oj = out + 3 * std::int64_t(j);
    oj[0] -= fx;
    oj[1] -= fy;
    oj[2] -= fz;
    if (i != cur) {
      if (cur >= 0) {
        double* oi = out + 3 * std::int64_t(cur);
        oi[0] += ax;
        oi[1] += ay;
        oi[2] += az;
      }
      cur = i;
      ax = ay = az = 0;
    }
    ax += fx;
    ay += fy;
    az += fz;
  };
  alignas(64) double Fx[4], Fy[4], Fz[4];
  std::int32_t l = begin;
  for (; l + 4 <= end; l += 4) {
    const std::int32_t* P = L.ij + 2 * std::int64_t(l);
    const std::int64_t i0 = 4 * std::int64_t(P[0]), i1 = 4 * std::int64_t(P[2]),
                       i2 = 4 * std::int64_t(P[4]), i3 = 4 * std::int64_t(P[6]);
    const std::int64_t j0 = 4 * std::int64_t(P[1]), j1 = 4 * std::int64_t(P[3]),
                       j2 = 4 * std::int64_t(P[5]), j3 = 4 * std::int64_t(P[7]);
    B xi, yi, zi, xj, yj, zj, vxi, vyi, vzi, vxj, vyj, vzj;
    load_transposed<Arch>(x4 + i0, x4 + i1, x4 + i2, x4 + i3, xi, yi, zi);
    load_transposed<Arch>(x4 + j0, x4 + j1, x4 + j2, x4 + j3, xj, yj, zj);
    load_transposed<Arch>(v4 + i0, v4 + i1, v4 + i2, v4 + i3, vxi, vyi, vzi);
    load_transposed<Arch>(v4 + j0, v4 + j1, v4 + j2, v4 + j3, vxj, vyj, vzj);
    const B dx = xj - xi, dy = yj - yi, dz = zj - zi;
    const B ux = vxj - vxi, uy = vyj - vyi, uz = vzj - vzi;
    const B l2 = dx * dx + dy * dy + dz * dz;
    const B inv = xsimd::select(l2 > B(0.0), B(1.0) / xsimd::sqrt(l2), B(0.0));
    const B rest = B::load_unaligned(L.rest + l);
    const B ks = B::load_unaligned(L.ks + l);
    const B e = l2 * inv - rest;
    B fe = ks * e;
    if (Bilinear) {
      const B es = B::load_unaligned(L.es + l) * rest;
      const B a = xsimd::abs(e);
      fe = xsimd::select(a <= es, fe,
                         xsimd::copysign(ks * es + B::load_unaligned(L.kl + l) * (a - es), e));
    }
    const B kd = B::load_unaligned(L.kd + l);
    if (AlongLink) {
      const B s = (fe + kd * (ux * dx + uy * dy + uz * dz) * inv) * inv;
      (s * dx).store_aligned(Fx);
      (s * dy).store_aligned(Fy);
      (s * dz).store_aligned(Fz);
    } else {
      const B s = fe * inv;
      (s * dx + kd * ux).store_aligned(Fx);
      (s * dy + kd * uy).store_aligned(Fy);
      (s * dz + kd * uz).store_aligned(Fz);
    }
    for (int k = 0; k < 4; ++k) put(P[2 * k], P[2 * k + 1], Fx[k], Fy[k], Fz[k]);
  }
  for (; l < end; ++l) {
    double F[3];
    link_force<Arch, Bilinear, AlongLink>(L, l, x4, v4, F);
    put(L.ij[2 * l], L.ij[2 * l + 1], F[0], F[1], F[2]);
  }
  if (cur >= 0) {
    double* oi = out + 3 * std::int64_t(cur);
    oi[0] += ax;
    oi[1] += ay;
    oi[2] += az;
  }
}

}  // namespace fsm::detail::simd
