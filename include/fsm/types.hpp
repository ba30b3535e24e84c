#pragma once

/// @file types.hpp
/// @brief Array types shared by the whole runtime.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

/// Inlines a small helper of a hot loop whatever the compiler's budget (GCC stopped inlining the
/// continuum law's volume gradient when its class grew, costing 8 % of the step).
#if defined(__GNUC__) || defined(__clang__)
#define FSM_ALWAYS_INLINE inline __attribute__((always_inline))
#elif defined(_MSC_VER)
#define FSM_ALWAYS_INLINE __forceinline
#else
#define FSM_ALWAYS_INLINE inline
#endif

/// Promises that a pointer's array overlaps no other array the loop touches.
#if defined(__GNUC__) || defined(__clang__) || defined(_MSC_VER)
#define FSM_RESTRICT __restrict
#else
#define FSM_RESTRICT
#endif

namespace fsm {

/// @brief Index of a node, link or region. 32 bits: a model of 2^31 links would not fit the
/// real-time budget anyway, and half-width indices halve the index traffic of the force loop.
using Index = std::int32_t;

/// @brief Row-major `N x 3` array of points or vectors (metres, m/s or newtons). Row-major so
/// that a node's x, y, z are adjacent (one cache line for a gather) and numpy sees it unchanged.
template <typename Scalar>
using Positions = Eigen::Matrix<Scalar, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// @brief Column vector of per-node or per-link scalars.
template <typename Scalar>
using ScalarArray = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;

/// @brief Row-major `|L| x 2` array of node pairs.
using LinkArray = Eigen::Matrix<Index, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// @brief Row-major `|T| x 4` array of tetrahedra (node indices).
using TetrahedronArray = Eigen::Matrix<Index, Eigen::Dynamic, 4, Eigen::RowMajor>;

/// @brief A 3-vector.
template <typename Scalar>
using Vector3 = Eigen::Matrix<Scalar, 3, 1>;

/// @brief A 3 x 3 matrix.
template <typename Scalar>
using Matrix3 = Eigen::Matrix<Scalar, 3, 3>;

namespace detail {

/// Whether all `n` scalars from `p` are finite. Eigen's allFinite() walks a row-major `N x 3`
/// array column by column with a branch per entry (most of `Simulation::advance`'s 7.7 % of a
/// 44 us uterus-sized Heun step, for its three checks); this is one pass in memory order with no
/// branch and no floating-point operation, which the compiler turns into vector instructions. A
/// value is not finite when its exponent bits are all set; adding one unit of the exponent to
/// those bits alone then carries into the sign bit, and the sums of all values are or-ed. So the
/// result does not depend on the rounding mode, raises no floating-point exception and holds
/// under -ffast-math, where `x != x` tests may be folded away.
template <typename Scalar>
[[nodiscard]] inline bool all_finite(const Scalar* p, std::ptrdiff_t n) noexcept {
  using Bits = std::conditional_t<sizeof(Scalar) == 8, std::uint64_t, std::uint32_t>;
  static_assert(sizeof(Bits) == sizeof(Scalar), "a float or a double");
  constexpr int kMantissa = sizeof(Scalar) == 8 ? 52 : 23;
  constexpr Bits kSign = Bits(1) << (8 * sizeof(Bits) - 1);
  constexpr Bits kExponent = (kSign - 1) & ~((Bits(1) << kMantissa) - 1);
  Bits any = 0;
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    Bits b;
    std::memcpy(&b, p + k, sizeof b);
    any |= (b & kExponent) + (Bits(1) << kMantissa);
  }
  return (any & kSign) == 0;
}

}  // namespace detail

}  // namespace fsm
