// Contact detection and response: the uterus model with an instrument pressing each part (the
// 20 us target), scaling from 1e3 to 1e5 spheres, and what sleeping saves per step.

#include <benchmark/benchmark.h>

#include <map>

#include "common.hpp"
#include "fsm/build/builder.hpp"
#include "fsm/collision/contact.hpp"

namespace fsm::bench {
namespace {

using namespace fsm::collision;
using V3 = Vector3<double>;

const TissueModel<double>& uterus() {
  static const TissueModel<double> model =
      build::build_model(std::string(FSM_SOURCE_DIR) + "/data/uterus/uterus.json");
  return model;
}

// An instrument (a 5 mm shaft with a rounded tip) pressing 1 mm into the given part, from outside:
// at the part's sphere farthest from the model's centre, along that direction.
Instrument<double> probe(const SphereModel<double>& m, const Part& p) {
  const V3 centre = m.rest_positions().colwise().mean().transpose();
  Index best = p.first_node;
  double far = -1;
  for (Index i = p.first_node; i < p.first_node + p.num_nodes; ++i) {
    const double d = (m.rest_positions().row(i).transpose() - centre).norm();
    if (d > far) {
      far = d;
      best = i;
    }
  }
  const V3 x = m.rest_positions().row(best).transpose();
  const V3 out = (x - centre).normalized();
  Instrument<double> ins;
  ins.name = "probe";
  ins.shape = CapsuleShape<double>{0.0025, 0.02};
  // The capsule's -z end is the tip; point it along -out, tip 1 mm into the sphere.
  ins.pose.orientation = Eigen::Quaterniond::FromTwoVectors(V3::UnitZ(), out);
  ins.pose.position = x + out * (m.radii()[best] + 0.0025 - 0.001 + 0.02);
  return ins;
}

void BM_UterusContact(benchmark::State& state, const std::string& part, bool parts) {
  const auto& model = uterus();
  ContactOptions<double> o;
  o.part_contact = parts;
  ContactSolver<double> solver(model.spheres, o);
  solver.add_instrument(probe(model.spheres, model.part(part)));
  Positions<double> f = Positions<double>::Zero(model.spheres.num_nodes(), 3);
  solver.compute(model.spheres, f);  // warm: the hash is built
  for (auto _ : state) {
    f.setZero();
    solver.compute(model.spheres, f);
    benchmark::DoNotOptimize(f.data());
  }
  state.counters["tool_contacts"] = double(solver.num_contacts());
  state.counters["candidates"] = double(solver.candidates());
  state.counters["force_N"] = solver.wrench(0).force.norm();
}

// Scaling: a lattice of about n spheres (5 mm spacing), the instrument pressing its top centre.
void BM_ContactScaling(benchmark::State& state) {
  const int cells = int(state.range(0));
  const SphereModel<double> m = lattice_model<double>(cells, false);
  ContactSolver<double> solver(m);
  Instrument<double> ins;
  ins.shape = SphereShape<double>{0.004};
  const double top = m.rest_positions().col(2).maxCoeff();
  ins.pose.position = V3(0.0025 * cells, 0.0025 * cells, top + 0.004);
  solver.add_instrument(ins);
  Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
  solver.compute(m, f);
  for (auto _ : state) {
    f.setZero();
    solver.compute(m, f);
    benchmark::DoNotOptimize(f.data());
  }
  state.counters["spheres"] = double(m.num_nodes());
  state.counters["contacts"] = double(solver.num_contacts());
  state.SetItemsProcessed(int64_t(state.iterations()) * m.num_nodes());
}
BENCHMARK(BM_ContactScaling)->Arg(5)->Arg(10)->Arg(21)->Arg(46)->ArgName("cells")->Unit(benchmark::kMicrosecond);

// A whole haptic step (contacts + implicit Euler at 1 ms) on the uterus with the probe on the body,
// with and without sleeping, after 0.3 s of settling.
void BM_UterusStepSleeping(benchmark::State& state) {
  const bool sleep = state.range(0) != 0;
  const auto& model = uterus();
  Simulation<double>::Options o;
  o.sleep.enabled = sleep;
  Simulation<double> sim(model.spheres, o);
  ContactSolver<double> solver(sim.model());
  solver.add_instrument(probe(model.spheres, model.part("body")));
  auto step = [&] {
    sim.external_forces().setZero();
    solver.compute(sim.model(), sim.external_forces());
    return sim.step(1e-3);
  };
  for (int s = 0; s < 300; ++s) step();
  for (auto _ : state) benchmark::DoNotOptimize(step());
  state.counters["asleep_regions"] = double(sim.num_asleep());
}
BENCHMARK(BM_UterusStepSleeping)->Arg(0)->Arg(1)->ArgName("sleep")->Unit(benchmark::kMicrosecond);

const bool registered = [] {
  for (const char* p : {"body", "fibroid", "ovary_left", "ligament_left", "tube_left"}) {
    benchmark::RegisterBenchmark((std::string("BM_UterusContact/") + p + "/parts:1").c_str(),
                                 [p](benchmark::State& s) { BM_UterusContact(s, p, true); })
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark((std::string("BM_UterusContact/") + p + "/parts:0").c_str(),
                                 [p](benchmark::State& s) { BM_UterusContact(s, p, false); })
        ->Unit(benchmark::kMicrosecond);
  }
  return true;
}();

}  // namespace
}  // namespace fsm::bench
