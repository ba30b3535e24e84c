#pragma once

// Parallel scatter over links without write conflicts, on a persistent WorkerPool: every thread
// accumulates its share of the links into its own zeroed buffer, then each thread writes its
// share of the nodes: out = init + the sum of the buffers. Where the links can be shared so that
// no two threads' links meet at a node (LinkPartition), each thread adds straight into the
// output instead. With one thread (the default) the links go straight into the output and no
// pool exists.

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

/// Links shared among T threads so that no two threads' links meet at a node, whence each can
/// add its forces straight into the output, with no buffer of its own to clear and sum (at 10^6
/// links those two passes were a fifth of the memory traffic: docs/benchmarks.md). Thread t owns
/// nodes [nodes[t], nodes[t+1]) and the links [owned[t].first, owned[t].second), whose ends all
/// lie in them; the links between two threads' ranges, [owned[t].second, owned[t+1].first), are
/// the band, and run after, on one thread. Links sorted by their lower end over nodes numbered
/// in space (a lattice's edges) leave a band of about one layer of nodes' links; the builder's
/// parts, numbered along a Morton curve whose jumps make some links span most of a part, and its
/// attachment links, listed last, leave a wide one (docs/benchmarks.md).
struct LinkPartition {
  std::vector<Index> nodes;                    // T + 1 bounds: 0 = nodes[0] <= ... <= nodes[T]
  std::vector<std::pair<Index, Index>> owned;  // T link ranges, in order, covering with the bands
  Index band_links{0};                         // links in the bands
  /// The threads it was made for; 0 when there is none (too few threads, or too wide a band).
  [[nodiscard]] int threads() const noexcept { return static_cast<int>(owned.size()); }
};

/// The partition of `num_links` links `ij` (two node indices each, in [0, num_nodes)) among T
/// threads, or an empty one (threads() == 0) when T < 2 or when its longest path, the largest
/// owned range plus the bands, would exceed an even share of the links by more than `max_extra`.
/// Each thread starts where its even share of the links starts: its first node is the lowest node
/// of the links from there on. Allocates (call it when the topology changes).
inline LinkPartition partition_links(const Index* ij, Index num_links, Index num_nodes, int T,
                                     Index max_extra) {
  LinkPartition p;
  if (T < 2 || num_links < 1 || num_nodes < 1) return p;
  const std::size_t L = static_cast<std::size_t>(num_links);
  // high[l]: the highest node of links [0, l) (-1 for none); low[l]: the lowest of [l, L).
  std::vector<Index> high(L + 1), low(L + 1);
  high[0] = -1;
  for (std::size_t l = 0; l < L; ++l) high[l + 1] = std::max({high[l], ij[2 * l], ij[2 * l + 1]});
  low[L] = num_nodes;
  for (std::size_t l = L; l-- > 0;) low[l] = std::min({low[l + 1], ij[2 * l], ij[2 * l + 1]});
  p.nodes.resize(std::size_t(T) + 1);
  p.nodes[0] = 0;
  p.nodes[std::size_t(T)] = num_nodes;
  for (int t = 1; t < T; ++t)
    p.nodes[std::size_t(t)] =
        std::clamp(low[std::size_t(share(num_links, t, T).first)], Index(0), num_nodes);
  p.owned.resize(std::size_t(T));
  for (int t = 0; t < T; ++t) {
    // From the first link whose later links all start at or above the thread's first node, to the
    // last before which every link ends below its successor's first node.
    const Index lo = p.nodes[std::size_t(t)], hi = p.nodes[std::size_t(t) + 1];
    const auto begin = Index(std::lower_bound(low.begin(), low.end(), lo) - low.begin());
    const auto end = Index(std::lower_bound(high.begin(), high.end(), hi) - high.begin()) - 1;
    p.owned[std::size_t(t)] = {begin, std::max(begin, end)};
  }
  Index longest = 0;
  for (int t = 0; t < T; ++t) {
    const auto k = std::size_t(t);
    longest = std::max(longest, p.owned[k].second - p.owned[k].first);
    if (t + 1 < T) p.band_links += p.owned[k + 1].first - p.owned[k].second;
  }
  const std::int64_t even = (std::int64_t(num_links) + T - 1) / T;
  if (std::int64_t(longest) + p.band_links > even + max_extra) return LinkPartition{};
  return p;
}

/// scatter_links() on a partition made for the pool's size: one dispatch in which thread t runs
/// nodes(begin, end) on its nodes (their initial values, and whatever its links read of them),
/// then kernel(begin, end, out) on its links; then the bands, on the calling thread.
template <typename Scalar, typename NodeWork, typename LinkKernel>
void scatter_links(WorkerPool& pool, const LinkPartition& p, Scalar* out, NodeWork&& nodes,
                   LinkKernel&& kernel) noexcept {
  const int T = p.threads();
  auto job = [&](int t, int) {
    if (t >= T) return;
    const auto k = std::size_t(t);
    nodes(p.nodes[k], p.nodes[k + 1]);
    kernel(p.owned[k].first, p.owned[k].second, out);
  };
  if (T == pool.size()) {
    pool.run(job);
  } else {  // made for another pool: every share here, in order (the callers check the size)
    for (int t = 0; t < T; ++t) job(t, T);
  }
  for (std::size_t k = 0; k + 1 < std::size_t(T); ++k)
    if (p.owned[k].second < p.owned[k + 1].first)
      kernel(p.owned[k].second, p.owned[k + 1].first, out);
}

}  // namespace fsm::detail
