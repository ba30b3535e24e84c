// Run-time choice of the link, element and CG kernels (compiled with the library's baseline flags:
// it must run on any x86-64 CPU, so it only asks the CPU what it has).

#include <cstdlib>
#include <cstring>

#include "fsm/detail/simd_links.hpp"
#include "fsm/detail/simd_solver.hpp"
#include "fsm/detail/simd_tets.hpp"

// The kernels whose getters take no argument: X(type, getter name).
#define FSM_SIMD_PLAIN_KERNELS(X)                    \
  X(LinkApplyKernel, link_apply_kernel)              \
  X(LinkEnergyKernel, link_energy_kernel)            \
  X(LinkNodeBlocksKernel, link_node_blocks_kernel)   \
  X(EdgeDashpotKernel, edge_dashpot_kernel)          \
  X(EdgeScatterKernel, edge_scatter_kernel)          \
  X(TetForceKernel, tet_force_kernel)                \
  X(TetEnergyKernel, tet_energy_kernel)              \
  X(PairBuildKernel, pair_build_kernel)              \
  X(PairFinishKernel, pair_finish_kernel)            \
  X(PairBlocksKernel, pair_blocks_kernel)            \
  X(PairSpreadKernel, pair_spread_kernel)            \
  X(PairGatherKernel, pair_gather_kernel)            \
  X(TetForceScatterKernel, tet_force_scatter_kernel) \
  X(PreconditionKernel, precondition_kernel)         \
  X(CgUpdateKernel, cg_update_kernel)                \
  X(CgDirectionKernel, cg_direction_kernel)          \
  X(DotKernel, dot_kernel)

namespace fsm::detail::simd {

#if defined(FSM_SIMD_AVX2)
// The getters each *_<isa>.cpp file defines (FSM_SIMD_LINK_GETTERS, FSM_SIMD_TET_GETTERS,
// FSM_SIMD_SOLVER_GETTERS).
#define FSM_SIMD_DECLARE_GETTERS(isa)                                                   \
  LinkForceKernel isa##_link_force_kernel(bool bilinear, bool along_link) noexcept;     \
  LinkPrepareKernel isa##_link_prepare_kernel(bool bilinear, bool along_link) noexcept; \
  FSM_SIMD_PLAIN_KERNELS(FSM_SIMD_DECLARE_PLAIN_##isa)
#define FSM_SIMD_DECLARE_PLAIN_avx2(Type, name) Type avx2_##name() noexcept;
#define FSM_SIMD_DECLARE_PLAIN_avx512(Type, name) Type avx512_##name() noexcept;
FSM_SIMD_DECLARE_GETTERS(avx2)
#if defined(FSM_SIMD_AVX512)
FSM_SIMD_DECLARE_GETTERS(avx512)
#endif
#undef FSM_SIMD_DECLARE_PLAIN_avx512
#undef FSM_SIMD_DECLARE_PLAIN_avx2
#undef FSM_SIMD_DECLARE_GETTERS

namespace {
enum class Level { none, avx2, avx512 };

// What the CPU runs: the AVX2 + FMA kernels, or the same compiled for AVX-512VL where the CPU has
// it (and this build made them). The environment variable FSM_SIMD=avx2 keeps the AVX2 kernels on
// an AVX-512 CPU (the tests run both; a user can compare). Read once.
Level level() noexcept {
  static const Level chosen = [] {
    if (!(__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))) return Level::none;
#if defined(FSM_SIMD_AVX512)
    const char* cap = std::getenv("FSM_SIMD");
    const bool capped = cap != nullptr && std::strcmp(cap, "avx2") == 0;
    if (!capped && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
        __builtin_cpu_supports("avx512dq"))
      return Level::avx512;
#endif
    return Level::avx2;
  }();
  return chosen;
}

}  // namespace

// The kernel `call` returns at the chosen level, nullptr at none; only that level's getter runs
// (the getters' files are compiled with their instruction sets).
#if defined(FSM_SIMD_AVX512)
#define FSM_PICK(call) \
  (level() == Level::avx512 ? avx512_##call : level() == Level::avx2 ? avx2_##call : nullptr)
#else
#define FSM_PICK(call) (level() == Level::avx2 ? avx2_##call : nullptr)
#endif

LinkForceKernel link_force_kernel(bool bilinear, bool along_link) noexcept {
  return FSM_PICK(link_force_kernel(bilinear, along_link));
}

LinkPrepareKernel link_prepare_kernel(bool bilinear, bool along_link) noexcept {
  return FSM_PICK(link_prepare_kernel(bilinear, along_link));
}

#define FSM_SIMD_DEFINE_PLAIN(Type, name) \
  Type name() noexcept {                  \
    return FSM_PICK(name());              \
  }
FSM_SIMD_PLAIN_KERNELS(FSM_SIMD_DEFINE_PLAIN)
#undef FSM_SIMD_DEFINE_PLAIN
#undef FSM_PICK

const char* instruction_set() noexcept {
  switch (level()) {
    case Level::avx512:
      return "avx2+fma (avx512vl)";
    case Level::avx2:
      return "avx2+fma";
    case Level::none:
      break;
  }
  return "none";
}
#else
LinkForceKernel link_force_kernel(bool, bool) noexcept {
  return nullptr;
}
LinkPrepareKernel link_prepare_kernel(bool, bool) noexcept {
  return nullptr;
}
#define FSM_SIMD_DEFINE_PLAIN(Type, name) \
  Type name() noexcept {                  \
    return nullptr;                       \
  }
FSM_SIMD_PLAIN_KERNELS(FSM_SIMD_DEFINE_PLAIN)
#undef FSM_SIMD_DEFINE_PLAIN
const char* instruction_set() noexcept {
  return "none";
}
#endif

}  // namespace fsm::detail::simd

#undef FSM_SIMD_PLAIN_KERNELS
