// fsm-demo: the main job. Loads the bundled procedural uterus (building and caching it on first
// run), prints a Table-1-like report, then runs a scripted laparoscopic session through the whole
// pipeline — the 1 kHz servo loop (scripted device, virtual coupling, contacts, implicit Euler) on
// one thread and the render side (snapshots, skinning) on another — and reports frame and servo
// statistics. Writes PNG renders (rest, deformed), the frame-rate plot and the deformed surface.
//
//   fsm-demo [--seconds S] [--out DIR] [--model FILE.fsm|SCENE.json] [--json] [--no-render]
//            [--stress [N]] [--realtime [PRIORITY]] [--threading lockstep|decoupled]
//            [--export DIR [--export-hz HZ]] [--contact vertices|faces]
//            [--energy-gain-strain STRAIN] [--help] [--version]
//
// Field names of --json: docs/demo.md.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <numeric>
#include <string>
#include <thread>

#include "fsm/builder/builder.hpp"
#include "fsm/collision/triangle_bvh.hpp"
#include "fsm/fsm.hpp"
#include "fsm/haptics/scripted_device.hpp"
#include "fsm/haptics/servo_loop.hpp"
#include "fsm/implicit_euler_integrator.hpp"
#include "fsm/model_file.hpp"
#include "fsm/vtk_export.hpp"
#include "fsm_support/cli.hpp"
#include "fsm_support/model_cache.hpp"
#include "fsm_support/probe.hpp"
#include "fsm_support/stress.hpp"
#include "gl_scene.hpp"
#include "myomectomy.hpp"
#include "offscreen.hpp"

using namespace fsm;
using namespace fsm::haptics;
using V3 = Vector3<double>;

