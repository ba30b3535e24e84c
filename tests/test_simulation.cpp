// Simulation: divergence detection with rollback, automatic sub-stepping, the energy account,
// edits between steps, gravity to static equilibrium, integrator swapping, bad input.

#include <cfenv>
#include <random>

#include "common.hpp"

namespace fsm::test {
namespace {

template <typename Scalar>
typename Simulation<Scalar>::Options options(const std::string& integrator, bool gravity = false) {
  typename Simulation<Scalar>::Options o;
  o.integrator = integrator;
  if (!gravity) o.forces.gravity.setZero();
  return o;
}

TEST(Simulation, RejectsBadModelsAndNames) {
  SphereModel<double> bad = two_spheres(0.001, 500.0, 0.1);
  bad.masses()[1] = -1;
  EXPECT_THROW(Simulation<double>{bad}, Error);
  try {
    Simulation<double> sim(two_spheres(0.001, 500.0, 0.1), options<double>("verlet"));
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("symplectic_euler"), std::string::npos) << e.what();
  }
  auto o = options<double>("heun");
  o.forces.threads = 0;
  EXPECT_THROW(Simulation<double>(two_spheres(0.001, 500.0, 0.1), o), Error);
}

TEST(Simulation, InvalidTimeStepChangesNothing) {
  Simulation<double> sim(two_spheres(0.001, 500.0, 0.1), options<double>("heun"));
  sim.model().positions()(1, 0) += 1e-4;
  const Positions<double> before = sim.model().positions();
  for (double dt : {0.0, -1e-3, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_EQ(sim.step(dt).status, StepStatus::invalid_time_step);
    EXPECT_EQ(sim.model().positions(), before);
  }
  EXPECT_EQ(sim.time(), 0.0);
}

// Symplectic Euler at three times its limit blows up; the step that crosses the energy bound is
// undone and every coordinate stays finite.
template <typename Scalar>
class SimulationTyped : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(SimulationTyped, Scalars);

TYPED_TEST(SimulationTyped, UnstableStepIsDetectedAndRolledBack) {
  using S = TypeParam;
  std::mt19937 rng(71);
  for (bool check_energy : {true, false}) {
    auto o = options<S>("symplectic_euler");
    o.divergence.check_energy = check_energy;
    Simulation<S> sim(random_model<S>(rng, {3, 3, 3}, S(0.2)), o);
    const S dt = S(3) * sim.stable_time_step();
    bool diverged = false;
    for (int s = 0; s < 5000 && !diverged; ++s) {
      const Positions<S> before = sim.model().positions();
      const Positions<S> vbefore = sim.model().velocities();
      const StepReport<S> r = sim.step(dt);
      if (r.status == StepStatus::diverged) {
        diverged = true;
        EXPECT_EQ(sim.model().positions(), before);
        EXPECT_EQ(sim.model().velocities(), vbefore);
      }
      ASSERT_TRUE(sim.model().positions().allFinite());
      ASSERT_TRUE(sim.model().velocities().allFinite());
    }
    EXPECT_TRUE(diverged) << "check_energy " << check_energy;
    if (check_energy) {
      // The state left after the rollback passed the check: its energy is within the documented
      // bound budget + tolerance |budget| + floor (floor: 1 % strain on every link).
      const auto& m = sim.model();
      const double floor =
          0.5 * 1e-4 * double(m.stiffness().dot(m.rest_lengths().cwiseProduct(m.rest_lengths())));
      const auto e = sim.energy();
      const double budget = double(e.budget());
      EXPECT_LE(double(e.total()), (budget + std::abs(budget) + floor) * (1 + 1e-4));
    }
  }
}

// DivergencePolicy::check_step_energy: the cumulative budget grows slack as damping removes
// energy, so a model that has come to rest could gain many times its energy in accepted steps.
// A stretched model rings down at a stable step to under 2 % of its energy; then symplectic Euler
// at three times its limit. With the step check the first step that more than doubles the energy
// is undone; without it, steps pass until the energy nears the old budget.
TEST(Simulation, EachStepIsHeldToTheEnergyItStartedWith) {
  for (const bool step_check : {true, false}) {
    std::mt19937 rng(71);
    auto o = options<double>("symplectic_euler");
    o.divergence.check_step_energy = step_check;
    SphereModel<double> model = random_model<double>(rng, {3, 3, 3}, 0.2);
    model.positions() *= 1.05;  // stretched: energy to ring down
    Simulation<double> sim(model, o);
    const double start = sim.energy().total();
    const double limit = sim.stable_time_step();
    for (int s = 0; s < 200000 && sim.energy().total() > 0.02 * start; ++s)
      ASSERT_EQ(sim.step(0.5 * limit).status, StepStatus::ok);
    const double rest = sim.energy().total();
    ASSERT_LT(rest, 0.02 * start);
    double highest = rest;
    for (int s = 0; s < 5000; ++s) {
      const StepReport<double> r = sim.step(3 * limit);
      if (r.status == StepStatus::diverged) break;
      highest = std::max(highest, double(r.energy));
    }
    std::printf("step check %d: %.3g J at rest (%.3g J at the start), highest accepted %.3g J\n",
                int(step_check), rest, start, highest);
    if (step_check)
      EXPECT_LT(highest, 10 * rest);
    else
      EXPECT_GT(highest, 10 * rest);  // what the step check is for
  }
}

// DivergencePolicy::energy_gain_strain. A backward-Euler step removes energy; one that gains
// some was made by an error (the solve's, the linearisation's), and a finer level makes less of
// it. This integrator is implicit Euler that then scales every velocity by 1 + a h^2: on a block
// moving as a whole (no internal force) a step of length h gains 2 a h^2 of its kinetic energy,
// and each halving halves a step's gain.
class GainingIntegrator final : public Integrator<double> {
 public:
  // fail_substeps: a step shorter than 1 ms breaks down (ok = false), as a solver can.
  GainingIntegrator(double a, bool implicit, bool fail_substeps = false)
      : m_a(a), m_implicit(implicit), m_fail_substeps(fail_substeps) {}
  std::string_view name() const noexcept override { return "gaining"; }
  int order() const noexcept override { return 1; }
  bool implicit() const noexcept override { return m_implicit; }
  void prepare(const SphereModel<double>& model) override { m_inner.prepare(model); }
  IntegratorResult step(SphereModel<double>& model, ForceModel<double>& forces,
                        double h) noexcept override {
    if (m_fail_substeps && h < 0.999e-3) return {false, 0, true};
    const IntegratorResult r = m_inner.step(model, forces, h);
    model.velocities() *= 1 + m_a * h * h;
    return r;
  }
  void reset() noexcept override { m_inner.reset(); }
  std::unique_ptr<Integrator<double>> clone() const override {
    return std::make_unique<GainingIntegrator>(*this);
  }
  double stable_time_step(const SpectralBound<double>& b) const noexcept override {
    return m_inner.stable_time_step(b);
  }

 private:
  ImplicitEulerIntegrator<double> m_inner;
  double m_a;
  bool m_implicit;
  bool m_fail_substeps;
};

struct GainRun {
  StepReport<double> report;
  double limit;
};

// One 1 ms step of a 3 x 3 x 3 block moving at 1 m/s whose step gains `limits` times the default
// limit at full length (a small share of its kinetic energy, so halving halves the gain to 0.1 %).
GainRun gaining_step(double limits, bool implicit, int halvings, double gain_strain = 0.005,
                     bool fail_substeps = false) {
  SphereModel<double> model = block<double>({3, 3, 3}, 0.005);
  model.velocities().col(0).setConstant(1.0);
  auto o = options<double>("implicit_euler");
  o.divergence.max_substep_halvings = halvings;
  // The default limit as the simulation computes it.
  const double limit = Simulation<double>(model, o).energy_gain_limit();
  o.divergence.energy_gain_strain = gain_strain;
  const double kinetic = 0.5 * model.masses().sum();
  const double dt = 1e-3;
  const double a = limits * limit / (2 * dt * dt * kinetic);
  Simulation<double> sim(model, std::make_unique<GainingIntegrator>(a, implicit, fail_substeps), o);
  return {sim.step(dt), limit};
}

// The step's status, its levels retried for their gain, and its gain within (lo, hi) limits.
void expect_gain(const GainRun& r, StepStatus status, int retries, double lo, double hi) {
  EXPECT_EQ(r.report.status, status);
  EXPECT_EQ(r.report.energy_gain_retries, retries);
  EXPECT_GT(r.report.energy_gain, lo * r.limit);
  EXPECT_LT(r.report.energy_gain, hi * r.limit);
}

TEST(Simulation, AnImplicitStepThatGainsEnergyIsRetriedFiner) {
  // Gains of 3, 1.5 and 0.75 limits at the levels 0, 1 and 2: the third is kept.
  const GainRun r = gaining_step(3, true, 3);
  ASSERT_GT(r.limit, 0);
  expect_gain(r, StepStatus::recovered, 2, 0.7, 0.8);
  EXPECT_EQ(r.report.substeps, 1 + 2 + 4);
  // Off: the full step stands with its gain.
  expect_gain(gaining_step(3, true, 3, 0.0), StepStatus::ok, 0, 2.9, 3.1);
}

TEST(Simulation, TheLastLevelStandsWhenItStillGains) {
  // One halving allowed: its 1.5 limits are kept (the divergence checks pass), not rolled back.
  expect_gain(gaining_step(3, true, 1), StepStatus::recovered, 1, 1.4, 1.6);
  // No halving allowed: nothing to retry.
  expect_gain(gaining_step(3, true, 0), StepStatus::ok, 0, 2.9, 3.1);
}

TEST(Simulation, AStepRetriedForItsGainIsNotRolledBackWhenTheFinerLevelsFail) {
  // Every sub-step breaks down: the full step, which passed the checks, runs again and stands.
  const GainRun r = gaining_step(3, true, 2, 0.005, true);
  expect_gain(r, StepStatus::ok, 1, 2.9, 3.1);
  EXPECT_EQ(r.report.substeps, 4);  // the full step, a first sub-step at each finer level, again
}

TEST(Simulation, ExplicitStepsAreNotRetriedForTheirGain) {
  // Explicit schemes gain energy by their nature (Heun on an undamped mode); only the divergence
  // checks hold them.
  expect_gain(gaining_step(3, false, 3), StepStatus::ok, 0, 2.9, 3.1);
}

// The real implicit Euler never trips the gain limit on a stretched model ringing down: its steps
// remove energy.
TEST(Simulation, HonestImplicitStepsAreNotRetriedForGain) {
  std::mt19937 rng(71);
  auto o = options<double>("implicit_euler");
  o.divergence.max_substep_halvings = 2;
  SphereModel<double> model = random_model<double>(rng, {3, 3, 3}, 0.2);
  model.positions() *= 1.05;
  Simulation<double> sim(model, o);
  double largest = -std::numeric_limits<double>::infinity();
  for (int s = 0; s < 500; ++s) {
    const StepReport<double> r = sim.step(1e-3);
    ASSERT_EQ(r.status, StepStatus::ok);
    ASSERT_EQ(r.energy_gain_retries, 0);
    largest = std::max(largest, double(r.energy_gain));
  }
  std::printf("largest gain %.3g J, limit %.3g J\n", largest, double(sim.energy_gain_limit()));
  EXPECT_LT(largest, 1e-3 * sim.energy_gain_limit());
}

TEST(Simulation, RejectsABadEnergyGainStrain) {
  for (const double g : {-0.01, std::nan(""), std::numeric_limits<double>::infinity()}) {
    auto o = options<double>("implicit_euler");
    o.divergence.energy_gain_strain = g;
    EXPECT_THROW(Simulation<double>(two_spheres(0.001, 500.0, 0.1), o), Error) << g;
  }
}

// Bad edits between steps and a model resized without refresh() are refused, never stepped.
TEST(Simulation, InvalidInputIsRefusedAndTheLastGoodStateKept) {
  SphereModel<double> model = block<double>({3, 3, 3}, 0.005);
  for (Index i = 0; i < 16; ++i) model.set_fixed(i);
  for (bool check_energy : {true, false}) {
    auto o = options<double>("implicit_euler", true);
    o.divergence.check_energy = check_energy;
    Simulation<double> sim(model, o);
    ASSERT_EQ(sim.step(1e-3).status, StepStatus::ok);
    const Positions<double> good = sim.model().positions();
    sim.model().positions()(40, 0) = std::nan("");
    EXPECT_EQ(sim.step(1e-3).status, StepStatus::invalid_input);
    EXPECT_EQ(sim.model().positions(), good);          // the last good state, not the NaN
    EXPECT_EQ(sim.step(1e-3).status, StepStatus::ok);  // and stepping goes on
    sim.external_forces()(40, 2) = std::numeric_limits<double>::infinity();
    EXPECT_EQ(sim.step(1e-3).status, StepStatus::invalid_input);
    EXPECT_TRUE(sim.model().positions().allFinite());
    sim.external_forces()(40, 2) = 0;
    EXPECT_EQ(sim.step(1e-3).status, StepStatus::ok);
    // Growing the model behind the simulation's back: refused until refresh().
    sim.model().add_node(Vector3<double>(1, 1, 1), 0.001, 0.001, 0);
    EXPECT_EQ(sim.step(1e-3).status, StepStatus::invalid_input);
    sim.refresh();
    EXPECT_EQ(sim.step(1e-3).status, StepStatus::ok);
  }
}

// The check behind invalid_input and a diverged step: every position of a non-finite value
// (NaN of both signs, a signalling NaN, infinities of both signs) in arrays of every length up to
// 70 (past any vector width and its tail), both precisions; finite extremes, zeros of both signs
// and subnormals pass. It raises no floating-point exception, in any rounding mode.
template <typename S>
void check_all_finite() {
  using L = std::numeric_limits<S>;
  const S finite[] = {S(0), -S(0), L::max(), -L::max(), L::min(), L::denorm_min(), S(-1.5)};
  const S bad[] = {L::quiet_NaN(), -L::quiet_NaN(), L::signaling_NaN(), L::infinity(),
                   -L::infinity()};
  std::feclearexcept(FE_ALL_EXCEPT);
  for (int n = 0; n <= 70; ++n) {
    std::vector<S> a(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) a[std::size_t(k)] = finite[k % 7];
    EXPECT_TRUE(detail::all_finite(a.data(), n)) << n;
    for (int k = 0; k < n; ++k)
      for (const S b : bad) {
        const S keep = a[std::size_t(k)];
        a[std::size_t(k)] = b;
        EXPECT_FALSE(detail::all_finite(a.data(), n)) << n << " " << k;
        EXPECT_TRUE(detail::all_finite(a.data(), k)) << n << " " << k;  // (before it)
        a[std::size_t(k)] = keep;
      }
  }
  EXPECT_EQ(std::fetestexcept(FE_ALL_EXCEPT & ~FE_INEXACT), 0);
}

TEST(Simulation, FiniteCheckFindsEveryNonFiniteValue) {
  check_all_finite<double>();
  check_all_finite<float>();
  // In a host engine that rounds downward too (the mode is set back however the test ends).
  struct Rounding {
    int mode = std::fegetround();
    ~Rounding() { std::fesetround(mode); }
  } keep;
  ASSERT_EQ(std::fesetround(FE_DOWNWARD), 0);
  check_all_finite<double>();
  check_all_finite<float>();
}

// A fixed node given a velocity (say, by a caller dragging it) still does not move by itself; it
// moves only when its position is edited.
TEST(Simulation, FixedNodesIgnoreAVelocityWrittenToThem) {
  SphereModel<double> model = block<double>({3, 3, 3}, 0.005);
  for (Index i = 0; i < 16; ++i) model.set_fixed(i);
  for (const auto& name : integrator_names()) {
    Simulation<double> sim(model, options<double>(name, true));
    const double dt = name == "implicit_euler" ? 1e-3 : 0.5 * sim.stable_time_step();
    sim.model().velocities().row(0) << 1.0, 0.0, 0.0;
    const Vector3<double> before = sim.model().positions().row(0).transpose();
    for (int s = 0; s < 100; ++s) ASSERT_EQ(sim.step(dt).status, StepStatus::ok) << name;
    EXPECT_EQ(sim.model().positions().row(0).transpose(), before) << name;
    // Dragging by position works.
    sim.model().positions()(0, 0) += 0.001;
    for (int s = 0; s < 10; ++s) ASSERT_TRUE(sim.step(dt).advanced()) << name;
    EXPECT_EQ(sim.model().positions()(0, 0), before.x() + 0.001) << name;
  }
}

TEST(Simulation, AutomaticSubSteppingRecovers) {
  std::mt19937 rng(73);
  auto o = options<double>("symplectic_euler");
  o.divergence.max_substep_halvings = 4;
  Simulation<double> sim(random_model<double>(rng, {3, 3, 3}, 0.2), o);
  const double dt = 3 * sim.stable_time_step();
  int recovered = 0;
  for (int s = 0; s < 400; ++s) {
    const auto r = sim.step(dt);
    ASSERT_TRUE(r.advanced()) << "step " << s << ": " << to_string(r.status);
    if (r.status == StepStatus::recovered) {
      ++recovered;
      EXPECT_GT(r.substeps, 1);
    }
  }
  EXPECT_GT(recovered, 0);
  EXPECT_TRUE(near(sim.time(), 400 * dt, 1e-12));
}

// External work enters the budget: a steady push raises the energy without a false divergence.
TEST(Simulation, ExternalWorkIsAccountedFor) {
  for (const auto& name : integrator_names()) {
    SphereModel<double> model = block<double>({3, 3, 3}, 0.005);
    for (Index i = 0; i < model.num_nodes(); ++i)
      if (model.rest_positions()(i, 2) < 1e-9) model.set_fixed(i);
    Simulation<double> sim(model, options<double>(name));
    const Index top = sim.model().num_nodes() - 1;
    sim.external_forces()(top, 2) = -0.05;
    const double dt = name == "implicit_euler" ? 1e-3 : 0.5 * sim.stable_time_step();
    for (int s = 0; s < 500; ++s) ASSERT_TRUE(sim.step(dt).advanced()) << name << " step " << s;
    const auto e = sim.energy();
    EXPECT_GT(e.external_work, 0) << name;
    EXPECT_LE(e.total(), e.budget() * (1 + 1e-6)) << name;  // damping only removes energy
    EXPECT_GT(e.elastic, 0) << name;
  }
}

// Moving a node by hand between steps is not a divergence: the simulation takes a new reference.
TEST(Simulation, EditsBetweenStepsStartANewEnergyReference) {
  Simulation<double> sim(block<double>({3, 3, 3}, 0.005), options<double>("implicit_euler"));
  for (int s = 0; s < 50; ++s) {
    sim.model().positions()(5, 0) += 0.001;  // large jumps, far beyond any tolerance
    ASSERT_EQ(sim.step(1e-3).status, StepStatus::ok) << "step " << s;
  }
}

// A bar hanging from its clamped top under its own weight stretches by rho g L^2 / (2 E_axis) with
// E_axis = 30E/29 for this lattice (test_material). The clamp stops the Poisson contraction near
// the top, which stiffens a bar of aspect 6 by a few per cent: tolerance 6 %.
TEST(Simulation, GravityHangingBarReachesTheStaticElongation) {
  const double h = 0.004, E = 13150;
  const Eigen::Vector3i cells(4, 4, 24);
  SphereModel<double> model = block<double>(cells, h, tissue<double>(E, 50.0));
  const double L = cells.z() * h;
  for (Index i = 0; i < model.num_nodes(); ++i)
    if (model.rest_positions()(i, 2) > L - 1e-9) model.set_fixed(i);
  Simulation<double> sim(model, options<double>("implicit_euler", true));
  auto bottom = [&] {
    double sum = 0;
    int n = 0;
    for (Index i = 0; i < sim.model().num_nodes(); ++i)
      if (sim.model().rest_positions()(i, 2) < 1e-9) {
        sum += sim.model().positions()(i, 2) - sim.model().rest_positions()(i, 2);
        ++n;
      }
    return sum / n;
  };
  for (int s = 0; s < 300; ++s) ASSERT_TRUE(sim.step(0.01).advanced());
  const double settled = bottom();
  for (int s = 0; s < 50; ++s) ASSERT_TRUE(sim.step(0.01).advanced());
  EXPECT_TRUE(near(bottom(), settled, 1e-3));  // static: no longer moving
  const double rho = 1050, g = 9.81;
  const double expected = -rho * g * L * L / (2 * 30.0 / 29.0 * E);
  EXPECT_TRUE(near(settled, expected, 0.06)) << settled << " vs " << expected;
  RecordProperty("elongation_over_analytic", std::to_string(settled / expected));
}

TEST(Simulation, SwappingIntegratorsChangesOnlyTheScheme) {
  Simulation<double> sim(two_spheres(0.001, 500.0, 0.1), options<double>("implicit_euler"));
  EXPECT_TRUE(std::isinf(sim.stable_time_step()));
  sim.set_integrator("symplectic_euler");
  EXPECT_EQ(sim.integrator().name(), "symplectic_euler");
  EXPECT_TRUE(near(sim.stable_time_step(), symplectic_euler_limit(sim.spectral_bound()), 1e-15));
  sim.set_integrator(std::make_unique<HeunIntegrator<double>>());
  EXPECT_EQ(sim.options().integrator, "heun");
  sim.model().positions()(1, 0) += 1e-4;
  EXPECT_EQ(sim.step(1e-4).status, StepStatus::ok);
}

// A linear solve cut off at its iteration cap is reported (StepReport::unconverged_solves), not
// passed off as converged. A block sagging under gravity, implicit Euler at 5 ms: with CG capped
// at 2 iterations to 1e-12 every sub-step's solve is cut off (rolled-back attempts included: the
// divergence checks judge the state, and may reject it); with the defaults none is.
TEST(Simulation, ReportsALinearSolveCutOffAtItsCap) {
  struct Counts {
    int unconverged = 0, advanced = 0, iterations = 0, substeps = 0;
  };
  auto run = [](int cap, double tolerance) {
    Simulation<double> sim(block<double>({3, 3, 3}, 0.005),
                           options<double>("implicit_euler", true));
    ImplicitEulerIntegrator<double>::Options io;
    io.max_iterations = cap;
    io.tolerance = tolerance;
    sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
    Counts c;
    for (int s = 0; s < 20; ++s) {
      const StepReport<double> r = sim.step(5e-3);
      c.unconverged += r.unconverged_solves;
      c.advanced += r.advanced() ? 1 : 0;
      c.iterations += r.solver_iterations;
      c.substeps += r.substeps;
    }
    return c;
  };
  const Counts cut = run(2, 1e-12);
  EXPECT_GT(cut.advanced, 10);  // most truncated steps pass the checks
  EXPECT_EQ(cut.unconverged, cut.substeps);
  EXPECT_EQ(cut.iterations, 2 * cut.substeps);
  const Counts full = run(200, 1e-6);
  EXPECT_EQ(full.advanced, 20);
  EXPECT_EQ(full.unconverged, 0);
  EXPECT_GT(full.iterations, 2 * full.substeps);
}

// StepReport::substeps counts the integrator steps that ran. An integrator whose solver breaks
// down at its 1st and 2nd calls (the whole step, then the first half step): the first halving
// stops after its first half step, the second runs its four quarter steps. 1 + 1 + 4 = 6 ran;
// counting every level's 2^k would give 7.
TEST(Simulation, SubstepsCountTheIntegratorStepsThatRan) {
  class BreaksTwice final : public Integrator<double> {
   public:
    int calls = 0;
    HeunIntegrator<double> heun;
    std::string_view name() const noexcept override { return "breaks_twice"; }
    int order() const noexcept override { return heun.order(); }
    void prepare(const SphereModel<double>& model) override { heun.prepare(model); }
    IntegratorResult step(SphereModel<double>& model, ForceModel<double>& forces,
                          double dt) noexcept override {
      if (calls++ < 2) return IntegratorResult{false, 0, true};
      return heun.step(model, forces, dt);
    }
    std::unique_ptr<Integrator<double>> clone() const override {
      return std::make_unique<BreaksTwice>(*this);
    }
    double stable_time_step(const SpectralBound<double>& b) const noexcept override {
      return heun.stable_time_step(b);
    }
  };
  auto o = options<double>("heun", true);
  o.divergence.max_substep_halvings = 3;
  Simulation<double> sim(block<double>({2, 2, 2}, 0.005), o);
  auto integrator = std::make_unique<BreaksTwice>();
  const BreaksTwice* counter = integrator.get();
  sim.set_integrator(std::move(integrator));
  const StepReport<double> r = sim.step(1e-5);
  EXPECT_EQ(r.status, StepStatus::recovered);
  EXPECT_EQ(counter->calls, 6);
  EXPECT_EQ(r.substeps, 6);
  // A step that passes at once: one.
  EXPECT_EQ(sim.step(1e-5).substeps, 1);
}

TEST(Simulation, ResetReturnsToRest) {
  Simulation<double> sim(block<double>({2, 2, 2}, 0.005), options<double>("heun", true));
  sim.external_forces()(3, 0) = 0.1;
  for (int s = 0; s < 20; ++s) sim.step(1e-4);
  sim.reset();
  EXPECT_EQ(sim.time(), 0.0);
  EXPECT_EQ(sim.model().positions(), sim.model().rest_positions());
  EXPECT_EQ(sim.external_forces().norm(), 0.0);
}

}  // namespace
}  // namespace fsm::test
