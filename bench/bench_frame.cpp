// The whole-frame budget (issue 8): physics for 1/60 s at 1 kHz (17 steps, each with contacts),
// then skinning of the full-resolution surface, its normals and the BVH refit. GPU draw excluded.
// Reported in frames per second next to the paper's 40-60 Hz.
//
// The instrument (a 5 mm capsule) oscillates 2 mm in and out of the body at 1 Hz so the tissue
// keeps moving; drag 5/s as in the demo.

#include <benchmark/benchmark.h>

#include "fsm/builder/builder.hpp"
#include "fsm/collision/contact.hpp"
#include "fsm/collision/triangle_bvh.hpp"
#include "fsm/fsm.hpp"
#include "fsm_support/model_cache.hpp"
#include "fsm_support/probe.hpp"

namespace fsm::bench {
namespace {

using V3 = Vector3<double>;

const TissueModel<double>& uterus() {
  return support::bundled_uterus([](const std::string& s) { return build::build_model(s); },
                                 "bench_frame");
}

// Args: CG tolerance exponent (3 = 1e-3), sleeping, force threads, adaptive threads (the pool
// only while it is faster: Simulation::Options::adaptive_threads).
void BM_WholeFrame(benchmark::State& state) {
  const double tolerance = std::pow(10.0, -double(state.range(0)));
  const bool sleep = state.range(1) != 0;
  const int threads = int(state.range(2));
  const bool adaptive = state.range(3) != 0;
  const auto& model = uterus();
  Simulation<double>::Options so;
  so.forces.drag = 5;
  so.forces.threads = threads;
  so.sleep.enabled = sleep;
  so.adaptive_threads = adaptive;
  Simulation<double> sim(model.spheres, so);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = tolerance;
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  collision::ContactSolver<double> contacts(sim.model(), sim.forces());
  // The probe presses the body's outermost free sphere after it has sagged for 0.5 s, its tip
  // 1 +- 1 mm past the sphere's centre (the vertex contact meets sphere centres).
  support::CapsuleProbe probe = support::capsule_probe(model, "body");
  const Index k = contacts.add_instrument(probe.instrument(-0.02));
  support::sag_then_aim(sim, contacts, k, probe);
  auto ws = model.skin.make_workspace();
  Positions<double> surface = model.skin.rest.vertices, normals = surface;
  collision::TriangleBvh<double> bvh(model.skin.rest.vertices, model.skin.rest.faces);
  long step = 0;
  long iterations = 0, probe_contacts = 0, on_pool = 0;
  auto frame = [&] {
    for (int s = 0; s < 17; ++s, ++step) {
      const double t = double(step) * 1e-3;
      const double pi = 3.14159265358979;
      probe.press(contacts, k, probe.site.radius + 0.001 + 0.001 * std::sin(2 * pi * t),
                  0.002 * pi * std::cos(2 * pi * t));
      contacts.compute(sim.model(), sim.forces());
      on_pool += sim.uses_pool() ? 1 : 0;
      iterations += sim.step(1e-3).solver_iterations;
      contacts.collect(sim.forces());
      for (Index c = 0; c < contacts.num_contacts(); ++c)
        probe_contacts += contacts.contacts()[c].instrument >= 0;
    }
    model.skin.evaluate(sim.model().positions(), ws, surface);
    compute_vertex_normals<double>(surface, model.skin.rest.faces, normals);
    bvh.refit(surface);
  };
  for (int f = 0; f < 60; ++f) frame();  // 1 s of settling
  iterations = probe_contacts = on_pool = 0;
  const Index rebuilds_before = contacts.pair_list_rebuilds();
  long frames = 0;
  for (auto _ : state) {
    frame();
    ++frames;
    benchmark::DoNotOptimize(surface.data());
  }
  state.counters["frame_Hz"] = benchmark::Counter(double(frames), benchmark::Counter::kIsRate);
  state.counters["CG_per_step"] = double(iterations) / double(17 * frames);
  state.counters["surface_vertices"] = double(model.skin.num_vertices());
  state.counters["probe_contacts"] = double(probe_contacts) / double(17 * std::max(frames, 1L));
  if (threads > 1)
    state.counters["pool_share"] = double(on_pool) / double(17 * std::max(frames, 1L));
  // How often the part-contact pair list was rebuilt (its Verlet skin crossed), per step.
  state.counters["pair_rebuilds"] =
      double(contacts.pair_list_rebuilds() - rebuilds_before) / double(17 * std::max(frames, 1L));
  if (probe_contacts == 0) state.SkipWithError("the probe never touched the body");
}
BENCHMARK(BM_WholeFrame)
    ->ArgNames({"tol_exp", "sleep", "threads", "adaptive"})
    ->Args({6, 0, 1, 0})
    ->Args({3, 0, 1, 0})
    ->Args({3, 1, 1, 0})
    ->Args({3, 0, 2, 0})
    ->Args({3, 0, 2, 1})
    ->Args({2, 0, 1, 0})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0);

// The render side alone: skinning + normals + refit of the full surface.
void BM_SkinningFrame(benchmark::State& state) {
  const auto& model = uterus();
  auto ws = model.skin.make_workspace();
  Positions<double> surface = model.skin.rest.vertices, normals = surface;
  collision::TriangleBvh<double> bvh(model.skin.rest.vertices, model.skin.rest.faces);
  for (auto _ : state) {
    model.skin.evaluate(model.spheres.positions(), ws, surface);
    compute_vertex_normals<double>(surface, model.skin.rest.faces, normals);
    bvh.refit(surface);
    benchmark::DoNotOptimize(surface.data());
  }
  state.counters["surface_vertices"] = double(model.skin.num_vertices());
}
BENCHMARK(BM_SkinningFrame)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fsm::bench