namespace {

struct Args {
  double seconds{21};
  std::string out{"fsm-demo-out"};
  std::string model;
  bool json{false};
  bool render{true};
  int stress{0};    // competing busy processes during the session
  int realtime{0};  // SCHED_FIFO priority of the servo loop's threads; 0: none
  std::string threading{"lockstep"};
  std::string export_dir;  // ParaView time series; empty: none
  double export_hz{10};
  std::string scenario{"probing"};
  double capsule_tear{0.2};
  std::string contact{"faces"};  // how the probe meets tetrahedral parts
  std::string law{"scene"};      // the tetrahedral parts' force law: scene, links or continuum
  // DivergencePolicy::energy_gain_strain of the probing session (0: off)
  double energy_gain_strain{DivergencePolicy<double>{}.energy_gain_strain};
};

// Parses the command line (CLI11): returns the exit status when the program should stop there
// (--help, --version: 0; a usage error: 2), else -1.
int parse(int argc, char** argv, Args& a) {
  CLI::App app(
      "The main job: loads a model (default: the bundled uterus, built and cached on first run), "
      "then runs a scripted probing session through the 1 kHz servo loop and reports frame and "
      "servo statistics.",
      "fsm-demo");
  support::add_version_flag(app);
  app.add_option("--seconds", a.seconds,
                 "simulated session length (s); every part is probed once per session")
      ->check(CLI::Range(2.0, 3600.0))
      ->capture_default_str();
  app.add_option("--out", a.out, "where renders, the plot, the deformed OBJ and stats.json go")
      ->capture_default_str();
  app.add_option("--model", a.model,
                 "a model file (.fsm), or a scene (.json) to build; any parts: each is probed");
  app.add_flag("--json", a.json, "print the statistics as JSON (docs/demo.md)");
  app.add_flag("!--no-render", a.render, "skip the PNG renders");
  app.add_option("--stress", a.stress, "run N competing busy processes during the session")
      ->expected(0, 1)
      ->default_str("1")
      ->check(CLI::Range(1, 64));
  app.add_option("--realtime", a.realtime,
                 "run the servo loop's threads under SCHED_FIFO at PRIORITY where the system "
                 "allows it (root, CAP_SYS_NICE or ulimit -r); stats say whether it was granted")
      ->expected(0, 1)
      ->default_str("80")
      ->check(CLI::Range(2, 98));
  app.add_option("--threading", a.threading,
                 "lockstep: one thread ticks the device and steps (deterministic); decoupled: the "
                 "tick runs on its own thread against a local contact model and the simulation "
                 "on another (docs/haptics.md)")
      ->check(CLI::IsMember({"lockstep", "decoupled"}))
      ->capture_default_str();
  app.add_option("--contact", a.contact,
                 "how the probe meets tetrahedral parts: vertices (their sphere centres) or faces "
                 "(sample points on their boundary faces; ContactOptions::face_contact)")
      ->check(CLI::IsMember({"vertices", "faces"}))
      ->capture_default_str();
  app.add_option("--law", a.law,
                 "the force law of every tetrahedral part: continuum (neo-Hookean tetrahedra with "
                 "the material's E and Poisson's ratio), links (the paper's Voigt network) or "
                 "scene (each part's own, as its scene or model file says; docs/physics.md)")
      ->check(CLI::IsMember({"scene", "links", "continuum"}))
      ->capture_default_str();
  app.add_option(
         "--scenario", a.scenario,
         "probing: the default session; myomectomy: incise around the fibroid, grasp it and "
         "pull until it is free (the bundled uterus; docs/demo.md)")
      ->check(CLI::IsMember({"probing", "myomectomy"}))
      ->capture_default_str();
  app.add_option("--capsule-tear", a.capsule_tear,
                 "myomectomy: the strain past which the fibroid's capsule tears")
      ->check(CLI::Range(0.01, 10.0))
      ->capture_default_str();
  app.add_option("--energy-gain-strain", a.energy_gain_strain,
                 "probing: an implicit step that gains more energy than every link and element "
                 "strained this much is retried as sub-steps (0: off; docs/physics.md section 7)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--export", a.export_dir,
                 "write the session as a ParaView time series (DIR/fsm.pvd: spheres, links, "
                 "tetrahedra and the render surface)");
  app.add_option("--export-hz", a.export_hz, "states per simulated second in --export")
      ->check(CLI::Range(1.0, 1000.0))
      ->capture_default_str();
  return support::parse_command_line(app, argc, argv);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5))];
}

