#pragma once
// A bump arena that makes CGAL's pointer-ordered containers deterministic (private to the builder).
//
// CGAL's mean-curvature-flow skeletonization (CGAL 5.5) contracts a Polyhedron_3 and picks the next
// edge to collapse from a std::set ordered by halfedge *address*, so the skeleton, and with it the
// axis chain, depends on where the heap happened to place each halfedge: the same scene built
// twice gave 9 or 10 spheres on a ligament. Every CGAL container takes its allocator from the
// CGAL_ALLOCATOR macro; defining it to ArenaAllocator before the first CGAL include (only in the
// translation unit that runs the skeletonization, whose CGAL types are its own) makes every node
// come from one contiguous block in allocation order, so address order is allocation order, which
// the algorithm itself determines. Deallocation inside the arena is a no-op; the block is freed at
// once when the arena goes out of scope.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <new>

namespace fsm::build::detail {

/// Thrown by an arena that is full; the caller retries with a larger one.
struct ArenaExhausted : std::bad_alloc {
  const char* what() const noexcept override { return "deterministic arena exhausted"; }
};

class Arena {
 public:
  /// Reserves `bytes` in one block and becomes the thread's current arena until destroyed.
  explicit Arena(std::size_t bytes)
      : m_begin(static_cast<std::byte*>(std::malloc(bytes))), m_size(bytes), m_previous(current()) {
    if (m_begin == nullptr) throw std::bad_alloc();
    current() = this;
  }
  ~Arena() {
    current() = m_previous;
    std::free(m_begin);
  }
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;

  void* allocate(std::size_t bytes, std::size_t align) {
    std::size_t at = (m_used + align - 1) / align * align;
    if (at < m_used || at > m_size || bytes > m_size - at) throw ArenaExhausted();
    m_used = at + bytes;
    return m_begin + at;
  }
  [[nodiscard]] bool owns(const void* p) const noexcept {
    const auto a = reinterpret_cast<std::uintptr_t>(p);
    const auto b = reinterpret_cast<std::uintptr_t>(m_begin);
    return a >= b && a < b + m_size;
  }
  [[nodiscard]] std::size_t used() const noexcept { return m_used; }

  static Arena*& current() noexcept {
    static thread_local Arena* arena = nullptr;
    return arena;
  }

 private:
  std::byte* m_begin;
  std::size_t m_size;
  std::size_t m_used{0};
  Arena* m_previous;
};

/// std::allocator outside an arena; the current arena inside one.
template <class T>
struct ArenaAllocator {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = ArenaAllocator<U>;
  };
  ArenaAllocator() noexcept = default;
  template <class U>
  ArenaAllocator(const ArenaAllocator<U>& /*other*/) noexcept {}

  T* allocate(std::size_t n) {
    Arena* arena = Arena::current();
    if (arena == nullptr) return std::allocator<T>{}.allocate(n);
    if (n > std::size_t(-1) / sizeof(T)) throw ArenaExhausted();
    return static_cast<T*>(arena->allocate(n * sizeof(T), alignof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept {
    const Arena* arena = Arena::current();
    if (arena != nullptr && arena->owns(p)) return;
    std::allocator<T>{}.deallocate(p, n);
  }
  template <class U>
  bool operator==(const ArenaAllocator<U>& /*other*/) const noexcept {
    return true;
  }
  template <class U>
  bool operator!=(const ArenaAllocator<U>& /*other*/) const noexcept {
    return false;
  }
};

}  // namespace fsm::build::detail

#ifdef CGAL_ALLOCATOR
#error "deterministic_arena.hpp must come before every CGAL header of its translation unit"
#endif
#define CGAL_ALLOCATOR(T) ::fsm::build::detail::ArenaAllocator<T>
