#pragma once

// The continuum law's element loop on SIMD registers (xsimd), chosen at run time for the CPU, as
// the link kernels are (simd_links.hpp): a plain interface, no Eigen. ContinuumTerm<double> uses
// it for its per-element work (deformation gradient, neo-Hookean stress, element forces, volume
// gradients, energy), the forces' scatter to the nodes, the volumetric product on node pairs and
// the volumetric part of the block-Jacobi blocks, and keeps the nodal pressures and the flags; its
// scalar loops stay the reference the tests compare with.

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
/// `grad`: the volume gradients (corner k, axis a at [4 (3 k + a)]), in their own compact array:
/// the node pairs' build (below) reads them once a step, and the scalar product at every
/// iteration (with the other outputs between them, a 19,683-node lattice's product on the old
/// element kernels ran 50 % slower than the scalar loop's).
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
/// The volumetric product on node pairs (ContinuumTerm's pair gradients): `G` holds 4 doubles per
/// pair (the fourth 0), the rows in CSR (`start`, n + 1 entries, and `col`).
/// Build: G[slot[16 t + 4 i + j]] += grad_j v_t / 4 for the first `nt` elements t and their
/// corners i != j, from the force kernel's `grad` (G zeroed by the caller; the diagonal pairs are
/// left to the finish kernel).
using PairBuildKernel = void (*)(const double* grad, const std::int32_t* slot, double* G,
                                 std::int32_t nt);
/// Finish, rows [begin, end): each row's diagonal pair `diagonal[a]` (-1: an empty row) set to
/// minus the sum of the row's other pairs (an element's volume gradients sum to zero), then
/// H[k] = G[transpose[k]] over the row: H, the transposed pairs, holds G's pair (b, a) at (a, b).
using PairFinishKernel = void (*)(const std::int32_t* start, const std::int32_t* diagonal,
                                  const std::int32_t* transpose, double* G, double* H,
                                  std::int32_t begin, std::int32_t end);
/// Blocks, rows [begin, end): blocks[a] (xx, yy, zz, xy, xz, yz) += sum over row a of
/// coefficient[col k] H_k H_k^T: the volumetric part's exact diagonal blocks.
using PairBlocksKernel = void (*)(const std::int32_t* start, const std::int32_t* col,
                                  const double* H, const double* coefficient, double* blocks,
                                  std::int32_t begin, std::int32_t end);
/// Spread: s[a] = sum over row a of G_k . p[col k] for rows [begin, end) (p: 4 doubles per node,
/// the fourth not read).
using PairSpreadKernel = void (*)(const std::int32_t* start, const std::int32_t* col,
                                  const double* G, const double* p4, double* s, std::int32_t begin,
                                  std::int32_t end);
/// Gather: y[a] += sum over row a of s[col k] H_k for rows [begin, end), with H the transposed
/// pairs (H's pair (a, b) holds G's pair (b, a); y: 3 doubles per node).
using PairGatherKernel = void (*)(const std::int32_t* start, const std::int32_t* col,
                                  const double* H, const double* s, double* y, std::int32_t begin,
                                  std::int32_t end);
/// The kernels for this CPU, or nullptr (no SIMD build, or a CPU without AVX2 and FMA).
TetForceKernel tet_force_kernel() noexcept;
TetForceScatterKernel tet_force_scatter_kernel() noexcept;
TetEnergyKernel tet_energy_kernel() noexcept;
PairBuildKernel pair_build_kernel() noexcept;
PairFinishKernel pair_finish_kernel() noexcept;
PairBlocksKernel pair_blocks_kernel() noexcept;
PairSpreadKernel pair_spread_kernel() noexcept;
PairGatherKernel pair_gather_kernel() noexcept;

}  // namespace fsm::detail::simd
