#pragma once

/// @file fsm_support/probe.hpp
/// @brief Where and how a scripted instrument presses a part of a built model: the probe site,
/// the capsule probe posed at a depth, and the pressed/retracted poses of a probing script.
/// Shared by the demo, the viewer, the benchmarks and the validation tools (support code for the
/// programs around the library, not part of it).

#include <string>
#include <vector>

#include "fsm/collision/contact.hpp"
#include "fsm/simulation.hpp"
#include "fsm/tissue_model.hpp"

namespace fsm::support {

/// @brief A sphere to press and the direction to press it from.
struct ProbeSite {
  Index sphere{-1};                                   ///< the sphere pressed
  Vector3<double> centre{Vector3<double>::Zero()};    ///< its rest centre (m)
  Vector3<double> outward{Vector3<double>::UnitZ()};  ///< unit, from the model's centre through it
  double radius{0};                                   ///< its radius (m)
};

/// @brief The part's free sphere farthest from the model's centre (an anchored one does not
/// yield), approached along the outward direction. fsm::Error if the part has no free sphere.
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

/// @brief A capsule instrument (a laparoscopic probe: shaft radius, half length) pressing a probe
/// site along -outward. The capsule's -z end is its tip; its pose is its centre.
struct CapsuleProbe {
  ProbeSite site;
  double radius{0.0025};     ///< shaft radius (m)
  double half_length{0.02};  ///< half the shaft's straight length (m)

  /// @brief The orientation that points the capsule's tip along -outward.
  [[nodiscard]] Eigen::Quaterniond orientation() const {
    return Eigen::Quaterniond::FromTwoVectors(Vector3<double>::UnitZ(), site.outward);
  }
  /// @brief The pose origin (m) with the tip `depth` (m) inside the sphere's rest surface
  /// (negative: outside it).
  [[nodiscard]] Vector3<double> position(double depth) const {
    return site.centre + site.outward * (site.radius - depth + radius + half_length);
  }
  /// @brief The instrument, posed at `depth`.
  [[nodiscard]] collision::Instrument<double> instrument(double depth,
                                                         const std::string& name = "probe") const {
    collision::Instrument<double> ins;
    ins.name = name;
    ins.shape = collision::CapsuleShape<double>{radius, half_length};
    ins.pose.orientation = orientation();
    ins.pose.position = position(depth);
    return ins;
  }
  /// @brief Poses instrument `k` of `solver` at `depth` (m), moving inward at `depth_rate` (m/s).
  void press(collision::ContactSolver<double>& solver, Index k, double depth,
             double depth_rate = 0) const {
    collision::Instrument<double>& ins = solver.instrument(k);
    ins.pose.orientation = orientation();
    ins.pose.position = position(depth);
    ins.linear_velocity = -site.outward * depth_rate;
  }
};

/// @brief Lets `sim` sag for `steps` steps of 1 ms with instrument `k` of `contacts` (the probe's)
/// held 2 cm outside the probe's site, then aims the probe at the site sphere's sagged centre, so
/// that press() depths count from where the tissue now is. Returns the steps that did not advance.
inline int sag_then_aim(Simulation<double>& sim, collision::ContactSolver<double>& contacts,
                        Index k, CapsuleProbe& probe, int steps = 500) {
  probe.press(contacts, k, -0.02);
  int failed = 0;
  for (int s = 0; s < steps; ++s) {
    contacts.compute(sim.model(), sim.forces());
    failed += !sim.step(1e-3).advanced();
    contacts.collect(sim.forces());
  }
  probe.site.centre = sim.model().positions().row(probe.site.sphere).transpose();
  return failed;
}

/// @brief A capsule probe at the outermost free sphere of the named part.
inline CapsuleProbe capsule_probe(const TissueModel<double>& model, const std::string& part,
                                  double radius = 0.0025, double half_length = 0.02) {
  return CapsuleProbe{outermost_free_sphere(model.spheres, model.part(part)), radius, half_length};
}

/// @brief Two poses of a probing script: pressed `depth` into a part, and `retreat` (m) back out.
struct ProbeTarget {
  Eigen::Quaterniond orientation{Eigen::Quaterniond::Identity()};
  Vector3<double> pressed{Vector3<double>::Zero()}, away{Vector3<double>::Zero()};
};

/// @brief Where a capsule of `radius` and `half_length` presses part `p` `depth` (m) deep, and
/// the pose `retreat` (m) outside that.
inline ProbeTarget probe_target(const TissueModel<double>& model, const Part& p, double radius,
                                double half_length, double depth, double retreat = 0.015) {
  const CapsuleProbe probe{outermost_free_sphere(model.spheres, p), radius, half_length};
  ProbeTarget t;
  t.orientation = probe.orientation();
  t.pressed = probe.position(depth);
  t.away = t.pressed + probe.site.outward * retreat;
  return t;
}

/// @brief One stop of a scripted probing session: a part and how deep to press it (m).
struct ProbeStop {
  const Part* part;
  double depth;
};

/// @brief The parts a scripted session (fsm-demo, fsm-viewer --scripted) probes, in order, and
/// how deep. The bundled uterus: its session order, 4 mm into the body and the fibroid, 2.5 mm into
/// the rest. Any other model: each part with spheres in the model's order, 4 mm into tetrahedral
/// parts, 2.5 mm into the rest. fsm::Error when there is no part to probe.
inline std::vector<ProbeStop> probing_plan(const TissueModel<double>& model) {
  static const char* const bundled[] = {"body",          "fibroid",       "ovary_left",
                                        "ovary_right",   "tube_left",     "tube_right",
                                        "ligament_left", "ligament_right"};
  auto find = [&](const std::string& name) -> const Part* {
    for (const Part& p : model.parts)
      if (p.name == name && p.num_nodes > 0) return &p;
    return nullptr;
  };
  std::vector<ProbeStop> plan;
  for (const char* name : bundled) {
    const Part* p = find(name);
    if (p == nullptr) {
      plan.clear();
      break;
    }
    const std::string n = name;
    plan.push_back({p, n == "body" || n == "fibroid" ? 0.004 : 0.0025});
  }
  if (plan.empty())
    for (const Part& p : model.parts)
      if (p.num_nodes > 0)
        plan.push_back({&p, p.topology == Topology::tetrahedral ? 0.004 : 0.0025});
  if (plan.empty()) throw Error("", "model '" + model.name + "'", "has no part to probe");
  return plan;
}

}  // namespace fsm::support
