// fsm-stability-map: the largest stable time step of each explicit scheme against stiffness and
// damping, measured on a built block and compared with the estimate the library uses
// (Integrator::stable_time_step of spectral_bound, docs/physics.md section 6); and the same for
// implicit Euler with the explicit volume term (VolumeTerm, limit 2 / omega_V).
//
//   fsm-stability-map SCENE.json [--steps N]
//
// For each (E, eta) the links are rescaled (k proportional to E, k_d to eta), the block's bottom
// layer fixed, every free sphere given a random velocity, and the step bisected (on a log scale)
// between one that keeps the energy below 100 x its start for N steps and one that does not.
// Prints JSON on stdout.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/scene.hpp"
#include "fsm/fsm.hpp"
#include "fsm/volume_term.hpp"

namespace {

using namespace fsm;

struct Case {
  SphereModel<double> model;
  const VolumeTerm<double>* volume{nullptr};
};

// True if `steps` steps of size dt keep the energy bounded (below 100 x the initial one).
bool stable(const SphereModel<double>& base, const std::string& integrator, double dt, int steps,
            VolumeTerm<double>* volume) {
  SphereModel<double> m = base;
  ForceModel<double>::Options fo;
  fo.gravity.setZero();
  ForceModel<double> forces(m, fo);
  auto integ = make_integrator<double>(integrator);
  integ->prepare(m);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (Index i = 0; i < m.num_nodes(); ++i)
    if (!m.fixed()[i])
      for (int c = 0; c < 3; ++c) m.velocities()(i, c) = 1e-3 * u(rng);
  auto energy = [&] {
    double e = forces.kinetic_energy(m, m.velocities()) + forces.elastic_energy(m, m.positions());
    if (volume) e += volume->energy(m.positions());
    return e;
  };
  const double e0 = energy();
  for (int s = 0; s < steps; ++s) {
    if (volume) {
      auto fe = forces.external_forces();
      fe.setZero();
      volume->add_forces(m.positions(), fe);
    }
    if (!integ->step(m, forces, dt).ok) return false;
    if (s % 50 == 49 || s == steps - 1) {
      const double e = energy();
      if (!std::isfinite(e) || e > 100 * e0) return false;
    }
  }
  return true;
}

double bisect(const SphereModel<double>& model, const std::string& integrator, double guess,
              int steps, VolumeTerm<double>* volume) {
  double lo = guess / 64, hi = guess * 64;
  if (!stable(model, integrator, lo, steps, volume)) return 0;  // below the search range
  if (stable(model, integrator, hi, steps, volume)) return hi;  // above it
  for (int k = 0; k < 14; ++k) {  // ratio hi / lo = 4096^(2^-14): 0.05 %
    const double mid = std::sqrt(lo * hi);
    (stable(model, integrator, mid, steps, volume) ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: fsm-stability-map SCENE.json [--steps N]\n");
    return 2;
  }
  int steps = 1500;
  for (int i = 2; i + 1 < argc; ++i)
    if (std::string(argv[i]) == "--steps") steps = std::atoi(argv[i + 1]);
  try {
    const std::string scene_path = argv[1];
    const build::Scene scene = build::load_scene(scene_path);
    TissueModel<double> tissue = build::build_model(scene_path);
    SphereModel<double> base = tissue.spheres;
    const double zmin = base.rest_positions().col(2).minCoeff();
    for (Index i = 0; i < base.num_nodes(); ++i)
      if (base.rest_positions()(i, 2) <= zmin + 1e-6) base.set_fixed(i);
    const Material<double> mat = scene.parts[0].material;
    const ScalarArray<double> k0 = base.stiffness(), kd0 = base.damping();

    // The filling's tetrahedra, for the volume term.
    const TetrahedronArray tetrahedra = tissue.spheres.tetrahedra();

    const std::vector<double> moduli{1e3, 3e3, 1e4, 3e4, 1e5, 3e5};  // Pa
    const std::vector<double> viscosities{0.0, 1.0, 10.26, 100.0};   // Pa s
    std::printf(
        "{\"title\": \"%d spheres, %d links (%s); %d steps from random velocities\", "
        "\"rows\": [\n",
        base.num_nodes(), base.num_links(), scene_path.c_str(), steps);
    bool first = true;
    for (const std::string integrator :
         {"symplectic_euler", "improved_euler", "heun", "implicit_euler+volume"}) {
      const bool vol = integrator == "implicit_euler+volume";
      for (double eta : viscosities) {
        for (double E : moduli) {
          SphereModel<double> m = base;
          m.stiffness() = k0 * (E / mat.youngs_modulus);
          m.damping() = kd0 * (eta / mat.viscosity);
          ForceModel<double>::Options fo;
          fo.gravity.setZero();
          const SpectralBound<double> bound = spectral_bound(m, fo.damping);
          double estimate = 0;
          VolumeTerm<double> volume;
          if (vol) {
            volume = VolumeTerm<double>(tetrahedra, m.rest_positions(),
                                        VolumeTerm<double>::bulk_modulus_for(E, 0.49));
            estimate = 2 / std::sqrt(volume.omega_max_squared(m.masses(), m.fixed()));
          } else {
            estimate = make_integrator<double>(integrator)->stable_time_step(bound);
          }
          const double guess =
              estimate > 0 && std::isfinite(estimate) ? estimate : 2 / bound.omega_max;
          const double measured =
              bisect(m, vol ? "implicit_euler" : integrator, guess, steps, vol ? &volume : nullptr);
          std::printf(
              "%s{\"integrator\": \"%s\", \"youngs_modulus\": %g, \"viscosity\": %g, "
              "\"omega_max\": %.6g, \"damping_max\": %.6g, \"estimated_dt\": %.6g, "
              "\"measured_dt\": %.6g}",
              first ? "" : ",\n", integrator.c_str(), E, eta, bound.omega_max, bound.damping_max,
              std::isfinite(estimate) ? estimate : -1.0, measured);
          std::fflush(stdout);
          first = false;
        }
      }
    }
    std::printf("\n]}\n");
  } catch (const fsm::Error& e) {
    std::fprintf(stderr, "fsm-stability-map: %s\n", e.what());
    return 1;
  }
  return 0;
}
