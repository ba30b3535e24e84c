// One 1 ms implicit Euler step of any model file, the way the servo loop steps it: drag 5/s,
// gravity, CG (block-Jacobi) to a relative residual TOL, part contacts on, and a capsule probe
// (5 mm shaft) pressing 1 mm past the sagged centre of the outermost free sphere of the largest
// tetrahedral part. The model first sags for 0.5 s with the probe away, then the probe presses
// for 0.3 s; then STEPS steps are timed one by one. Not a Google Benchmark: it reports the
// distribution (mean, p50, p99, max) and the CG iterations, for the scale issue's models (the
// bundled uterus, the VHF left adnexa, a pelvis-sized model: docs/benchmarks.md); also the mean
// time of contact detection within the step and how often the part-contact pair list was rebuilt.
//
//   bench_model_step MODEL.fsm [--law links|continuum] [--threads N] [--tolerance TOL]
//                    [--velocity-tolerance M_PER_S] [--steps N] [--no-probe]
//                    [--continuum-part NAME] [--element-tangent-quality Q]
//                    [--smoothing element|face|edge|node] [--gravity-y] [--no-simd]
//                    [--detection-margin F] [--adaptive-threads] [--nu NU] [--json]
//                    [--preconditioners] [--trace FILE] [--phases]
// --gravity-y: gravity along -y (the Visible Human data set's down) instead of -z.
// --no-simd: the scalar link loops (ForceModel::Options::simd = false).
// --detection-margin: collision::ContactOptions::detection_margin (0: penetrating spheres only).
// --adaptive-threads: Simulation::Options::adaptive_threads (the pool only while it is faster);
// the JSON's "pool_share" is the share of the timed steps that ran on the pool.
// --velocity-tolerance: ImplicitEulerIntegrator::Options::velocity_tolerance (0: the relative test
// alone).
// --trace FILE: a CSV file, a header row then one line per timed step: its index from 0, its time
// (us), CG iterations, kinetic energy (J) at its end and the number of contacts.
// --nu: every region's Poisson's ratio (the continuum law's; the JSON's "nu" is region 0's).
// --preconditioners: the step's matrix (contacts in) at the end of the timed steps ("held") and
// 110 ms after the probe was pressed in ("pressing"), with factors of the same 10 and 100 steps
// earlier and at rest, and its preconditioners compared (preconditioners.hpp), to CG's tolerance
// and to 1e-6: one JSON line each, printed with or without --json.
//
// --phases: after the timed steps, the step's parts each on their own at the state reached, the
// fastest of 15 rounds of 200 calls each (a shared machine's slow phases drop out): the force
// evaluation (once a step), the implicit preparation (an evaluation included), one product (once
// per CG iteration) and contact detection with its forces' collection; one line, or JSON with
// --json.
//
// --law continuum puts every tetrahedral part on the continuum law, or only NAME with
// --continuum-part.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fsm/collision/contact.hpp"
#include "fsm/fsm.hpp"
#include "fsm/implicit_euler_integrator.hpp"
#include "fsm/model_file.hpp"
#include "fsm_support/probe.hpp"
#include "preconditioners.hpp"

using namespace fsm;

