// Servo-loop timing with the whole uterus model stepped in the loop: a scripted probe presses the
// body, the fibroid side, an ovary and a tube while the loop runs in real time at 1 kHz. Prints
// the period statistics (p50, p99, max, error), missed deadlines, the step time and the watchdog
// and stall figures. Not a Google Benchmark: one long real-time run.
//
//   servo_latency [--seconds 30] [--threading lockstep|decoupled] [--integrator NAME]
//                 [--json] [--stall-test] [--stress [N]] [--realtime [PRIORITY]]
//
// --stress runs N (default 1) competing busy processes for the run (docs/haptics.md).
// --realtime runs the loop's threads under SCHED_FIFO at PRIORITY (default 80) where the system
// allows it (ServoOptions::realtime_priority; the JSON says whether it was granted).

#include <chrono>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>

#include "fsm/builder/builder.hpp"
#include "fsm/haptics/scripted_device.hpp"
#include "fsm/haptics/servo_loop.hpp"
#include "fsm/implicit_euler_integrator.hpp"
#include "fsm_support/model_cache.hpp"
#include "fsm_support/probe.hpp"
#include "fsm_support/stress.hpp"

using namespace fsm;
using namespace fsm::haptics;
using V3 = Vector3<double>;

namespace {

// A waypoint 1 mm into the part's outermost sphere, along the outward direction, and one 15 mm
// outside it.
std::pair<V3, V3> approach(const SphereModel<double>& m, const Part& p) {
  const support::ProbeSite site = support::outermost_free_sphere(m, p);
  const Index best = site.sphere;
  const V3 x = site.centre, out = site.outward;
  const double r = m.radii()[best] + 0.003;  // sphere radius + the probe's
  return {x + out * (r - 0.002), x + out * (r + 0.015)};
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 30;
  std::string threading = "lockstep", integrator = "implicit_euler";
  double tolerance = 1e-3;
  bool json = false, stall_test = false;
  int stress = 0;
  int realtime = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seconds" && i + 1 < argc)
      seconds = std::atof(argv[++i]);
    else if (a == "--threading" && i + 1 < argc)
      threading = argv[++i];
    else if (a == "--integrator" && i + 1 < argc)
      integrator = argv[++i];
    else if (a == "--json")
      json = true;
    else if (a == "--stall-test")
      stall_test = true;
    else if (a == "--stress") {
      stress = 1;
      if (i + 1 < argc && argv[i + 1][0] != '-') stress = std::atoi(argv[++i]);
      if (stress < 1 || stress > 64) {
        std::fprintf(stderr, "servo_latency: --stress takes 1 to 64 processes\n");
        return 2;
      }
    } else if (a == "--realtime") {
      realtime = 80;
      if (i + 1 < argc && argv[i + 1][0] != '-') realtime = std::atoi(argv[++i]);
      if (realtime < 2 || realtime > 98) {
        std::fprintf(stderr, "servo_latency: --realtime takes a priority from 2 to 98\n");
        return 2;
      }
    } else {
      std::fprintf(stderr,
                   "usage: %s [--seconds S] [--threading lockstep|decoupled] [--integrator NAME] "
                   "[--json] [--stall-test] [--stress [N]] [--realtime [PRIORITY]]\n",
                   argv[0]);
      return 2;
    }
  }
  try {
    const TissueModel<double>& model = support::bundled_uterus(
        [](const std::string& s) { return build::build_model(s); }, "servo_latency");
    Simulation<double>::Options so;
    so.integrator = integrator;
    so.forces.drag = 5;
    // A step that fails the energy check is retried as two (then four) half steps before it counts
    // as diverged (and the servo loop's watchdog zeroes the force): a thin ligament flung by the
    // probe gained energy in one linearised 1 ms step (docs/haptics.md, "Under load").
    so.divergence.max_substep_halvings = 2;
    Simulation<double> sim(model.spheres, so);
    if (integrator == "implicit_euler") {
      ImplicitEulerIntegrator<double>::Options io;
      io.tolerance = tolerance;
      sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
    }
    collision::ContactSolver<double> contacts(sim.model(), sim.forces());
    collision::Instrument<double> tool;
    tool.name = "probe";
    tool.shape = collision::SphereShape<double>{0.003};
    const Index k = contacts.add_instrument(tool);

    // The script: visit each part (2 s per visit: approach, press, hold, retreat), repeated.
    std::vector<Waypoint> w;
    double t = 0;
    const char* parts[] = {"body",      "fibroid",        "ovary_left",
                           "tube_left", "ligament_right", "ovary_right"};
    auto [p0_in, p0_out] = approach(sim.model(), model.part(parts[0]));
    w.push_back({t, p0_out, Eigen::Quaterniond::Identity(), 0});
    for (int v = 0; t < seconds; ++v) {
      auto [in, out] = approach(sim.model(), model.part(parts[v % 6]));
      w.push_back({t += 0.5, out, Eigen::Quaterniond::Identity(), 0});
      w.push_back({t += 0.5, in, Eigen::Quaterniond::Identity(), 1});
      w.push_back({t += 0.5, in, Eigen::Quaterniond::Identity(), 1});
      w.push_back({t += 0.5, out, Eigen::Quaterniond::Identity(), 0});
    }
    ScriptedHapticDevice device(w, DeviceLimits{}, std::size_t(seconds * 1000) + 16);
    ServoOptions o;
    o.threading = threading == "decoupled" ? ServoOptions::Threading::decoupled
                                           : ServoOptions::Threading::lockstep;
    o.max_recorded_ticks = std::size_t(seconds * 1000) + 16;
    o.realtime_priority = realtime;
    ServoLoop loop(sim, contacts, k, device, o);

    // Stall test: the step stalls 20 ms at 5 s; how long until the device is commanded zero?
    std::chrono::steady_clock::time_point stall_begin{};
    double zero_after = -1;
    if (stall_test)
      loop.set_step_hook([&](double ts) {
        if (std::abs(ts - 5.0) < 1e-9) {
          stall_begin = std::chrono::steady_clock::now();
          const auto end = stall_begin + std::chrono::milliseconds(20);
          while (std::chrono::steady_clock::now() < end) {
            if (zero_after < 0 && loop.tripped())
              zero_after =
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - stall_begin)
                      .count();
            std::this_thread::sleep_for(std::chrono::microseconds(20));
          }
        }
      });
    const support::BusyProcesses busy(stress);
    const auto wall0 = std::chrono::steady_clock::now();
    loop.run_real_time(seconds);
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    const ServoStats s = loop.stats();
    if (json) {
      std::printf(
          "{\"seconds\": %.3f, \"threading\": \"%s\", \"integrator\": \"%s\", \"spheres\": %d, "
          "\"ticks\": %zu, "
          "\"steps\": %zu, \"missed_deadlines\": %zu, \"period_p50_us\": %.2f, \"period_p99_us\": "
          "%.2f, "
          "\"period_max_us\": %.2f, \"period_error_p99_us\": %.2f, \"period_error_max_us\": %.2f, "
          "\"step_p50_us\": %.2f, \"step_p99_us\": %.2f, \"step_max_us\": %.2f, "
          "\"watchdog_trips\": %zu, "
          "\"diverged_steps\": %zu, \"peak_force_N\": %.4f, \"stall_zero_after_us\": %.1f, "
          "\"stress_processes\": %d, \"realtime_priority\": %d, \"realtime\": %s}\n",
          wall, threading.c_str(), integrator.c_str(), int(sim.model().num_nodes()), s.ticks,
          s.steps, s.missed_deadlines, s.period_p50 * 1e6, s.period_p99 * 1e6, s.period_max * 1e6,
          s.period_error_p99 * 1e6, s.period_error_max * 1e6, s.step_p50 * 1e6, s.step_p99 * 1e6,
          s.step_max * 1e6, s.watchdog_trips, s.diverged_steps, s.peak_force, zero_after * 1e6,
          busy.count(), realtime, s.realtime ? "true" : "false");
    } else {
      std::printf("servo loop, %s, %s, uterus %d spheres, %.1f s wall, %d competing process(es)\n",
                  threading.c_str(), integrator.c_str(), int(sim.model().num_nodes()), wall,
                  busy.count());
      std::printf("  ticks %zu, steps %zu, missed deadlines %zu\n", s.ticks, s.steps,
                  s.missed_deadlines);
      std::printf(
          "  period p50 %.1f us, p99 %.1f us, max %.1f us; |error| p99 %.1f us, max %.1f us\n",
          s.period_p50 * 1e6, s.period_p99 * 1e6, s.period_max * 1e6, s.period_error_p99 * 1e6,
          s.period_error_max * 1e6);
      std::printf("  step (contacts + simulation) p50 %.1f us, p99 %.1f us, max %.1f us\n",
                  s.step_p50 * 1e6, s.step_p99 * 1e6, s.step_max * 1e6);
      std::printf("  watchdog trips %zu, diverged steps %zu, peak force %.3f N\n", s.watchdog_trips,
                  s.diverged_steps, s.peak_force);
      if (realtime > 0)
        std::printf("  real-time priority %d: %s\n", realtime,
                    s.realtime ? "granted" : "refused by the system (default scheduler)");
      if (stall_test)
        std::printf("  injected 20 ms stall: force zeroed after %.0f us\n", zero_after * 1e6);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "servo_latency: %s\n", e.what());
    return 1;
  }
}
