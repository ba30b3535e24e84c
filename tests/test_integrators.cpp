// The four integrators: the two-sphere oscillator's frequency and damping ratio against the
// analytic solution, convergence order by step halving, measured stability limits against the
// analytic bounds, implicit Euler far beyond them, energy behaviour, momentum conservation and
// fixed nodes. float and double where the property does not depend on rounding.

#include <random>

#include "common.hpp"

namespace fsm::test {
namespace {

template <typename Scalar>
std::unique_ptr<Integrator<Scalar>> make(const std::string& name, double cg_tolerance = 0) {
  if (name == "implicit_euler" && cg_tolerance > 0) {
    typename ImplicitEulerIntegrator<Scalar>::Options o;
    o.tolerance = Scalar(cg_tolerance);
    o.velocity_tolerance = 0;  // solved to that tolerance, however small the motion
    o.max_iterations = 2000;
    return std::make_unique<ImplicitEulerIntegrator<Scalar>>(o);
  }
  return make_integrator<Scalar>(name);
}

// A 4 x 3 x 3-cell block of tissue at 5 mm whose bottom layer is fixed, those nodes' masses
// scaled by `fixed_mass_factor`.
template <typename Scalar>
SphereModel<Scalar> block_on_fixed_base(Scalar fixed_mass_factor = Scalar(1)) {
  SphereModel<Scalar> model = block<Scalar>({4, 3, 3}, Scalar(0.005), tissue<Scalar>());
  for (Index i = 0; i < model.num_nodes(); ++i)
    if (model.rest_positions()(i, 2) < Scalar(1e-9)) {
      model.set_fixed(i);
      model.masses()[i] *= fixed_mass_factor;
    }
  return model;
}

// The relative coordinate q = l - l0 of the two-sphere model and its rate.
template <typename Scalar>
double gap(const SphereModel<Scalar>& m, double l0) {
  return double(m.positions()(1, 0) - m.positions()(0, 0)) - l0;
}

template <typename Scalar>
class IntegratorsTyped : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(IntegratorsTyped, Scalars);

// Heun's relative frequency error is about (omega h)^2 / 6 and its amplitude error per period
// 2 pi (omega h)^3 / 8. In double, omega h = 0.01 keeps both below 2e-5, so 1e-3 is a safe
// tolerance. In float a step moves a 1 cm coordinate by a few hundred ulps, and the rounding of
// each increment biases the decay; omega h = 0.05 (errors below 5e-4) with a 1 % tolerance.
TYPED_TEST(IntegratorsTyped, TwoSphereOscillatorFrequencyAndDampingRatio) {
  using S = TypeParam;
  constexpr bool single = std::is_same_v<S, float>;
  const double tol = single ? 1e-2 : 1e-3;
  const double m = 0.001, k = 500, w0 = std::sqrt(2 * k / m);  // 1000 rad/s
  for (double zeta : {0.02, 0.1}) {
    const double kd = zeta * w0 * m;  // c = 2 kd / m = 2 zeta w0
    const double l0 = 0.01;
    SphereModel<S> model = two_spheres<S>(S(m), S(k), S(kd), S(l0));
    model.positions()(1, 0) += S(1e-4);
    ForceModel<S> forces = no_gravity(model);
    HeunIntegrator<S> heun;
    heun.prepare(model);
    const double h = (single ? 0.05 : 0.01) / w0;
    const int steps = int(6 * 2 * M_PI / (w0 * h));  // six periods
    std::vector<double> crossings, peaks;
    double q_prev2 = 0, q_prev = gap(model, l0), t = 0;
    for (int s = 0; s < steps; ++s) {
      heun.step(model, forces, S(h));
      t += h;
      const double q = gap(model, l0);
      if ((q_prev < 0) != (q < 0)) crossings.push_back(t - h * q / (q - q_prev));
      if (s > 1 && q_prev > q_prev2 && q_prev >= q && q_prev > 0) {
        // Parabola through the three samples around the maximum.
        const double a = 0.5 * (q_prev2 - 2 * q_prev + q), b = 0.5 * (q - q_prev2);
        peaks.push_back(q_prev - b * b / (4 * a));
      }
      q_prev2 = q_prev;
      q_prev = q;
    }
    ASSERT_GE(crossings.size(), 10u);
    ASSERT_GE(peaks.size(), 5u);
    const double wd = M_PI * double(crossings.size() - 1) / (crossings.back() - crossings.front());
    EXPECT_TRUE(near(wd, w0 * std::sqrt(1 - zeta * zeta), tol)) << "zeta " << zeta;
    const double delta = std::log(peaks.front() / peaks.back()) / double(peaks.size() - 1);
    const double zeta_measured = delta / std::sqrt(4 * M_PI * M_PI + delta * delta);
    EXPECT_TRUE(near(zeta_measured, zeta, tol)) << "zeta " << zeta;
  }
}

// Step halving on a nonlinear random model: p = log2(|x_h - x_{h/2}| / |x_{h/2} - x_{h/4}|).
TEST(Integrators, ConvergenceOrderFromStepHalving) {
  std::mt19937 rng(31);
  const SphereModel<double> start = random_model<double>(rng, {2, 2, 2}, 0.3, false, 20.0);
  const auto bound = spectral_bound(start);
  struct Case {
    std::string name;
    double expected;
  };
  for (const Case& c : {Case{"heun", 2}, Case{"symplectic_euler", 1}, Case{"improved_euler", 1},
                        Case{"implicit_euler", 1}}) {
    auto integrator = make<double>(c.name, 1e-13);
    const double limit =
        std::min({symplectic_euler_limit(bound), heun_limit(bound), improved_euler_limit(bound)});
    const double T = 40 * limit, h0 = 0.1 * limit;
    std::vector<Positions<double>> finals;
    for (int level = 0; level < 3; ++level) {
      SphereModel<double> model = start;
      ForceModel<double> forces = no_gravity(model);
      integrator->prepare(model);
      const double h = h0 / (1 << level);
      const int steps = int(std::lround(T / h));
      for (int s = 0; s < steps; ++s) ASSERT_TRUE(integrator->step(model, forces, h).ok);
      finals.push_back(model.positions());
    }
    const double e1 = (finals[0] - finals[1]).norm(), e2 = (finals[1] - finals[2]).norm();
    const double p = std::log2(e1 / e2);
    EXPECT_NEAR(p, c.expected, 0.25) << c.name;
    EXPECT_EQ(integrator->order(), int(c.expected)) << c.name;
  }
}

// Largest stable step, measured on the linear two-sphere oscillator: growth between two windows
// of a long run (so transient growth of non-normal update matrices cancels), bisected.
double measured_limit(Integrator<double>& integrator, double m, double k, double kd, double guess) {
  auto unstable = [&](double h) {
    SphereModel<double> model = two_spheres(m, k, kd);
    model.positions()(1, 0) += 1e-5;
    ForceModel<double> forces = no_gravity(model);
    integrator.prepare(model);
    const int n = 20000, w = 2000;
    double early = 0, late = 0, window = 0;
    for (int s = 0; s < n; ++s) {
      integrator.step(model, forces, h);
      const double q = std::abs(gap(model, 0.01));
      if (!std::isfinite(q) || q > 1e-3) return true;
      if (s >= n / 2 - w && s < n / 2) early = std::max(early, q);
      if (s >= n - w) late = std::max(late, q);
      window = std::max(window, q);
      if ((s + 1) % w == 0) {
        // Decayed a million-fold: stable. (Going on would reach the rounding floor of q, a
        // difference of 1 cm positions, where noise could pass for growth.)
        if (window < 1e-11) return false;
        window = 0;
      }
    }
    return late > early * 1.01;  // 1 %: above the sampling jitter of a constant amplitude
  };
  double lo = 0.3 * guess, hi = 3 * guess;
  EXPECT_FALSE(unstable(lo)) << integrator.name() << " kd " << kd;
  EXPECT_TRUE(unstable(hi)) << integrator.name() << " kd " << kd;
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    (unstable(mid) ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

TEST(Integrators, MeasuredStabilityLimitsMatchTheAnalyticBounds) {
  const double m = 0.001, k = 500, w0 = 1000;
  struct Case {
    std::string name;
    double zeta;
  };
  for (const Case& c :
       {Case{"symplectic_euler", 0.0}, Case{"symplectic_euler", 0.3}, Case{"improved_euler", 0.1},
        Case{"improved_euler", 0.8}, Case{"heun", 0.1}, Case{"heun", 0.8}}) {
    const double kd = c.zeta * w0 * m;
    auto integrator = make_integrator<double>(c.name);
    const double predicted = integrator->stable_time_step(spectral_bound(two_spheres(m, k, kd)));
    ASSERT_GT(predicted, 0) << c.name;
    const double measured = measured_limit(*integrator, m, k, kd, predicted);
    // The issue asks for 5 %; the bounds are exact for this linear system, so hold them to 1 %.
    EXPECT_TRUE(near(measured, predicted, 0.01)) << c.name << " zeta " << c.zeta;
    RecordProperty(c.name + "_zeta_" + std::to_string(c.zeta) + "_measured_over_predicted",
                   std::to_string(measured / predicted));
  }
  // Without damping Heun and improved Euler have no stable step: growth at a tiny step.
  for (const std::string name : {"heun", "improved_euler"}) {
    auto integrator = make_integrator<double>(name);
    EXPECT_EQ(integrator->stable_time_step(spectral_bound(two_spheres(m, k, 0.0))), 0.0);
    SphereModel<double> model = two_spheres(m, k, 0.0);
    model.positions()(1, 0) += 1e-5;
    ForceModel<double> forces = no_gravity(model);
    integrator->prepare(model);
    const double e0 = total_energy(model, forces);
    for (int s = 0; s < 20000; ++s) integrator->step(model, forces, 0.2 / w0);
    EXPECT_GT(total_energy(model, forces), e0 * 1.01) << name;
  }
}

// The estimated stable step of each explicit scheme is stable: every eigenvalue of the one-step
// matrix of the linearised system has modulus <= 1, on random models with two materials of very
// different retardation times (damping not proportional to stiffness) and on one material.
TEST(Integrators, EstimatedStableStepsAreStableForMixedMaterials) {
  std::mt19937 rng(83);
  for (int trial = 0; trial < 6; ++trial) {
    SphereModel<double> model = random_model<double>(rng, {2, 2, 2}, 0.3, false, 10.0);
    model.reset_to_rest();
    if (trial % 3 != 0) {  // make some links far more viscous: a second material
      std::uniform_real_distribution<double> u(0, 1);
      for (Index l = 0; l < model.num_links(); ++l)
        if (u(rng) < 0.3) model.damping()[l] *= trial % 3 == 1 ? 300.0 : 3000.0;
    }
    for (Index i = 0; i < 4; ++i) model.set_fixed(i);
    const ForceModel<double> forces = no_gravity(model);
    // Linearised at rest: a = M^-1 (K x + D v) on the free degrees of freedom.
    const Eigen::MatrixXd K = Eigen::MatrixXd(forces.stiffness_matrix(model, JacobianForm::exact));
    const Eigen::MatrixXd D = Eigen::MatrixXd(forces.damping_matrix(model));
    std::vector<int> dof;
    for (Index i = 0; i < model.num_nodes(); ++i)
      if (!model.fixed()[i])
        for (int c = 0; c < 3; ++c) dof.push_back(3 * i + c);
    const int n = int(dof.size());
    Eigen::MatrixXd Ak(n, n), Ad(n, n);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        const double w = 1.0 / model.masses()[dof[std::size_t(r)] / 3];
        Ak(r, c) = w * K(dof[std::size_t(r)], dof[std::size_t(c)]);
        Ad(r, c) = w * D(dof[std::size_t(r)], dof[std::size_t(c)]);
      }
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
    const auto bound = spectral_bound(model);
    for (const std::string name : {"symplectic_euler", "improved_euler", "heun"}) {
      const double h = make_integrator<double>(name)->stable_time_step(bound);
      ASSERT_GT(h, 0) << name;
      // One-step matrices on z = (x, v).
      Eigen::MatrixXd S(2 * n, 2 * n);
      if (name == "symplectic_euler") {  // v+ = v + h a(x, v); x+ = x + h v+
        const Eigen::MatrixXd Vx = h * Ak, Vv = I + h * Ad;
        S << I + h * Vx, h * Vv, Vx, Vv;
      } else if (name == "improved_euler") {  // v+ = v + h a; x+ = x + h/2 (v + v+)
        const Eigen::MatrixXd Vx = h * Ak, Vv = I + h * Ad;
        S << I + 0.5 * h * Vx, 0.5 * h * (I + Vv), Vx, Vv;
      } else {  // Heun: z+ = (I + hJ + (hJ)^2 / 2) z with J = [0 I; Ak Ad]
        Eigen::MatrixXd J(2 * n, 2 * n);
        J << Eigen::MatrixXd::Zero(n, n), I, Ak, Ad;
        const Eigen::MatrixXd hJ = h * J;
        S = Eigen::MatrixXd::Identity(2 * n, 2 * n) + hJ + 0.5 * hJ * hJ;
      }
      const double rho =
          Eigen::EigenSolver<Eigen::MatrixXd>(S, false).eigenvalues().cwiseAbs().maxCoeff();
      EXPECT_LE(rho, 1 + 1e-9) << name << " trial " << trial << " h " << h;
    }
  }
}

// Implicit Euler at 100x the symplectic limit on a lattice: finite, and the energy only falls.
TYPED_TEST(IntegratorsTyped, ImplicitEulerStableAtHundredTimesTheExplicitLimit) {
  using S = TypeParam;
  std::mt19937 rng(41);
  SphereModel<S> model = random_model<S>(rng, {4, 3, 3}, S(0.2), false, S(0));  // undamped
  model.set_fixed(0);
  model.set_fixed(1);
  ForceModel<S> forces = no_gravity(model);
  forces.refresh(model);
  const S h = S(100) * symplectic_euler_limit(spectral_bound(model));
  ImplicitEulerIntegrator<S> implicit;
  implicit.prepare(model);
  double e = double(total_energy(model, forces));
  const double e0 = e;
  for (int s = 0; s < 100; ++s) {
    ASSERT_TRUE(implicit.step(model, forces, h).ok) << "step " << s;
    ASSERT_TRUE(model.positions().allFinite());
    const double en = double(total_energy(model, forces));
    EXPECT_LE(en, e * (1 + 1e-4)) << "step " << s;
    e = en;
  }
  EXPECT_LT(e, 0.5 * e0);
}

// Backward Euler never adds energy: step by step on nonlinear random models, with and without
// damping, from small steps to far beyond the explicit limit. The tolerance is the CG residual.
TEST(Integrators, ImplicitEulerEnergyNeverRises) {
  std::mt19937 rng(43);
  for (double eta : {0.0, 10.26}) {
    for (double factor : {0.5, 5.0, 50.0}) {
      SphereModel<double> model = random_model<double>(rng, {3, 3, 2}, 0.3, true, eta);
      ForceModel<double> forces = no_gravity(model);
      auto implicit = make<double>("implicit_euler", 1e-12);
      implicit->prepare(model);
      const double h = factor * symplectic_euler_limit(spectral_bound(model));
      double e = total_energy(model, forces);
      for (int s = 0; s < 200; ++s) {
        ASSERT_TRUE(implicit->step(model, forces, h).ok);
        const double en = total_energy(model, forces);
        EXPECT_LE(en, e + 1e-9 * e) << "eta " << eta << " factor " << factor << " step " << s;
        e = en;
      }
    }
  }
}

// Symplectic Euler conserves the modified energy Q = v^2 + w^2 q^2 - h w^2 q v of a linear
// oscillator exactly, at any stable step; so its energy never drifts.
TEST(Integrators, SymplecticEulerConservesItsModifiedEnergy) {
  const double m = 0.001, k = 500, w = 1000, l0 = 0.01;
  SphereModel<double> model = two_spheres(m, k, 0.0, l0);
  model.positions()(1, 0) += 1e-4;
  ForceModel<double> forces = no_gravity(model);
  SymplecticEulerIntegrator<double> se;
  se.prepare(model);
  const double h = 1.5 / w;
  auto Q = [&] {
    const double q = gap(model, l0), v = model.velocities()(1, 0) - model.velocities()(0, 0);
    return v * v + w * w * q * q - h * w * w * q * v;
  };
  const double q0 = Q();
  double worst = 0;
  for (int s = 0; s < 100000; ++s) {
    se.step(model, forces, h);
    worst = std::max(worst, std::abs(Q() - q0));
  }
  EXPECT_LT(worst, 1e-9 * q0);
}

// On nonlinear random models: undamped, the energy of the last window is no higher than that of
// the first (no secular drift); damped, the windowed maximum never rises.
TEST(Integrators, SymplecticEulerEnergyDoesNotDriftOrRiseWithDamping) {
  std::mt19937 rng(47);
  for (double eta : {0.0, 10.26}) {
    SphereModel<double> model = random_model<double>(rng, {3, 2, 2}, 0.3, false, eta);
    ForceModel<double> forces = no_gravity(model);
    SymplecticEulerIntegrator<double> se;
    se.prepare(model);
    const double h = 0.3 * symplectic_euler_limit(spectral_bound(model));
    const int windows = 20, per = 2000;
    std::vector<double> wmax(windows, 0);
    for (int win = 0; win < windows; ++win)
      for (int s = 0; s < per; ++s) {
        se.step(model, forces, h);
        wmax[std::size_t(win)] = std::max(wmax[std::size_t(win)], total_energy(model, forces));
      }
    if (eta == 0.0) {
      EXPECT_LE(wmax.back(), wmax.front() * 1.02);
    } else {
      for (int win = 1; win < windows; ++win)
        EXPECT_LE(wmax[std::size_t(win)], wmax[std::size_t(win - 1)] * (1 + 1e-12))
            << "window " << win;
      EXPECT_LT(wmax.back(), 0.5 * wmax.front());
    }
  }
}

// Momentum of a free model (no gravity, no fixed node) is conserved by every scheme; angular
// momentum exactly by symplectic Euler with damping along the links (central forces), but not with
// the paper's full relative-velocity damping.
TYPED_TEST(IntegratorsTyped, MomentumIsConserved) {
  using S = TypeParam;
  const double tol = std::is_same_v<S, float> ? 1e-5 : 1e-11;
  std::mt19937 rng(53);
  for (const std::string name : {"improved_euler", "heun", "symplectic_euler", "implicit_euler"}) {
    SphereModel<S> model = random_model<S>(rng, {3, 2, 2}, S(0.3), true);
    ForceModel<S> forces = no_gravity(model);
    auto integrator = make<S>(name, std::is_same_v<S, float> ? 1e-6 : 1e-13);
    integrator->prepare(model);
    const auto bound = spectral_bound(model);
    const S h = S(0.2) * std::min({symplectic_euler_limit(bound), heun_limit(bound),
                                   improved_euler_limit(bound)});
    const Vector3<S> p0 = momentum(model);
    const double scale =
        double((model.velocities().rowwise().norm().array() * model.masses().array()).sum());
    for (int s = 0; s < 300; ++s) integrator->step(model, forces, h);
    EXPECT_LT(double((momentum(model) - p0).norm()), tol * scale) << name;
  }
}

TEST(Integrators, SymplecticEulerConservesAngularMomentumWithCentralDamping) {
  std::mt19937 rng(59);
  for (DampingModel dm : {DampingModel::along_link, DampingModel::full_relative_velocity}) {
    SphereModel<double> model = random_model<double>(rng, {3, 2, 2}, 0.3, false, 30.0);
    // Add a rigid spin about z so there is angular momentum to lose.
    for (Index i = 0; i < model.num_nodes(); ++i) {
      model.velocities()(i, 0) += -20 * model.positions()(i, 1);
      model.velocities()(i, 1) += 20 * model.positions()(i, 0);
    }
    ForceModel<double> forces = no_gravity(model, dm);
    SymplecticEulerIntegrator<double> se;
    se.prepare(model);
    const Vector3<double> L0 = angular_momentum(model);
    const double h = 0.2 * symplectic_euler_limit(spectral_bound(model));
    for (int s = 0; s < 2000; ++s) se.step(model, forces, h);
    const double change = (angular_momentum(model) - L0).norm() / L0.norm();
    if (dm == DampingModel::along_link)
      EXPECT_LT(change, 1e-10);
    else
      EXPECT_GT(change, 1e-3);
  }
}

TYPED_TEST(IntegratorsTyped, FixedNodesNeverMove) {
  using S = TypeParam;
  std::mt19937 rng(61);
  for (const std::string name : {"improved_euler", "heun", "symplectic_euler", "implicit_euler"}) {
    SphereModel<S> model = random_model<S>(rng, {3, 2, 2}, S(0.2));
    for (Index i : {0, 3, 7}) model.set_fixed(i);
    ForceModel<S> forces(model);  // with gravity
    auto integrator = make_integrator<S>(name);
    integrator->prepare(model);
    const Positions<S> before = model.positions();
    const S h = S(0.2) * std::min(symplectic_euler_limit(spectral_bound(model)),
                                  improved_euler_limit(spectral_bound(model)));
    for (int s = 0; s < 50; ++s) integrator->step(model, forces, h);
    for (Index i : {0, 3, 7}) {
      EXPECT_EQ(model.positions().row(i), before.row(i)) << name;
      EXPECT_EQ(model.velocities().row(i).norm(), S(0)) << name;
    }
    EXPECT_GT(double((model.positions() - before).norm()), 0.0) << name;
  }
}

// A non-finite force gives a failed step with the state untouched, not a stale solution.
TEST(Integrators, ImplicitEulerRefusesNonFiniteForces) {
  std::mt19937 rng(89);
  SphereModel<double> model = random_model<double>(rng, {3, 3, 3}, 0.2);
  ForceModel<double> forces = no_gravity(model);
  ImplicitEulerIntegrator<double> ie;
  ie.prepare(model);
  ASSERT_TRUE(ie.step(model, forces, 1e-3).ok);  // a warm start now exists
  const Positions<double> x = model.positions(), v = model.velocities();
  forces.external_forces()(40, 2) = std::nan("");
  EXPECT_FALSE(ie.step(model, forces, 1e-3).ok);
  EXPECT_EQ(model.positions(), x);
  EXPECT_EQ(model.velocities(), v);
}

TEST(Integrators, UnpreparedStepIsRefusedWithoutTouchingTheState) {
  SphereModel<double> model = two_spheres(0.001, 500.0, 0.1);
  ForceModel<double> forces = no_gravity(model);
  for (const auto& name : integrator_names()) {
    auto integrator = make_integrator<double>(name);
    model.positions()(1, 0) = 0.0105;
    const Positions<double> before = model.positions();
    EXPECT_FALSE(integrator->step(model, forces, 1e-4).ok) << name;
    EXPECT_EQ(model.positions(), before) << name;
  }
}

TEST(Integrators, RegistryNamesAndErrors) {
  for (const auto& name : integrator_names())
    EXPECT_EQ(make_integrator<double>(name)->name(), name);
  try {
    (void)make_integrator<double>("runge_kutta");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("runge_kutta"), std::string::npos);
    for (const auto& name : integrator_names()) EXPECT_NE(what.find(name), std::string::npos);
  }
}

// The direct solver agrees with matrix-free CG (default, definite form); LU runs the exact
// Jacobian.
TEST(Integrators, ImplicitSolversAgree) {
  std::mt19937 rng(67);
  const SphereModel<double> start = random_model<double>(rng, {3, 2, 2}, 0.3, true);
  const double h = 10 * symplectic_euler_limit(spectral_bound(start));
  using IE = ImplicitEulerIntegrator<double>;
  auto run = [&](IE::Solver solver, JacobianForm form, double step) {
    SphereModel<double> model = start;
    ForceModel<double> forces = no_gravity(model);
    IE::Options o;
    o.solver = solver;
    o.jacobian = form;
    o.tolerance = 1e-13;
    o.velocity_tolerance = 0;  // the exact solve, not one to 1e-9 m/s
    o.max_iterations = 5000;
    IE ie(o);
    ie.prepare(model);
    EXPECT_TRUE(ie.step(model, forces, step).ok);
    return Positions<double>(model.velocities());
  };
  const auto cg = run(IE::Solver::conjugate_gradient, JacobianForm::definite, h);
  const auto ldlt = run(IE::Solver::eigen_ldlt, JacobianForm::definite, h);
  EXPECT_TRUE(matrices_near(cg, ldlt, 1e-9));
  // The linearisations differ by terms of order h^2 (the non-symmetric damping term and the
  // compressive transverse term): at a small step LU with the exact Jacobian agrees closely; at a
  // large one it does not.
  const double small = 0.01 * h;
  const auto lu_small = run(IE::Solver::eigen_lu, JacobianForm::exact, small);
  const auto ldlt_small = run(IE::Solver::eigen_ldlt, JacobianForm::definite, small);
  const Positions<double> dv_lu = lu_small - start.velocities(),
                          dv_ldlt = ldlt_small - start.velocities();
  EXPECT_TRUE(matrices_near(dv_lu, dv_ldlt, 1e-3));
  EXPECT_FALSE(matrices_near(dv_lu, dv_ldlt, 1e-9));
}

// Options::extrapolate_warm_start: the same motion to the solver's tolerance in fewer CG
// iterations while the load changes smoothly (a block under gravity, its top pushed down by a
// force that grows steadily, as a tool pressing), and no extrapolation when the step length
// changes. (Measured: 2,265 iterations with the last step's change, 1,109 extrapolated. Before
// the warm start was scaled to the least error in the energy norm, 2026-11-29: 2,449 and 1,731.)
TEST(Integrators, ExtrapolatedWarmStartSavesIterationsNotAccuracy) {
  using IE = ImplicitEulerIntegrator<double>;
  auto run = [](bool extrapolate, bool vary_step) {
    SphereModel<double> model = block_on_fixed_base<double>();
    ForceModel<double> forces(model);  // gravity along -z
    IE::Options o;
    o.tolerance = 1e-3;  // as the servo loop's step
    o.extrapolate_warm_start = extrapolate;
    IE ie(o);
    ie.prepare(model);
    long iterations = 0;
    for (int s = 0; s < 400; ++s) {
      for (Index i = 0; i < model.num_nodes(); ++i)
        if (model.rest_positions()(i, 2) > 0.015 - 1e-9) forces.external_forces()(i, 2) = -2e-6 * s;
      const IntegratorResult r = ie.step(model, forces, vary_step && s % 2 ? 5e-4 : 1e-3);
      EXPECT_TRUE(r.ok);
      iterations += r.iterations;
    }
    return std::pair{Positions<double>(model.positions()), iterations};
  };
  const auto [x_plain, it_plain] = run(false, false);
  const auto [x_extrapolated, it_extrapolated] = run(true, false);
  const double sag = (x_plain - block<double>({4, 3, 3}, 0.005, tissue<double>()).positions())
                         .cwiseAbs()
                         .maxCoeff();
  EXPECT_GT(sag, 1e-4);
  EXPECT_LT((x_plain - x_extrapolated).cwiseAbs().maxCoeff(), 1e-4 * sag);
  EXPECT_LT(double(it_extrapolated), 0.6 * double(it_plain));
  std::printf(
      "400 steps: %ld CG iterations with the last step's change, %ld extrapolated; sag "
      "%.3g mm, difference %.3g mm\n",
      it_plain, it_extrapolated, sag * 1e3, (x_plain - x_extrapolated).cwiseAbs().maxCoeff() * 1e3);
  // Steps of alternating length: never extrapolated, so the same iterations as without.
  EXPECT_EQ(run(true, true).second, run(false, true).second);
}

// Options::velocity_tolerance: a block settling under gravity (drag 40/s, so its motion dies away
// in half a second) until its kinetic energy is at the round-off of its forces. The relative test
// alone then chases that round-off; the floor stops CG as soon as the velocity change is solved to
// about 1e-9 m/s. Both runs take the same iterations while the block moves and end at the same
// positions to within a nanometre; at rest the floor's run takes at most a third of the other's
// iterations.
TEST(Integrators, VelocityFloorStopsChasingRoundOffAtRest) {
  using IE = ImplicitEulerIntegrator<double>;
  struct Run {
    Positions<double> x;
    long moving{0}, resting{0};  // CG iterations in the first 100 steps, the last 400
    double kinetic{0};           // at the end (J)
  };
  auto settle = [](double velocity_tolerance) {
    SphereModel<double> model = block_on_fixed_base<double>();
    ForceModel<double>::Options fo;
    fo.drag = 40;
    ForceModel<double> forces(model, fo);  // gravity along -z
    IE::Options o;
    o.tolerance = 1e-3;  // as the servo loop's step
    o.velocity_tolerance = velocity_tolerance;
    IE ie(o);
    ie.prepare(model);
    Run run;
    const int steps = 2400;
    for (int s = 0; s < steps; ++s) {
      const IntegratorResult r = ie.step(model, forces, 1e-3);
      EXPECT_TRUE(r.ok && r.converged);
      if (s < 100) run.moving += r.iterations;
      if (s >= steps - 400) run.resting += r.iterations;
    }
    run.x = model.positions();
    run.kinetic = forces.kinetic_energy(model, model.velocities());
    return run;
  };
  const Run plain = settle(0), floored = settle(IE::Options{}.velocity_tolerance);
  std::printf(
      "CG iterations, first 100 steps: %ld relative test alone, %ld with the floor; last 400 "
      "(at rest): %ld and %ld; kinetic energy at the end %.3g and %.3g J; positions differ by "
      "%.3g nm\n",
      plain.moving, floored.moving, plain.resting, floored.resting, plain.kinetic, floored.kinetic,
      (plain.x - floored.x).cwiseAbs().maxCoeff() * 1e9);
  EXPECT_EQ(floored.moving, plain.moving);
  EXPECT_LT(plain.kinetic, 1e-25);  // the block is at rest: its motion is round-off
  EXPECT_LT(floored.kinetic, 1e-15);
  EXPECT_LE(3 * floored.resting, plain.resting);
  EXPECT_LT((plain.x - floored.x).cwiseAbs().maxCoeff(), 1e-9);
}

// One step from rest under gravity (h g = 1 cm/s), in both precisions, the fixed bottom layer a
// million times heavier than the rest: a floor of 1 m/s, far above the step's motion, stops CG at
// its warm start (zero: no iteration, no velocity); one of 1e-12 m/s, far below the relative
// test's target, gives exactly the solve without a floor; one of 1 mm/s still lets CG iterate,
// which it would not if the fixed nodes' mass were counted (the floor counts the moving nodes').
TYPED_TEST(IntegratorsTyped, VelocityFloorOnOneStepFromRest) {
  using S = TypeParam;
  using IE = ImplicitEulerIntegrator<S>;
  auto first_step = [](double velocity_tolerance) {
    SphereModel<S> model = block_on_fixed_base<S>(S(1e6));
    ForceModel<S> forces(model);
    typename IE::Options o;
    o.tolerance = std::is_same_v<S, float> ? S(1e-4) : S(1e-8);
    o.velocity_tolerance = S(velocity_tolerance);
    IE ie(o);
    ie.prepare(model);
    const IntegratorResult r = ie.step(model, forces, S(1e-3));
    EXPECT_TRUE(r.ok);
    return std::pair{r.iterations, Positions<S>(model.velocities())};
  };
  const auto [it_high, v_high] = first_step(1.0);
  const auto [it_low, v_low] = first_step(1e-12);
  const auto [it_none, v_none] = first_step(0);
  EXPECT_EQ(it_high, 0);
  EXPECT_EQ(v_high.cwiseAbs().maxCoeff(), S(0));
  EXPECT_GT(it_none, 0);
  EXPECT_EQ(it_low, it_none);
  EXPECT_EQ((v_low - v_none).cwiseAbs().maxCoeff(), S(0));
  EXPECT_GT(first_step(1e-3).first, 0);
}

// A block pushed for two steps keeps their velocity change as its (extrapolated) warm start; put
// back at rest with nothing on it, its right-hand side is exactly 0 and so is the solution. The
// warm start is scaled along itself to the least error in the energy norm (b^T w / w^T A w = 0),
// so the solve starts at the solution, with or without the velocity floor. (Before the scaling,
// 2026-11-29: with the floor CG stopped after 19 iterations at 2e-9 m/s; without it, it ran to
// its cap, 200, chasing round-off.)
TEST(Integrators, AStaleWarmStartAtRestIsDropped) {
  using IE = ImplicitEulerIntegrator<double>;
  for (const double velocity_tolerance : {1e-9, 0.0}) {
    SphereModel<double> model = block_on_fixed_base<double>();
    ForceModel<double> forces = no_gravity(model);
    IE::Options o;
    o.tolerance = 1e-6;
    o.velocity_tolerance = velocity_tolerance;
    IE ie(o);
    ie.prepare(model);
    for (Index i = 0; i < model.num_nodes(); ++i)
      if (!model.fixed()[i]) forces.external_forces().row(i) = Eigen::RowVector3d(0, 0, -1e-3);
    for (int s = 0; s < 2; ++s) EXPECT_TRUE(ie.step(model, forces, 1e-3).ok);
    EXPECT_GT(model.velocities().cwiseAbs().maxCoeff(), 1e-3);
    model.positions() = model.rest_positions();
    model.velocities().setZero();
    forces.external_forces().setZero();
    const IntegratorResult r = ie.step(model, forces, 1e-3);
    EXPECT_TRUE(r.ok);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(r.iterations, 0) << "floor " << velocity_tolerance;
    EXPECT_EQ(model.velocities().cwiseAbs().maxCoeff(), 0.0) << "floor " << velocity_tolerance;
  }
}

// block_on_fixed_base(), moving at random (up to 1 cm/s).
SphereModel<double> moving_block() {
  SphereModel<double> start = block_on_fixed_base<double>();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> speed(-0.01, 0.01);
  for (Index i = 0; i < start.num_nodes(); ++i)
    for (int c = 0; c < 3; ++c) start.velocities()(i, c) = start.fixed()[i] ? 0.0 : speed(rng);
  return start;
}

// The model's forces without gravity, its top face held by stiff springs (1e5 N/m, an
// instrument's grip) at targets 1 mm sideways of where it is.
ForceModel<double> held_top(const SphereModel<double>& model) {
  ForceModel<double> forces = no_gravity(model);
  forces.reserve_held(model.num_nodes());
  for (Index i = 0; i < model.num_nodes(); ++i)
    if (model.rest_positions()(i, 2) > 0.015 - 1e-9) {
      HeldNode<double> hn;
      hn.node = i;
      hn.target = model.positions().row(i).transpose() + Vector3<double>(1e-3, 0, 0);
      hn.stiffness = 1e5;
      EXPECT_TRUE(forces.add_held(hn));
    }
  return forces;
}

// The implicit step's system A = M - h D - h^2 K on the free nodes at the model's state (the
// matrix of the direct solve, without contacts), and its energy norm u^T A u.
struct EnergyNorm {
  Eigen::SparseMatrix<double> A;
  EnergyNorm(const SphereModel<double>& model, const ForceModel<double>& forces, double h) {
    A = -h * forces.damping_matrix(model) -
        h * h * forces.stiffness_matrix(model, JacobianForm::definite);
    for (Index i = 0; i < model.num_nodes(); ++i)
      for (int c = 0; c < 3; ++c) A.coeffRef(3 * i + c, 3 * i + c) += model.masses()[i];
    A.prune([&](Index r, Index c, const double&) {
      return !model.fixed()[r / 3] && !model.fixed()[c / 3];
    });
  }
  double operator()(const Positions<double>& u) const {
    const Eigen::Map<const Eigen::VectorXd> f(u.data(), u.size());
    return f.dot(A * f);
  }
};

// CG's stopping test weighs the residual by the preconditioner (Options::tolerance), which makes
// it a test on the error in the system's energy norm against the change's. A block whose top face
// is held by stiff springs pulled 1 mm sideways, the rest moving at random: the held rows dominate
// |b|, so the plain |r| <= tol |b| stopped with an error of 7 times the tolerance in that norm
// (0.0072 at 1e-3, tried 2026-11-27); the weighted test 0.0012.
TEST(Integrators, ConjugateGradientStopsOnTheErrorsEnergyNotItsMomentum) {
  using IE = ImplicitEulerIntegrator<double>;
  const SphereModel<double> start = moving_block();
  auto run = [&](IE::Solver solver, double tolerance,
                 IE::Preconditioner preconditioner = IE::Preconditioner::block_jacobi) {
    SphereModel<double> model = start;
    ForceModel<double> forces = held_top(model);
    IE::Options o;
    o.solver = solver;
    o.tolerance = tolerance;
    o.preconditioner = preconditioner;
    IE ie(o);
    ie.prepare(model);
    EXPECT_TRUE(ie.step(model, forces, 1e-3).ok);
    return Positions<double>(model.velocities() - start.velocities());
  };
  const Positions<double> exact = run(IE::Solver::eigen_ldlt, 0);
  // (The held springs' targets do not enter A.)
  const EnergyNorm energy(start, held_top(start), 1e-3);
  for (const auto preconditioner : {IE::Preconditioner::block_jacobi, IE::Preconditioner::jacobi})
    for (const double tolerance : {1e-3, 1e-2}) {
      const Positions<double> cg = run(IE::Solver::conjugate_gradient, tolerance, preconditioner);
      const double ratio = std::sqrt(energy(cg - exact) / energy(exact));
      std::printf("%s, tolerance %g: error / change in the energy norm %.3g\n",
                  preconditioner == IE::Preconditioner::jacobi ? "Jacobi" : "block-Jacobi",
                  tolerance, ratio);
      EXPECT_LT(ratio, 2 * tolerance);
    }
}

// A warm start is scaled along itself to the least error in the energy norm before CG runs
// (s = b^T w / w^T A w), so a solve never starts further from the solution in that norm than zero
// is. The block of the test above, not held, pushed sideways (10 N/kg on every free node) for
// five steps, then pushed the other way: the extrapolated warm start points away from the new
// solution. Capped at 0 iterations the step keeps its start: 0.82 |dv*|_A from the solution
// scaled, 1.25 unscaled (measured 2026-11-29); with CG it solves to the tolerance.
TEST(Integrators, AWarmStartNeverStartsFurtherThanZeroInTheEnergyNorm) {
  using IE = ImplicitEulerIntegrator<double>;
  SphereModel<double> pushed = moving_block();
  ForceModel<double> forces = no_gravity(pushed);
  IE::Options o;
  o.tolerance = 1e-3;  // as the servo loop's step
  IE ie(o);
  ie.prepare(pushed);
  for (Index i = 0; i < pushed.num_nodes(); ++i)
    if (!pushed.fixed()[i]) forces.external_forces()(i, 1) = 10 * pushed.masses()[i];
  for (int s = 0; s < 5; ++s) ASSERT_TRUE(ie.step(pushed, forces, 1e-3).ok);
  forces.external_forces() *= -1;

  auto change = [&](IE integrator, const IE::Options& options) {
    SphereModel<double> model = pushed;
    integrator.set_options(options);
    const IntegratorResult r = integrator.step(model, forces, 1e-3);
    EXPECT_TRUE(r.ok);
    return std::pair{Positions<double>(model.velocities() - pushed.velocities()), r.iterations};
  };
  IE::Options direct;
  direct.solver = IE::Solver::eigen_ldlt;
  IE::Options capped = o;
  capped.max_iterations = 0;
  IE direct_ie(direct);
  direct_ie.prepare(pushed);
  const Positions<double> exact = change(direct_ie, direct).first;
  const auto [start, none] = change(ie, capped);
  const auto [solved, iterations] = change(ie, o);

  const EnergyNorm energy(pushed, forces, 1e-3);
  const double start_error = std::sqrt(energy(start - exact) / energy(exact));
  const double solved_error = std::sqrt(energy(solved - exact) / energy(exact));
  std::printf("start %.3g |dv*|_A from the solution (0 iterations); %d iterations: %.3g\n",
              start_error, iterations, solved_error);
  EXPECT_EQ(none, 0);
  EXPECT_LT(start_error, 0.95);  // nearer than zero (1), and not zero: the scaled guess helps
  EXPECT_LT(solved_error, 2 * o.tolerance);
}

// The weighted stopping test needs r^T P^-1 r > 0. Under JacobianForm::symmetric a strongly
// compressed link's transverse term can make a diagonal of A, and so of the Jacobi
// preconditioner, negative; there the plain test applies. A sphere on a link compressed to half
// its length, moving across it: CG must either solve the step as the direct solver does or report
// failure (the simulation then rolls back), never return its starting guess as converged.
TEST(Integrators, ConjugateGradientNeverStopsOnANegativeWeightedResidual) {
  using IE = ImplicitEulerIntegrator<double>;
  SphereModel<double> start = two_spheres<double>(1e-6, 1000, 0);
  start.set_fixed(0);
  start.positions()(1, 0) = 0.005;  // compressed to half its rest length
  start.velocities()(1, 1) = 100;   // across the link: the transverse row dominates b
  auto run = [&](IE::Solver solver) {
    SphereModel<double> model = start;
    ForceModel<double> forces = no_gravity(model);
    IE::Options o;
    o.solver = solver;
    o.jacobian = JacobianForm::symmetric;
    o.preconditioner = IE::Preconditioner::jacobi;
    o.tolerance = 1e-6;
    IE ie(o);
    ie.prepare(model);
    const bool ok = ie.step(model, forces, 1e-3).ok;
    return std::pair{ok, Positions<double>(model.velocities())};
  };
  const auto [exact_ok, exact] = run(IE::Solver::eigen_ldlt);
  ASSERT_TRUE(exact_ok);
  const auto [cg_ok, cg] = run(IE::Solver::conjugate_gradient);
  if (cg_ok) {
    EXPECT_TRUE(matrices_near(cg, exact, 1e-6)) << cg << "\n" << exact;
  }
}

// The velocity floor's plain form (|r| <= v_tol sqrt(sum m^2)) where the weighted test cannot be
// used: the compressed link above, whose Jacobi preconditioner is negative across it, so
// b^T P^-1 b < 0. A very large floor turns CG off (0 iterations, the step keeps its warm start:
// zero here); without a floor CG runs.
TEST(Integrators, PlainVelocityFloorStopsCGWhereTheWeightedTestCannotApply) {
  using IE = ImplicitEulerIntegrator<double>;
  auto iterations = [](double velocity_tolerance) {
    SphereModel<double> model = two_spheres<double>(1e-6, 1000, 0);
    model.set_fixed(0);
    model.positions()(1, 0) = 0.005;
    model.velocities()(1, 1) = 100;
    ForceModel<double> forces = no_gravity(model);
    IE::Options o;
    o.jacobian = JacobianForm::symmetric;
    o.preconditioner = IE::Preconditioner::jacobi;
    o.tolerance = 1e-6;
    o.velocity_tolerance = velocity_tolerance;
    IE ie(o);
    ie.prepare(model);
    const Positions<double> v0 = model.velocities();
    const IntegratorResult r = ie.step(model, forces, 1e-3);
    return std::tuple{r.ok, r.iterations, Positions<double>(model.velocities() - v0)};
  };
  const auto [off_ok, off_iterations, off_change] = iterations(1e9);
  EXPECT_TRUE(off_ok);
  EXPECT_EQ(off_iterations, 0);
  EXPECT_EQ(off_change.cwiseAbs().maxCoeff(), 0.0);
  // Solved, or failed in CG (the step then reports it): either way CG ran.
  EXPECT_GE(std::get<1>(iterations(0)), 1);
}

}  // namespace
}  // namespace fsm::test
