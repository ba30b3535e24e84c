#pragma once

// Where a scripted instrument presses a part of a built model: the part's free sphere farthest
// from the model's centre, approached along the outward direction. Shared by the demo, the viewer
// and the benchmarks (example code, not part of the library).

#include "fsm/tissue_model.hpp"

namespace fsm::examples {

struct ProbeSite {
  Index sphere{-1};                                   ///< the sphere pressed
  Vector3<double> centre{Vector3<double>::Zero()};    ///< its rest centre (m)
  Vector3<double> outward{Vector3<double>::UnitZ()};  ///< unit, from the model's centre through it
  double radius{0};                                   ///< its radius (m)
};

/// The part's outermost free sphere (an anchored one does not yield); fsm::Error if the part has
/// no free sphere.
inline ProbeSite outermost_free_sphere(const SphereModel<double>& m, const Part& p) {
  const Vector3<double> centre = m.rest_positions().colwise().mean().transpose();
  ProbeSite s;
  double far = -1;
  for (Index i = p.first_node; i < p.first_node + p.num_nodes; ++i) {
    if (m.fixed()[i]) continue;
    const double d = (m.rest_positions().row(i).transpose() - centre).norm();
    if (d > far) {
      far = d;
      s.sphere = i;
    }
  }
  if (s.sphere < 0) throw Error("", "part '" + p.name + "'", "has no free sphere to press");
  s.centre = m.rest_positions().row(s.sphere).transpose();
  s.outward = (s.centre - centre).normalized();
  s.radius = m.radii()[s.sphere];
  return s;
}

}  // namespace fsm::examples
