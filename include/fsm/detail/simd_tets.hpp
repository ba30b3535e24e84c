#pragma once

// The continuum law's element loop on SIMD registers (xsimd), chosen at run time for the CPU, as
// the link kernels are (simd_links.hpp): a plain interface, no Eigen. ContinuumTerm<double> uses
// it for its per-element work (deformation gradient, neo-Hookean stress, element forces, volume
// gradients, energy), the forces' scatter to the nodes, the volumetric product and the volumetric
// part of the block-Jacobi blocks, and keeps the nodal pressures and the flags; its scalar loops
// stay the reference the tests compare with.

#include <cstdint>

namespace fsm::detail::simd {

/// Elements come in batches of four (the last one filled with copies of the last element).
/// Per batch, `nodes` holds 16 indices (corner c of lane l at 4 c + l) and `rest` holds
/// tet_rest_stride doubles, each quantity as 4 lanes: D_m^-1 (entry r + 3 c at [4 (r + 3 c)]),
/// then C10, C10 beyond the switch (0: linear), I1bar - 3 at the switch, rest volume.
constexpr int tet_rest_stride = 52;
constexpr int tet_rest_c10 = 36, tet_rest_c10_large = 40, tet_rest_q_switch = 44,
              tet_rest_volume = 48;

/// Per batch, the force kernel writes tet_out_stride doubles to `out`, each quantity as 4 lanes:
/// H = -V P D_m^-T (entry r + 3 c at [4 (r + 3 c)]: the force on corner c + 1; corner 0 gets
/// minus their sum), then the current volume, its rate (0 without velocities), the state factor
/// (bilinear stiffening times max(1, J^-2/3)), I1bar - 3 and V W (the deviatoric energy, as the
/// energy kernel computes it); and tet_grad_stride doubles to
/// `grad`: the volume gradients (corner k, axis a at [4 (3 k + a)]). The gradients have their own
/// array because the implicit product reads them at every iteration: a compact one keeps a large
/// model's in cache (with the other outputs between them, a 19,683-node lattice's product ran
/// 50 % slower than the scalar loop's).
constexpr int tet_out_stride = 4 * 14;
constexpr int tet_out_volume = 4 * 9, tet_out_rate = 4 * 10, tet_out_state = 4 * 11,
              tet_out_distortion = 4 * 12, tet_out_energy = 4 * 13;
constexpr int tet_grad_stride = 4 * 12;

/// The element kernel over batches [begin, end). `x4` and `v4` hold 4 doubles per node; `v4` may
/// be null (no rate). `j_min`: below it J^-2/3 is extended by its second-order Taylor polynomial.
using TetForceKernel = void (*)(const std::int32_t* nodes, const double* rest, const double* x4,
                                const double* v4, double j_min, double* out, double* grad,
                                std::int32_t begin, std::int32_t end);

/// Per batch, the energy kernel writes 8 doubles: V W (4 lanes), then the current volume.
constexpr int tet_energy_stride = 8;
using TetEnergyKernel = void (*)(const std::int32_t* nodes, const double* rest, const double* x4,
                                 double j_min, double* out, std::int32_t begin, std::int32_t end);

/// The volumetric product's two passes over batches [begin, end), of which only the first `nt`
/// elements count, with the volume gradients of the force kernel's output `grad`:
/// spread: s[a] += (grad v_T . p) / 4 at each corner a (p: 4 doubles per node);
/// gather: y[a] += c_T grad_a v_T with c_T the mean of s over the corners (y: `stride` doubles
/// per node, 4 (one 32-byte add per corner, the fourth unchanged) or 3).
using TetSpreadKernel = void (*)(const std::int32_t* nodes, const double* grad, const double* p4,
                                 double* s, std::int32_t begin, std::int32_t end, std::int32_t nt);
using TetGatherKernel = void (*)(const std::int32_t* nodes, const double* grad, const double* s,
                                 double* y, int stride, std::int32_t begin, std::int32_t end,
                                 std::int32_t nt);

/// The forces' scatter of ContinuumTerm::add_forces (its second pass) over batches [begin, end),
/// of which only the first `nt` elements count: with `out` and `grad` the force kernel's outputs
/// and `s` each node's pressure negated (0 at a node without volume), y[a] += H_a + c_T grad_a v_T
/// (y: 3 doubles per node), c_T the mean of s over the corners (minus the element's pressure),
/// written to `mean` per element. H_a is `out`'s column for corners 1-3, minus their sum for
/// corner 0. The same roundings in the same order per element as that pass, so the same forces
/// where no element shares a node with another of its batch (else the sums at a node come in
/// another order).
using TetForceScatterKernel = void (*)(const std::int32_t* nodes, const double* out,
                                       const double* grad, const double* s, double* y, double* mean,
                                       std::int32_t begin, std::int32_t end, std::int32_t nt);
/// The volumetric part of ContinuumTerm's 3 x 3 diagonal blocks over batches [begin, end), of
/// which only the first `nt` elements count: per element, a = (the sum of `coefficient` over its
/// corners) / 16, and a g_k g_k^T added to corner k's 6 doubles (xx, yy, zz, xy, xz, yz) in
/// `blocks`, g_k the volume gradient at corner k (`grad` as above). Each product rounds as
/// ContinuumTerm::add_block's.
using TetNodeBlocksKernel = void (*)(const std::int32_t* nodes, const double* grad,
                                     const double* coefficient, double* blocks, std::int32_t begin,
                                     std::int32_t end, std::int32_t nt);
/// The kernels for this CPU, or nullptr (no SIMD build, or a CPU without AVX2 and FMA).
TetForceKernel tet_force_kernel() noexcept;
TetForceScatterKernel tet_force_scatter_kernel() noexcept;
TetNodeBlocksKernel tet_node_blocks_kernel() noexcept;
TetEnergyKernel tet_energy_kernel() noexcept;
TetSpreadKernel tet_spread_kernel() noexcept;
TetGatherKernel tet_gather_kernel() noexcept;

}  // namespace fsm::detail::simd
