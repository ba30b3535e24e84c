#pragma once

// The conjugate-gradient solve's vector work on SIMD registers (xsimd), chosen at run time for the
// CPU as the link kernels are (simd_links.hpp): a plain interface, no Eigen. The implicit
// integrator uses it for its (block-)Jacobi preconditioned CG on doubles: one pass per iteration
// does the update, the preconditioner and r^T z together, where separate vector operations read
// the same arrays five times. Its scalar loops stay the reference the tests compare with.
//
// Vectors hold 3 doubles per node (the model's layout). The preconditioner is stored by groups of
// four nodes: group g holds 24 doubles, entry c (xx yy zz xy xz yz of the inverse block) of node
// 4 g + l at 24 g + 4 c + l; precondition_size() gives the length.

#include <cstdint>

namespace fsm::detail::simd {

/// Doubles the grouped preconditioner of n nodes takes.
constexpr std::int64_t precondition_size(std::int32_t n) noexcept {
  return 24 * ((std::int64_t(n) + 3) / 4);
}

/// Writes the grouped preconditioner of n nodes into `inv`. With `blocks` (6 per node: xx yy zz
/// xy xz yz of the diagonal block), each block's inverse where the block is positive definite
/// (a > 0, its leading 2 x 2 minor > 0, a finite determinant > 0), else 1 / `diag` on the diagonal
/// (3 per node); without (nullptr), 1 / `diag` (Jacobi).
using PreconditionKernel = void (*)(std::int32_t n, const double* blocks, const double* diag,
                                    double* inv);

/// One CG step's vector work on n nodes: dv += alpha p, r -= alpha q, z = P r (the grouped
/// preconditioner `inv`); returns r^T z. With `p` null, only z = P r and r^T z.
using CgUpdateKernel = double (*)(std::int32_t n, double alpha, const double* p, const double* q,
                                  double* dv, double* r, const double* inv, double* z);

/// p = z + beta p over `count` doubles.
using CgDirectionKernel = void (*)(std::int64_t count, double beta, const double* z, double* p);

/// a^T b over `count` doubles.
using DotKernel = double (*)(std::int64_t count, const double* a, const double* b);

/// The kernels for this CPU, or nullptr (no SIMD build, or a CPU without AVX2 and FMA).
PreconditionKernel precondition_kernel() noexcept;
CgUpdateKernel cg_update_kernel() noexcept;
CgDirectionKernel cg_direction_kernel() noexcept;
DotKernel dot_kernel() noexcept;

}  // namespace fsm::detail::simd
