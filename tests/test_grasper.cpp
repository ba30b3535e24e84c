// The grasper (fsm/collision/grasper.hpp) and the held nodes it writes into the force model.

#include "fsm/collision/grasper.hpp"

#include <gtest/gtest.h>

#include "common.hpp"

namespace fsm::collision {
namespace {

using V3 = Vector3<double>;

// A 20 x 20 x 10 mm block (5 mm spheres), bottom fixed, no gravity; the jaws hinge on its top
// face at x = 4 mm and reach along +x over the middle.
SphereModel<double> block(ForceLaw law) {
  SphereModel<double> model = fsm::test::block<double>({4, 4, 2}, 0.005);
  model.set_region_law(0, law);
  fsm::test::fix_below(model, 2);
  return model;
}

Pose<double> jaws_at(double lift) {
  Pose<double> pose;
  pose.position = V3(0.004, 0.010, 0.010 + lift);
  return pose;
}

class Grasp : public ::testing::TestWithParam<ForceLaw> {};

TEST_P(Grasp, HoldsWhatItClosesOnFollowsTheJawsAndReleases) {
  Simulation<double>::Options o;
  o.forces.gravity.setZero();
  o.forces.drag = 5;
  Simulation<double> sim(block(GetParam()), o);
  GrasperOptions<double> go;
  Grasper<double> grasper(sim.model(), sim.forces(), go, 0.6);
  const double h = 1e-3;
  // Open: nothing held, whatever lies between the jaws.
  GraspEvent e = grasper.update(sim.model(), sim.forces(), jaws_at(0), V3::Zero(), V3::Zero(), 0.6);
  EXPECT_EQ(e.grasped, 0);
  EXPECT_EQ(sim.forces().num_held(), 0);
  // Close past the grip angle: the spheres of the top face between the jaws are held.
  e = grasper.update(sim.model(), sim.forces(), jaws_at(0), V3::Zero(), V3::Zero(), 0.05);
  ASSERT_GT(e.grasped, 0);
  EXPECT_EQ(sim.forces().num_held(), e.grasped);
  for (const Index i : grasper.held()) {
    const V3 local = jaws_at(0).to_local(sim.model().positions().row(i).transpose());
    EXPECT_TRUE(grasper.between_jaws(local, 0.6)) << i;
  }
  // Lift the jaws 3 mm over 0.3 s, then hold still for 0.5 s.
  const double speed = 0.01;
  double lift = 0;
  for (int s = 0; s < 800; ++s) {
    const V3 vel(0, 0, s < 300 ? speed : 0.0);
    grasper.update(sim.model(), sim.forces(), jaws_at(lift), vel, V3::Zero(), 0.05);
    ASSERT_TRUE(sim.step(h).advanced()) << s;
    if (s < 300) lift += speed * h;
  }
  // Each held sphere sits where its tie's force says: its lag behind its point on the jaws is
  // that force over the tie's stiffness (a linear spring at rest: the damping term is zero), and
  // the load it carries is under 0.4 N here, so with k = 10^4 N/m the lag is under 0.05 mm.
  const auto* held = sim.forces().held();
  double max_lag = 0;
  for (Index k = 0; k < sim.forces().num_held(); ++k) {
    const V3 p = jaws_at(lift).to_world(grasper.held_offsets()[std::size_t(k)]);
    const V3 x = sim.model().positions().row(held[k].node).transpose();
    const double lag = (p - x).norm();
    max_lag = std::max(max_lag, lag);
    EXPECT_TRUE(fsm::test::near(lag, held[k].force.norm() / go.stiffness, 0.02, 1e-7)) << k;
    EXPECT_LT(lag, 5e-5) << k;
    EXPECT_GT(x.z() - sim.model().rest_positions()(held[k].node, 2), 0.00295) << k;
  }
  // The wrench on the jaws is the held spheres' reaction, and it balances what the fixed base
  // holds (no gravity: the block's internal forces sum to zero, so the pull on the base equals
  // the ties' pull on the tissue, minus the jaws' force).
  const Wrench<double> w = grasper.wrench(sim.forces());
  EXPECT_LT(w.force.z(), -0.01) << "the stretched tissue pulls the jaws down";
  Positions<double> f(sim.model().num_nodes(), 3);
  sim.forces().evaluate(sim.model(), sim.model().positions(), sim.model().velocities(), f);
  V3 base = V3::Zero();
  for (Index i = 0; i < sim.model().num_nodes(); ++i)
    if (sim.model().fixed()[i]) base += f.row(i).transpose();
  EXPECT_TRUE(fsm::test::matrices_near(w.force, (-base).eval(), 0.02));
  // Open past the release angle: everything is let go and the tissue springs back.
  e = grasper.update(sim.model(), sim.forces(), jaws_at(lift), V3::Zero(), V3::Zero(), 0.5);
  EXPECT_GT(e.released, 0);
  EXPECT_FALSE(grasper.holding());
  EXPECT_EQ(sim.forces().num_held(), 0);
  for (int s = 0; s < 1500; ++s) ASSERT_TRUE(sim.step(h).advanced());
  const double back =
      (sim.model().positions() - sim.model().rest_positions()).cwiseAbs().maxCoeff();
  EXPECT_LT(back, 1e-4) << "released tissue returns to rest";
  EXPECT_EQ(grasper.wrench(sim.forces()).force.norm(), 0.0);
}

INSTANTIATE_TEST_SUITE_P(BothLaws, Grasp, ::testing::Values(ForceLaw::links, ForceLaw::continuum),
                         [](const auto& p) { return std::string(to_string(p.param)); });

TEST(Grasp, HeldNodesEnterTheAssembledSolversToo) {
  // The direct solver (assembled matrix) and the matrix-free CG give the same step.
  std::vector<Positions<double>> result;
  for (const char* solver : {"cg", "eigen_ldlt"}) {
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    auto integrator = std::make_unique<ImplicitEulerIntegrator<double>>();
    auto io = integrator->options();
    io.solver = std::string(solver) == "cg"
                    ? ImplicitEulerIntegrator<double>::Solver::conjugate_gradient
                    : ImplicitEulerIntegrator<double>::Solver::eigen_ldlt;
    io.tolerance = 1e-12;
    integrator->set_options(io);
    Simulation<double> sim(block(ForceLaw::links), std::move(integrator), o);
    Grasper<double> grasper(sim.model(), sim.forces(), GrasperOptions<double>{}, 0.6);
    grasper.update(sim.model(), sim.forces(), jaws_at(0), V3::Zero(), V3::Zero(), 0.6);
    grasper.update(sim.model(), sim.forces(), jaws_at(0), V3::Zero(), V3::Zero(), 0.05);
    for (int s = 0; s < 20; ++s) {
      grasper.update(sim.model(), sim.forces(), jaws_at(0.0001 * s), V3(0, 0, 0.1), V3::Zero(),
                     0.05);
      ASSERT_TRUE(sim.step(1e-3).advanced());
    }
    result.push_back(sim.model().positions() - sim.model().rest_positions());
  }
  EXPECT_TRUE(fsm::test::matrices_near(result[0], result[1], 1e-6));
  EXPECT_GT(result[0].cwiseAbs().maxCoeff(), 1e-3);
}

// An explicit scheme cannot take the ties' stiffness at its step: they are softened to its limit
// (as penalty contacts are), reported, and the held block stays stable.
TEST(Grasp, ExplicitStepsSoftenTheTies) {
  Simulation<double>::Options o;
  o.integrator = "symplectic_euler";
  o.forces.gravity.setZero();
  o.forces.drag = 5;
  Simulation<double> sim(block(ForceLaw::links), o);
  GrasperOptions<double> stiff;
  stiff.stiffness = 1e6;  // far past m / 2h^2 for any step the block allows
  Grasper<double> grasper(sim.model(), sim.forces(), stiff, 0.6);
  grasper.update(sim.model(), sim.forces(), jaws_at(0), V3::Zero(), V3::Zero(), 0.6);
  const GraspEvent e =
      grasper.update(sim.model(), sim.forces(), jaws_at(0), V3::Zero(), V3::Zero(), 0.05);
  ASSERT_GT(e.grasped, 0);
  const double h = 0.5 * sim.stable_time_step();
  for (int s = 0; s < 400; ++s) {  // lifting 1 um a step
    grasper.update(sim.model(), sim.forces(), jaws_at(1e-6 * s), V3(0, 0, 1e-6 / h), V3::Zero(),
                   0.05);
    const StepReport<double> r = sim.step(h);
    ASSERT_TRUE(r.advanced()) << s;
    EXPECT_EQ(r.softened_contacts, e.grasped) << s;
  }
  for (Index k = 0; k < sim.forces().num_held(); ++k)
    EXPECT_LE(sim.forces().held()[k].stiffness,
              0.5 * sim.model().masses()[sim.forces().held()[k].node] / (h * h) * (1 + 1e-12));
  EXPECT_TRUE(sim.model().positions().allFinite());
}

TEST(Grasp, BadInput) {
  SphereModel<double> model = block(ForceLaw::links);
  ForceModel<double> forces(model);
  GrasperOptions<double> go;
  try {
    Grasper<double> closed(model, forces, go, 0.05);
    FAIL() << "closed jaws at start";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("closed"), std::string::npos) << e.what();
  }
  for (auto edit : std::vector<void (*)(GrasperOptions<double>&)>{
           [](GrasperOptions<double>& g) { g.jaw_length = 0; },
           [](GrasperOptions<double>& g) { g.stiffness = std::nan(""); },
           [](GrasperOptions<double>& g) { g.release_angle = g.grip_angle; },
           [](GrasperOptions<double>& g) { g.damping = -1; },
           [](GrasperOptions<double>& g) { g.max_held = 0; }}) {
    GrasperOptions<double> bad;
    edit(bad);
    EXPECT_THROW(Grasper<double>(model, forces, bad, 0.6), Error);
  }
  Grasper<double> g(model, forces, go, 0.6);
  Pose<double> nan = jaws_at(0);
  nan.position.x() = std::nan("");
  const GraspEvent e = g.update(model, forces, nan, V3::Zero(), V3::Zero(), 0.05);
  EXPECT_TRUE(e.invalid);
  EXPECT_FALSE(g.holding());
  HeldNode<double> hn;
  hn.node = model.num_nodes();
  hn.stiffness = 1;
  EXPECT_FALSE(forces.add_held(hn)) << "node out of range";
  hn.node = 0;
  hn.stiffness = -1;
  EXPECT_FALSE(forces.add_held(hn)) << "negative stiffness";
}

}  // namespace
}  // namespace fsm::collision
