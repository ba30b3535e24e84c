// Contact detection and response: the uterus model with an instrument pressing each part (the
// 20 us target), scaling from 1e3 to 1e5 spheres, and what sleeping saves per step.

#include <benchmark/benchmark.h>

#include <map>
#include <random>

#include "common.hpp"
#include "fsm/builder/builder.hpp"
#include "fsm/collision/contact.hpp"
#include "fsm_support/model_cache.hpp"
#include "fsm_support/probe.hpp"
#include "preconditioners.hpp"

namespace fsm::bench {
namespace {

using namespace fsm::collision;
using V3 = Vector3<double>;

const TissueModel<double>& uterus() {
  return support::bundled_uterus([](const std::string& s) { return build::build_model(s); },
                                 "bench_contact");
}

// An instrument (a 5 mm shaft with a rounded tip) pressing the given part from outside, its tip
// 1 mm past the centre of the part's sphere farthest from the model's centre, along that
// direction (the vertex contact meets sphere centres: 1 mm into the sphere's surface would touch
// nothing).
Instrument<double> probe(const SphereModel<double>& m, const Part& p) {
  const support::CapsuleProbe cp{support::outermost_free_sphere(m, p)};
  return cp.instrument(cp.site.radius + 0.001);
}

void BM_UterusContact(benchmark::State& state, const std::string& part, bool parts,
                      bool faces = false) {
  const auto& model = uterus();
  ContactOptions<double> o;
  o.part_contact = parts;
  o.face_contact = faces;
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
  if (solver.num_contacts() == 0) state.SkipWithError("the instrument touches nothing");
}

// Scaling: a lattice of about n spheres (5 mm spacing), the instrument pressing its top centre.
void BM_ContactScaling(benchmark::State& state) {
  const int cells = int(state.range(0));
  const SphereModel<double> m = lattice_model<double>(cells, false);
  ContactSolver<double> solver(m);
  Instrument<double> ins;
  ins.shape = SphereShape<double>{0.004};
  // 2.5 mm past the top node nearest the top's centre (the lattice is jittered).
  const auto x = m.rest_positions();
  const double top = x.col(2).maxCoeff();
  const V3 centre(0.0025 * cells, 0.0025 * cells, top);
  Index under = 0;
  for (Index i = 0; i < m.num_nodes(); ++i)
    if ((x.row(i).transpose() - centre).squaredNorm() <
        (x.row(under).transpose() - centre).squaredNorm())
      under = i;
  ins.pose.position = x.row(under).transpose() + V3(0, 0, 0.0015);
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
  if (solver.num_contacts() == 0) state.SkipWithError("the instrument touches nothing");
}
BENCHMARK(BM_ContactScaling)
    ->Arg(5)
    ->Arg(10)
    ->Arg(21)
    ->Arg(46)
    ->ArgName("cells")
    ->Unit(benchmark::kMicrosecond);

// Narrow phase alone: one shape against one sphere, per shape (the sphere placed so that about
// half of the queries touch).
void BM_NarrowPhase(benchmark::State& state) {
  const int which = int(state.range(0));
  Shape<double> shape;
  if (which == 0) shape = SphereShape<double>{0.004};
  if (which == 1) shape = CapsuleShape<double>{0.0025, 0.02};
  if (which == 2) shape = CylinderShape<double>{0.0025, 0.02};
  if (which == 3) {  // a grasper jaw: 16 points
    ConvexHullShape<double> h;
    h.points.resize(16, 3);
    for (int i = 0; i < 16; ++i) {
      const double a = 2 * 3.14159265358979 * (i % 8) / 8;
      h.points.row(i) = V3(0.0025 * std::cos(a), 0.0015 * std::sin(a), i < 8 ? -0.01 : 0.01);
    }
    shape = h;
  }
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.008, 0.008);
  std::vector<V3> points(256);
  for (auto& p : points) p = V3(u(rng), u(rng), u(rng) * 2.5);
  Pose<double> pose;
  std::size_t k = 0, hits = 0;
  for (auto _ : state) {
    const auto c = contact(shape, pose, points[k++ & 255], 0.003);
    hits += c ? 1 : 0;
    benchmark::DoNotOptimize(c);
  }
  state.counters["hit_fraction"] = double(hits) / double(state.iterations());
  state.SetItemsProcessed(int64_t(state.iterations()));
  state.SetLabel(which == 0   ? "sphere"
                 : which == 1 ? "capsule"
                 : which == 2 ? "cylinder"
                              : "hull16");
}
BENCHMARK(BM_NarrowPhase)->DenseRange(0, 3)->ArgName("shape");

// Broad phase alone: the incremental hash update with the instrument disabled and no part contact.
void BM_UterusBroadPhase(benchmark::State& state) {
  const auto& model = uterus();
  ContactOptions<double> o;
  o.part_contact = false;
  ContactSolver<double> solver(model.spheres, o);
  Instrument<double> ins = probe(model.spheres, model.part("body"));
  ins.enabled = false;
  solver.add_instrument(ins);
  SphereModel<double> m = model.spheres;
  Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
  // Two states ~1 mm apart (a large motion: many spheres change cell every step), alternated by
  // a copy that is included in the time (about 0.5 us for the 687 x 3 coordinates).
  std::mt19937 rng(2);
  std::normal_distribution<double> g(0, 1e-3);
  Positions<double> a = m.positions(), b = m.positions();
  for (Index i = 0; i < m.num_nodes(); ++i) b.row(i) += V3(g(rng), g(rng), g(rng)).transpose();
  solver.compute(m, f);
  bool flip = false;
  for (auto _ : state) {
    m.positions() = (flip = !flip) ? b : a;
    solver.compute(m, f);
    benchmark::DoNotOptimize(f.data());
  }
  state.counters["spheres"] = double(m.num_nodes());
}
BENCHMARK(BM_UterusBroadPhase)->Unit(benchmark::kMicrosecond);

// A scripted session on the uterus (drag 5/s, implicit Euler at 1 ms, contacts every step): 1 s
// settling, then the probe presses the body, the left ovary and the left tube for 1 s each. With
// sleeping on, the counters give its accuracy cost against the same session awake: the RMS and
// largest difference of the final sphere positions and the largest difference of the probe force.
struct SessionResult {
  Positions<double> x;
  std::vector<double> force;
  double asleep_fraction{0};
};

SessionResult run_session(bool sleep) {
  const auto& model = uterus();
  Simulation<double>::Options o;
  o.sleep.enabled = sleep;
  o.forces.drag = 5;
  Simulation<double> sim(model.spheres, o);
  ContactSolver<double> solver(sim.model(), sim.forces());
  const Index k = solver.add_instrument(probe(model.spheres, model.part("body")));
  solver.instrument(k).enabled = false;
  SessionResult r;
  double asleep = 0;
  int steps = 0;
  for (int phase = 0; phase < 4; ++phase) {
    if (phase > 0) {
      const char* part[] = {"body", "ovary_left", "tube_left"};
      const Instrument<double> next = probe(model.spheres, model.part(part[phase - 1]));
      solver.instrument(k).pose = next.pose;
      solver.instrument(k).enabled = true;
    }
    for (int s = 0; s < 1000; ++s, ++steps) {
      solver.compute(sim.model(), sim.forces());
      sim.step(1e-3);
      solver.collect(sim.forces());
      r.force.push_back(solver.wrench(k).force.norm());
      asleep += double(sim.num_asleep()) / double(sim.model().num_regions());
    }
  }
  r.x = sim.model().positions();
  r.asleep_fraction = asleep / steps;
  return r;
}

void BM_UterusSession(benchmark::State& state) {
  const bool sleep = state.range(0) != 0;
  SessionResult r;
  for (auto _ : state) r = run_session(sleep);
  // Seconds per step (printed with an SI prefix: 450u is 450 us).
  state.counters["s_per_step"] =
      benchmark::Counter(4000.0 * double(state.iterations()),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["asleep_fraction"] = r.asleep_fraction;
  if (sleep) {
    const SessionResult awake = run_session(false);
    const Eigen::ArrayXd d = (r.x - awake.x).rowwise().norm().array();
    state.counters["rms_dx_um"] = std::sqrt(d.square().mean()) * 1e6;
    state.counters["max_dx_um"] = d.maxCoeff() * 1e6;
    double df = 0;
    for (std::size_t i = 0; i < r.force.size(); ++i)
      df = std::max(df, std::abs(r.force[i] - awake.force[i]));
    state.counters["max_dF_mN"] = df * 1e3;
  }
}
BENCHMARK(BM_UterusSession)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("sleep")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// One 1 ms implicit step of the uterus with the probe pressing the body 1 mm past the sagged
// surface (contacts in the solve), the tetrahedral parts on the link law (0) or the continuum law
// (1), the instrument's contact stiffness_ratio 100 (default) or 10 (softer, cheaper to solve). One
// core. Counters: CG iterations per step, contacts (instrument and part), the probe's force. The
// scale issue's targets: 100 us (links) and 150 us (continuum). The bundled uterus (tetrahedral
// parts on the link or the continuum law, drag 5/s) with the capsule probe on the body: the model
// first sags under gravity for 0.5 s with the probe away, then the probe's tip goes 1 mm past the
// sagged centre of the body's outermost sphere (a tetrahedral part meets instruments at its
// spheres' centres: ContactOptions:: tetrahedral_surface). step() is one 1 ms step with contacts,
// settle() 0.3 s of them.
struct PressedUterus {
  static Simulation<double> make(bool continuum) {
    SphereModel<double> m = uterus().spheres;
    if (continuum)
      for (const Part& p : uterus().parts)
        if (p.topology == Topology::tetrahedral) m.set_region_law(p.region, ForceLaw::continuum);
    Simulation<double>::Options o;
    o.forces.drag = 5;
    return Simulation<double>(std::move(m), o);
  }
  static ContactOptions<double> contact_options(double stiffness_ratio) {
    ContactOptions<double> co;
    co.stiffness_ratio = stiffness_ratio;
    return co;
  }
  PressedUterus(bool continuum, double stiffness_ratio)
      : sim(make(continuum)), solver(sim.model(), sim.forces(), contact_options(stiffness_ratio)) {
    support::CapsuleProbe cp{
        support::outermost_free_sphere(uterus().spheres, uterus().part("body"))};
    solver.add_instrument(cp.instrument(-0.02));
    support::sag_then_aim(sim, solver, 0, cp);
    cp.press(solver, 0, cp.site.radius + 0.001);
  }
  // Contacts of the instrument (not between parts) in the last step.
  [[nodiscard]] Index instrument_contacts() const {
    Index n = 0;
    for (Index k = 0; k < solver.num_contacts(); ++k)
      if (solver.contacts()[k].instrument >= 0) ++n;
    return n;
  }
  StepReport<double> step() {
    solver.compute(sim.model(), sim.forces());
    const StepReport<double> r = sim.step(1e-3);
    solver.collect(sim.forces());
    return r;
  }
  void settle() {
    for (int s = 0; s < 300; ++s) step();
  }
  Simulation<double> sim;
  ContactSolver<double> solver;
};

void BM_UterusImplicitStepWithContact(benchmark::State& state) {
  PressedUterus u(state.range(0) != 0, double(state.range(1)));
  u.settle();  // the measured steps are the steady pressing
  long iterations = 0, steps = 0;
  for (auto _ : state) {
    iterations += u.step().solver_iterations;
    ++steps;
  }
  state.counters["cg_iterations"] = double(iterations) / double(std::max(steps, 1L));
  state.counters["contacts"] = double(u.solver.num_contacts());
  state.counters["probe_contacts"] = double(u.instrument_contacts());
  state.counters["probe_force_N"] = u.solver.wrench(0).force.norm();
  if (u.instrument_contacts() == 0) state.SkipWithError("the probe does not touch the tissue");
  state.counters["tetrahedra"] = double(u.sim.model().num_tetrahedra());
}
BENCHMARK(BM_UterusImplicitStepWithContact)
    ->ArgsProduct({{0, 1}, {100, 10}})
    ->ArgNames({"continuum", "ratio"})
    ->Unit(benchmark::kMicrosecond);

// Preconditioners of the implicit step's matrix A = M + h D + h^2 K (assembled at the state of
// BM_UterusImplicitStepWithContact after 0.3 s of pressing, contacts in), to choose the CG
// solver's (preconditioners.hpp: PCG from zero to |r| <= 1e-6 |b| for a random b with each, the
// factors' sizes and times). The timed loop is one sparse product A p (the assembled form; the
// matrix-free one is in the step benchmark).
void BM_UterusPreconditioners(benchmark::State& state) {
  PressedUterus u(state.range(0) != 0, ContactOptions<double>().stiffness_ratio);
  Simulation<double>& sim = u.sim;
  const double h = 1e-3;
  const Eigen::SparseMatrix<double> A_rest = bench::implicit_matrix(sim, h);  // before contact
  u.settle();
  u.solver.compute(sim.model(), sim.forces());
  sim.forces().start_contacts(sim.model());
  const Eigen::SparseMatrix<double> A = bench::implicit_matrix(sim, h);
  const bench::PreconditionerStudy s = bench::study_preconditioners(A_rest, A, 1e-6);
  const Eigen::VectorXd b = Eigen::VectorXd::Random(A.rows());
  Eigen::VectorXd y;
  for (auto _ : state) {
    y = A * b;
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["it_jacobi"] = s.it_jacobi;
  state.counters["it_block_jacobi"] = s.it_block_jacobi;
  state.counters["it_incomplete_cholesky"] = s.it_incomplete_cholesky;
  state.counters["it_cholesky_rest"] = s.it_cholesky_rest;
  state.counters["it_cholesky_now"] = s.it_cholesky_now;
  state.counters["dofs"] = s.dofs;
  state.counters["nnz_A"] = s.nnz_A;
  state.counters["nnz_L"] = s.nnz_L;
  state.counters["factor_us"] = s.factor_us;
  state.counters["cholesky_apply_us"] = s.cholesky_apply_us;
}
BENCHMARK(BM_UterusPreconditioners)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("continuum")
    ->Unit(benchmark::kMicrosecond);

const bool registered = [] {
  for (const char* p : {"body", "fibroid", "ovary_left", "ligament_left", "tube_left"}) {
    benchmark::RegisterBenchmark((std::string("BM_UterusContact/") + p + "/parts:1").c_str(),
                                 [p](benchmark::State& s) { BM_UterusContact(s, p, true); })
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark((std::string("BM_UterusContact/") + p + "/parts:0").c_str(),
                                 [p](benchmark::State& s) { BM_UterusContact(s, p, false); })
        ->Unit(benchmark::kMicrosecond);
    // The probe against the tetrahedral parts' faces (ContactOptions::face_contact).
    benchmark::RegisterBenchmark(
        (std::string("BM_UterusContact/") + p + "/parts:0/faces:1").c_str(),
        [p](benchmark::State& s) { BM_UterusContact(s, p, false, true); })
        ->Unit(benchmark::kMicrosecond);
  }
  return true;
}();

}  // namespace
}  // namespace fsm::bench
