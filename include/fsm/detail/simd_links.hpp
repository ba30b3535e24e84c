#pragma once

// The link force loop on SIMD registers (xsimd), chosen at run time for the CPU. A plain interface
// (no Eigen, no templates) so that the kernels' translation units, compiled for their instruction
// set, share no inline code with the rest of the library. ForceModel<double>::evaluate uses it
// when Options::simd is set and the CPU has a kernel; the scalar loop (accumulate_link_forces)
// stays the reference the tests compare with.

#include <cstdint>

namespace fsm::detail::simd {

/// Raw views of the link arrays: `ij` holds (i, j) per link.
struct LinkArrays {
  const std::int32_t* ij;
  const double *rest, *ks, *kd, *kl, *es;
};

/// Accumulates the Voigt forces of links [begin, end) into `out` (3 per node: F_i += F,
/// F_j -= F), as detail::accumulate_link_forces does. `x4` and `v4` hold 4 doubles per node
/// (x, y, z, any), so that one load reads a node.
using LinkForceKernel = void (*)(const LinkArrays& links, const double* x4, const double* v4,
                                 double* out, std::int32_t begin, std::int32_t end);

/// The kernel for this CPU, or nullptr (no SIMD build, or a CPU without AVX2 and FMA).
/// `bilinear`: the modulus switches at a finite strain; `along_link`: DampingModel::along_link
/// (else full_relative_velocity).
LinkForceKernel link_force_kernel(bool bilinear, bool along_link) noexcept;

/// The links' part of ForceModel::prepare_implicit for links [begin, end), all carrying force:
/// per link the block (n, a, b) of B = h D + h^2 K = a n n^T + b I into `blocks` (5 per link), and
/// h F + h^2 K u (u = v_j - v_i) into `rhs` (3 per node: += on i, -= on j). `definite`: the
/// transverse term of a compressed link dropped (JacobianForm::definite), else symmetric.
using LinkPrepareKernel = void (*)(const LinkArrays& links, const double* x4, const double* v4,
                                   double h, bool definite, double* blocks, double* rhs,
                                   std::int32_t begin, std::int32_t end);

/// y += the links' part of A p for links [begin, end): -B_l (p_j - p_i) on i, +B_l (p_j - p_i) on
/// j, with the blocks of the prepare kernel; `p4` holds 4 doubles per node, `y` 3.
using LinkApplyKernel = void (*)(const std::int32_t* ij, const double* blocks, const double* p4,
                                 double* y, std::int32_t begin, std::int32_t end);

/// The elastic energy (J) of links [begin, end), VoigtLink::energy summed; `x` holds 3 doubles
/// per node (the model's positions) for `num_nodes` nodes.
using LinkEnergyKernel = double (*)(const LinkArrays& links, const double* x,
                                    std::int32_t num_nodes, std::int32_t begin, std::int32_t end);

/// The energy kernel for this CPU, or nullptr.
LinkEnergyKernel link_energy_kernel() noexcept;

/// The links' 3 x 3 diagonal blocks for links [begin, end), what ForceModel::add_link_node_blocks
/// does with the same roundings: each link's a n n^T + b I (its `blocks` entry: n, a, b) added to
/// both ends' 6 doubles (xx, yy, zz, xy, xz, yz) in `out`.
using LinkNodeBlocksKernel = void (*)(const std::int32_t* ij, const double* blocks, double* out,
                                      std::int32_t begin, std::int32_t end);

/// The node-block kernel for this CPU, or nullptr.
LinkNodeBlocksKernel link_node_blocks_kernel() noexcept;
/// The continuum law's edge dashpots (ContinuumTerm::add_forces's viscous pass) for edges
/// [begin, end) of `ij`: per edge, its direction n = (x_j - x_i) / |x_j - x_i| (0 for a zero
/// length) into entries 0-2 of its 5 in `blocks` (the others untouched), its rate of extension
/// r = n . (v_j - v_i) into `rate`, and the force (tau k) r n added to `out` on i and subtracted on
/// j (3 per node; tau and k per edge). `x4`, `v4` as for the link kernels.
using EdgeDashpotKernel = void (*)(const std::int32_t* ij, const double* tau, const double* k,
                                   const double* x4, const double* v4, double* blocks, double* rate,
                                   double* out, std::int32_t begin, std::int32_t end);
/// For edges [begin, end): w r n added to `out` on i and subtracted on j, with n from entries 0-2
/// of each edge's 5 in `blocks`, r from `rate` and w per edge (ContinuumTerm::prepare_implicit's
/// right-hand side).
using EdgeScatterKernel = void (*)(const std::int32_t* ij, const double* blocks, const double* rate,
                                   const double* w, double* out, std::int32_t begin,
                                   std::int32_t end);
/// The edge kernels for this CPU, or nullptr.
EdgeDashpotKernel edge_dashpot_kernel() noexcept;
EdgeScatterKernel edge_scatter_kernel() noexcept;

/// The prepare kernel for this CPU, or nullptr.
LinkPrepareKernel link_prepare_kernel(bool bilinear, bool along_link) noexcept;

/// The apply kernel for this CPU, or nullptr.
LinkApplyKernel link_apply_kernel() noexcept;

/// The instruction set of the kernels link_force_kernel() returns: "avx2+fma", "avx2+fma
/// (avx512vl)" (the same kernels compiled for AVX-512VL, chosen where the CPU has it unless the
/// environment variable FSM_SIMD is "avx2"; any other value is ignored), or "none".
const char* instruction_set() noexcept;

}  // namespace fsm::detail::simd
