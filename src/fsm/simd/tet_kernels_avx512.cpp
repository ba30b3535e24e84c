// The element kernels for CPUs with AVX-512VL (compiled with -mavx512f -mavx512vl -mavx512dq, as
// link_kernels_avx512.cpp).

#include "evex_arch.hpp"
#include "tet_kernels.hpp"

namespace fsm::detail::simd {

TetForceKernel avx512_tet_force_kernel() noexcept {
  return &tet_forces<Avx2Evex>;
}

TetEnergyKernel avx512_tet_energy_kernel() noexcept {
  return &tet_energy<Avx2Evex>;
}

TetSpreadKernel avx512_tet_spread_kernel() noexcept {
  return &tet_spread<Avx2Evex>;
}

TetGatherKernel avx512_tet_gather_kernel() noexcept {
  return &tet_gather<Avx2Evex>;
}

}  // namespace fsm::detail::simd
