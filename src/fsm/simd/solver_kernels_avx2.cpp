// The CG kernels for AVX2 with FMA (this file alone is compiled with -mavx2 -mfma).

#include "solver_kernels.hpp"

namespace fsm::detail::simd {

using Avx2 = xsimd::fma3<xsimd::avx2>;

FSM_SIMD_SOLVER_GETTERS(avx2, Avx2)

}  // namespace fsm::detail::simd
