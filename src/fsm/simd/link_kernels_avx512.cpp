// The link kernels for CPUs with AVX-512VL: the AVX2 kernels' code (four doubles a batch), compiled
// with -mavx512f -mavx512vl -mavx512dq (this file and tet_kernels_avx512.cpp alone) for 32 vector
// registers, which the two-batch loops need (docs/benchmarks.md, 2026-11-28).

#include "evex_arch.hpp"
#include "link_kernels.hpp"

namespace fsm::detail::simd {

FSM_SIMD_LINK_GETTERS(avx512, Avx2Evex)

}  // namespace fsm::detail::simd
