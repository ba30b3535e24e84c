// fsm-poke-block: builds the paper's 20 x 20 x 10 mm tissue sample as a sphere block, clamps its
// bottom, presses a 4 x 4 mm patch of its top with a force ramped up and held, and reports what
// happened: indentation, energy, step status and the cost of a step.
//
//   fsm-poke-block [--integrator NAME] [--spacing M] [--force N] [--seconds S] [--dt S]
//                  [--threads N] [--float]

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "fsm/fsm.hpp"
#include "fsm_support/paper.hpp"

namespace {

struct Args {
  std::string integrator = "implicit_euler";
  double spacing = 0.002;  // m: 10 x 10 x 5 cells, 726 spheres (uterus-sized)
  double force = 0.1;      // N on the patch (6 kPa)
  double seconds = 1.0;
  double dt = 1e-3;
  int threads = 1;
  bool single = false;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "fsm-poke-block: %s\n"
               "usage: fsm-poke-block [--integrator %s] [--spacing M] [--force N] [--seconds S]\n"
               "                      [--dt S] [--threads N] [--float]\n",
               why, "implicit_euler|improved_euler|heun|symplectic_euler");
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) usage(("missing value after " + k).c_str());
      return argv[++i];
    };
    if (k == "--integrator")
      a.integrator = value();
    else if (k == "--spacing")
      a.spacing = std::atof(value());
    else if (k == "--force")
      a.force = std::atof(value());
    else if (k == "--seconds")
      a.seconds = std::atof(value());
    else if (k == "--dt")
      a.dt = std::atof(value());
    else if (k == "--threads")
      a.threads = std::atoi(value());
    else if (k == "--float")
      a.single = true;
    else if (k == "--help" || k == "-h")
      usage("help");
    else
      usage(("unknown option " + k).c_str());
  }
  if (!(a.spacing > 0) || !(a.dt > 0) || !(a.seconds > 0))
    usage("spacing, dt and seconds must be positive");
  return a;
}

template <typename Scalar>
int run(const Args& a) {
  using namespace fsm;
  // The paper's tissue (docs/physics.md section 10): 13.15 kPa small-strain and 68.38 kPa
  // large-strain moduli, 10.26 Pa s, switching at 10 % (ours: the paper does not say).
  const Material<Scalar> tissue = support::paper::bilinear_tissue<Scalar>();

  const double W = 0.020, H = 0.010;
  const Eigen::Vector3i cells(int(std::lround(W / a.spacing)), int(std::lround(W / a.spacing)),
                              int(std::lround(H / a.spacing)));
  const Scalar h = Scalar(W / cells.x());
  SphereModel<Scalar> model;
  const Index region = model.add_region("sample", tissue);
  add_tetrahedral_part(model, make_cube_lattice(Vector3<Scalar>::Zero().eval(), cells, h), region,
                       h / 2);
  std::vector<Index> patch;
  const double top = cells.z() * double(h);
  for (Index i = 0; i < model.num_nodes(); ++i) {
    const auto p = model.rest_positions().row(i);
    if (double(p.z()) < 1e-9) model.set_fixed(i);
    if (double(p.z()) > top - 1e-9 && std::abs(double(p.x()) - W / 2) <= 0.002 + 1e-9 &&
        std::abs(double(p.y()) - W / 2) <= 0.002 + 1e-9)
      patch.push_back(i);
  }

  typename Simulation<Scalar>::Options opt;
  opt.integrator = a.integrator;
  opt.forces.threads = a.threads;
  opt.divergence.max_substep_halvings = 4;
  Simulation<Scalar> sim(std::move(model), opt);

  std::printf("libfsm %s: %s block %.0f x %.0f x %.0f mm, %d spheres (%d fixed), %d links, %s\n",
              fsm::version, a.single ? "float" : "double", W * 1e3, W * 1e3, H * 1e3,
              sim.model().num_nodes(), sim.model().num_fixed(), sim.model().num_links(),
              a.integrator.c_str());
  std::printf("highest eigenfrequency <= %.0f rad/s; stable step of %s: %.3g ms; dt = %.3g ms\n",
              double(sim.spectral_bound().omega_max), a.integrator.c_str(),
              1e3 * double(sim.stable_time_step()), 1e3 * a.dt);
  std::printf("pressing %zu top spheres (4 x 4 mm) with up to %.2f N, ramped over %.2f s\n\n",
              patch.size(), a.force, 0.5 * a.seconds);
  std::printf("%8s %9s %12s %12s %12s %10s\n", "t (s)", "F (N)", "indent (mm)", "energy (mJ)",
              "work (mJ)", "status");

  const int steps = int(std::lround(a.seconds / a.dt));
  const int report_every = std::max(1, steps / 10);
  double step_seconds = 0, worst_step = 0, indent = 0;
  int diverged = 0, recovered = 0;
  auto patch_indent = [&] {
    double s = 0;
    for (Index i : patch)
      s += double(sim.model().rest_positions()(i, 2) - sim.model().positions()(i, 2));
    return s / double(patch.size());
  };
  for (int s = 1; s <= steps; ++s) {
    const double t = s * a.dt;
    const double F = a.force * std::min(1.0, t / (0.5 * a.seconds));
    for (Index i : patch) sim.external_forces()(i, 2) = Scalar(-F / double(patch.size()));
    const auto t0 = std::chrono::steady_clock::now();
    const StepReport<Scalar> r = sim.step(Scalar(a.dt));
    const double cost =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    step_seconds += cost;
    worst_step = std::max(worst_step, cost);
    diverged += r.status == StepStatus::diverged;
    recovered += r.status == StepStatus::recovered;
    indent = patch_indent();
    if (s % report_every == 0 || s == steps) {
      const auto e = sim.energy();
      std::printf("%8.3f %9.3f %12.4f %12.4f %12.4f %10s\n", t, F, indent * 1e3,
                  double(e.total()) * 1e3, double(e.external_work) * 1e3, to_string(r.status));
    }
  }
  const auto e = sim.energy();
  std::printf("\nfinal indentation %.4f mm under %.2f N: apparent patch stiffness %.1f N/m\n",
              indent * 1e3, a.force, a.force / indent);
  std::printf("energy %.4f mJ of %.4f mJ put in by the load (damping took the rest)\n",
              double(e.total()) * 1e3, double(e.budget()) * 1e3);
  std::printf(
      "%d steps: mean %.1f us, worst %.1f us per step (%.0f steps/s); %d recovered by "
      "sub-stepping, %d rolled back\n",
      steps, 1e6 * step_seconds / steps, 1e6 * worst_step, steps / step_seconds, recovered,
      diverged);
  return diverged == 0 && indent > 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  try {
    return a.single ? run<float>(a) : run<double>(a);
  } catch (const fsm::Error& e) {
    std::fprintf(stderr, "fsm-poke-block: %s\n", e.what());
    return 1;
  }
}
