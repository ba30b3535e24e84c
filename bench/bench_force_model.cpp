// Force evaluation: time per link for lattices of about 1e3 to 1e6 links, on 1 and 2 threads.

#include <atomic>

#include "common.hpp"
#include "fsm/detail/worker_pool.hpp"

namespace fsm::bench {
namespace {

template <typename Scalar>
void BM_ForceEvaluation(benchmark::State& state) {
  const SphereModel<Scalar> model = lattice_model<Scalar>(int(state.range(0)), state.range(2) != 0);
  typename ForceModel<Scalar>::Options o;
  o.threads = int(state.range(1));
  o.simd = state.range(3) != 0;
  ForceModel<Scalar> forces(model, o);
  Positions<Scalar> f(model.num_nodes(), 3);
  forces.evaluate(model, model.positions(), model.velocities(), f);  // warm-up
  for (auto _ : state) {
    forces.evaluate(model, model.positions(), model.velocities(), f);
    benchmark::DoNotOptimize(f.data());
    benchmark::ClobberMemory();
  }
  state.counters["links"] = double(model.num_links());
  per_link(state, double(model.num_links()));
}

void sizes(benchmark::internal::Benchmark* b) {
  for (double links : {1e3, 1e4, 1e5, 1e6})
    for (int threads : {1, 2})
      for (int bilinear : {0, 1})
        for (int simd : {0, 1}) b->Args({cells_for_links(links), threads, bilinear, simd});
  // simd: the SIMD link kernel (ForceModel::Options::simd; double only: float runs the scalar
  // loop).
  b->ArgNames({"cells", "threads", "bilinear", "simd"})->UseRealTime()->MinWarmUpTime(0.05);
}

BENCHMARK_TEMPLATE(BM_ForceEvaluation, double)->Apply(sizes);
BENCHMARK_TEMPLATE(BM_ForceEvaluation, float)->Apply(sizes);

// The implicit step's product y = A p (ForceModel::apply_implicit, the link law's blocks prepared
// at the model's state, h = 1 ms): what each CG iteration costs beyond its vector work. The
// uterus-sized model (cells 0) and lattices; one thread.
void BM_ImplicitProduct(benchmark::State& state) {
  const int cells = int(state.range(0));
  const SphereModel<double> model =
      cells == 0 ? uterus_sized_model<double>() : lattice_model<double>(cells);
  ForceModel<double> forces(model);
  std::vector<double> blocks(std::size_t(ForceModel<double>::implicit_block_size) *
                             std::size_t(model.num_links()));
  Positions<double> rhs(model.num_nodes(), 3), diagonal(model.num_nodes(), 3),
      p(model.num_nodes(), 3), y(model.num_nodes(), 3);
  forces.prepare_implicit(model, 1e-3, JacobianForm::definite, blocks.data(), rhs, diagonal);
  p = model.velocities();
  for (auto _ : state) {
    forces.apply_implicit(model, blocks.data(), p, y);
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  state.counters["links"] = double(model.num_links());
  per_link(state, double(model.num_links()));
}
BENCHMARK(BM_ImplicitProduct)->Arg(0)->Arg(11)->Arg(51)->ArgName("cells")->UseRealTime();

// Elastic energy pass (what the divergence check adds per step).
void BM_ElasticEnergy(benchmark::State& state) {
  const SphereModel<double> model = lattice_model<double>(int(state.range(0)));
  const ForceModel<double> forces(model);
  for (auto _ : state) benchmark::DoNotOptimize(forces.elastic_energy(model, model.positions()));
  per_link(state, double(model.num_links()));
}
BENCHMARK(BM_ElasticEnergy)->Arg(cells_for_links(1e4))->Arg(cells_for_links(1e6))->ArgName("cells");

// One dispatch of a job with almost no work on the worker pool: the hand-over every parallel loop
// pays (a helper's share it has not claimed by the time the caller is done runs on the caller,
// so this is at most one round trip to the other core). It depends on where the host puts the
// vCPUs: docs/benchmarks.md.
void BM_PoolDispatch(benchmark::State& state) {
  detail::WorkerPool pool(int(state.range(0)));
  std::atomic<long> sink{0};
  auto job = [&](int t, int) { sink.fetch_add(t, std::memory_order_relaxed); };
  for (auto _ : state) pool.run(job);
  benchmark::DoNotOptimize(sink.load());
}
BENCHMARK(BM_PoolDispatch)->Arg(2)->ArgName("threads")->Unit(benchmark::kNanosecond);

}  // namespace
}  // namespace fsm::bench
