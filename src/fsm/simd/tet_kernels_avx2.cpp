// The element kernels for AVX2 with FMA (compiled with -mavx2 -mfma, as link_kernels_avx2.cpp).

#include "tet_kernels.hpp"

namespace fsm::detail::simd {

using Avx2 = xsimd::fma3<xsimd::avx2>;

TetForceKernel avx2_tet_force_kernel() noexcept {
  return &tet_forces<Avx2>;
}

TetEnergyKernel avx2_tet_energy_kernel() noexcept {
  return &tet_energy<Avx2>;
}

TetSpreadKernel avx2_tet_spread_kernel() noexcept {
  return &tet_spread<Avx2>;
}

TetGatherKernel avx2_tet_gather_kernel() noexcept {
  return &tet_gather<Avx2>;
}

}  // namespace fsm::detail::simd
