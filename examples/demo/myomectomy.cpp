// fsm-demo --scenario myomectomy: the steps of a laparoscopic myomectomy on the bundled uterus,
// through the 1 kHz servo loop (docs/demo.md, "The myomectomy scenario").
//
// 1. The uterus settles under gravity; a uterine manipulator holds the body more than 15 mm
//    below the fibroid's centre (its nodes are fixed), as the assistant's does in theatre.
// 2. Incision: a blade on the instrument (its edge along the instrument's axis) sweeps 300
//    degrees around the fibroid's base, cutting the serosa and the capsule there.
// 3. Grasp: the instrument moves over the fibroid and closes its jaws on it.
// 4. Enucleation: it pulls along the fibroid's axis; the capsule's remaining links stretch past
//    their tear strain and break until the fibroid is free.
// The scripted device drives the instrument through the virtual coupling; the instrument's
// action (blade, jaws) runs inside each simulation step (haptics::InstrumentAction).

#include "myomectomy.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <thread>
#include <vector>

#include "fsm/collision/contact.hpp"
#include "fsm/collision/grasper.hpp"
#include "fsm/cut_surface.hpp"
#include "fsm/cutting.hpp"
#include "fsm/haptics/scripted_device.hpp"
#include "fsm/haptics/servo_loop.hpp"
#include "fsm/implicit_euler_integrator.hpp"
#include "fsm/simulation.hpp"
#include "fsm_support/stress.hpp"
#include "gl_scene.hpp"
#include "offscreen.hpp"

namespace fsm::examples {
namespace {

using V3 = Vector3<double>;
using haptics::Waypoint;

// The script's timeline (s of servo time).
constexpr double k_incision_start = 1.0, k_incision_end = 4.0;
constexpr double k_close_start = 5.3, k_close_end = 5.5;
constexpr double k_pull_start = 5.5, k_pull_end = 8.5, k_end = 9.5;
constexpr double k_open = 0.8, k_closed = 0.05;  // jaw angles (rad)
constexpr double k_blade_half = 0.004;           // the blade's edge: 8 mm along the instrument
constexpr double k_pull = 0.03;                  // the device pulls 30 mm
constexpr double k_step = 1e-3;                  // the servo loop's period (s)

enum Stage { before = 0, incised, half_out, free_fibroid, num_stages };
const char* const k_stage_names[num_stages] = {"before", "incised", "half_out", "free"};

// What the render side draws for a stage: captured inside the step, in preallocated buffers.
struct StageCapture {
  std::atomic<bool> taken{false};
  double time{0};
  Positions<double> spheres;
  FaceArray faces, walls;
  Index num_walls{0};
  collision::Pose<double> pose;
  V3 force{V3::Zero()};
};

// The instrument's action: the blade during the incision, the jaws from then on; the capsule's
// state; the stage captures. Runs on the simulation's thread: nothing here allocates.
class MyomectomyTool final : public haptics::InstrumentAction {
 public:
  MyomectomyTool(Simulation<double>& sim, const TissueModel<double>& model,
                 std::vector<Index> capsule, std::size_t max_steps)
      : m_model(model),
        m_capsule(std::move(capsule)),
        m_grasper(sim.model(), sim.forces(), grasper_options(), k_open),
        m_surface(sim.model(), model.skin),
        m_skin_ws(model.skin.make_workspace()),
        m_vertices(model.skin.rest.vertices) {
    m_jaw_force.reserve(max_steps);
    m_jaw_time.reserve(max_steps);
    m_capsule_left.reserve(max_steps);
    for (StageCapture& s : m_stages) {
      s.spheres = sim.model().positions();
      s.faces = model.skin.rest.faces;
      s.walls.resize(4 * sim.model().num_tetrahedra(), 3);
    }
    m_capsule_intact = count_capsule(sim.model());
  }

  static collision::GrasperOptions<double> grasper_options() {
    collision::GrasperOptions<double> o;
    o.jaw_length = 0.008;  // a 5 mm laparoscopic grasper's jaws
    return o;
  }

