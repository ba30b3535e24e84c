// The element kernels for AVX2 with FMA (compiled with -mavx2 -mfma, as link_kernels_avx2.cpp).

#include "tet_kernels.hpp"

namespace fsm::detail::simd {

using Avx2 = xsimd::fma3<xsimd::avx2>;

FSM_SIMD_TET_GETTERS(avx2, Avx2)

}  // namespace fsm::detail::simd
