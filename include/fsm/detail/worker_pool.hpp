#pragma once

/// @file detail/worker_pool.hpp
/// @brief A persistent pool of helper threads for the loops of a step: one dispatch costs an
/// atomic increment and a wait for the slowest share, not a thread start (an OpenMP parallel
/// region cost about 5 us per call here, more than a whole link loop of the uterus).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace fsm::detail {

/// @brief `run(fn)` calls `fn(t, n)` for every t in [0, n) (n = size()): t = 0 on the calling
/// thread, the others on the pool's helpers, and returns when all have returned. Between jobs a
/// helper spins for `spin` (the gaps between the loops of one step, and between the steps of a
/// 1 kHz loop, are shorter) and then sleeps until the next job (a futex on Linux, so waking it
/// takes no lock; elsewhere it polls every 50 us). run() allocates nothing, takes no lock and
/// makes no system call unless a helper sleeps; `fn` must not throw. One caller at a time. A
/// helper's share that it has not claimed by the time the caller has done its own runs on the
/// caller (so `fn(t, n)` must depend on t only as a share, not on the thread it runs on).
class WorkerPool {
 public:
  /// @param threads the calling thread plus threads - 1 helpers, started here (at least 1)
  /// @param spin how long an idle helper spins before it sleeps
  explicit WorkerPool(int threads, std::chrono::microseconds spin = std::chrono::microseconds(2000))
      : m_size(std::max(threads, 1)), m_spin(spin), m_claim(std::size_t(m_size)) {
    m_threads.reserve(std::size_t(m_size - 1));
    try {
      for (int t = 1; t < m_size; ++t) m_threads.emplace_back([this, t] { helper(t); });
    } catch (...) {  // a thread that could not start: stop the ones that did, then report
      shut_down();
      throw;
    }
  }
  ~WorkerPool() { shut_down(); }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// @brief Threads that share a job: the caller and the helpers.
  [[nodiscard]] int size() const noexcept { return m_size; }

  /// @brief Runs fn(t, size()) on every thread t of the pool and waits for all.
  template <typename F>
  void run(F& fn) noexcept {
    if (m_size == 1) {
      fn(0, 1);
      return;
    }
    m_call = [](void* f, int t, int n) { (*static_cast<F*>(f))(t, n); };
    m_fn = &fn;
    m_pending.store(m_size - 1, std::memory_order_relaxed);
    // publishes m_call, m_fn, m_pending
    const std::uint32_t e = m_epoch.fetch_add(1, std::memory_order_seq_cst) + 1;
    if (m_sleepers.load(std::memory_order_seq_cst) > 0) wake();
    fn(0, m_size);
    // A share no helper has claimed yet (its helper is descheduled, or still asleep) runs here:
    // a busy machine then costs the caller the work, not a scheduler time slice of waiting.
    for (int t = 1; t < m_size; ++t)
      if (claim(t, e)) {
        fn(t, m_size);
        m_pending.fetch_sub(1, std::memory_order_release);
      }
    while (m_pending.load(std::memory_order_acquire) != 0) relax();
  }

 private:
  // Claims share t of job e for the calling thread: true for exactly one claimant. Every share of
  // a job is claimed before run() returns, so share t's word holds e - 1 until job e's claim; a
  // helper that looks at a job already over (a stale e) fails as well.
  bool claim(int t, std::uint32_t e) noexcept {
    std::uint32_t previous = e - 1;
    return m_claim[std::size_t(t)].compare_exchange_strong(previous, e, std::memory_order_acq_rel,
                                                           std::memory_order_relaxed);
  }

  void shut_down() noexcept {
    m_stop.store(true, std::memory_order_seq_cst);
    m_epoch.fetch_add(1, std::memory_order_seq_cst);
    wake();
    for (auto& t : m_threads)
      if (t.joinable()) t.join();
  }

  static void relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }

  void wake() noexcept {
#if defined(__linux__)
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&m_epoch), FUTEX_WAKE_PRIVATE, INT32_MAX,
            nullptr, nullptr, 0);
#endif
  }

  // Sleeps while the epoch is still `seen` (or returns at once if it has moved on).
  void sleep(std::uint32_t seen) noexcept {
#if defined(__linux__)
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&m_epoch), FUTEX_WAIT_PRIVATE, seen,
            nullptr, nullptr, 0);