  void before_step(Simulation<double>& sim, const collision::Pose<double>& pose, const V3& velocity,
                   double t) noexcept override {
    m_pose = pose;
    // The jaws' force at the end of the last step (update() below rewrites the held nodes).
    m_last_wrench = m_grasper.wrench(sim.forces(), k_step).force;
    // The blade: its edge along the instrument's axis (local x), swept from the last step's.
    const V3 a = pose.to_world(V3(-k_blade_half, 0, 0));
    const V3 b = pose.to_world(V3(k_blade_half, 0, 0));
    // Tears happened inside the last step.
    const Index broken = sim.model().num_broken_links();
    bool changed = broken != m_broken;
    m_torn_links += broken - m_broken;
    m_broken = broken;
    if (t >= k_incision_start && t <= k_incision_end) {
      if (m_blade_live) {
        const Blade<double> blade{m_edge_a, m_edge_b, a, b};
        const TopologyChange c = sim.cut(blade);
        if (c.any()) {
          m_cut += c;
          m_broken += c.links_cut;
          m_model.skin.evaluate(sim.model().positions(), m_skin_ws, m_vertices);
          m_surface.add_cut(blade, m_vertices);
          changed = true;
        }
      }
      m_blade_live = true;
    } else {
      m_blade_live = false;
    }
    m_edge_a = a;
    m_edge_b = b;
    if (changed) {
      m_surface.update(sim.model());
      m_capsule_intact = count_capsule(sim.model());
    }
    // The jaws: open, then closed over k_close_start..k_close_end, then held.
    const double s = std::clamp((t - k_close_start) / (k_close_end - k_close_start), 0.0, 1.0);
    const double opening = k_open + (k_closed - k_open) * s;
    const collision::GraspEvent e =
        m_grasper.update(sim.model(), sim.forces(), pose, velocity, V3::Zero(), opening);
    m_grasped += e.grasped;
    // The stages.
    if (t >= k_incision_start - 0.1) capture(before, sim, t);
    if (t >= k_incision_end + 0.2) {
      capture(incised, sim, t);
      if (m_capsule_after_incision < 0) m_capsule_after_incision = m_capsule_intact;
    }
    if (m_capsule_after_incision > 0 && 2 * m_capsule_intact <= m_capsule_after_incision)
      capture(half_out, sim, t);
    if (m_capsule_intact == 0) {
      if (m_free_time < 0) m_free_time = t;
      if (t >= m_free_time + 0.3) capture(free_fibroid, sim, t);
    }
    if (m_jaw_time.size() < m_jaw_time.capacity()) {
      m_jaw_time.push_back(float(t));
      m_jaw_force.push_back(float(m_last_wrench.norm()));
      m_capsule_left.push_back(m_capsule_intact);
    }
  }

  [[nodiscard]] collision::Wrench<double> wrench(
      const Simulation<double>& sim) const noexcept override {
    return m_grasper.wrench(sim.forces(), k_step);
  }

  [[nodiscard]] const StageCapture& stage(Stage s) const { return m_stages[s]; }
  [[nodiscard]] const TopologyChange& cut() const { return m_cut; }
  [[nodiscard]] Index torn_links() const { return m_torn_links; }
  [[nodiscard]] Index grasped() const { return m_grasped; }
  [[nodiscard]] Index capsule_links() const { return Index(m_capsule.size()); }
  [[nodiscard]] Index capsule_after_incision() const { return m_capsule_after_incision; }
  [[nodiscard]] double free_time() const { return m_free_time; }
  [[nodiscard]] const std::vector<float>& jaw_time() const { return m_jaw_time; }
  [[nodiscard]] const std::vector<float>& jaw_force() const { return m_jaw_force; }
  [[nodiscard]] const std::vector<Index>& capsule_left() const { return m_capsule_left; }

