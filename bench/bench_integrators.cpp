// A full step per integrator (Simulation::step with divergence checks, and the bare integrator),
// for lattices of about 1e3 to 1e6 links on 1 and 2 threads, and for a uterus-sized model.

#include "common.hpp"

namespace fsm::bench {
namespace {

// Step size: half the scheme's stable step for explicit schemes, 1 ms (the haptic period) for
// implicit Euler.
template <typename Scalar>
Scalar step_for(const Simulation<Scalar>& sim) {
  const Scalar s = sim.stable_time_step();
  return std::isinf(double(s)) ? Scalar(1e-3) : Scalar(0.5) * s;
}

template <typename Scalar>
void run_simulation(benchmark::State& state, SphereModel<Scalar> model, const std::string& name,
                    int threads, bool check_energy, bool simd = true) {
  typename Simulation<Scalar>::Options o;
  o.integrator = name;
  o.forces.threads = threads;
  o.forces.simd = simd;
  o.divergence.check_energy = check_energy;
  Simulation<Scalar> sim(std::move(model), o);
  const Scalar dt = step_for(sim);
  for (int s = 0; s < 3; ++s) sim.step(dt);  // warm-up
  int iterations = 0, failures = 0;
  for (auto _ : state) {
    const auto r = sim.step(dt);
    iterations += r.solver_iterations;
    failures += !r.advanced();
  }
  state.counters["links"] = double(sim.model().num_links());
  state.counters["dt_us"] = 1e6 * double(dt);
  state.counters["cg_iters"] = benchmark::Counter(iterations, benchmark::Counter::kAvgIterations);
  if (failures) state.SkipWithError("steps failed");
  per_link(state, double(sim.model().num_links()));
}

template <typename Scalar>
void BM_Step(benchmark::State& state, const std::string& name) {
  run_simulation<Scalar>(state, lattice_model<Scalar>(int(state.range(0))), name,
                         int(state.range(1)), true);
}

template <typename Scalar>
void BM_StepUterusSized(benchmark::State& state, const std::string& name) {
  run_simulation<Scalar>(state, uterus_sized_model<Scalar>(), name, int(state.range(0)),
                         state.range(1) != 0, state.range(2) != 0);
  state.counters["spheres"] = double(uterus_sized_model<Scalar>().num_nodes());
}

// The bare integrator: no rollback copy, no divergence check.
template <typename Scalar>
void BM_IntegratorOnly(benchmark::State& state, const std::string& name) {
  SphereModel<Scalar> model = uterus_sized_model<Scalar>();
  ForceModel<Scalar> forces(model);
  auto integrator = make_integrator<Scalar>(name);
  integrator->prepare(model);
  const Scalar s = integrator->stable_time_step(spectral_bound(model));
  const Scalar dt = std::isinf(double(s)) ? Scalar(1e-3) : Scalar(0.5) * s;
  for (int i = 0; i < 3; ++i) integrator->step(model, forces, dt);
  for (auto _ : state) benchmark::DoNotOptimize(integrator->step(model, forces, dt));
  per_link(state, double(model.num_links()));
}

// Scale: one 1 ms implicit Euler step (Simulation::step, CG with the default block-Jacobi
// preconditioner) of a cube lattice of (cells + 1)^3 spheres (729 to 19,683; bottom fixed,
// gravity, random initial velocities), the link law or the continuum law (its tetrahedra), on 1
// or 2 threads. Counters: spheres, CG iterations per step, and the real-time factor (1 ms over
// the step's time: at least 1 runs at 1 kHz). docs/img/scale_step_time.png charts it.
void scale_implicit_step(benchmark::State& state, bool extrapolate) {
  SphereModel<double> model = lattice_model<double>(int(state.range(0)));
  if (state.range(1) != 0) model.set_region_law(0, ForceLaw::continuum);
  Simulation<double>::Options o;
  o.forces.threads = int(state.range(2));
  Simulation<double> sim(std::move(model), o);
  ImplicitEulerIntegrator<double>::Options io;
  io.extrapolate_warm_start = extrapolate;
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  for (int s = 0; s < 20; ++s) sim.step(1e-3);  // warm-up: CG's warm start settles
  long iterations = 0, steps = 0, failures = 0;
  for (auto _ : state) {
    const auto r = sim.step(1e-3);
    iterations += r.solver_iterations;
    failures += !r.advanced();
    ++steps;
  }
  state.counters["spheres"] = double(sim.model().num_nodes());
  state.counters["cg_iters"] = double(iterations) / double(std::max(steps, 1L));
  state.counters["realtime_factor"] =
      benchmark::Counter(1e-3 * double(steps), benchmark::Counter::kIsRate);
  if (failures) state.SkipWithError("steps failed");
}
void BM_ScaleImplicitStep(benchmark::State& state) {
  scale_implicit_step(state, true);
}
BENCHMARK(BM_ScaleImplicitStep)
    ->ArgsProduct({{8, 12, 17, 21, 26}, {0, 1}, {1, 2}})
    ->ArgNames({"cells", "continuum", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
// The same without ImplicitEulerIntegrator::Options::extrapolate_warm_start (the step before it).
void BM_ScaleImplicitStepNoExtrapolation(benchmark::State& state) {
  scale_implicit_step(state, false);
}
BENCHMARK(BM_ScaleImplicitStepNoExtrapolation)
    ->ArgsProduct({{8, 12, 17, 21, 26}, {0, 1}, {1}})
    ->ArgNames({"cells", "continuum", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

void sizes(benchmark::internal::Benchmark* b) {
  for (double links : {1e3, 1e4, 1e5, 1e6})
    for (int threads : {1, 2}) b->Args({cells_for_links(links), threads});
  b->ArgNames({"cells", "threads"})->UseRealTime();
}

void uterus(benchmark::internal::Benchmark* b) {
  // simd: the SIMD link kernel (ForceModel::Options::simd; double only), 0 = the scalar loop.
  b->Args({1, 1, 1})->Args({2, 1, 1})->Args({1, 0, 1})->Args({1, 1, 0})->Args({2, 1, 0});
  b->ArgNames({"threads", "energy_check", "simd"})->UseRealTime();
}

const bool registered = [] {
  for (const std::string& name : integrator_names()) {
    benchmark::RegisterBenchmark(("BM_Step<double>/" + name).c_str(), [name](benchmark::State& st) {
      BM_Step<double>(st, name);
    })->Apply(sizes);
    benchmark::RegisterBenchmark(
        ("BM_StepUterusSized<double>/" + name).c_str(),
        [name](benchmark::State& st) { BM_StepUterusSized<double>(st, name); })
        ->Apply(uterus);
    benchmark::RegisterBenchmark(
        ("BM_StepUterusSized<float>/" + name).c_str(),
        [name](benchmark::State& st) { BM_StepUterusSized<float>(st, name); })
        ->Apply(uterus);
    benchmark::RegisterBenchmark(
        ("BM_IntegratorOnly<double>/" + name).c_str(),
        [name](benchmark::State& st) { BM_IntegratorOnly<double>(st, name); });
  }
  return true;
}();

}  // namespace
}  // namespace fsm::bench
