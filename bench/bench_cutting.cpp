// Cutting and tearing on the bundled uterus (the myomectomy issue's target: a cut or a tear adds at
// most 20 us to the uterus step): the tear check inside the step, a blade's cut between steps
// (Simulation::cut: the search, the force model's update, the pieces, the energy reference), and
// the render surface's update (CutSurface).

#include <benchmark/benchmark.h>

#include <limits>

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

// The tear check the step runs after each accepted step when any link can tear: every tearable
// intact link's strain against its limit (none is strained that far here); all links can tear, or
// only the attachment links between the body and the fibroid (the myomectomy scenario's capsule).
// The step itself takes 0.6-2 ms on this model, with a spread between runs far larger than this.
void BM_UterusTearCheck(benchmark::State& state) {
  const auto law = state.range(0) ? ForceLaw::continuum : ForceLaw::links;
  SphereModel<double> m = with_law(law);
  const TissueModel<double>& u = uterus();
  const Part& body = u.part("body");
  const Part& fibroid = u.part("fibroid");
  auto in = [](const Part& p, Index i) {
    return i >= p.first_node && i < p.first_node + p.num_nodes;
  };
  Index tearable = 0;
  for (Index l = 0; l < m.num_links(); ++l) {
    const Index i = m.links()(l, 0), j = m.links()(l, 1);
    const bool capsule = (in(body, i) && in(fibroid, j)) || (in(body, j) && in(fibroid, i));
    if (state.range(1) == 0 || capsule) {
      m.tear_strain()[l] = 5.0;
      ++tearable;
    }
  }
  Simulation<double>::Options o;
  o.forces.drag = 5;
  Simulation<double> sim(m, o);
  for (int s = 0; s < 300; ++s) (void)sim.step(1e-3);
  for (auto _ : state) benchmark::DoNotOptimize(sim.topology().tear(sim.model()).links_torn);
  state.counters["tearable"] = double(tearable);
}
BENCHMARK(BM_UterusTearCheck)
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->ArgNames({"continuum", "capsule_only"})
    ->Unit(benchmark::kMicrosecond);

// A tear as the step makes it: the check finds one link past its limit, the force model is
// updated by what broke and the pieces by a search from the wound (restored, untimed, between
// iterations).
void BM_UterusTearEvent(benchmark::State& state) {
  const auto law = state.range(0) ? ForceLaw::continuum : ForceLaw::links;
  Simulation<double> sim = settled(law, false);
  SphereModel<double>& m = sim.model();
  const Part& body = uterus().part("body");
  Index link = -1;  // a stretched link of the body: it tears at any positive limit
  for (Index l = body.first_link; l < body.first_link + body.num_links && link < 0; ++l)
    if ((m.positions().row(m.links()(l, 1)) - m.positions().row(m.links()(l, 0))).norm() >
        1.001 * m.rest_lengths()[l])
      link = l;
  auto limits = sim.topology().tear_strains();
  limits.setConstant(std::numeric_limits<double>::infinity());
  limits[link] = 1e-4;
  sim.topology().refresh_tearing(m);
  Index torn = 0;
  for (auto _ : state) {
    TopologyChange c = sim.topology().tear(m);
    sim.forces().update_topology(m, sim.topology().broken_links(),
                                 sim.topology().removed_tetrahedra());
    sim.topology().update_pieces(m, sim.forces().force_links(), c);
    torn = c.links_torn + c.tetrahedra_torn;
    state.PauseTiming();
    m.restore_topology();
    sim.forces().update_topology(m);
    TopologyChange whole;
    sim.topology().count_pieces(m, sim.forces().force_links(), whole);
    state.ResumeTiming();
  }
  state.counters["links_and_tetrahedra_torn"] = double(torn);
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
    TopologyChange whole;
    sim.topology().count_pieces(sim.model(), sim.forces().force_links(), whole);
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
    TopologyChange whole;
    sim.topology().count_pieces(sim.model(), sim.forces().force_links(), whole);
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
