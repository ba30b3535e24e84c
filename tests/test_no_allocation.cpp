// Simulation::step must not touch the heap. Global operator new/delete are replaced with counting
// versions; the count is armed only around the steps.

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <random>

#include "fsm/fsm.hpp"
#include "fsm_support/paper.hpp"

#include "counting_allocator.hpp"  // replaces global operator new/delete in this test

namespace fsm {
namespace {

template <typename Scalar>
SphereModel<Scalar> jittered_block(const Eigen::Vector3i& cells = Eigen::Vector3i(4, 4, 4)) {
  auto mesh = make_cube_lattice(Vector3<Scalar>::Zero().eval(), cells, Scalar(0.005));
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (Index i = 0; i < mesh.vertices.rows(); ++i)
    for (int c = 0; c < 3; ++c) mesh.vertices(i, c) += Scalar(0.001 * u(rng));
  Material<Scalar> m = support::paper::bilinear_tissue<Scalar>();
  m.switch_strain = Scalar(0.05);
  SphereModel<Scalar> model;
  add_tetrahedral_part(model, mesh, model.add_region("block", m), Scalar(0.0025));
  for (Index i = 0; i < 25; ++i) model.set_fixed(i);
  return model;
}

// Counts allocations over `steps` calls of step(dt) after one warm-up step.
template <typename Scalar>
long allocations(Simulation<Scalar>& sim, Scalar dt, int steps) {
  sim.step(dt);
  g_allocations = 0;
  g_counting = true;
  for (int s = 0; s < steps; ++s) {
    sim.external_forces()(100, 2) = Scalar(-0.01 * (s % 7));  // an edit between steps
    sim.model().positions()(50, 0) += Scalar(1e-6);
    (void)sim.step(dt);
  }
  g_counting = false;
  return g_allocations.load();
}

template <typename Scalar>
class NoAllocation : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(NoAllocation, Scalars);

TYPED_TEST(NoAllocation, StepAllocatesNothingForAnyIntegrator) {
  using S = TypeParam;
  for (const auto& name : integrator_names()) {
    typename Simulation<S>::Options o;
    o.integrator = name;
    Simulation<S> sim(jittered_block<S>(), o);
    const S dt = name == "implicit_euler" ? S(1e-3) : S(0.5) * sim.stable_time_step();
    EXPECT_EQ(allocations(sim, dt, 50), 0) << name;
  }
}

// The continuum law and instrument contacts in the step: every integrator, contacts handed to the
// force model by the solver each step (as ServoLoop does).
TYPED_TEST(NoAllocation, ContinuumWithContactsAllocatesNothing) {
  using S = TypeParam;
  for (const auto& name : integrator_names()) {
    SphereModel<S> model = jittered_block<S>();
    model.set_region_law(0, ForceLaw::continuum);
    typename Simulation<S>::Options o;
    o.integrator = name;
    Simulation<S> sim(model, o);
    collision::ContactSolver<S> contacts(sim.model(), sim.forces());
    collision::Instrument<S> tool;
    tool.shape = collision::SphereShape<S>{S(0.004)};
    tool.pose.position = Vector3<S>(S(0.0075), S(0.0075), S(0.021));
    tool.linear_velocity = Vector3<S>(0, 0, S(-0.01));
    const Index k = contacts.add_instrument(tool);
    const S dt = name == "implicit_euler" ? S(1e-3) : S(0.5) * sim.stable_time_step();
    Index touched = 0;
    auto step = [&] {
      contacts.instrument(k).pose.position.z() -= S(0.01) * dt;
      contacts.compute(sim.model(), sim.forces());
      touched = std::max(touched, contacts.num_contacts());
      (void)sim.step(dt);
      contacts.collect(sim.forces());
    };
    step();
    g_allocations = 0;
    g_counting = true;
    for (int s = 0; s < 50; ++s) step();
    g_counting = false;
    EXPECT_EQ(g_allocations.load(), 0) << name;
    EXPECT_GT(touched, 0) << name;  // the tool really pressed
  }
}

// The rollback and sub-stepping paths too: an explicit scheme far beyond its limit.
TYPED_TEST(NoAllocation, DivergenceAndSubSteppingAllocateNothing) {
  using S = TypeParam;
  typename Simulation<S>::Options o;
  o.integrator = "symplectic_euler";
  o.divergence.max_substep_halvings = 3;
  Simulation<S> sim(jittered_block<S>(), o);
  const S dt = S(20) * sim.stable_time_step();
  g_allocations = 0;
  g_counting = true;
  int diverged = 0;
  for (int s = 0; s < 200; ++s) diverged += sim.step(dt).status == StepStatus::diverged;
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_GT(diverged, 0);  // the path under test really ran
}

// Cutting between steps and tearing inside them (both laws): no allocation either.
TYPED_TEST(NoAllocation, CutAndTearAllocateNothing) {
  using S = TypeParam;
  for (const ForceLaw law : {ForceLaw::links, ForceLaw::continuum}) {
    SphereModel<S> model = jittered_block<S>();
    Material<S> m = model.region(0).material;
    m.tear_strain = S(0.15);
    model.set_region_material(0, m);
    model.set_region_law(0, law);
    Simulation<S> sim(model);
    (void)sim.step(S(1e-3));
    Index cut = 0, torn = 0;
    g_allocations = 0;
    g_counting = true;
    for (int s = 0; s < 40; ++s) {
      Blade<S> blade;  // a blade sweeping down through the block, a little further each step
      const S x = S(0.004) + S(0.0003) * S(s);
      blade.start_a = Vector3<S>(x, S(-0.001), S(0.021));
      blade.start_b = Vector3<S>(x, S(0.021), S(0.021));
      blade.end_a = Vector3<S>(x + S(0.0003), S(-0.001), S(0.004));
      blade.end_b = Vector3<S>(x + S(0.0003), S(0.021), S(0.004));
      cut += sim.cut(blade).links_cut;
      for (Index i = 75; i < sim.model().num_nodes(); ++i)  // pull the top: it tears
        sim.external_forces()(i, 2) = S(0.02);
      torn += sim.step(S(1e-3)).torn.links_torn;
    }
    g_counting = false;
    EXPECT_EQ(g_allocations.load(), 0) << to_string(law);
    EXPECT_GT(cut, 0) << to_string(law);
    EXPECT_GT(torn, 0) << to_string(law);
  }
}

// A copied ForceModel and ContactSolver (copy-constructed, and copy-assigned into
// default-constructed ones) keep the capacity their lists were given at refresh(): putting every
// other node to sleep and breaking every other link splits the active and force links into more
// ranges than the source had, and the face contact fills its touched-node list, with no
// allocation. (A copy of a plain std::vector has capacity for its elements only: this failed.)
TYPED_TEST(NoAllocation, CopiesKeepTheirReservedCapacity) {
  using S = TypeParam;
  SphereModel<S> model = jittered_block<S>();
  ForceModel<S> source(model);
  collision::ContactOptions<S> co;
  co.face_contact = true;
  collision::ContactSolver<S> contacts_source(model, source, co);
  collision::Instrument<S> tool;
  tool.shape = collision::SphereShape<S>{S(0.004)};
  tool.pose.position = Vector3<S>(S(0.0075), S(0.0075), S(0.0235));
  contacts_source.add_instrument(tool);
  const auto ranges_before = source.active_links().size();
  ForceModel<S> assigned;
  assigned = source;
  collision::ContactSolver<S> contacts_assigned;
  contacts_assigned = contacts_source;
  ForceModel<S> forces_copy(source);
  collision::ContactSolver<S> contacts_copy(contacts_source);
  std::vector<std::uint8_t> asleep(std::size_t(model.num_nodes()), 0);
  for (std::size_t i = 1; i < asleep.size(); i += 2) asleep[i] = 1;
  std::vector<Index> broken, none;
  for (Index l = 0; l < model.num_links(); l += 2) broken.push_back(l);
  ImplicitEulerIntegrator<S> integrator;
  integrator.prepare(model);
  for (ForceModel<S>* forces : {&forces_copy, &assigned}) {
    collision::ContactSolver<S>& contacts = forces == &assigned ? contacts_assigned : contacts_copy;
    const char* what = forces == &assigned ? "copy-assigned" : "copy-constructed";
    g_allocations = 0;
    g_counting = true;
    const bool slept = forces->set_asleep(asleep, model);
    forces->update_topology(model, broken, none);
    const long ranging = g_allocations.exchange(0);
    const bool found = contacts.compute(model, *forces);
    const long detecting = g_allocations.exchange(0);
    const bool stepped = integrator.step(model, *forces, S(1e-3)).ok;
    g_counting = false;
    EXPECT_EQ(ranging, 0) << what;
    EXPECT_EQ(detecting, 0) << what;
    EXPECT_EQ(g_allocations.load(), 0) << what;
    EXPECT_TRUE(slept && found && stepped);
    EXPECT_GT(forces->active_links().size(), ranges_before);  // more ranges than the source had
    EXPECT_GT(contacts.num_contacts(), 0);                    // the tool touched faces
    model.positions() = model.rest_positions();
    model.velocities().setZero();
  }
}

// The same for the other objects whose lists a step refills: the continuum law's list of elements
// on the element tangent (every element, with the quality threshold at 1), a Grasper's gripped
// spheres, and a TopologyEditor's broken links, removed elements and touched pieces. Each is
// copy-constructed, and copy-assigned into one with less capacity (a default-constructed editor,
// a ForceModel without elements, a grasper that holds one sphere at most).
TYPED_TEST(NoAllocation, CopiesOfTheOtherStepListsKeepTheirCapacity) {
  using S = TypeParam;
  SphereModel<S> model = jittered_block<S>();
  model.set_region_law(0, ForceLaw::continuum);
  typename ForceModel<S>::Options fo;
  fo.element_tangent_quality = S(1);  // every element takes the element tangent
  ForceModel<S> forces_source(model, fo);
  const collision::GrasperOptions<S> go;
  collision::Grasper<S> grasper_source(model, forces_source, go, S(0.6));
  TopologyEditor<S> editor_source(model);
  ForceModel<S> forces_assigned(jittered_block<S>());  // the link law: no elements
  forces_assigned = forces_source;
  collision::GrasperOptions<S> one = go;
  one.max_held = 1;
  collision::Grasper<S> grasper_assigned(model, forces_source, one, S(0.6));
  grasper_assigned = grasper_source;
  TopologyEditor<S> editor_assigned;
  editor_assigned = editor_source;
  ForceModel<S> forces_copy(forces_source);
  collision::Grasper<S> grasper_copy(grasper_source);
  TopologyEditor<S> editor_copy(editor_source);
  Positions<S> f(model.num_nodes(), 3);
  for (const bool copied : {true, false}) {
    const char* what = copied ? "copy-constructed" : "copy-assigned";
    ForceModel<S>& forces = copied ? forces_copy : forces_assigned;
    collision::Grasper<S>& grasper = copied ? grasper_copy : grasper_assigned;
    TopologyEditor<S>& editor = copied ? editor_copy : editor_assigned;
    SphereModel<S> m = model;
    collision::Pose<S> pose;
    pose.position = Vector3<S>(S(0.004), S(0.01), S(0.02));
    Blade<S> blade;  // down through the block
    blade.start_a = Vector3<S>(S(0.0075), S(-0.001), S(0.021));
    blade.start_b = Vector3<S>(S(0.0075), S(0.021), S(0.021));
    blade.end_a = Vector3<S>(S(0.0078), S(-0.001), S(0.008));
    blade.end_b = Vector3<S>(S(0.0078), S(0.021), S(0.008));
    g_allocations = 0;
    g_counting = true;
    forces.evaluate(m, m.positions(), m.velocities(), f);
    const long continuum = g_allocations.exchange(0);
    grasper.update(m, forces, pose, Vector3<S>::Zero(), Vector3<S>::Zero(), S(0.6));
    const collision::GraspEvent e =
        grasper.update(m, forces, pose, Vector3<S>::Zero(), Vector3<S>::Zero(), S(0.05));
    const long gripping = g_allocations.exchange(0);
    TopologyChange change = editor.cut(m, blade);
    editor.update_pieces(m, forces.force_links(), change);
    g_counting = false;
    EXPECT_EQ(continuum, 0) << what;
    EXPECT_EQ(gripping, 0) << what;
    EXPECT_EQ(g_allocations.load(), 0) << what;
    EXPECT_GT(forces.continuum_element_tangents(), 1) << what;
    EXPECT_GT(e.grasped, 1) << what;  // more than the one-sphere grasper could hold
    EXPECT_GT(change.links_cut, 0) << what;
  }
}

// A grasper gripping, pulling and releasing through the steps.
TYPED_TEST(NoAllocation, GraspingAllocatesNothing) {
  using S = TypeParam;
  Simulation<S> sim(jittered_block<S>());
  collision::Grasper<S> grasper(sim.model(), sim.forces(), collision::GrasperOptions<S>{}, S(0.6));
  collision::Pose<S> pose;
  pose.position = Vector3<S>(S(0.004), S(0.01), S(0.02));
  (void)sim.step(S(1e-3));
  Index grasped = 0, released = 0;
  g_allocations = 0;
  g_counting = true;
  for (int s = 0; s < 60; ++s) {
    const S opening = s < 5 ? S(0.6) : s < 50 ? S(0.05) : S(0.6);
    const Vector3<S> velocity(0, 0, S(0.01));
    const collision::GraspEvent e =
        grasper.update(sim.model(), sim.forces(), pose, velocity, Vector3<S>::Zero(), opening);
    grasped += e.grasped;
    released += e.released;
    (void)sim.step(S(1e-3));
    (void)grasper.wrench(sim.forces());
    pose.position.z() += S(1e-5);
  }
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_GT(grasped, 0);
  EXPECT_EQ(released, grasped);
}

// Skinning runs every render frame: it must not allocate either (both binding kinds).
TEST(NoAllocation, SkinEvaluation) {
  Skin<double> skin;
  const int n = 6;
  Positions<double> spheres(n, 3);
  for (int i = 0; i < n; ++i) spheres.row(i) << 0.01 * i, 0, 0;
  skin.chain_nodes.resize(n, 3);
  skin.chain_rest_tangents.resize(n, 3);
  for (int i = 0; i < n; ++i) {
    skin.chain_nodes.row(i) << std::max(i - 1, 0), i, std::min(i + 1, n - 1);
    skin.chain_rest_tangents.row(i) << 1, 0, 0;
  }
  skin.rest.vertices.setRandom(40, 3);
  skin.rest.faces.resize(1, 3);
  skin.rest.faces << 0, 1, 2;
  skin.kind.resize(40);
  skin.nodes.resize(40, 4);
  skin.weights.setZero(40, 4);
  skin.offsets.setRandom(40, 3);
  for (Index v = 0; v < 40; ++v) {
    if (v % 2) {
      skin.kind[v] = std::uint8_t(SkinKind::barycentric);
      skin.nodes.row(v) << 0, 1, 2, 3;
      skin.weights.row(v) << 0.1, 0.2, 0.3, 0.4;
    } else {
      skin.kind[v] = std::uint8_t(SkinKind::chain);
      skin.nodes.row(v) << 1, 2, -1, -1;
      skin.weights.row(v) << 0.5, 0.5, 0, 0;
    }
  }
  auto ws = skin.make_workspace();
  Positions<double> out(40, 3);
  spheres(3, 1) = 0.004;  // a bent chain
  g_allocations = 0;
  g_counting = true;
  for (int k = 0; k < 20; ++k) skin.evaluate(spheres, ws, out);
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_TRUE(out.allFinite());
}

TEST(NoAllocation, TwoThreadsAfterWarmUp) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  Simulation<double>::Options o;
  o.integrator = "heun";
  o.forces.threads = 2;
  Simulation<double> sim(jittered_block<double>(), o);
  EXPECT_EQ(allocations(sim, 0.5 * sim.stable_time_step(), 50), 0);
}

// The same on a block large enough that the two threads share the links by node (one dispatch,
// no buffers: ForceModel::links_partitioned()), with Heun and the implicit step (link law).
TEST(NoAllocation, TwoThreadsWithTheLinksPartitioned) {
  if (detail::max_threads() < 2) GTEST_SKIP() << "a machine with one hardware thread";
  for (const std::string name : {"heun", "implicit_euler"}) {
    Simulation<double>::Options o;
    o.integrator = name;
    o.forces.threads = 2;
    Simulation<double> sim(jittered_block<double>(Eigen::Vector3i(14, 12, 13)), o);
    ASSERT_TRUE(sim.forces().links_partitioned()) << name;
    const double dt = name == "heun" ? 0.5 * sim.stable_time_step() : 1e-3;
    EXPECT_EQ(allocations(sim, dt, 20), 0) << name;
  }
}

}  // namespace
}  // namespace fsm

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
