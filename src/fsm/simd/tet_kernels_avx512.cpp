// The element kernels for CPUs with AVX-512VL (compiled with -mavx512f -mavx512vl -mavx512dq, as
// link_kernels_avx512.cpp).

#include "evex_arch.hpp"
#include "tet_kernels.hpp"

namespace fsm::detail::simd {

FSM_SIMD_TET_GETTERS(avx512, Avx2Evex)

}  // namespace fsm::detail::simd