#else
    (void)seen;
    std::this_thread::sleep_for(std::chrono::microseconds(50));
#endif
  }

  void helper(int t) noexcept {
    using Clock = std::chrono::steady_clock;
    std::uint32_t seen = 0;
    for (;;) {
      auto idle_since = Clock::now();
      std::uint32_t e;
      int polls = 0;
      while ((e = m_epoch.load(std::memory_order_acquire)) == seen) {
        relax();
        if (++polls < 64) continue;
        polls = 0;
        if (Clock::now() - idle_since < m_spin) continue;
        // Registering as a sleeper before the last look at the epoch (both sequentially
        // consistent, as run()'s increment and its look at m_sleepers) means that either this
        // look sees the new job or run() sees the sleeper and wakes it; the futex itself sleeps
        // only if the epoch is still `seen`.
        m_sleepers.fetch_add(1, std::memory_order_seq_cst);
        if (m_epoch.load(std::memory_order_seq_cst) == seen) sleep(seen);
        m_sleepers.fetch_sub(1, std::memory_order_seq_cst);
        idle_since = Clock::now();
      }
      seen = e;
      if (m_stop.load(std::memory_order_acquire)) return;
      // The share is this helper's unless the caller has taken it (run()), or the job is over
      // and a later one started (then e is stale and its claim fails too).
      if (!claim(t, e)) continue;
      m_call(m_fn, t, m_size);
      m_pending.fetch_sub(1, std::memory_order_release);
    }
  }

  // One claim word per cache line (the caller and a helper race for it).
  struct alignas(64) ClaimSlot : std::atomic<std::uint32_t> {
    ClaimSlot() noexcept : std::atomic<std::uint32_t>(0) {}
  };
  const int m_size;
  const std::chrono::microseconds m_spin;
  std::vector<std::thread> m_threads;
  void (*m_call)(void*, int, int){nullptr};
  void* m_fn{nullptr};
  // The futex waits on the epoch's 32 bits.
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t) &&
                    std::atomic<std::uint32_t>::is_always_lock_free,
                "the epoch must be a plain 32-bit word");
  // Per share: the last job (epoch) whose share was claimed, by its helper or by the caller.
  std::vector<ClaimSlot> m_claim;
  alignas(64) std::atomic<std::uint32_t> m_epoch{0};
  alignas(64) std::atomic<int> m_pending{0};
  alignas(64) std::atomic<int> m_sleepers{0};
  std::atomic<bool> m_stop{false};
};

/// @brief Owns a WorkerPool of a given size, or none for one thread; copying makes a pool of the
/// same size for the copy (a pool serves one caller at a time), so that what holds it stays
/// copyable.
class PoolHandle {
 public:
  PoolHandle() = default;
  explicit PoolHandle(int threads) { reset(threads); }
  PoolHandle(const PoolHandle& o) : m_enabled(o.m_enabled) { reset(o.threads()); }
  PoolHandle& operator=(const PoolHandle& o) {
    if (this != &o) {
      reset(o.threads());
      m_enabled = o.m_enabled;
    }
    return *this;
  }
  PoolHandle(PoolHandle&&) noexcept = default;
  PoolHandle& operator=(PoolHandle&&) noexcept = default;
  ~PoolHandle() = default;

  /// @brief A pool of `threads` (none for 1 or fewer); keeps the pool it has when the size is the
  /// same.
  void reset(int threads) {
    if (threads == this->threads()) return;
    m_pool.reset();
    if (threads > 1) m_pool = std::make_unique<WorkerPool>(threads);
  }
  [[nodiscard]] int threads() const noexcept { return m_pool ? m_pool->size() : 1; }
  /// @brief The pool, or nullptr for one thread or while it is set aside.
  [[nodiscard]] WorkerPool* get() const noexcept { return m_enabled ? m_pool.get() : nullptr; }
  /// @brief Sets the pool aside (false: get() returns nullptr, the loops run on the calling
  /// thread and the helpers go to sleep after their spin) or takes it back; allocates nothing.
  void set_enabled(bool enabled) noexcept { m_enabled = enabled; }
  [[nodiscard]] bool enabled() const noexcept { return m_enabled; }

 private:
  std::unique_ptr<WorkerPool> m_pool;
  bool m_enabled{true};
};

}  // namespace fsm::detail
