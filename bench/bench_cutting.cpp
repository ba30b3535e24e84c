// Cutting and tearing on the bundled uterus (the myomectomy issue's target: a cut or a tear adds at
// most 20 us to the uterus step): the tear check inside the step, a blade's cut between steps
// (Simulation::cut: the search, the force model's update, the pieces, the energy reference), and
// the render surface's update (CutSurface).

#include <benchmark/benchmark.h>

#include "fsm/builder/builder.hpp"
#include "fsm/cut_surface.hpp"
#include "fsm/fsm.hpp"
#include "fsm_support/model_cache.hpp"

namespace {

using namespace fsm;
using V3 = Vector3<double>;

const TissueModel<double>& uterus() {
  return support::bundled_uterus([](const std::string& s) { return build::build_model(s); },
                                 "bench_cutting");
}

SphereModel<double> with_law(ForceLaw law) {
  SphereModel<double> m = uterus().spheres;
  for (const Part& p : uterus().parts)
    if (p.topology == Topology::tetrahedral) m.set_region_law(p.region, law);
  return m;
}

// A blade whose edge (20 mm, along y) sweeps 1 mm down through the body's top at its centre:
// the cut of one servo step of an incision at 1 m/s.
Blade<double> one_step_blade(const SphereModel<double>& m, const Part& body) {
  V3 lo = V3::Constant(1e9), hi = V3::Constant(-1e9);
  for (Index i = body.first_node; i < body.first_node + body.num_nodes; ++i) {
    lo = lo.cwiseMin(m.positions().row(i).transpose());
    hi = hi.cwiseMax(m.positions().row(i).transpose());
  }
  const V3 c = (lo + hi) / 2;
  const double z = hi.z() - 0.006;
  return Blade<double>{V3(c.x(), c.y() - 0.01, z), V3(c.x(), c.y() + 0.01, z),
                       V3(c.x(), c.y() - 0.01, z - 0.001), V3(c.x(), c.y() + 0.01, z - 0.001)};
}

Simulation<double> settled(ForceLaw law, bool tearing) {
  SphereModel<double> m = with_law(law);
  if (tearing)  // every link may tear (none is strained that far: this is the check's cost)
    for (Index l = 0; l < m.num_links(); ++l) m.tear_strain()[l] = 5.0;
  Simulation<double>::Options o;
  o.forces.drag = 5;
  Simulation<double> sim(m, o);
  for (int s = 0; s < 300; ++s) (void)sim.step(1e-3);
  return sim;
}

// The tear check the step runs after each accepted step when any link can tear: every intact
// link's strain against its limit (none is strained that far here). The step itself takes
// 0.6-2 ms on this model, with a spread between runs far larger than this.
void BM_UterusTearCheck(benchmark::State& state) {
  const auto law = state.range(0) ? ForceLaw::continuum : ForceLaw::links;
  Simulation<double> sim = settled(law, true);
  for (auto _ : state) benchmark::DoNotOptimize(sim.topology().tear(sim.model()).links_torn);
  state.counters["links"] = double(sim.model().num_links());
}
BENCHMARK(BM_UterusTearCheck)->Arg(0)->Arg(1)->ArgName("continuum")->Unit(benchmark::kMicrosecond);

// A tear: the force model's update and the pieces after one link breaks (what a tear adds to the
// step that tears; restored, untimed, between iterations).
void BM_UterusTearEvent(benchmark::State& state) {
  const auto law = state.range(0) ? ForceLaw::continuum : ForceLaw::links;
  Simulation<double> sim = settled(law, false);
  const Index link = uterus().part("body").first_link + uterus().part("body").num_links / 2;
  for (auto _ : state) {
    sim.model().link_intact()[link] = 0;
    const auto [b, e] = sim.topology().tetrahedra_at_link(link);
    for (const Index* t = b; t != e; ++t) sim.model().tetrahedron_intact()[*t] = 0;
    sim.forces().update_topology(sim.model());
    TopologyChange c;
    c.links_torn = 1;
    sim.topology().count_pieces(sim.model(), sim.forces().force_links(), c);
    benchmark::DoNotOptimize(c.pieces);
    state.PauseTiming();
    sim.model().restore_topology();
    sim.forces().update_topology(sim.model());
    state.ResumeTiming();
  }
}
BENCHMARK(BM_UterusTearEvent)->Arg(0)->Arg(1)->ArgName("continuum")->Unit(benchmark::kMicrosecond);

// Simulation::cut of one step's sweep that cuts links (restored, untimed, between iterations).
void BM_UterusCut(benchmark::State& state) {
  const auto law = state.range(0) ? ForceLaw::continuum : ForceLaw::links;
  Simulation<double> sim = settled(law, false);
  const Blade<double> blade = one_step_blade(sim.model(), uterus().part("body"));
  Index cut = 0;
  for (auto _ : state) {
    const TopologyChange c = sim.cut(blade);
    cut = c.links_cut;
    state.PauseTiming();
    sim.model().restore_topology();
    sim.forces().update_topology(sim.model());
    state.ResumeTiming();
  }
  state.counters["links_cut"] = double(cut);
}
BENCHMARK(BM_UterusCut)->Arg(0)->Arg(1)->ArgName("continuum")->Unit(benchmark::kMicrosecond);

// A blade that misses everything: the search alone (what every step of an incision pays).
void BM_UterusCutSearch(benchmark::State& state) {
  Simulation<double> sim = settled(ForceLaw::links, false);
  Blade<double> blade = one_step_blade(sim.model(), uterus().part("body"));
  for (V3* p : {&blade.start_a, &blade.start_b, &blade.end_a, &blade.end_b}) p->z() += 0.2;
  for (auto _ : state) benchmark::DoNotOptimize(sim.cut(blade).links_cut);
}
BENCHMARK(BM_UterusCutSearch)->Unit(benchmark::kMicrosecond);

// The cut with its render surface: Simulation::cut, then the skin evaluated, the crossed faces
// hidden and the walls added (CutSurface); its cost less BM_UterusCut's is the surface's.
void BM_UterusCutWithSurface(benchmark::State& state) {
  Simulation<double> sim = settled(ForceLaw::links, false);
  const Blade<double> blade = one_step_blade(sim.model(), uterus().part("body"));
  const Skin<double>& skin = uterus().skin;
  auto ws = skin.make_workspace();
  Positions<double> vertices = skin.rest.vertices;
  CutSurface<double> surface(sim.model(), skin);
  Index hidden = 0, walls = 0;
  for (auto _ : state) {
    (void)sim.cut(blade);
    skin.evaluate(sim.model().positions(), ws, vertices);
    benchmark::DoNotOptimize(surface.add_cut(blade, vertices));
    surface.update(sim.model());
    hidden = surface.num_hidden();
    walls = surface.num_walls();
    state.PauseTiming();
    sim.model().restore_topology();
    sim.forces().update_topology(sim.model());
    surface.restore(sim.model());
    state.ResumeTiming();
  }
  state.counters["hidden"] = double(hidden);
  state.counters["walls"] = double(walls);
}
BENCHMARK(BM_UterusCutWithSurface)->Unit(benchmark::kMicrosecond);

// The skin alone (what the render side pays each frame, and a cut with its surface once).
void BM_UterusSkin(benchmark::State& state) {
  const Skin<double>& skin = uterus().skin;
  auto ws = skin.make_workspace();
  Positions<double> vertices = skin.rest.vertices;
  for (auto _ : state) {
    skin.evaluate(uterus().spheres.positions(), ws, vertices);
    benchmark::DoNotOptimize(vertices.data());
  }
  state.counters["vertices"] = double(skin.num_vertices());
}
BENCHMARK(BM_UterusSkin)->Unit(benchmark::kMicrosecond);

}  // namespace
