// Speed against accuracy of the whole frame (issue 8): the uterus with a probe oscillating 1 +- 1
// mm into the body, 3 s (180 frames of 17 steps at 1 kHz + skinning), for each CG tolerance, with
// and without sleeping. Accuracy against a reference run (CG to 1e-9, no sleeping): the RMS and
// largest difference of the skinned surface at the end, and the largest difference of the probe
// force over the run. Cost: the mean frame time. Writes CSV (stdout or --out FILE).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "fsm/builder/builder.hpp"
#include "fsm/fsm.hpp"
#include "fsm_support/model_cache.hpp"
#include "fsm_support/probe.hpp"

using namespace fsm;
using V3 = Vector3<double>;

namespace {

struct Run {
  Positions<double> surface;
  std::vector<double> force;
  double frame_s{0};
  double cg{0};
};

Run run(const TissueModel<double>& model, double tolerance, bool sleep) {
  Simulation<double>::Options so;
  so.forces.drag = 5;
  so.sleep.enabled = sleep;
  Simulation<double> sim(model.spheres, so);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = tolerance;
  io.max_iterations = 1000;
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  collision::ContactSolver<double> contacts(sim.model(), sim.forces());
  // The probe presses the body's outermost free sphere after it has sagged for 0.5 s, its tip
  // 1 +- 1 mm past the sphere's centre (the vertex contact meets sphere centres).
  support::CapsuleProbe probe = support::capsule_probe(model, "body");
  const Index k = contacts.add_instrument(probe.instrument(-0.02));
  support::sag_then_aim(sim, contacts, k, probe);
  auto ws = model.skin.make_workspace();
  Run r;
  r.surface = model.skin.rest.vertices;
  Positions<double> normals = r.surface;
  long iterations = 0;
  double busy = 0;
  const double pi = 3.14159265358979;
  for (int frame = 0; frame < 240; ++frame) {  // 1 s settling + 3 s measured
    const auto t0 = std::chrono::steady_clock::now();
    for (int s = 0; s < 17; ++s) {
      const double t = double(frame * 17 + s) * 1e-3;
      probe.press(contacts, k, probe.site.radius + 0.001 + 0.001 * std::sin(2 * pi * t),
                  0.002 * pi * std::cos(2 * pi * t));
      contacts.compute(sim.model(), sim.forces());
      const auto rep = sim.step(1e-3);
      contacts.collect(sim.forces());
      if (frame >= 60) iterations += rep.solver_iterations;
      if (frame >= 60) r.force.push_back(contacts.wrench(k).force.norm());
    }
    model.skin.evaluate(sim.model().positions(), ws, r.surface);
    compute_vertex_normals<double>(r.surface, model.skin.rest.faces, normals);
    if (frame >= 60)
      busy += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  r.frame_s = busy / 180.0;
  r.cg = double(iterations) / (180.0 * 17.0);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_path;
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--out" && i + 1 < argc) out_path = argv[++i];
  try {
    const TissueModel<double>& model = support::bundled_uterus(
        [](const std::string& s) { return build::build_model(s); }, "frame_accuracy");
    const Run ref = run(model, 1e-9, false);
    std::fprintf(stderr, "reference: probe force max %.4f N\n",
                 *std::max_element(ref.force.begin(), ref.force.end()));
    std::string csv =
        "tolerance,sleep,frame_ms,frame_hz,cg_per_step,surface_rms_um,surface_max_um,force_max_"
        "diff_uN\n";
    for (double tol : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4, 1e-6})
      for (bool sleep : {false, true}) {
        const Run r = run(model, tol, sleep);
        const Eigen::ArrayXd d = (r.surface - ref.surface).rowwise().norm().array();
        double df = 0;
        for (std::size_t i = 0; i < r.force.size(); ++i)
          df = std::max(df, std::abs(r.force[i] - ref.force[i]));
        char line[256];
        std::snprintf(line, sizeof line, "%g,%d,%.4f,%.1f,%.2f,%.4f,%.4f,%.4f\n", tol, int(sleep),
                      r.frame_s * 1e3, 1.0 / r.frame_s, r.cg, std::sqrt(d.square().mean()) * 1e6,
                      d.maxCoeff() * 1e6, df * 1e6);
        csv += line;
        std::fputs(line, stderr);
      }
    if (out_path.empty()) {
      std::fputs(csv.c_str(), stdout);
    } else {
      std::ofstream(out_path) << csv;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "frame_accuracy: %s\n", e.what());
    return 1;
  }
}
