#pragma once

/// @file detail/reserved_vector.hpp
/// @brief A std::vector whose copies keep the source's capacity.
///
/// A step must not allocate. A list that the step clears and refills (`clear()`, then
/// `push_back()` within what refresh() reserved) is safe in its owner, but a copy of a std::vector
/// gets only as much capacity as the source has elements: a copied ForceModel, ContactSolver,
/// Grasper or TopologyEditor would then allocate inside its first step that needs more. This type
/// copies the capacity too (the allocation happens in the copy, outside the step). Moves keep the
/// buffer, as std::vector's do. It derives publicly and adds no data member, so it passes as a
/// `const std::vector<T>&` (a copy made through that base loses the capacity, as any vector copy).

#include <vector>

namespace fsm::detail {

template <typename T>
class ReservedVector : public std::vector<T> {
 public:
  using std::vector<T>::vector;
  ReservedVector() = default;
  ReservedVector(const ReservedVector& o) : std::vector<T>() {
    this->reserve(o.capacity());
    this->assign(o.begin(), o.end());
  }
  ReservedVector& operator=(const ReservedVector& o) {
    if (this != &o) {
      this->clear();
      this->reserve(o.capacity());
      this->assign(o.begin(), o.end());
    }
    return *this;
  }
  ReservedVector(ReservedVector&&) noexcept = default;
  ReservedVector& operator=(ReservedVector&&) noexcept = default;
  ~ReservedVector() = default;
};

}  // namespace fsm::detail