 private:
  Index count_capsule(const SphereModel<double>& m) const noexcept {
    Index n = 0;
    for (const Index l : m_capsule) n += m.link_intact()[l];
    return n;
  }
  void capture(Stage s, const Simulation<double>& sim, double t) noexcept {
    StageCapture& c = m_stages[s];
    if (c.taken.load(std::memory_order_relaxed)) return;
    c.time = t;
    c.spheres = sim.model().positions();  // same size: no allocation
    c.faces = m_surface.skin_faces();
    c.num_walls = m_surface.num_walls();
    c.walls.topRows(c.num_walls) = m_surface.wall_faces().topRows(c.num_walls);
    c.pose = m_pose;
    c.force = m_last_wrench;
    c.taken.store(true, std::memory_order_release);
  }

  const TissueModel<double>& m_model;
  std::vector<Index> m_capsule;  // the fibroid's attachment links
  collision::Grasper<double> m_grasper;
  CutSurface<double> m_surface;
  Skin<double>::Workspace m_skin_ws;
  Positions<double> m_vertices;
  collision::Pose<double> m_pose;
  bool m_blade_live{false};
  V3 m_edge_a{V3::Zero()}, m_edge_b{V3::Zero()};
  TopologyChange m_cut;
  Index m_broken{0}, m_torn_links{0}, m_grasped{0};
  Index m_capsule_intact{0}, m_capsule_after_incision{-1};
  double m_free_time{-1};
  V3 m_last_wrench{V3::Zero()};
  std::array<StageCapture, num_stages> m_stages;
  std::vector<float> m_jaw_time, m_jaw_force;
  std::vector<Index> m_capsule_left;
};

const Part& find_part(const TissueModel<double>& model, const char* name) {
  for (const Part& p : model.parts)
    if (p.name == name) return p;
  throw Error("", "--scenario myomectomy",
              std::string("the model has no part named '") + name +
                  "' (the scenario needs 'body' and 'fibroid': the bundled uterus)");
}

V3 centre(const Positions<double>& x, const Part& p) {
  V3 c = V3::Zero();
  for (Index i = p.first_node; i < p.first_node + p.num_nodes; ++i) c += x.row(i).transpose();
  return c / double(std::max<Index>(1, p.num_nodes));
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5))];
}

}  // namespace

std::string apply_law(const TissueModel<double>& model, SphereModel<double>& spheres,
                      const std::string& law) {
  bool links = false, continuum = false;
  for (const Part& p : model.parts) {
    if (p.topology != Topology::tetrahedral) continue;
    if (law != "scene")
      spheres.set_region_law(p.region, law == "continuum" ? ForceLaw::continuum : ForceLaw::links);
    (spheres.region(p.region).law == ForceLaw::continuum ? continuum : links) = true;
  }
  return continuum && links ? "mixed" : continuum ? "continuum" : "links";
}

std::string energy_gain_json(const haptics::ServoStats& st, double limit) {
  char gain[32] = "null", to_limit[32] = "null", out[160];
  if (std::isfinite(st.largest_energy_gain)) {
    std::snprintf(gain, sizeof gain, "%.3e", st.largest_energy_gain);
    if (limit > 0) std::snprintf(to_limit, sizeof to_limit, "%.3f", st.largest_energy_gain / limit);
  }
  std::snprintf(out, sizeof out,
                "\"energy_gain_retries\": %zu, \"largest_energy_gain_J\": %s, "
                "\"largest_energy_gain_to_limit\": %s",
                st.energy_gain_retries, gain, to_limit);
  return out;
}

