// The link kernels for CPUs with AVX-512VL: the AVX2 kernels' code (four doubles a batch), compiled
// with -mavx512f -mavx512vl -mavx512dq (this file and tet_kernels_avx512.cpp alone) for 32 vector
// registers, which the two-batch loops need (docs/benchmarks.md, 2026-11-28).

#include "evex_arch.hpp"
#include "link_kernels.hpp"

namespace fsm::detail::simd {

LinkForceKernel avx512_link_force_kernel(bool bilinear, bool along_link) noexcept {
  if (bilinear)
    return along_link ? &link_forces<Avx2Evex, true, true> : &link_forces<Avx2Evex, true, false>;
  return along_link ? &link_forces<Avx2Evex, false, true> : &link_forces<Avx2Evex, false, false>;
}

LinkPrepareKernel avx512_link_prepare_kernel(bool bilinear, bool along_link) noexcept {
  if (bilinear)
    return along_link ? &link_prepare<Avx2Evex, true, true> : &link_prepare<Avx2Evex, true, false>;
  return along_link ? &link_prepare<Avx2Evex, false, true> : &link_prepare<Avx2Evex, false, false>;
}

LinkApplyKernel avx512_link_apply_kernel() noexcept {
  return &link_apply<Avx2Evex>;
}

LinkEnergyKernel avx512_link_energy_kernel() noexcept {
  return &link_energy<Avx2Evex>;
}

}  // namespace fsm::detail::simd
