// Run-time choice of the link and element kernels (compiled with the library's baseline flags: it
// must run on any x86-64 CPU, so it only asks the CPU what it has).

#include "fsm/detail/simd_links.hpp"
#include "fsm/detail/simd_tets.hpp"

namespace fsm::detail::simd {

#if defined(FSM_SIMD_AVX2)
LinkForceKernel avx2_link_force_kernel(bool bilinear, bool along_link) noexcept;
LinkPrepareKernel avx2_link_prepare_kernel(bool bilinear, bool along_link) noexcept;
LinkApplyKernel avx2_link_apply_kernel() noexcept;
LinkEnergyKernel avx2_link_energy_kernel() noexcept;
TetForceKernel avx2_tet_force_kernel() noexcept;
TetEnergyKernel avx2_tet_energy_kernel() noexcept;
TetSpreadKernel avx2_tet_spread_kernel() noexcept;
TetGatherKernel avx2_tet_gather_kernel() noexcept;

namespace {
bool has_avx2_fma() noexcept {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
}
}  // namespace

LinkForceKernel link_force_kernel(bool bilinear, bool along_link) noexcept {
  return has_avx2_fma() ? avx2_link_force_kernel(bilinear, along_link) : nullptr;
}

LinkPrepareKernel link_prepare_kernel(bool bilinear, bool along_link) noexcept {
  return has_avx2_fma() ? avx2_link_prepare_kernel(bilinear, along_link) : nullptr;
}

LinkApplyKernel link_apply_kernel() noexcept {
  return has_avx2_fma() ? avx2_link_apply_kernel() : nullptr;
}

LinkEnergyKernel link_energy_kernel() noexcept {
  return has_avx2_fma() ? avx2_link_energy_kernel() : nullptr;
}

TetForceKernel tet_force_kernel() noexcept {
  return has_avx2_fma() ? avx2_tet_force_kernel() : nullptr;
}

TetEnergyKernel tet_energy_kernel() noexcept {
  return has_avx2_fma() ? avx2_tet_energy_kernel() : nullptr;
}

TetSpreadKernel tet_spread_kernel() noexcept {
  return has_avx2_fma() ? avx2_tet_spread_kernel() : nullptr;
}

TetGatherKernel tet_gather_kernel() noexcept {
  return has_avx2_fma() ? avx2_tet_gather_kernel() : nullptr;
}

const char* instruction_set() noexcept {
  return has_avx2_fma() ? "avx2+fma" : "none";
}
#else
LinkForceKernel link_force_kernel(bool, bool) noexcept {
  return nullptr;
}
LinkPrepareKernel link_prepare_kernel(bool, bool) noexcept {
  return nullptr;
}
LinkApplyKernel link_apply_kernel() noexcept {
  return nullptr;
}
LinkEnergyKernel link_energy_kernel() noexcept {
  return nullptr;
}
TetForceKernel tet_force_kernel() noexcept {
  return nullptr;
}
TetEnergyKernel tet_energy_kernel() noexcept {
  return nullptr;
}
TetSpreadKernel tet_spread_kernel() noexcept {
  return nullptr;
}
TetGatherKernel tet_gather_kernel() noexcept {
  return nullptr;
}
const char* instruction_set() noexcept {
  return "none";
}
#endif

}  // namespace fsm::detail::simd
