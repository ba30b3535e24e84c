#pragma once

// The instruction set of the *_avx512.cpp kernel files: xsimd's AVX2 + FMA batches (four doubles),
// compiled with AVX-512VL so that the compiler has 32 vector registers and the EVEX forms. A type
// of its own, so that the kernels and the xsimd templates they instantiate on it differ from the
// AVX2 files' and cannot be merged with them at link time (an AVX2-only CPU must never run an EVEX
// instruction). Not quite everything: xsimd's explicit specializations for the base types (the AVX
// registers' conversions) are shared; optimised, they are inlined, so the kernel files are
// compiled optimised in every build type (CMakeLists.txt), and ctest's
// Simd.KernelObjectsShareNoCode checks that every weak function of these objects names this type.
// Include only in files compiled with -mavx512f -mavx512vl -mavx512dq.

#include <xsimd/xsimd.hpp>

namespace fsm::detail::simd {

struct Avx2Evex : xsimd::fma3<xsimd::avx2> {
  static constexpr char const* name() noexcept { return "avx2+fma (avx512vl)"; }
};

}  // namespace fsm::detail::simd

namespace xsimd::types {
XSIMD_DECLARE_SIMD_REGISTER_ALIAS(fsm::detail::simd::Avx2Evex, fma3<avx2>);
}  // namespace xsimd::types
