#pragma once

// Shared test fixtures: small models with known answers, random models, and a comparison helper
// that is relative, absolute near zero, and fails on NaN.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>

#include "fsm/fsm.hpp"
#include "fsm_support/paper.hpp"

namespace fsm::test {

/// Relative comparison with an absolute floor; NaN never compares equal.
template <typename A, typename B>
::testing::AssertionResult near(A a, B b, double rel, double abs = 0.0) {
  const double x = double(a), y = double(b);
  if (std::isnan(x) || std::isnan(y))
    return ::testing::AssertionFailure() << "NaN: " << x << " vs " << y;
  const double tol = std::max(abs, rel * std::max(std::abs(x), std::abs(y)));
  if (std::abs(x - y) <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << x << " vs " << y << " differ by " << std::abs(x - y) << " > " << tol;
}

/// Matrix comparison, entry by entry, relative to the larger matrix's max norm.
template <typename DA, typename DB>
::testing::AssertionResult matrices_near(const Eigen::MatrixBase<DA>& a,
                                         const Eigen::MatrixBase<DB>& b, double rel) {
  if (a.rows() != b.rows() || a.cols() != b.cols())
    return ::testing::AssertionFailure() << "shapes differ";
  if (!a.allFinite() || !b.allFinite()) return ::testing::AssertionFailure() << "non-finite entry";
  const double scale = std::max(double(a.cwiseAbs().maxCoeff()), double(b.cwiseAbs().maxCoeff()));
  const double err = double((a - b).cwiseAbs().maxCoeff());
  if (err <= rel * scale) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "max difference " << err << " > " << rel << " * " << scale << "\n"
         << a << "\n---\n"
         << b;
}

/// The paper's linear tissue (fsm_support/paper.hpp), E (Pa) and eta (Pa s) overridable.
template <typename Scalar>
Material<Scalar> tissue(Scalar E = Scalar(support::paper::youngs_modulus),
                        Scalar eta = Scalar(support::paper::viscosity)) {
  Material<Scalar> m = support::paper::linear_tissue<Scalar>();
  m.youngs_modulus = E;
  m.viscosity = eta;
  return m;
}

/// Two spheres of mass m on the x axis, l0 apart, joined by one link (k, kd). The relative
/// coordinate q = l - l0 obeys q'' = -(2k/m) q - (2kd/m) q'.
template <typename Scalar>
SphereModel<Scalar> two_spheres(Scalar m, Scalar k, Scalar kd, Scalar l0 = Scalar(0.01)) {
  SphereModel<Scalar> model;
  const Index r = model.add_region("pair", tissue<Scalar>());
  model.add_node(Vector3<Scalar>(0, 0, 0), Scalar(0.002), m, r);
  model.add_node(Vector3<Scalar>(l0, 0, 0), Scalar(0.002), m, r);
  model.add_link(0, 1, k, kd);
  return model;
}

/// Fixes every node whose rest coordinate along `axis` is below `bound` (m): with the default,
/// the face of a block() at the origin.
template <typename Scalar>
void fix_below(SphereModel<Scalar>& model, int axis, Scalar bound = Scalar(1e-9)) {
  for (Index i = 0; i < model.num_nodes(); ++i)
    if (model.rest_positions()(i, axis) < bound) model.set_fixed(i);
}

/// A block of the Freudenthal lattice as a model.
template <typename Scalar>
SphereModel<Scalar> block(Eigen::Vector3i cells, Scalar spacing,
                          const Material<Scalar>& material = tissue<Scalar>()) {
  SphereModel<Scalar> model;
  const Index r = model.add_region("block", material);
  add_tetrahedral_part(model, make_cube_lattice(Vector3<Scalar>::Zero().eval(), cells, spacing), r,
                       spacing / 2);
  return model;
}

/// A lattice block whose nodes are jittered by up to `jitter` x spacing, so links point in
/// every direction and the geometry is nonlinear from the start; random masses and velocities.
template <typename Scalar>
SphereModel<Scalar> random_model(std::mt19937& rng, Eigen::Vector3i cells = {3, 3, 3},
                                 Scalar jitter = Scalar(0.25), bool bilinear = false,
                                 Scalar eta = Scalar(10.26)) {
  const Scalar h = Scalar(0.01);
  auto mesh = make_cube_lattice(Vector3<Scalar>::Zero().eval(), cells, h);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Index i = 0; i < mesh.vertices.rows(); ++i)
    for (int c = 0; c < 3; ++c) mesh.vertices(i, c) += Scalar(double(jitter) * double(h) * u(rng));
  Material<Scalar> mat = tissue<Scalar>(Scalar(support::paper::youngs_modulus), eta);
  if (bilinear) {
    mat.large_strain_modulus = Scalar(support::paper::large_strain_modulus);
    mat.switch_strain = Scalar(0.05);
  }
  SphereModel<Scalar> model;
  const Index r = model.add_region("random", mat);
  add_tetrahedral_part(model, mesh, r, h / 2);
  for (Index i = 0; i < model.num_nodes(); ++i) {
    model.masses()[i] *= Scalar(0.5 + 0.5 * (u(rng) + 1.0));
    for (int c = 0; c < 3; ++c) {
      model.positions()(i, c) += Scalar(0.1 * double(h) * u(rng));
      model.velocities()(i, c) = Scalar(0.05 * u(rng));
    }
  }
  return model;
}

/// A ForceModel without gravity.
template <typename Scalar>
ForceModel<Scalar> no_gravity(const SphereModel<Scalar>& model,
                              DampingModel damping = DampingModel::along_link, int threads = 1) {
  typename ForceModel<Scalar>::Options o;
  o.gravity.setZero();
  o.damping = damping;
  o.threads = threads;
  return ForceModel<Scalar>(model, o);
}

template <typename Scalar>
Vector3<Scalar> momentum(const SphereModel<Scalar>& m) {
  return (m.velocities().array().colwise() * m.masses().array()).colwise().sum().transpose();
}

template <typename Scalar>
Vector3<Scalar> angular_momentum(const SphereModel<Scalar>& m) {
  Vector3<Scalar> L = Vector3<Scalar>::Zero();
  for (Index i = 0; i < m.num_nodes(); ++i)
    L += m.masses()[i] * m.positions().row(i).transpose().cross(m.velocities().row(i).transpose());
  return L;
}

template <typename Scalar>
Scalar total_energy(const SphereModel<Scalar>& m, const ForceModel<Scalar>& f) {
  return f.kinetic_energy(m, m.velocities()) + f.elastic_energy(m, m.positions()) +
         f.gravity_energy(m, m.positions());
}

}  // namespace fsm::test