int main(int argc, char** argv) {
  std::string path, law = "links", only, smoothing = "element", trace_path;
  int threads = 1, steps = 2000;
  double tolerance = 1e-3;
  double velocity_tolerance = ImplicitEulerIntegrator<double>::Options{}.velocity_tolerance;
  double element_tangent_quality = ForceModel<double>::Options{}.element_tangent_quality;
  double detection_margin = collision::ContactOptions<double>{}.detection_margin;
  std::optional<double> nu;  // unset: each region's own Poisson's ratio
  bool probe = true, json = false, gravity_y = false, simd = true, flutter_guard = true,
       extrapolate = true, reuse = true, adaptive = false, preconditioners = false, phases = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_model_step: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--law")
      law = value();
    else if (a == "--threads")
      threads = std::atoi(value().c_str());
    else if (a == "--tolerance")
      tolerance = std::atof(value().c_str());
    else if (a == "--velocity-tolerance") {
      velocity_tolerance = std::atof(value().c_str());
      if (!(velocity_tolerance >= 0)) {
        std::fprintf(stderr, "bench_model_step: --velocity-tolerance must be >= 0\n");
        return 2;
      }
    } else if (a == "--steps")
      steps = std::atoi(value().c_str());
    else if (a == "--continuum-part")
      only = value();
    else if (a == "--element-tangent-quality")
      element_tangent_quality = std::atof(value().c_str());
    else if (a == "--smoothing")
      smoothing = value();
    else if (a == "--gravity-y")
      gravity_y = true;
    else if (a == "--no-probe")
      probe = false;
    else if (a == "--no-simd")
      simd = false;
    else if (a == "--no-flutter-guard")
      flutter_guard = false;
    else if (a == "--no-extrapolation")
      extrapolate = false;
    else if (a == "--no-reuse-end-forces")
      reuse = false;
    else if (a == "--adaptive-threads")
      adaptive = true;
    else if (a == "--detection-margin")
      detection_margin = std::atof(value().c_str());
    else if (a == "--nu")
      nu = std::atof(value().c_str());
    else if (a == "--preconditioners")
      preconditioners = true;
    else if (a == "--phases")
      phases = true;
    else if (a == "--json")
      json = true;
    else if (a == "--trace")
      trace_path = value();
    else if (!a.empty() && a[0] != '-' && path.empty())
      path = a;
    else {
      std::fprintf(
          stderr,
          "usage: %s MODEL.fsm [--law links|continuum] [--threads N] [--tolerance TOL] "
          "[--velocity-tolerance M_PER_S] "
          "[--steps N] [--no-probe] [--continuum-part NAME] "
          "[--element-tangent-quality Q] [--smoothing element|face|edge|node] [--gravity-y] "
          "[--no-simd] [--no-flutter-guard] [--no-extrapolation] [--no-reuse-end-forces] "
          "[--detection-margin F] [--adaptive-threads] [--nu NU] [--json] [--preconditioners] "
          "[--trace FILE] [--phases]\n",
          argv[0]);
      return 2;
    }
  }
  if (path.empty() || (law != "links" && law != "continuum") || threads < 1 || steps < 1 ||
      !(tolerance > 0) || !(element_tangent_quality >= 0) ||
      (smoothing != "element" && smoothing != "face" && smoothing != "edge" &&
       smoothing != "node")) {
    std::fprintf(stderr,
                 "bench_model_step: a model file, --law links|continuum, --threads >= 1, "
                 "--steps >= 1, --tolerance > 0 and --smoothing element|face|edge|node\n");
    return 2;
  }
  try {
    const TissueModel<double> model = load_model(path);
    SphereModel<double> spheres = model.spheres;
    const Part* target = nullptr;
    if (nu)  // every region's Poisson's ratio (the continuum law's; the links ignore it)
      for (Index r = 0; r < spheres.num_regions(); ++r) {
        Material<double> m = spheres.region(r).material;
        m.poisson_ratio = *nu;
        spheres.set_region_material(r, m);
      }
    for (const Part& p : model.parts) {
      if (law == "continuum" && p.topology == Topology::tetrahedral &&
          (only.empty() || p.name == only))
        spheres.set_region_law(p.region, ForceLaw::continuum);
      if (p.topology == Topology::tetrahedral && (!target || p.num_nodes > target->num_nodes))
        target = &p;
    }
    if (!target) target = &model.parts.front();
    Simulation<double>::Options so;
    so.forces.drag = 5;
    so.forces.threads = threads;
    so.forces.simd = simd;
    so.forces.flutter_guard = flutter_guard;
    so.forces.reuse_end_forces = reuse;
    so.forces.element_tangent_quality = element_tangent_quality;
    so.forces.strain_smoothing = smoothing == "face"   ? StrainSmoothing::face
                                 : smoothing == "edge" ? StrainSmoothing::edge
                                 : smoothing == "node" ? StrainSmoothing::node
                                                       : StrainSmoothing::element;
    if (gravity_y) so.forces.gravity = Vector3<double>(0, -9.81, 0);
    so.divergence.max_substep_halvings = 2;  // as the demo and servo_latency
    so.adaptive_threads = adaptive;
    Simulation<double> sim(std::move(spheres), so);
    ImplicitEulerIntegrator<double>::Options io;
    io.tolerance = tolerance;
    io.velocity_tolerance = velocity_tolerance;
    io.extrapolate_warm_start = extrapolate;
    sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
    Eigen::SparseMatrix<double> A_rest;  // the step's matrix at rest, no contacts
    if (preconditioners) A_rest = bench::implicit_matrix(sim, 1e-3);
    collision::ContactOptions<double> contact_options;
    contact_options.detection_margin = detection_margin;
    collision::ContactSolver<double> contacts(sim.model(), sim.forces(), contact_options);
    support::CapsuleProbe cp{support::outermost_free_sphere(model.spheres, *target)};
    contacts.add_instrument(cp.instrument(-0.02));  // away while the model sags
    long diverged = 0, recovered = 0, diverged_before = 0;
    double detection_s = 0;  // the time in contact detection (ContactSolver::compute)
    auto step = [&] {
      const auto t0 = std::chrono::steady_clock::now();
      contacts.compute(sim.model(), sim.forces());
      detection_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const StepReport<double> r = sim.step(1e-3);
      contacts.collect(sim.forces());
      diverged += !r.advanced();
      recovered += r.status == StepStatus::recovered;
      return r;
    };
    diverged += support::sag_then_aim(sim, contacts, 0, cp);
    if (probe) cp.press(contacts, 0, cp.site.radius + 0.001);
    // --preconditioners: the step's matrix while the tissue still moves after the press (steps 10,
    // 100 and 110 of it: factors 100 and 10 steps old against the state at 110).
    std::vector<std::pair<int, Eigen::SparseMatrix<double>>> pressing_lagged;
    Eigen::SparseMatrix<double> A_pressing;
    auto assemble = [&] {
      contacts.compute(sim.model(), sim.forces());
      sim.forces().start_contacts(sim.model());
      return bench::implicit_matrix(sim, 1e-3);
    };
    for (int s = 0; s < 300; ++s) {
      if (preconditioners && (s == 10 || s == 100))
        pressing_lagged.emplace_back(s == 10 ? 100 : 10, assemble());
      if (preconditioners && s == 110) A_pressing = assemble();
      step();
    }
    diverged_before = diverged;  // while sagging and pressing
    diverged = recovered = 0;    // count the timed steps only
    std::vector<double> t(std::size_t(steps), 0.0);
    // --trace: one CSV line per timed step (its time, CG iterations, kinetic energy, contacts).
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> trace(nullptr, &std::fclose);
    if (!trace_path.empty()) {
      trace.reset(std::fopen(trace_path.c_str(), "w"));
      if (!trace) {
        std::fprintf(stderr, "bench_model_step: cannot write %s\n", trace_path.c_str());
        return 1;
      }
      std::fprintf(trace.get(), "step,us,cg_iterations,kinetic_energy_J,contacts\n");
    }
    long iterations = 0, on_pool = 0, unconverged = 0, gain_retries = 0;
    // The largest energy a timed step gained beyond its start energy and work, over the limit
    // past which a level is retried finer (DivergencePolicy::energy_gain_strain).
    double largest_gain = -std::numeric_limits<double>::infinity();
    Index probe_contacts = 0;
    const Index rebuilds_before = contacts.pair_list_rebuilds();
    detection_s = 0;
    // --preconditioners: the step's matrix 10 and 100 steps before the end, contacts in.
    std::vector<std::pair<int, Eigen::SparseMatrix<double>>> lagged;
    for (int s = 0; s < steps; ++s) {
      for (const int lag : {100, 10})
        if (preconditioners && s == steps - lag) lagged.emplace_back(lag, assemble());
      on_pool += sim.uses_pool() ? 1 : 0;
      const auto t0 = std::chrono::steady_clock::now();
      const StepReport<double> r = step();
      t[std::size_t(s)] =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      iterations += r.solver_iterations;
      unconverged += r.unconverged_solves;
      gain_retries += r.energy_gain_retries;
      if (r.advanced() && std::isfinite(r.energy_gain))
        largest_gain = std::max(largest_gain, double(r.energy_gain));
      if (trace)
        std::fprintf(trace.get(), "%d,%.2f,%d,%.6g,%d\n", s, t[std::size_t(s)] * 1e6,
                     r.solver_iterations,
                     sim.forces().kinetic_energy(sim.model(), sim.model().velocities()),
                     int(contacts.num_contacts()));
    }
    for (Index k = 0; k < contacts.num_contacts(); ++k)
      if (contacts.contacts()[k].instrument >= 0) ++probe_contacts;
    const double mean = [&] {
      double s = 0;
      for (double x : t) s += x;
      return s / double(t.size());
    }();
    std::sort(t.begin(), t.end());
    auto pct = [&](double q) {
      return t[std::min(t.size() - 1, std::size_t(q * double(t.size() - 1) + 0.5))];
    };
    const double it = double(iterations) / double(steps);
    const double gain_to_limit = sim.energy_gain_limit() > 0 && std::isfinite(largest_gain)
                                     ? largest_gain / sim.energy_gain_limit()
                                     : std::numeric_limits<double>::quiet_NaN();
    char gain[32] = "null";
    if (std::isfinite(gain_to_limit)) std::snprintf(gain, sizeof gain, "%.3g", gain_to_limit);
    if (json)
      std::printf(
          "{\"model\": \"%s\", \"spheres\": %d, \"links\": %d, \"tetrahedra\": %d, "
          "\"law\": \"%s\", \"threads\": %d, \"tolerance\": %g, \"velocity_tolerance\": %g, "
          "\"probe\": %s, "
          "\"probe_contacts\": %d, \"contacts\": %d, \"steps\": %d, \"mean_us\": %.1f, "
          "\"p50_us\": %.1f, \"p99_us\": %.1f, \"max_us\": %.1f, \"cg_iterations\": %.2f, "
          "\"unconverged_solves\": %ld, \"energy_gain_retries\": %ld, "
          "\"largest_energy_gain_to_limit\": %s, "
          "\"recovered\": %ld, \"diverged\": %ld, \"diverged_before_timing\": %ld, "
          "\"element_tangent_quality\": %g, \"element_tangents\": %d, \"fluttered\": %d, "
          "\"flutter_guard\": %s, \"extrapolated_warm_start\": %s, \"reuse_end_forces\": %s, "
          "\"gravity\": \"%s\", \"smoothing\": \"%s\", \"adaptive_threads\": %s, "
          "\"pool_share\": %.3f, \"links_partitioned\": %s, \"nu\": %g, "
          "\"detection_mean_us\": %.1f, \"pair_list_rebuilds\": %d}\n",
          path.c_str(), int(sim.model().num_nodes()), int(sim.model().num_links()),
          int(sim.model().num_tetrahedra()), law.c_str(), threads, tolerance, velocity_tolerance,
          probe ? "true" : "false", int(probe_contacts), int(contacts.num_contacts()), steps,
          mean * 1e6, pct(0.5) * 1e6, pct(0.99) * 1e6, t.back() * 1e6, it, unconverged,
          gain_retries, gain, recovered, diverged, diverged_before, element_tangent_quality,
          int(sim.forces().continuum_element_tangents()),
          int(sim.forces().continuum_fluttered_elements()), flutter_guard ? "true" : "false",
          extrapolate ? "true" : "false", reuse ? "true" : "false", gravity_y ? "-y" : "-z",
          smoothing.c_str(), adaptive ? "true" : "false", double(on_pool) / double(steps),
          sim.forces().links_partitioned() ? "true" : "false",
          sim.model().region(0).material.poisson_ratio, detection_s / double(steps) * 1e6,
          int(contacts.pair_list_rebuilds() - rebuilds_before));
    else
      std::printf(
          "%s: %d spheres, %d links, %d tetrahedra; %s law (%s strain), %d thread(s)%s, CG to %g; "
          "probe on '%s' (%d contacts of %d)\n  1 ms step: mean %.1f us, p50 %.1f, p99 "
          "%.1f, max %.1f; %.2f CG iterations; %ld steps retried as half steps (%ld levels for "
          "their energy gain; the largest gain %s of the limit), %ld diverged "
          "(%ld before timing); %d elements with the element tangent, %d of them fluttered; "
          "contact detection %.1f us a step, part-contact pair list rebuilt %d times\n",
          path.c_str(), int(sim.model().num_nodes()), int(sim.model().num_links()),
          int(sim.model().num_tetrahedra()), law.c_str(), smoothing.c_str(), threads,
          sim.forces().links_partitioned() ? " (links shared by node)" : "", tolerance,
          target->name.c_str(), int(probe_contacts), int(contacts.num_contacts()), mean * 1e6,
          pct(0.5) * 1e6, pct(0.99) * 1e6, t.back() * 1e6, it, recovered, gain_retries, gain,
          diverged, diverged_before, int(sim.forces().continuum_element_tangents()),
          int(sim.forces().continuum_fluttered_elements()), detection_s / double(steps) * 1e6,
          int(contacts.pair_list_rebuilds() - rebuilds_before));
    // "held": at the end of the timed steps, the probe held at its depth for 0.3 s + STEPS ms;
    // "pressing": 110 ms after the probe was pressed in, the tissue still moving.
    // Where the iterations are: block-Jacobi but with these groups of nodes solved exactly (each
    // part's diagonal block of A factored): the axis parts (chains); every part; every part but
    // the probed one (the largest tetrahedral part; the first part of a model without one).
    std::vector<std::vector<std::vector<Index>>> groupings(3);
    for (const Part& q : model.parts) {
      std::vector<Index> g(std::size_t(q.num_nodes));
      for (Index i = 0; i < q.num_nodes; ++i) g[std::size_t(i)] = q.first_node + i;
      if (q.topology == Topology::axis) groupings[0].push_back(g);
      groupings[1].push_back(g);
      if (&q != target) groupings[2].push_back(g);
    }
    auto study = [&](const char* phase, const Eigen::SparseMatrix<double>& A,
                     const std::vector<std::pair<int, Eigen::SparseMatrix<double>>>& lags_of) {
      for (const double tol : {tolerance, 1e-6}) {
        const bench::PreconditionerStudy p =
            bench::study_preconditioners(A_rest, A, tol, lags_of, 50, groupings);
        std::string lags;
        for (const auto& [lag, n] : p.it_cholesky_lagged)
          lags += ", \"it_cholesky_lag" + std::to_string(lag) + "\": " + std::to_string(n);
        std::printf(
            "{\"model\": \"%s\", \"law\": \"%s\", \"phase\": \"%s\", \"preconditioners_to\": %g, "
            "\"dofs\": %.0f, "
            "\"it_jacobi\": %d, \"it_block_jacobi\": %d, \"it_incomplete_cholesky\": %d, "
            "\"it_cholesky_rest\": %d, \"it_cholesky_now\": %d, \"it_cholmod_now\": %d, "
            "\"nnz_A\": %.0f, \"nnz_L\": %.0f, \"product_us\": %.1f, \"factor_us\": %.1f, "
            "\"cholesky_apply_us\": %.1f, \"cholmod_factor_us\": %.1f, "
            "\"cholmod_apply_us\": %.1f, \"incomplete_cholesky_apply_us\": %.1f%s, "
            "\"it_axis_parts_exact\": %d, \"it_parts_exact\": %d, "
            "\"it_parts_but_largest_exact\": %d, "
            "\"step_mean_us\": %.1f, \"step_cg_iterations\": %.2f}\n",
            path.c_str(), law.c_str(), phase, tol, p.dofs, p.it_jacobi, p.it_block_jacobi,
            p.it_incomplete_cholesky, p.it_cholesky_rest, p.it_cholesky_now, p.it_cholmod_now,
            p.nnz_A, p.nnz_L, p.product_us, p.factor_us, p.cholesky_apply_us, p.cholmod_factor_us,
            p.cholmod_apply_us, p.incomplete_cholesky_apply_us, lags.c_str(), p.it_groups[0],
            p.it_groups[1], p.it_groups[2], mean * 1e6, it);
      }
    };
    if (preconditioners) {
      study("held", assemble(), lagged);
      study("pressing", A_pressing, pressing_lagged);
    }
    if (phases) {
      auto fastest_us = [](auto&& call) {
        double best = std::numeric_limits<double>::infinity();
        for (int round = 0; round < 15; ++round) {
          const auto t0 = std::chrono::steady_clock::now();
          for (int k = 0; k < 200; ++k) call();
          best = std::min(
              best,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / 200.0);
        }
        return best * 1e6;
      };
      SphereModel<double>& m = sim.model();
      ForceModel<double>& f = sim.forces();
      const Index n = m.num_nodes();
      Positions<double> forces(n, 3), rhs(n, 3), diagonal(n, 3), p(n, 3), y(n, 3);
      p = m.velocities();  // a direction with the model's own scales
      std::vector<double> blocks(std::size_t(ForceModel<double>::implicit_block_size) *
                                 std::size_t(m.num_links()));
      const double evaluate_us =
          fastest_us([&] { f.evaluate(m, m.positions(), m.velocities(), forces); });
      const double prepare_us = fastest_us([&] {
        f.prepare_implicit(m, 1e-3, JacobianForm::definite, blocks.data(), rhs, diagonal);
      });
      const double product_us = fastest_us([&] { f.apply_implicit(m, blocks.data(), p, y); });
      const double contact_us = fastest_us([&] {
        contacts.compute(m, f);
        contacts.collect(f);
      });
      if (json)
        std::printf(
            "{\"model\": \"%s\", \"law\": \"%s\", \"evaluate_us\": %.1f, "
            "\"prepare_implicit_us\": %.1f, \"product_us\": %.1f, "
            "\"contact_us\": %.1f}\n",
            path.c_str(), law.c_str(), evaluate_us, prepare_us, product_us, contact_us);
      else
        std::printf(
            "  phases (fastest of 15 rounds): evaluate %.1f us, prepare_implicit %.1f us "
            "(an evaluation included), one product %.1f us, contact detection %.1f us\n",
            evaluate_us, prepare_us, product_us, contact_us);
    }
    if (probe && probe_contacts == 0) {
      std::fprintf(stderr, "bench_model_step: the probe does not touch the tissue\n");
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_model_step: %s\n", e.what());
    return 1;
  }
}