void write_obj(const std::string& path, const TissueModel<double>& model,
               const Positions<double>& v) {
  std::ofstream f(path);
  if (!f) throw Error(path, "OBJ", "cannot write");
  f << "# fsm-demo: the deformed surface of " << model.name << " (m)\n";
  for (Index i = 0; i < v.rows(); ++i)
    f << "v " << v(i, 0) << ' ' << v(i, 1) << ' ' << v(i, 2) << '\n';
  for (const Part& p : model.parts) {
    if (p.surface < 0) continue;
    const auto& s = model.skin.surfaces[std::size_t(p.surface)];
    f << "g " << p.name << '\n';
    for (Index k = s.first_face; k < s.first_face + s.num_faces; ++k)
      f << "f " << model.skin.rest.faces(k, 0) + 1 << ' ' << model.skin.rest.faces(k, 1) + 1 << ' '
        << model.skin.rest.faces(k, 2) + 1 << '\n';
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (const int status = parse(argc, argv, args); status >= 0) return status;
  try {
    support::make_dirs(args.out);
    const support::OpenedModel opened = support::open_model(
        args.model, support::source_data_dir(),
        [](const std::string& scene) { return build::build_model(scene); }, "fsm-demo");
    const TissueModel<double>& model = opened.model;
    const std::string& source = opened.source;
    const bool built = opened.built;
    const double build_s = opened.build_seconds;
    if (args.scenario == "myomectomy") {
      examples::ScenarioOptions so;
      so.out = args.out;
      so.json = args.json;
      so.render = args.render;
      so.stress = args.stress;
      so.realtime = args.realtime;
      so.capsule_tear = args.capsule_tear;
      so.law = args.law;
      return examples::run_myomectomy(model, so);
    }

    // ---- Table-1-like report.
    const std::pair<const char*, int> paper[] = {
        {"body", 517},        {"fibroid", 39},       {"ovary_left", 29}, {"ovary_right", 29},
        {"ligament_left", 9}, {"ligament_right", 9}, {"tube_left", 31},  {"tube_right", 31}};
    if (!args.json) {
      std::printf("fsm-demo: %s (%s%s)\n", model.name.c_str(), source.c_str(),
                  built ? (", built in " + std::to_string(build_s).substr(0, 4) + " s").c_str()
                        : ", cached");
      std::printf("  %-15s %-12s %8s %8s %10s %8s\n", "part", "filling", "spheres", "links",
                  "radius mm", "paper");
      for (const Part& p : model.parts) {
        int ref = 0;
        for (const auto& [n, c] : paper)
          if (p.name == n) ref = c;
        std::printf("  %-15s %-12s %8d %8d %10.2f %8d\n", p.name.c_str(), to_string(p.topology),
                    int(p.num_nodes), int(p.num_links), p.radius * 1e3, ref);
      }
      std::printf("  %-15s %-12s %8d %8d %10s %8d\n", "total", "", int(model.spheres.num_nodes()),
                  int(model.spheres.num_links()), "", 694);
    }

    // ---- The session: simulation, contacts, instrument, scripted device, servo loop.
    Simulation<double>::Options so;
    so.forces.drag = 5;  // the surrounding tissue and fluid (docs/physics.md section 9)
    // A step that fails the energy check is retried as two (then four) half steps before it counts
    // as diverged (and the servo loop's watchdog zeroes the force): a thin ligament flung by the
    // probe gained energy in one linearised 1 ms step (docs/haptics.md, "Under load").
    so.divergence.max_substep_halvings = 2;
    so.divergence.energy_gain_strain = args.energy_gain_strain;
    SphereModel<double> spheres = model.spheres;
    const std::string law = examples::apply_law(model, spheres, args.law);
    Simulation<double> sim(std::move(spheres), so);
    // CG to a relative tolerance of 1e-3 (ImplicitEulerIntegrator::Options::tolerance): against
    // 1e-9 the surface differs by well under a micrometre after 3 s of probing, at a fraction of
    // the iterations of 1e-6 (docs/benchmarks.md, whole frame).
    ImplicitEulerIntegrator<double>::Options io;
    io.tolerance = 1e-3;
    sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
    collision::ContactOptions<double> co;
    co.face_contact = args.contact == "faces";
    collision::ContactSolver<double> contacts(sim.model(), sim.forces(), co);
    const double shaft_r = 0.0025, half = 0.02;
    collision::Instrument<double> tool;
    tool.name = "probe";
    tool.shape = collision::CapsuleShape<double>{shaft_r, half};
    const Index k = contacts.add_instrument(tool);

    // The bundled uterus keeps its session; any other model has each of its parts probed.
    const std::vector<support::ProbeStop> visit = support::probing_plan(model);
    std::vector<Waypoint> script;
    double t = 0;
    const double slot = (args.seconds - 1.0) / double(visit.size());
    {
      const support::ProbeTarget first =
          support::probe_target(model, *visit.front().part, shaft_r, half, 0.003);
      script.push_back({0.0, first.away, first.orientation, 0});
      t = 1.0;  // settle under gravity
      script.push_back({t, first.away, first.orientation, 0});
    }
    for (const support::ProbeStop& stop : visit) {
      const support::ProbeTarget tg =
          support::probe_target(model, *stop.part, shaft_r, half, stop.depth);
      script.push_back({t + 0.25 * slot, tg.away, tg.orientation, 0});
      script.push_back({t + 0.5 * slot, tg.pressed, tg.orientation, 1});
      script.push_back({t + 0.7 * slot, tg.pressed, tg.orientation, 1});
      script.push_back({t + 0.95 * slot, tg.away, tg.orientation, 0});
      t += slot;
    }
    ScriptedHapticDevice device(script, DeviceLimits{}, std::size_t(args.seconds * 1000) + 64);
    ServoOptions o;
    o.max_recorded_ticks = std::size_t(args.seconds * 1000) + 64;
    o.snapshot_velocities = !args.export_dir.empty();
    o.realtime_priority = args.realtime;
    o.threading = args.threading == "decoupled" ? ServoOptions::Threading::decoupled
                                                : ServoOptions::Threading::lockstep;
    ServoLoop loop(sim, contacts, k, device, o);
    // Before any thread starts: the children only spin.
    const support::BusyProcesses stress(args.stress);

    // Render side (this thread): snapshots at 60 Hz, skinning, normals, BVH refit (for picking).
    auto ws = model.skin.make_workspace();
    Positions<double> surface = model.skin.rest.vertices, peak_surface = surface, normals = surface;
    collision::TriangleBvh<double> bvh(model.skin.rest.vertices, model.skin.rest.faces);
    ServoSnapshot snap, peak_snap;
    double peak = -1;
    std::vector<double> skin_times;
    // --export: the render side writes states at export_hz of simulated time, with the force each
    // sphere feels from the tissue (links or elements, gravity, drag; not the contacts) evaluated
    // here on a force model of its own.
    std::unique_ptr<VtkSeriesWriter> exporter;
    ForceModel<double> export_forces;
    Positions<double> export_f;
    double next_export = 0;
    if (!args.export_dir.empty()) {
      exporter = std::make_unique<VtkSeriesWriter>(args.export_dir, model.spheres, &model.skin);
      export_forces = ForceModel<double>(model.spheres, so.forces);
      export_f.setZero(model.spheres.num_nodes(), 3);
    }
    loop.start();
    const auto start = std::chrono::steady_clock::now();
    for (int frame = 0;; ++frame) {
      std::this_thread::sleep_until(start + std::chrono::microseconds(16667 * (frame + 1)));
      if (loop.read_snapshot(snap)) {
        const auto s0 = std::chrono::steady_clock::now();
        model.skin.evaluate(snap.positions, ws, surface);
        compute_vertex_normals<double>(surface, model.skin.rest.faces, normals);
        bvh.refit(surface);
        skin_times.push_back(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count());
        if (exporter && snap.time >= next_export) {
          export_forces.evaluate(model.spheres, snap.positions, snap.velocities, export_f);
          exporter->write(snap.time, snap.positions, snap.velocities, export_f, &surface);
          next_export = snap.time + 1.0 / args.export_hz;
        }
        if (snap.tissue_force.norm() > peak) {
          peak = snap.tissue_force.norm();
          peak_snap = snap;
          peak_surface = surface;
        }
      }
      if (snap.time >= args.seconds - 2e-3 || !loop.running()) break;
    }
    loop.stop();
    const ServoStats st = loop.stats();

    // ---- Whole-frame rate, as the paper's Fig. 9: physics for 1/60 s (17 steps at 1 kHz,
    // contacts included) plus skinning, per frame of simulated time.
    const auto& steps = loop.step_times();
    const double skin_mean = skin_times.empty()
                                 ? 0
                                 : std::accumulate(skin_times.begin(), skin_times.end(), 0.0) /
                                       double(skin_times.size());
    std::vector<double> frame_hz, frame_t;
    const std::size_t per_frame = 17;
    for (std::size_t i = 0; i + per_frame <= steps.size(); i += per_frame) {
      double sum = skin_mean;
      for (std::size_t j = i; j < i + per_frame; ++j) sum += double(steps[j]);
      frame_hz.push_back(1.0 / sum);
      frame_t.push_back(double(i) / 1000.0);
    }
    const double fmin = frame_hz.empty() ? 0 : *std::min_element(frame_hz.begin(), frame_hz.end());
    const double fmed = percentile(frame_hz, 0.5);
    const double fmax = frame_hz.empty() ? 0 : *std::max_element(frame_hz.begin(), frame_hz.end());

    // ---- Outputs.
    write_obj(args.out + "/deformed.obj", model, peak_surface);
    {
      std::ofstream f(args.out + "/frame_rate.csv");
      f << "time_s,whole_frame_hz\n";
      for (std::size_t i = 0; i < frame_hz.size(); ++i)
        f << frame_t[i] << ',' << frame_hz[i] << '\n';
    }
    if (args.render) {
      examples::OffscreenContext gl(960, 720);
      examples::OrbitCamera cam = examples::frame_model(model);
      examples::SceneFrame rest;
      rest.model = &model;
      rest.caption = "libfsm: " + model.name + " at rest (" +
                     std::to_string(model.spheres.num_nodes()) + " spheres)";
      examples::draw_scene(rest, cam, gl.width(), gl.height());
      examples::write_png(args.out + "/rest.png", examples::read_pixels(gl.width(), gl.height()),
                          gl.width(), gl.height());
      examples::SceneFrame def;
      def.model = &model;
      def.surface = &peak_surface;
      def.has_instrument = true;
      def.instrument = peak_snap.instrument;
      def.instrument_radius = shaft_r;
      def.instrument_half_length = half;
      def.force = peak_snap.tissue_force;
      char cap[160];
      std::snprintf(cap, sizeof cap, "deformed at t = %.2f s, instrument force %.3f N",
                    peak_snap.time, peak);
      def.caption = cap;
      // Look at the pressed point from the side the instrument comes from.
      examples::OrbitCamera c2 = cam;
      const V3 dir = peak_snap.instrument.orientation * V3::UnitZ();
      c2.target = peak_snap.instrument.position - dir * (half + shaft_r);  // the tip
      c2.distance = 0.45 * cam.distance;
      def.arrow_scale = 0.25 * c2.distance / std::max(peak, 1e-3);  // a quarter of the view
      c2.yaw = std::atan2(dir.y(), dir.x()) + 0.45;
      c2.pitch = std::clamp(std::asin(std::clamp(dir.z(), -1.0, 1.0)) + 0.35, -0.9, 1.2);
      examples::draw_scene(def, c2, gl.width(), gl.height());
      examples::write_png(args.out + "/deformed.png",
                          examples::read_pixels(gl.width(), gl.height()), gl.width(), gl.height());
      examples::PlotSeries s;
      s.x = frame_t;
      s.y = frame_hz;
      s.label = "libfsm whole frame";
      examples::PlotSeries p40{{0, frame_t.empty() ? 1.0 : frame_t.back()},
                               {40, 40},
                               {0.8f, 0.2f, 0.2f},
                               "paper: 40-60 Hz"};
      examples::PlotSeries p60{
          {0, frame_t.empty() ? 1.0 : frame_t.back()}, {60, 60}, {0.8f, 0.2f, 0.2f}, ""};
      examples::draw_plot({s, p40, p60},
                          "Whole-frame rate (physics 1/60 s at 1 kHz + contacts + skinning)",
                          "time (s)", "Hz", gl.width(), gl.height(), true);
      examples::write_png(args.out + "/frame_rate.png",
                          examples::read_pixels(gl.width(), gl.height()), gl.width(), gl.height());
    }

    char json[2048];
    std::snprintf(
        json, sizeof json,
        "{\"model\": \"%s\", \"spheres\": %d, \"links\": %d, \"surface_vertices\": %d, "
        "\"simulated_s\": %.3f, "
        "\"frames\": %zu, \"frame_hz_min\": %.1f, \"frame_hz_median\": %.1f, \"frame_hz_max\": "
        "%.1f, "
        "\"skinning_us_mean\": %.1f, \"servo_ticks\": %zu, \"servo_missed_deadlines\": %zu, "
        "\"servo_period_p50_us\": %.1f, \"servo_period_p99_us\": %.1f, \"servo_period_max_us\": "
        "%.1f, "
        "\"servo_period_error_p99_us\": %.1f, \"step_p50_us\": %.1f, \"step_p99_us\": %.1f, "
        "\"step_max_us\": %.1f, "
        "\"watchdog_trips\": %zu, \"diverged_steps\": %zu, \"unconverged_solves\": %zu, "
        "%s, "
        "\"peak_instrument_force_N\": %.4f, \"peak_instrument_force_rendered_N\": %.4f, "
        "\"peak_commanded_force_N\": %.4f, \"stress_processes\": %d, \"realtime_priority\": %d, "
        "\"realtime\": %s, \"threading\": \"%s\", \"law\": \"%s\", \"exported_states\": %zu, "
        "\"out\": \"%s\"}",
        model.name.c_str(), int(model.spheres.num_nodes()), int(model.spheres.num_links()),
        int(model.skin.num_vertices()), snap.time, frame_hz.size(), fmin, fmed, fmax,
        skin_mean * 1e6, st.ticks, st.missed_deadlines, st.period_p50 * 1e6, st.period_p99 * 1e6,
        st.period_max * 1e6, st.period_error_p99 * 1e6, st.step_p50 * 1e6, st.step_p99 * 1e6,
        st.step_max * 1e6, st.watchdog_trips, st.diverged_steps, st.unconverged_solves,
        examples::energy_gain_json(st, sim.energy_gain_limit()).c_str(), st.peak_tissue_force, peak,
        st.peak_force, stress.count(), args.realtime, st.realtime ? "true" : "false",
        args.threading.c_str(), law.c_str(), exporter ? exporter->states() : std::size_t(0),
        args.out.c_str());
    {
      std::ofstream f(args.out + "/stats.json");
      f << json << '\n';
    }
    if (args.json) {
      std::printf("%s\n", json);
    } else {
      std::string probed;
      for (const support::ProbeStop& stop : visit)
        probed += (probed.empty() ? "" : ", ") + stop.part->name;
      std::printf("session: %.1f s simulated, every part probed (%s)\n", snap.time, probed.c_str());
      std::printf(
          "  whole frame (physics 1/60 s at 1 kHz + contacts + skinning): min %.0f Hz, median %.0f "
          "Hz, "
          "max %.0f Hz (paper: 40-60 Hz)\n",
          fmin, fmed, fmax);
      std::printf(
          "  servo loop: %zu ticks, period p50 %.1f us, p99 %.1f us, max %.1f us, missed deadlines "
          "%zu\n",
          st.ticks, st.period_p50 * 1e6, st.period_p99 * 1e6, st.period_max * 1e6,
          st.missed_deadlines);
      std::printf(
          "  simulation step (contacts + implicit Euler, %s law): p50 %.0f us, p99 %.0f us, max "
          "%.0f us\n",
          law.c_str(), st.step_p50 * 1e6, st.step_p99 * 1e6, st.step_max * 1e6);
      std::printf("  skinning (%d vertices) + normals + BVH refit: %.0f us per frame\n",
                  int(model.skin.num_vertices()), skin_mean * 1e6);
      std::printf(
          "  peak instrument force %.3f N (in the rendered states: %.3f N; commanded to the "
          "device: %.3f N); watchdog trips %zu\n",
          st.peak_tissue_force, peak, st.peak_force, st.watchdog_trips);
      if (exporter)
        std::printf("  ParaView series: %s (%zu states)\n", exporter->series_path().c_str(),
                    exporter->states());
      std::printf("  wrote %s/{%sdeformed.obj,frame_rate.csv,stats.json}\n", args.out.c_str(),
                  args.render ? "rest.png,deformed.png,frame_rate.png," : "");
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fsm-demo: %s\n", e.what());
    return 1;
  }
}
