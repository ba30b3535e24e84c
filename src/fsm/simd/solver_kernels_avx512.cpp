// The CG kernels for CPUs with AVX-512VL: the AVX2 kernels' code (four doubles a batch), compiled
// with -mavx512f -mavx512vl -mavx512dq, as link_kernels_avx512.cpp is.

#include "evex_arch.hpp"
#include "solver_kernels.hpp"

namespace fsm::detail::simd {

FSM_SIMD_SOLVER_GETTERS(avx512, Avx2Evex)

}  // namespace fsm::detail::simd
