#pragma once

/// @file detail/triple_buffer.hpp
/// @brief A single-producer single-consumer triple buffer: the writer never waits, the reader
/// always gets the latest complete value. Lock-free and allocation-free after construction.

#include <array>
#include <atomic>
#include <cstdint>

namespace fsm::detail {

/// @brief Three slots: the writer fills its back slot and publishes it by swapping it with the
/// middle one; the reader takes the middle one (when it is newer than what it has) by swapping it
/// with its front slot. Each swap is one atomic exchange (acquire-release), so a slot is only ever
/// touched by one thread at a time.
template <typename T>
class TripleBuffer {
 public:
  /// @brief All three slots start as copies of `initial` (which sizes any buffers inside T).
  explicit TripleBuffer(const T& initial = T()) : m_slots{initial, initial, initial} {}

  /// @brief The writer's slot: fill it, then publish().
  T& back() noexcept { return m_slots[m_back]; }
  /// @brief Makes the back slot the latest value.
  void publish() noexcept {
    const std::uint8_t old =
        m_middle.exchange(std::uint8_t(m_back | kFresh), std::memory_order_acq_rel);
    m_back = old & kIndex;
  }

  /// @brief Takes the latest published value if there is a newer one than front(); returns
  /// whether there was.
  bool update() noexcept {
    if (!(m_middle.load(std::memory_order_relaxed) & kFresh)) return false;
    const std::uint8_t old = m_middle.exchange(m_front, std::memory_order_acq_rel);
    m_front = old & kIndex;
    return true;
  }
  /// @brief The reader's slot: the value taken by the last update().
  const T& front() const noexcept { return m_slots[m_front]; }

 private:
  static constexpr std::uint8_t kIndex = 3, kFresh = 4;
  std::array<T, 3> m_slots;
  std::uint8_t m_back{0};   // writer only
  std::uint8_t m_front{1};  // reader only
  std::atomic<std::uint8_t> m_middle{2};
};

}  // namespace fsm::detail
