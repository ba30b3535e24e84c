#pragma once

// Parallel scatter over links without write conflicts: thread 0 accumulates into the output,
// every other thread into its own zeroed buffer, and the buffers are summed per node at the end.
// With one thread (the default) no OpenMP construct runs, so no thread is ever started.

#include <algorithm>
#include <vector>

#include "fsm/types.hpp"

#if defined(FSM_WITH_OPENMP) && defined(_OPENMP)
#include <omp.h>
#define FSM_PARALLEL 1
#else
#define FSM_PARALLEL 0
#endif

namespace fsm::detail {

/// Number of threads the build can use at most (1 without OpenMP).
inline int max_threads() noexcept {
#if FSM_PARALLEL
  return omp_get_max_threads() > 0 ? std::max(omp_get_max_threads(), 1) : 1;
#else
  return 1;
#endif
}

/// out[3i..3i+2] = init(i) for every node, then kernel(begin, end, buffer) over link ranges.
/// `scratch` must hold (threads - 1) buffers of 3 * num_nodes scalars.
template <typename Scalar, typename NodeInit, typename LinkKernel>
void scatter_links(int threads, Index num_nodes, Index num_links, Scalar* out,
                   std::vector<std::vector<Scalar>>& scratch, NodeInit&& init,
                   LinkKernel&& kernel) noexcept {
  const auto n3 = 3 * static_cast<std::ptrdiff_t>(num_nodes);
#if FSM_PARALLEL
  const int T = std::min<int>(threads, static_cast<int>(scratch.size()) + 1);
  if (T > 1) {
#pragma omp parallel num_threads(T)
    {
      const int t = omp_get_thread_num();
      const int nt = omp_get_num_threads();
      Scalar* buf = t == 0 ? out : scratch[std::size_t(t - 1)].data();
#pragma omp for schedule(static)
      for (Index i = 0; i < num_nodes; ++i) init(i, out + 3 * std::ptrdiff_t(i));
      if (t > 0) std::fill(buf, buf + n3, Scalar(0));
      const Index begin = static_cast<Index>(std::int64_t(num_links) * t / nt);
      const Index end = static_cast<Index>(std::int64_t(num_links) * (t + 1) / nt);
      kernel(begin, end, buf);
#pragma omp barrier
#pragma omp for schedule(static)
      for (std::ptrdiff_t k = 0; k < n3; ++k) {
        Scalar s = out[k];
        for (int b = 0; b < nt - 1; ++b) s += scratch[std::size_t(b)][std::size_t(k)];
        out[k] = s;
      }
    }
    return;
  }
#else
  (void)threads;
  (void)scratch;
#endif
  (void)n3;
  for (Index i = 0; i < num_nodes; ++i) init(i, out + 3 * std::ptrdiff_t(i));
  kernel(Index(0), num_links, out);
}

}  // namespace fsm::detail
