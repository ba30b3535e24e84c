#pragma once

// Parallel scatter over links without write conflicts, on a persistent WorkerPool: every thread
// accumulates its share of the links into its own zeroed buffer, then each thread writes its
// share of the nodes: out = init + the sum of the buffers. With one thread (the default) the
// links go straight into the output and no pool exists.

#include <algorithm>
#include <cstdint>
#include <thread>
#include <utility>
#include <vector>

#if defined(__linux__)
#include <sched.h>
#endif

#include "fsm/detail/worker_pool.hpp"
#include "fsm/types.hpp"

namespace fsm::detail {

/// Threads a simulation may use at most: the CPUs this process may run on (its affinity mask,
/// which a container or `taskset` narrows; hardware_concurrency() does not see it).
inline int max_threads() noexcept {
#if defined(__linux__)
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) return std::max(1, CPU_COUNT(&set));
#endif
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

/// [begin, end) of `count` items for share t of T: contiguous, in order, sizes within one.
template <typename I>
std::pair<I, I> share(I count, int t, int T) noexcept {
  return {static_cast<I>(std::int64_t(count) * t / T),
          static_cast<I>(std::int64_t(count) * (t + 1) / T)};
}

/// Nodes [begin, end) of one thread's share of a scatter: out = init + the first T buffers.
template <typename Scalar, typename NodeInit>
void sum_buffers(Index begin, Index end, Scalar* out,
                 const std::vector<std::vector<Scalar>>& scratch, int T, NodeInit&& init) noexcept {
  for (Index i = begin; i < end; ++i) init(i, out + 3 * std::ptrdiff_t(i));
  for (std::ptrdiff_t k = 3 * std::ptrdiff_t(begin); k < 3 * std::ptrdiff_t(end); ++k) {
    Scalar s = out[k];
    for (int b = 0; b < T; ++b) s += scratch[std::size_t(b)][std::size_t(k)];
    out[k] = s;
  }
}

/// No extra work per share of a scatter_links() on the pool.
struct NoShareWork {
  template <typename... A>
  void operator()(A&&...) const noexcept {}
};

/// out[3i..3i+2] = init(i) for every node, plus kernel(begin, end, buffer) over link ranges.
/// With a pool of T threads, `scratch` must hold T buffers of 3 * num_nodes scalars; then each
/// thread also calls links_done(t, begin, end) after its links and nodes_done(begin, end, T)
/// after its nodes (for work that rides on the same two dispatches). Returns whether it ran on
/// the pool (the hooks were called).
template <typename Scalar, typename NodeInit, typename LinkKernel, typename LinksDone = NoShareWork,
          typename NodesDone = NoShareWork>
bool scatter_links(WorkerPool* pool, Index num_nodes, Index num_links, Scalar* out,
                   std::vector<std::vector<Scalar>>& scratch, NodeInit&& init, LinkKernel&& kernel,
                   LinksDone&& links_done = {}, NodesDone&& nodes_done = {}) noexcept {
  const int T = pool ? std::min<int>(pool->size(), static_cast<int>(scratch.size())) : 1;
  if (T > 1) {
    const auto n3 = 3 * static_cast<std::ptrdiff_t>(num_nodes);
    auto links = [&](int t, int) {
      if (t >= T) return;
      Scalar* buf = scratch[std::size_t(t)].data();
      std::fill(buf, buf + n3, Scalar(0));
      const auto [begin, end] = share(num_links, t, T);
      kernel(begin, end, buf);
      links_done(t, begin, end);
    };
    pool->run(links);
    auto nodes = [&](int t, int) {
      if (t >= T) return;
      const auto [begin, end] = share(num_nodes, t, T);
      sum_buffers(begin, end, out, scratch, T, init);
      nodes_done(begin, end, T);
    };
    pool->run(nodes);
    return true;
  }
  for (Index i = 0; i < num_nodes; ++i) init(i, out + 3 * std::ptrdiff_t(i));
  kernel(Index(0), num_links, out);
  return false;
}

}  // namespace fsm::detail
