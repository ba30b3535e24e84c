#pragma once

// The link kernels' body, instantiated per instruction set by link_kernels_<isa>.cpp (each compiled
// with that set's flags). Include only xsimd and the plain interface here: anything inline shared
// with the rest of the library could be linked in its wide-instruction version.

#include <xsimd/xsimd.hpp>

#include "fsm/detail/simd_links.hpp"

namespace fsm::detail::simd {

// The 4 x 4 transpose: rows a, b, c, d into columns X, Y, Z, W (and back: it is its own inverse).
template <class Arch>
inline void transpose4(const xsimd::batch<double, Arch>& a, const xsimd::batch<double, Arch>& b,
                       const xsimd::batch<double, Arch>& c, const xsimd::batch<double, Arch>& d,
                       xsimd::batch<double, Arch>& X, xsimd::batch<double, Arch>& Y,
                       xsimd::batch<double, Arch>& Z, xsimd::batch<double, Arch>& W) noexcept {
  using B = xsimd::batch<double, Arch>;
  using Swap = xsimd::batch_constant<xsimd::batch<std::uint64_t, Arch>, 2, 3, 0, 1>;
  using High = xsimd::batch_bool_constant<B, false, false, true, true>;
  const B t0 = xsimd::zip_lo(a, b), t1 = xsimd::zip_hi(a, b);
  const B t2 = xsimd::zip_lo(c, d), t3 = xsimd::zip_hi(c, d);
  X = xsimd::select(High{}, xsimd::swizzle(t2, Swap{}), t0);
  Y = xsimd::select(High{}, xsimd::swizzle(t3, Swap{}), t1);
  Z = xsimd::select(High{}, t2, xsimd::swizzle(t0, Swap{}));
  W = xsimd::select(High{}, t3, xsimd::swizzle(t1, Swap{}));
}

// Four rows of four doubles into the batches of their columns.
template <class Arch>
inline void load_transposed4(const double* r0, const double* r1, const double* r2, const double* r3,
                             xsimd::batch<double, Arch>& X, xsimd::batch<double, Arch>& Y,
                             xsimd::batch<double, Arch>& Z,
                             xsimd::batch<double, Arch>& W) noexcept {
  using B = xsimd::batch<double, Arch>;
  transpose4<Arch>(B::load_unaligned(r0), B::load_unaligned(r1), B::load_unaligned(r2),
                   B::load_unaligned(r3), X, Y, Z, W);
}

// Four nodes' (x, y, z, _) rows into the batches X, Y, Z (4 lanes: one per node).
template <class Arch>
inline void load_transposed(const double* r0, const double* r1, const double* r2, const double* r3,
                            xsimd::batch<double, Arch>& X, xsimd::batch<double, Arch>& Y,
                            xsimd::batch<double, Arch>& Z) noexcept {
  xsimd::batch<double, Arch> unused;
  load_transposed4<Arch>(r0, r1, r2, r3, X, Y, Z, unused);
}

// Four links' differences of node rows, (x_j - x_i) per link, into the batches of their columns:
// the rows are subtracted first and one transpose does the rest (the same subtractions, lane by
// lane, as transposing both ends and subtracting: the results are identical).
template <class Arch>
inline void load_difference_transposed(const double* base, const std::int32_t* P,
                                       xsimd::batch<double, Arch>& X, xsimd::batch<double, Arch>& Y,
                                       xsimd::batch<double, Arch>& Z) noexcept {
  using B = xsimd::batch<double, Arch>;
  auto row = [&](int k) {
    return B::load_unaligned(base + 4 * std::int64_t(P[2 * k + 1])) -
           B::load_unaligned(base + 4 * std::int64_t(P[2 * k]));
  };
  B unused;
  transpose4<Arch>(row(0), row(1), row(2), row(3), X, Y, Z, unused);
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

// Scatter of per-link vectors r: out_i += r, out_j -= r, the first node's run of links summed in
// registers and written once (Arch only names the instantiation apart).
template <class Arch>
struct RunScatter {
  double* out;
  std::int32_t cur{-1};
  double ax{0}, ay{0}, az{0};
  explicit RunScatter(double* o) noexcept : out(o) {}
  inline void put(std::int32_t i, std::int32_t j, double rx, double ry, double rz) noexcept {
    double* oj = out + 3 * std::int64_t(j);
    oj[0] -= rx;
    oj[1] -= ry;
    oj[2] -= rz;
    if (i != cur) {
      flush();
      cur = i;
    }
    ax += rx;
    ay += ry;
    az += rz;
  }
  inline void flush() noexcept {
    if (cur >= 0) {
      double* oi = out + 3 * std::int64_t(cur);
      oi[0] += ax;
      oi[1] += ay;
      oi[2] += az;
    }
    ax = ay = az = 0;
  }
};

// Four links per batch: each link's two nodes are loaded as rows, subtracted, and the differences
// transposed (no gathers: on this machine's AMD cores AVX2 gathers cost more than the arithmetic
// they feed); the forces go back link by link, the first node's summed over a run of links that
// share it (the builder sorts links so), which keeps its force out of memory between links.
template <class Arch, bool Bilinear, bool AlongLink>
void link_forces(const LinkArrays& L, const double* x4, const double* v4, double* out,
                 std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  static_assert(B::size == 4, "the transpose is written for 4 lanes");
  RunScatter<Arch> scatter(out);
  alignas(64) double Fx[8], Fy[8], Fz[8];
  // One batch of four links from l into lanes [k, k + 4) of Fx, Fy, Fz.
  auto batch = [&](std::int32_t l, int k) {
    const std::int32_t* P = L.ij + 2 * std::int64_t(l);
    B dx, dy, dz, ux, uy, uz;
    load_difference_transposed<Arch>(x4, P, dx, dy, dz);
    load_difference_transposed<Arch>(v4, P, ux, uy, uz);
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
      (s * dx).store_aligned(Fx + k);
      (s * dy).store_aligned(Fy + k);
      (s * dz).store_aligned(Fz + k);
    } else {
      const B s = fe * inv;
      (s * dx + kd * ux).store_aligned(Fx + k);
      (s * dy + kd * uy).store_aligned(Fy + k);
      (s * dz + kd * uz).store_aligned(Fz + k);
    }
  };
  // Two batches before their scatter: their square roots and divisions overlap.
  std::int32_t l = begin;
  for (; l + 8 <= end; l += 8) {
    batch(l, 0);
    batch(l + 4, 4);
    const std::int32_t* P = L.ij + 2 * std::int64_t(l);
    for (int k = 0; k < 8; ++k) scatter.put(P[2 * k], P[2 * k + 1], Fx[k], Fy[k], Fz[k]);
  }
  for (; l + 4 <= end; l += 4) {
    batch(l, 0);
    const std::int32_t* P = L.ij + 2 * std::int64_t(l);
    for (int k = 0; k < 4; ++k) scatter.put(P[2 * k], P[2 * k + 1], Fx[k], Fy[k], Fz[k]);
  }
  for (; l < end; ++l) {
    double F[3];
    link_force<Arch, Bilinear, AlongLink>(L, l, x4, v4, F);
    scatter.put(L.ij[2 * l], L.ij[2 * l + 1], F[0], F[1], F[2]);
  }
  scatter.flush();
}

// The prepare kernel (see simd_links.hpp). The same formulas as link_state, symmetric_stiffness
// and ForceModel::prepare_implicit's link loop, four links per batch.
template <class Arch, bool Bilinear, bool AlongLink>
void link_prepare(const LinkArrays& L, const double* x4, const double* v4, double h, bool definite,
                  double* blocks, double* rhs, std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  const double h2 = h * h;
  RunScatter<Arch> scatter(rhs);
  alignas(64) double outs[2][9][4];  // two batches' rx, ry, rz, n0, n1, n2, a, b, (unused)
  auto batch = [&](int slot, const B& dx, const B& dy, const B& dz, const B& ux, const B& uy,
                   const B& uz, const B& rest, const B& ks, const B& kd, const B& kl,
                   const B& esw) {
    double(&out)[9][4] = outs[slot];
    const B l2 = dx * dx + dy * dy + dz * dz;
    const auto pos = l2 > B(0.0);
    const B len = xsimd::sqrt(l2);
    const B inv = xsimd::select(pos, B(1.0) / len, B(0.0));
    const B nx = dx * inv, ny = dy * inv, nz = dz * inv;
    const B e = len - rest;
    B fe = ks * e, tangent = ks;
    if (Bilinear) {
      const B es = esw * rest;
      const B a = xsimd::abs(e);
      const auto small = a <= es;
      fe = xsimd::select(small, fe, xsimd::copysign(ks * es + kl * (a - es), e));
      tangent = xsimd::select(small, ks, kl);
    }
    const B un = ux * nx + uy * ny + uz * nz;
    const B total = AlongLink ? fe + kd * un : fe;
    const B used = definite ? xsimd::max(total, B(0.0)) : total;
    const B beta = xsimd::select(pos, used * inv, B(0.0));
    const B alpha = xsimd::select(pos, tangent - beta, B(0.0));
    // r = h F + h^2 K u, F = total n (+ kd u), K u = alpha (n . u) n + beta u.
    const B an = alpha * un;
    B rx = B(h) * (total * nx) + B(h2) * (an * nx + beta * ux);
    B ry = B(h) * (total * ny) + B(h2) * (an * ny + beta * uy);
    B rz = B(h) * (total * nz) + B(h2) * (an * nz + beta * uz);
    if (!AlongLink) {
      rx += B(h) * (kd * ux);
      ry += B(h) * (kd * uy);
      rz += B(h) * (kd * uz);
    }
    rx.store_aligned(out[0]);
    ry.store_aligned(out[1]);
    rz.store_aligned(out[2]);
    nx.store_aligned(out[3]);
    ny.store_aligned(out[4]);
    nz.store_aligned(out[5]);
    (B(h2) * alpha + (AlongLink ? B(h) * kd : B(0.0))).store_aligned(out[6]);
    (B(h2) * beta + (AlongLink ? B(0.0) : B(h) * kd)).store_aligned(out[7]);
  };
  auto emit = [&](std::int32_t l, int lanes, int slot) {
    const double(&out)[9][4] = outs[slot];
    for (int k = 0; k < lanes; ++k) {
      double* blk = blocks + 5 * std::int64_t(l + k);
      blk[0] = out[3][k];
      blk[1] = out[4][k];
      blk[2] = out[5][k];
      blk[3] = out[6][k];
      blk[4] = out[7][k];
      scatter.put(L.ij[2 * (l + k)], L.ij[2 * (l + k) + 1], out[0][k], out[1][k], out[2][k]);
    }
  };
  auto full_batch = [&](std::int32_t l, int slot) {
    const std::int32_t* P = L.ij + 2 * std::int64_t(l);
    B dx, dy, dz, ux, uy, uz;
    load_difference_transposed<Arch>(x4, P, dx, dy, dz);
    load_difference_transposed<Arch>(v4, P, ux, uy, uz);
    batch(slot, dx, dy, dz, ux, uy, uz, B::load_unaligned(L.rest + l), B::load_unaligned(L.ks + l),
          B::load_unaligned(L.kd + l), B::load_unaligned(L.kl + l), B::load_unaligned(L.es + l));
  };
  // Two batches before their output, as in link_forces.
  std::int32_t l = begin;
  for (; l + 8 <= end; l += 8) {
    full_batch(l, 0);
    full_batch(l + 4, 1);
    emit(l, 4, 0);
    emit(l + 4, 4, 1);
  }
  for (; l + 4 <= end; l += 4) {
    full_batch(l, 0);
    emit(l, 4, 0);
  }
  if (l < end) {  // the remainder: fill the missing lanes with copies of the last link
    alignas(64) double d[6][4], c[5][4];
    for (int k = 0; k < 4; ++k) {
      const std::int32_t q = l + k < end ? l + k : end - 1;
      const double* xi = x4 + 4 * std::int64_t(L.ij[2 * q]);
      const double* xj = x4 + 4 * std::int64_t(L.ij[2 * q + 1]);
      const double* vi = v4 + 4 * std::int64_t(L.ij[2 * q]);
      const double* vj = v4 + 4 * std::int64_t(L.ij[2 * q + 1]);
      for (int a = 0; a < 3; ++a) {
        d[a][k] = xj[a] - xi[a];
        d[3 + a][k] = vj[a] - vi[a];
      }
      c[0][k] = L.rest[q];
      c[1][k] = L.ks[q];
      c[2][k] = L.kd[q];
      c[3][k] = L.kl[q];
      c[4][k] = L.es[q];
    }
    batch(0, B::load_aligned(d[0]), B::load_aligned(d[1]), B::load_aligned(d[2]),
          B::load_aligned(d[3]), B::load_aligned(d[4]), B::load_aligned(d[5]),
          B::load_aligned(c[0]), B::load_aligned(c[1]), B::load_aligned(c[2]),
          B::load_aligned(c[3]), B::load_aligned(c[4]));
    emit(l, int(end - l), 0);
  }
  scatter.flush();
}

// The apply kernel (see simd_links.hpp): g = a (n . dp) n + b dp with dp = p_j - p_i; y_i -= g,
// y_j += g.
template <class Arch>
void link_apply(const std::int32_t* ij, const double* blocks, const double* p4, double* y,
                std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  RunScatter<Arch> scatter(y);  // puts -g: y_i += (-g), y_j -= (-g)
  alignas(64) double gx[8], gy[8], gz[8];
  // One batch of four links from l into lanes [k, k + 4) of gx, gy, gz.
  auto batch = [&](std::int32_t l, int k) {
    const std::int32_t* P = ij + 2 * std::int64_t(l);
    B dx, dy, dz, n0, n1, n2, a;
    load_difference_transposed<Arch>(p4, P, dx, dy, dz);
    const double* blk = blocks + 5 * std::int64_t(l);
    // (n0, n1, n2, a) of each link as rows; b on its own.
    load_transposed4<Arch>(blk, blk + 5, blk + 10, blk + 15, n0, n1, n2, a);
    alignas(32) const double bs[4] = {blk[4], blk[9], blk[14], blk[19]};
    const B b = B::load_aligned(bs);
    const B s = a * (n0 * dx + n1 * dy + n2 * dz);
    (B(0.0) - (s * n0 + b * dx)).store_aligned(gx + k);
    (B(0.0) - (s * n1 + b * dy)).store_aligned(gy + k);
    (B(0.0) - (s * n2 + b * dz)).store_aligned(gz + k);
  };
  std::int32_t l = begin;
  for (; l + 8 <= end; l += 8) {  // two batches before their scatter, as in link_forces
    batch(l, 0);
    batch(l + 4, 4);
    const std::int32_t* P = ij + 2 * std::int64_t(l);
    for (int k = 0; k < 8; ++k) scatter.put(P[2 * k], P[2 * k + 1], gx[k], gy[k], gz[k]);
  }
  for (; l + 4 <= end; l += 4) {
    batch(l, 0);
    const std::int32_t* P = ij + 2 * std::int64_t(l);
    for (int k = 0; k < 4; ++k) scatter.put(P[2 * k], P[2 * k + 1], gx[k], gy[k], gz[k]);
  }
  for (; l < end; ++l) {
    const double* Bl = blocks + 5 * std::int64_t(l);
    const double* pi = p4 + 4 * std::int64_t(ij[2 * l]);
    const double* pj = p4 + 4 * std::int64_t(ij[2 * l + 1]);
    const double dx = pj[0] - pi[0], dy = pj[1] - pi[1], dz = pj[2] - pi[2];
    const double s = Bl[3] * (Bl[0] * dx + Bl[1] * dy + Bl[2] * dz);
    scatter.put(ij[2 * l], ij[2 * l + 1], -(s * Bl[0] + Bl[4] * dx), -(s * Bl[1] + Bl[4] * dy),
                -(s * Bl[2] + Bl[4] * dz));
  }
  scatter.flush();
}

// The node-block kernel (see simd_links.hpp): each link's a n n^T + b I as (xx, yy, zz, xy, xz, yz)
// added to both ends, the first node's sum over a run of links that share it kept in registers.
// The first four entries are one batch: (a n0, a n1, a n2, a n0) times (n0, n1, n2, n1), plus b on
// the diagonal lanes; xz and yz are (a n0) n2 and (a n1) n2 of the same products. Per entry these
// are ForceModel::add_link_node_blocks's operations in its order: the results are identical to
// that loop's (where it is not contracted into FMA, which an FSM_NATIVE build may do).
template <class Arch>
void link_node_blocks(const std::int32_t* ij, const double* blocks, double* out, std::int32_t begin,
                      std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  using U = xsimd::batch<std::uint64_t, Arch>;
  static_assert(B::size == 4, "(xx, yy, zz, xy) in one batch");
  using Diagonal = xsimd::batch_bool_constant<B, true, true, true, false>;
  using A = xsimd::batch_constant<U, 3, 3, 3, 3>;
  using First = xsimd::batch_constant<U, 0, 1, 2, 0>;
  using Second = xsimd::batch_constant<U, 0, 1, 2, 1>;
  using Third = xsimd::batch_constant<U, 2, 2, 2, 2>;
  alignas(32) double r[4];
  for (std::int32_t l = begin; l < end;) {
    const std::int32_t i = ij[2 * std::int64_t(l)];
    B acc(0.0);
    double acc_xz = 0, acc_yz = 0;
    for (; l < end && ij[2 * std::int64_t(l)] == i; ++l) {
      const double* Bl = blocks + 5 * std::int64_t(l);
      const B nb = B::load_unaligned(Bl);  // (n0, n1, n2, a)
      const B p = xsimd::swizzle(nb, A{}) * xsimd::swizzle(nb, First{});
      const B q = p * xsimd::swizzle(nb, Second{});
      const B d = xsimd::select(Diagonal{}, q + B(Bl[4]), q);
      (p * xsimd::swizzle(nb, Third{})).store_aligned(r);
      double* o = out + 6 * std::int64_t(ij[2 * std::int64_t(l) + 1]);
      (B::load_unaligned(o) + d).store_unaligned(o);
      o[4] += r[0];
      o[5] += r[1];
      acc += d;
      acc_xz += r[0];
      acc_yz += r[1];
    }
    double* o = out + 6 * std::int64_t(i);
    (B::load_unaligned(o) + acc).store_unaligned(o);
    o[4] += acc_xz;
    o[5] += acc_yz;
  }
}

// The energy kernel (see simd_links.hpp): VoigtLink::energy of each link, four per batch. Each
// node's (x, y, z) is one 4-wide load from the 3-per-node array (its fourth lane the next node's
// x, unused; the last node, which has no next, is loaded lane by lane), and the four links'
// differences are transposed once, as in the force kernel. The bilinear form covers the linear
// links too (their switch strain is never reached).
template <class Arch>
inline double link_energy_one(const LinkArrays& L, const double* x, std::int32_t l) noexcept {
  const double* xi = x + 3 * std::int64_t(L.ij[2 * l]);
  const double* xj = x + 3 * std::int64_t(L.ij[2 * l + 1]);
  const double dx = xj[0] - xi[0], dy = xj[1] - xi[1], dz = xj[2] - xi[2];
  const double a = __builtin_fabs(__builtin_sqrt(dx * dx + dy * dy + dz * dz) - L.rest[l]);
  const double es = L.es[l] * L.rest[l];
  if (a <= es) return 0.5 * L.ks[l] * a * a;
  const double b = a - es;
  return 0.5 * L.ks[l] * es * es + L.ks[l] * es * b + 0.5 * L.kl[l] * b * b;
}

template <class Arch>
double link_energy(const LinkArrays& L, const double* x, std::int32_t num_nodes, std::int32_t begin,
                   std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  static_assert(B::size == 4, "four links per batch");
  const std::int32_t last = num_nodes - 1;
  auto node = [&](std::int32_t i) {
    const double* r = x + 3 * std::int64_t(i);
    return i < last ? B::load_unaligned(r) : B{r[0], r[1], r[2], 0.0};
  };
  B sum(0.0);
  std::int32_t l = begin;
  for (; l + 4 <= end; l += 4) {
    const std::int32_t* P = L.ij + 2 * std::int64_t(l);
    B dx, dy, dz, unused;
    transpose4<Arch>(node(P[1]) - node(P[0]), node(P[3]) - node(P[2]), node(P[5]) - node(P[4]),
                     node(P[7]) - node(P[6]), dx, dy, dz, unused);
    const B rest = B::load_unaligned(L.rest + l);
    const B ks = B::load_unaligned(L.ks + l);
    const B a = xsimd::abs(xsimd::sqrt(dx * dx + dy * dy + dz * dz) - rest);
    const B es = B::load_unaligned(L.es + l) * rest;
    const B b = a - es;
    const B large =
        B(0.5) * ks * es * es + ks * es * b + B(0.5) * B::load_unaligned(L.kl + l) * b * b;
    sum += xsimd::select(a <= es, B(0.5) * ks * a * a, large);
  }
  double e = xsimd::hadd(sum);
  for (; l < end; ++l) e += link_energy_one<Arch>(L, x, l);
  return e;
}

// The edge dashpot kernel (see simd_links.hpp): the formulas of ContinuumTerm::add_forces's
// viscous pass, four edges per batch, two batches before their output as in link_forces. One edge,
// scalar (the remainder): the batch's own formula, times 1 / l, so every edge rounds alike.
template <class Arch>
inline void edge_dashpot(const std::int32_t* ij, const double* tau, const double* k,
                         const double* x4, const double* v4, std::int32_t e, double n[3], double& r,
                         double F[3]) noexcept {
  const double* xi = x4 + 4 * std::int64_t(ij[2 * e]);
  const double* xj = x4 + 4 * std::int64_t(ij[2 * e + 1]);
  const double* vi = v4 + 4 * std::int64_t(ij[2 * e]);
  const double* vj = v4 + 4 * std::int64_t(ij[2 * e + 1]);
  const double dx = xj[0] - xi[0], dy = xj[1] - xi[1], dz = xj[2] - xi[2];
  const double l2 = dx * dx + dy * dy + dz * dz;
  const double inv = l2 > 0 ? 1 / __builtin_sqrt(l2) : 0.0;
  n[0] = dx * inv;
  n[1] = dy * inv;
  n[2] = dz * inv;
  r = n[0] * (vj[0] - vi[0]) + n[1] * (vj[1] - vi[1]) + n[2] * (vj[2] - vi[2]);
  const double c = tau[e] * k[e] * r;
  for (int a = 0; a < 3; ++a) F[a] = c * n[a];
}

template <class Arch>
void edge_dashpots(const std::int32_t* ij, const double* tau, const double* k, const double* x4,
                   const double* v4, double* blocks, double* rate, double* out, std::int32_t begin,
                   std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  RunScatter<Arch> scatter(out);
  alignas(64) double Fx[8], Fy[8], Fz[8], N[3][8];
  auto batch = [&](std::int32_t e, int slot) {
    const std::int32_t* P = ij + 2 * std::int64_t(e);
    B dx, dy, dz, ux, uy, uz;
    load_difference_transposed<Arch>(x4, P, dx, dy, dz);
    load_difference_transposed<Arch>(v4, P, ux, uy, uz);
    // One division a batch (times 1 / l rather than three divisions by l: the divider is what
    // this loop waits on); n differs from the scalar loop's d / l by at most an ulp.
    const B l2 = dx * dx + dy * dy + dz * dz;
    const B inv = xsimd::select(l2 > B(0.0), B(1.0) / xsimd::sqrt(l2), B(0.0));
    const B nx = dx * inv, ny = dy * inv, nz = dz * inv;
    const B r = nx * ux + ny * uy + nz * uz;
    r.store_unaligned(rate + e);
    const B c = B::load_unaligned(tau + e) * B::load_unaligned(k + e) * r;
    (c * nx).store_aligned(Fx + slot);
    (c * ny).store_aligned(Fy + slot);
    (c * nz).store_aligned(Fz + slot);
    nx.store_aligned(N[0] + slot);
    ny.store_aligned(N[1] + slot);
    nz.store_aligned(N[2] + slot);
  };
  auto emit = [&](std::int32_t e, int count) {
    for (int q = 0; q < count; ++q) {
      double* blk = blocks + 5 * std::int64_t(e + q);
      blk[0] = N[0][q];
      blk[1] = N[1][q];
      blk[2] = N[2][q];
      scatter.put(ij[2 * (e + q)], ij[2 * (e + q) + 1], Fx[q], Fy[q], Fz[q]);
    }
  };
  std::int32_t e = begin;
  for (; e + 8 <= end; e += 8) {
    batch(e, 0);
    batch(e + 4, 4);
    emit(e, 8);
  }
  for (; e + 4 <= end; e += 4) {
    batch(e, 0);
    emit(e, 4);
  }
  for (; e < end; ++e) {
    double n[3], F[3];
    edge_dashpot<Arch>(ij, tau, k, x4, v4, e, n, rate[e], F);
    double* blk = blocks + 5 * std::int64_t(e);
    blk[0] = n[0];
    blk[1] = n[1];
    blk[2] = n[2];
    scatter.put(ij[2 * e], ij[2 * e + 1], F[0], F[1], F[2]);
  }
  scatter.flush();
}

// The edge scatter kernel (see simd_links.hpp): (w r) n per edge, as prepare_implicit's loop
// computes it, four edges per batch.
template <class Arch>
void edge_scatter(const std::int32_t* ij, const double* blocks, const double* rate, const double* w,
                  double* out, std::int32_t begin, std::int32_t end) noexcept {
  using B = xsimd::batch<double, Arch>;
  RunScatter<Arch> scatter(out);
  alignas(64) double Fx[4], Fy[4], Fz[4];
  std::int32_t e = begin;
  for (; e + 4 <= end; e += 4) {
    const double* blk = blocks + 5 * std::int64_t(e);
    B n0, n1, n2, unused;
    load_transposed4<Arch>(blk, blk + 5, blk + 10, blk + 15, n0, n1, n2, unused);
    const B c = B::load_unaligned(w + e) * B::load_unaligned(rate + e);
    (c * n0).store_aligned(Fx);
    (c * n1).store_aligned(Fy);
    (c * n2).store_aligned(Fz);
    for (int q = 0; q < 4; ++q)
      scatter.put(ij[2 * (e + q)], ij[2 * (e + q) + 1], Fx[q], Fy[q], Fz[q]);
  }
  for (; e < end; ++e) {
    const double* blk = blocks + 5 * std::int64_t(e);
    const double c = w[e] * rate[e];
    scatter.put(ij[2 * e], ij[2 * e + 1], c * blk[0], c * blk[1], c * blk[2]);
  }
  scatter.flush();
}

// The getters of one instruction set's link kernels (`isa`_link_force_kernel, ...), defined by its
// *_<isa>.cpp file with its arch type; dispatch.cpp declares them (FSM_SIMD_DECLARE_GETTERS).
#define FSM_SIMD_LINK_GETTERS(isa, Arch)                                                      \
  LinkForceKernel isa##_link_force_kernel(bool bilinear, bool along_link) noexcept {          \
    if (bilinear)                                                                             \
      return along_link ? &link_forces<Arch, true, true> : &link_forces<Arch, true, false>;   \
    return along_link ? &link_forces<Arch, false, true> : &link_forces<Arch, false, false>;   \
  }                                                                                           \
  LinkPrepareKernel isa##_link_prepare_kernel(bool bilinear, bool along_link) noexcept {      \
    if (bilinear)                                                                             \
      return along_link ? &link_prepare<Arch, true, true> : &link_prepare<Arch, true, false>; \
    return along_link ? &link_prepare<Arch, false, true> : &link_prepare<Arch, false, false>; \
  }                                                                                           \
  LinkApplyKernel isa##_link_apply_kernel() noexcept {                                        \
    return &link_apply<Arch>;                                                                 \
  }                                                                                           \
  LinkEnergyKernel isa##_link_energy_kernel() noexcept {                                      \
    return &link_energy<Arch>;                                                                \
  }                                                                                           \
  LinkNodeBlocksKernel isa##_link_node_blocks_kernel() noexcept {                             \
    return &link_node_blocks<Arch>;                                                           \
  }                                                                                           \
  EdgeDashpotKernel isa##_edge_dashpot_kernel() noexcept {                                    \
    return &edge_dashpots<Arch>;                                                              \
  }                                                                                           \
  EdgeScatterKernel isa##_edge_scatter_kernel() noexcept {                                    \
    return &edge_scatter<Arch>;                                                               \
  }

}  // namespace fsm::detail::simd