int run_myomectomy(const TissueModel<double>& model, const ScenarioOptions& opt) {
  const Part& body = find_part(model, "body");
  const Part& fibroid = find_part(model, "fibroid");
  auto in = [](const Part& p, Index i) {
    return i >= p.first_node && i < p.first_node + p.num_nodes;
  };

  // ---- The simulation, as the probing session's (docs/demo.md), settled under gravity.
  Simulation<double>::Options so;
  so.forces.drag = 5;
  so.divergence.max_substep_halvings = 2;
  SphereModel<double> spheres = model.spheres;
  // The capsule: the fibroid's attachment links tear at opt.capsule_tear (the bundled scene
  // leaves tearing off, so that the probing session stays what it was).
  std::vector<Index> capsule;
  const auto links = spheres.links();
  for (Index l = model.first_attachment_link;
       l < model.first_attachment_link + model.num_attachment_links; ++l) {
    const Index i = links(l, 0), j = links(l, 1);
    if ((in(fibroid, i) && in(body, j)) || (in(fibroid, j) && in(body, i))) {
      capsule.push_back(l);
      spheres.tear_strain()[l] = opt.capsule_tear;
    }
  }
  if (capsule.empty())
    throw Error("", "--scenario myomectomy", "the fibroid is not attached to the body");
  const std::string law = apply_law(model, spheres, opt.law);
  Simulation<double> sim(spheres, so);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = 1e-3;
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  for (int s = 0; s < 1000; ++s) (void)sim.step(k_step);
  // The geometry at the settled state: the fibroid's axis points from the body's centre to its.
  const Positions<double> x0 = sim.model().positions();
  const V3 cf = centre(x0, fibroid), cb = centre(x0, body);
  const V3 axis = (cf - cb).normalized();
  double reach = 0;  // the fibroid's outer radius (sphere centres plus their radius)
  for (Index i = fibroid.first_node; i < fibroid.first_node + fibroid.num_nodes; ++i)
    reach = std::max(reach, (x0.row(i).transpose() - cf).norm() + sim.model().radii()[i]);
  // The manipulator: body spheres more than 15 mm below the fibroid's centre are held.
  Index held_body = 0;
  for (Index i = body.first_node; i < body.first_node + body.num_nodes; ++i)
    if ((x0.row(i).transpose() - cf).dot(axis) < -0.015 && !sim.model().fixed()[i]) {
      sim.model().set_fixed(i);
      ++held_body;
    }
  sim.refresh();

  // ---- The script: instrument axis (local x) pointing into the fibroid.
  V3 e1 = axis.cross(V3::UnitX());
  if (e1.norm() < 0.3) e1 = axis.cross(V3::UnitY());
  e1.normalize();
  const V3 e2 = axis.cross(e1);
  Eigen::Matrix3d R;
  R.col(0) = -axis;
  R.col(2) = (-axis).cross(e1).normalized();
  R.col(1) = R.col(2).cross(R.col(0));
  const Eigen::Quaterniond q(R);
  const double rho = reach + 0.001, h0 = -0.003;  // the incision ring, around the fibroid's base
  auto ring = [&](double deg) {
    const double th = deg * M_PI / 180;
    return V3(cf + h0 * axis + rho * (std::cos(th) * e1 + std::sin(th) * e2));
  };
  const V3 hinge = cf + (reach + 0.001) * axis;  // the jaws' hinge just above the fibroid
  std::vector<Waypoint> script;
  script.push_back({0.0, ring(0) + 0.015 * axis, q, 0});
  script.push_back({0.7, ring(0) + 0.015 * axis, q, 0});
  script.push_back({k_incision_start, ring(0), q, 0});
  for (int deg = 10; deg <= 300; deg += 10)
    script.push_back(
        {k_incision_start + (k_incision_end - k_incision_start) * deg / 300.0, ring(deg), q, 0});
  script.push_back({4.4, ring(300) + 0.015 * axis, q, 0});
  script.push_back({4.9, hinge + 0.01 * axis, q, 0});
  script.push_back({5.2, hinge, q, 0});
  script.push_back({k_pull_start, hinge, q, 1});
  script.push_back({k_pull_end, hinge + k_pull * axis, q, 1});
  script.push_back({k_end, hinge + k_pull * axis, q, 1});
  const std::size_t ticks = std::size_t(k_end * 1000) + 64;
  haptics::ScriptedHapticDevice device(script, haptics::DeviceLimits{}, ticks);

  collision::ContactSolver<double> contacts(sim.model(), sim.forces());
  collision::Instrument<double> tool;
  tool.name = "grasper";
  tool.shape = collision::CapsuleShape<double>{0.0025, 0.02};
  tool.enabled = false;  // the blade and the jaws act; the shaft stays clear of the tissue
  const Index k = contacts.add_instrument(tool);
  MyomectomyTool action(sim, model, capsule, ticks);
  haptics::ServoOptions o;
  o.max_recorded_ticks = ticks;
  o.realtime_priority = opt.realtime;
  haptics::ServoLoop loop(sim, contacts, k, device, o);
  loop.set_action(&action);
  const support::BusyProcesses stress(opt.stress);
  loop.run_real_time(k_end);
  const haptics::ServoStats st = loop.stats();

  // ---- Outputs: the force against time, the stages, the statistics.
  const auto& t = action.jaw_time();
  const auto& f = action.jaw_force();
  double peak = 0;
  for (const float v : f) peak = std::max(peak, double(v));
  {
    std::ofstream csv(opt.out + "/myomectomy_force.csv");
    csv << "time_s,jaw_force_N,capsule_links_intact\n";
    for (std::size_t i = 0; i < t.size(); ++i)
      csv << t[i] << ',' << f[i] << ',' << action.capsule_left()[i] << '\n';
  }
  std::vector<std::string> written{"myomectomy_force.csv"};
  if (opt.render) {
    OffscreenContext gl(960, 720);
    OrbitCamera cam = frame_model(model);
    cam.target = cf;
    cam.distance *= 0.55;
    cam.yaw = std::atan2(axis.y(), axis.x()) + 0.9;
    cam.pitch = 0.6;
    for (int s = 0; s < num_stages; ++s) {
      const StageCapture& c = action.stage(Stage(s));
      if (!c.taken.load(std::memory_order_acquire)) continue;
      Positions<double> surface(model.skin.num_vertices(), 3);
      auto ws = model.skin.make_workspace();
      model.skin.evaluate(c.spheres, ws, surface);
      SceneFrame frame;
      frame.model = &model;
      frame.surface = &surface;
      frame.faces = &c.faces;
      frame.spheres = &c.spheres;
      frame.show_spheres = false;
      frame.walls = &c.walls;
      frame.num_walls = c.num_walls;
      frame.has_instrument = s != before;
      // The shaft behind the jaws' hinge, along the instrument's axis (local x; the capsule is
      // drawn along its local z).
      frame.instrument.orientation =
          c.pose.orientation * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, V3::UnitY()));
      frame.instrument.position = c.pose.to_world(V3(-0.02, 0, 0));
      frame.instrument_radius = 0.0025;
      frame.instrument_half_length = 0.02;
      frame.force = c.force;
      frame.arrow_scale = 0.01;
      char cap[200];
      std::snprintf(cap, sizeof cap, "myomectomy: %s (t = %.2f s, jaw force %.2f N)",
                    k_stage_names[s], c.time, c.force.norm());
      frame.caption = cap;
      draw_scene(frame, cam, gl.width(), gl.height());
      const std::string name = std::string("myomectomy_") + k_stage_names[s] + ".png";
      write_png(opt.out + "/" + name, read_pixels(gl.width(), gl.height()), gl.width(),
                gl.height());
      written.push_back(name);
    }
    PlotSeries jaw;
    PlotSeries cmd;
    for (std::size_t i = 0; i < t.size(); i += 5) {
      jaw.x.push_back(t[i]);
      jaw.y.push_back(f[i]);
    }
    jaw.label = "force on the jaws (N)";
    for (const auto& sample : device.forces()) {
      cmd.x.push_back(sample.time);
      cmd.y.push_back(sample.force.norm());
    }
    cmd.colour = {0.8f, 0.3f, 0.1f};
    cmd.label = "commanded to the device (N)";
    draw_plot({jaw, cmd}, "myomectomy: incise, grasp, pull until free", "time (s)", "N", gl.width(),
              gl.height());
    write_png(opt.out + "/myomectomy_force.png", read_pixels(gl.width(), gl.height()), gl.width(),
              gl.height());
    written.push_back("myomectomy_force.png");
  }
  std::vector<double> steps(loop.step_times().begin(), loop.step_times().end());
  const bool freed = action.free_time() >= 0;
  char json[2048];
  std::snprintf(
      json, sizeof json,
      "{\"scenario\": \"myomectomy\", \"model\": \"%s\", \"spheres\": %d, \"held_by_manipulator\": "
      "%d, \"capsule_links\": %d, \"capsule_tear_strain\": %.3f, \"links_cut\": %d, "
      "\"tetrahedra_cut\": %d, \"capsule_links_after_incision\": %d, \"links_torn\": %d, "
      "\"spheres_grasped\": %d, \"free\": %s, \"free_time_s\": %.3f, \"peak_jaw_force_N\": %.3f, "
      "\"peak_commanded_force_N\": %.3f, \"servo_ticks\": %zu, \"servo_missed_deadlines\": %zu, "
      "\"servo_period_p99_us\": %.1f, \"step_p50_us\": %.1f, \"step_p99_us\": %.1f, "
      "\"step_max_us\": %.1f, \"watchdog_trips\": %zu, \"diverged_steps\": %zu, "
      "\"unconverged_solves\": %zu, %s, \"stress_processes\": %d, \"law\": \"%s\", "
      "\"out\": \"%s\"}",
      model.name.c_str(), int(model.spheres.num_nodes()), int(held_body),
      int(action.capsule_links()), opt.capsule_tear, int(action.cut().links_cut),
      int(action.cut().tetrahedra_cut), int(action.capsule_after_incision()),
      int(action.torn_links()), int(action.grasped()), freed ? "true" : "false", action.free_time(),
      peak, st.peak_force, st.ticks, st.missed_deadlines, st.period_p99 * 1e6,
      percentile(steps, 0.5) * 1e6, percentile(steps, 0.99) * 1e6, st.step_max * 1e6,
      st.watchdog_trips, st.diverged_steps, st.unconverged_solves,
      energy_gain_json(st, sim.energy_gain_limit()).c_str(), stress.count(), law.c_str(),
      opt.out.c_str());
  {
    std::ofstream out(opt.out + "/stats.json");
    out << json << '\n';
  }
  if (opt.json) {
    std::printf("%s\n", json);
  } else {
    std::printf("myomectomy on %s (%d spheres; the manipulator holds %d body spheres)\n",
                model.name.c_str(), int(model.spheres.num_nodes()), int(held_body));
    std::printf(
        "  incision: %d links and %d tetrahedra cut; the capsule keeps %d of its %d links\n",
        int(action.cut().links_cut), int(action.cut().tetrahedra_cut),
        int(action.capsule_after_incision()), int(action.capsule_links()));
    std::printf(
        "  grasp: %d spheres held; pull: %d links torn (tear strain %.2f); %s\n",
        int(action.grasped()), int(action.torn_links()), opt.capsule_tear,
        freed ? ("free at t = " + std::to_string(action.free_time()).substr(0, 5) + " s").c_str()
              : "NOT free by the end");
    std::printf("  peak force on the jaws %.2f N (commanded to the device: %.2f N)\n", peak,
                st.peak_force);
    std::printf(
        "  servo loop: %zu ticks, missed deadlines %zu, period p99 %.1f us; step p50 %.0f us, "
        "p99 %.0f us, max %.0f us; watchdog trips %zu, diverged steps %zu\n",
        st.ticks, st.missed_deadlines, st.period_p99 * 1e6, percentile(steps, 0.5) * 1e6,
        percentile(steps, 0.99) * 1e6, st.step_max * 1e6, st.watchdog_trips, st.diverged_steps);
    std::string files;
    for (const auto& w : written) files += (files.empty() ? "" : ",") + w;
    std::printf("  wrote %s/{%s,stats.json}\n", opt.out.c_str(), files.c_str());
  }
  return freed && st.diverged_steps == 0 ? 0 : 3;
}

}  // namespace fsm::examples
