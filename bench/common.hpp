#pragma once

// Benchmark helpers: lattice models of a given link count, a uterus-sized model, and one helper to
// register a benchmark that reports time per link.

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <random>

#include "fsm/fsm.hpp"
#include "fsm_support/paper.hpp"

namespace fsm::bench {

/// A cube lattice of n^3 cells (about 7 n^3 links), 5 mm spacing, bottom layer fixed, nodes
/// jittered by 10 % so no link is axis-aligned, and a small random velocity field.
template <typename Scalar>
SphereModel<Scalar> lattice_model(int n, bool bilinear = true) {
  const Scalar h = Scalar(0.005);
  auto mesh = make_cube_lattice(Vector3<Scalar>::Zero().eval(), Eigen::Vector3i(n, n, n), h);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (Index i = 0; i < mesh.vertices.rows(); ++i)
    for (int c = 0; c < 3; ++c) mesh.vertices(i, c) += Scalar(0.1 * double(h) * u(rng));
  SphereModel<Scalar> model;
  Material<Scalar> tissue = support::paper::bilinear_tissue<Scalar>();
  if (!bilinear) tissue.large_strain_modulus = 0;
  add_tetrahedral_part(model, mesh, model.add_region("lattice", tissue), h / 2);
  for (Index i = 0; i < model.num_nodes(); ++i) {
    if (model.rest_positions()(i, 2) < Scalar(0.1) * h)
      model.set_fixed(i);
    else
      for (int c = 0; c < 3; ++c) model.velocities()(i, c) = Scalar(0.01 * u(rng));
  }
  return model;
}

/// Cells per side giving about `links` links.
inline int cells_for_links(double links) {
  return std::max(2, int(std::lround(std::cbrt(links / 7.4))));
}

/// A uterus-sized model: an ellipsoid (semi-axes 40 x 28 x 22 mm, the size of an adult uterine
/// body) filled with the lattice at 6.2 mm spacing: 696 spheres and 3,827 links, like the
/// paper's 694-sphere model. One end fixed (the cervix).
template <typename Scalar>
SphereModel<Scalar> uterus_sized_model() {
  const Vector3<Scalar> axes(Scalar(0.040), Scalar(0.028), Scalar(0.022));
  const Scalar h = Scalar(0.0062);
  const Eigen::Vector3i cells = (2 * axes / h).array().ceil().template cast<int>();
  auto mesh = make_cube_lattice(Vector3<Scalar>(-axes), cells, h, [&](const Vector3<Scalar>& c) {
    return (c.array() / axes.array()).matrix().squaredNorm() <= Scalar(1);
  });
  SphereModel<Scalar> model;
  add_tetrahedral_part(model, mesh,
                       model.add_region("body", support::paper::bilinear_tissue<Scalar>()), h / 2);
  const Scalar xmin = model.rest_positions().col(0).minCoeff();
  for (Index i = 0; i < model.num_nodes(); ++i)
    if (model.rest_positions()(i, 0) < xmin + Scalar(1.5) * h) model.set_fixed(i);
  return model;
}

/// Reports time per link as a counter named "per_link" (seconds; shown with an n/u prefix).
inline void per_link(benchmark::State& state, double links_per_iteration) {
  state.SetItemsProcessed(int64_t(double(state.iterations()) * links_per_iteration));
  state.counters["per_link"] =
      benchmark::Counter(links_per_iteration, benchmark::Counter::kIsIterationInvariantRate |
                                                  benchmark::Counter::kInvert);
}

}  // namespace fsm::bench
