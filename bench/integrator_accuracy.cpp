// Speed against accuracy for the four integrators: the paper's tissue sample (20 x 20 x 10 mm,
// 726 spheres, bilinear Voigt tissue) pressed on a 4 x 4 mm patch with a force ramped to 0.1 N in
// 50 ms and held, simulated for 100 ms at a range of steps. The error is the largest RMS position
// difference over the nodes, at 25, 50, 75 and 100 ms, from a reference run with Heun at 1 us.
// The cost is wall time per simulated second on one thread, the fastest of three runs.
//
//   integrator_accuracy [--out FILE.csv]     (prints the table; writes CSV for docs/charts.py)

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "common.hpp"

namespace {

using namespace fsm;

struct Run {
  std::vector<Positions<double>> samples;
  double seconds = 0;
  bool diverged = false;
};

SphereModel<double> sample_block(std::vector<Index>& patch) {
  const double h = 0.002;
  SphereModel<double> model;
  add_tetrahedral_part(model, make_cube_lattice<double>(Vector3<double>::Zero(), {10, 10, 5}, h),
                       model.add_region("sample", support::paper::bilinear_tissue<double>()),
                       h / 2);
  for (Index i = 0; i < model.num_nodes(); ++i) {
    const auto p = model.rest_positions().row(i);
    if (p.z() < 1e-9) model.set_fixed(i);
    if (p.z() > 0.01 - 1e-9 && std::abs(p.x() - 0.01) <= 0.002 + 1e-9 &&
        std::abs(p.y() - 0.01) <= 0.002 + 1e-9)
      patch.push_back(i);
  }
  return model;
}

Run simulate(const std::string& integrator, double dt) {
  std::vector<Index> patch;
  SphereModel<double> model = sample_block(patch);
  Simulation<double>::Options o;
  o.integrator = integrator;
  Simulation<double> sim(std::move(model), o);
  const double T = 0.1, ramp = 0.05, force = 0.1;
  const int steps = int(std::lround(T / dt));
  const int every = steps / 4;
  Run run;
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 1; s <= steps; ++s) {
    // The load is held over a step: take its value at the step's midpoint, so the forcing itself
    // is second-order accurate and the integrators' own orders show.
    const double F = force * std::min(1.0, (s - 0.5) * dt / ramp);
    for (Index i : patch) sim.external_forces()(i, 2) = -F / double(patch.size());
    if (!sim.step(dt).advanced()) {
      run.diverged = true;
      break;
    }
    if (s % every == 0) run.samples.push_back(sim.model().positions());
  }
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / T;
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  const char* out = nullptr;
  for (int i = 1; i + 1 < argc; ++i)
    if (std::strcmp(argv[i], "--out") == 0) out = argv[i + 1];
  const Run reference = simulate("heun", 1e-6);
  std::FILE* csv = out ? std::fopen(out, "w") : nullptr;
  if (out && !csv) {
    std::fprintf(stderr, "cannot write %s\n", out);
    return 1;
  }
  if (csv) std::fprintf(csv, "integrator,dt_s,error_m,cost_s_per_s,status\n");
  std::printf("%-18s %10s %14s %18s %10s\n", "integrator", "dt (ms)", "error (um)",
              "cost (ms per s)", "status");
  for (const std::string name : {"improved_euler", "heun", "symplectic_euler", "implicit_euler"}) {
    for (double dt : {1e-5, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3}) {
      // Wall time is the fastest of three runs (the machine is shared); the states are identical.
      Run r = simulate(name, dt);
      for (int rep = 0; rep < 2 && !r.diverged; ++rep)
        r.seconds = std::min(r.seconds, simulate(name, dt).seconds);
      double error = 0;
      if (!r.diverged)
        for (std::size_t k = 0; k < r.samples.size(); ++k)
          error = std::max(
              error,
              std::sqrt((r.samples[k] - reference.samples[k]).rowwise().squaredNorm().mean()));
      const char* status = r.diverged ? "diverged" : "ok";
      std::printf("%-18s %10.3f %14.4g %18.4g %10s\n", name.c_str(), dt * 1e3, error * 1e6,
                  r.seconds * 1e3, status);
      if (csv) std::fprintf(csv, "%s,%g,%g,%g,%s\n", name.c_str(), dt, error, r.seconds, status);
    }
  }
  if (csv) std::fclose(csv);
  return 0;
}
