// The link kernels for AVX2 with FMA (this file alone is compiled with -mavx2 -mfma).

#include "link_kernels.hpp"

namespace fsm::detail::simd {

using Avx2 = xsimd::fma3<xsimd::avx2>;

LinkForceKernel avx2_link_force_kernel(bool bilinear, bool along_link) noexcept {
  if (bilinear)
    return along_link ? &link_forces<Avx2, true, true> : &link_forces<Avx2, true, false>;
  return along_link ? &link_forces<Avx2, false, true> : &link_forces<Avx2, false, false>;
}

LinkPrepareKernel avx2_link_prepare_kernel(bool bilinear, bool along_link) noexcept {
  if (bilinear)
    return along_link ? &link_prepare<Avx2, true, true> : &link_prepare<Avx2, true, false>;
  return along_link ? &link_prepare<Avx2, false, true> : &link_prepare<Avx2, false, false>;
}

LinkApplyKernel avx2_link_apply_kernel() noexcept {
  return &link_apply<Avx2>;
}

LinkEnergyKernel avx2_link_energy_kernel() noexcept {
  return &link_energy<Avx2>;
}

}  // namespace fsm::detail::simd
