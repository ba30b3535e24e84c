// fsm-viewer: the interactive viewer. A GLFW window draws the tissue (a colour per part), the
// instrument and the force the tissue exerts on it, while the 1 kHz servo loop (virtual coupling,
// contacts, implicit Euler) runs in the background. The mouse drives the instrument through
// MouseDevice; --scripted plays a probing script instead (for tests), --device touch uses a 3D
// Systems Touch when one answers.
//
//   fsm-viewer [--model FILE.fsm|SCENE.json] [--device mouse|touch] [--scripted] [--frames N]
//              [--screenshot PATH.png] [--size WxH]
//   fsm-viewer --check-screenshot PATH.png [--min-fraction F]
//
// Mouse: left-drag moves the instrument's tip in the view plane; shift+scroll or the up/down
// arrows move it in depth; ctrl+left-click puts it on the surface under the cursor; right-drag
// orbits; scroll zooms. Keys: space toggles the spheres, r resets the instrument, esc quits.
//
// Exit status: 0, 1 on an error, 77 when there is no display or no OpenGL context (a test skips).

#include <GLFW/glfw3.h>

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl2.h>
#include <imgui.h>

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "fsm/fsm.hpp"
#include "fsm/haptics/touch_device.hpp"
#include "fsm_support/cli.hpp"
#include "fsm_support/model_cache.hpp"
#include "fsm_support/probe.hpp"
#include "gl_scene.hpp"
#include "mouse_device.hpp"
#include "screenshot_check.hpp"
#ifdef FSM_VIEWER_HAS_BUILDER
#include "fsm/builder/builder.hpp"
#endif

using namespace fsm;
using namespace fsm::haptics;
using V3 = Vector3<double>;

namespace {

constexpr int kExitSkip = 77;  // no display or no GL context: ctest's SKIP_RETURN_CODE
constexpr double kPi = 3.14159265358979323846;
// The instrument: a capsule like the demo's probe.
constexpr double kShaftRadius = 0.0025, kHalfLength = 0.02;

struct Args {
  std::string model;
  std::string device{"mouse"};
  bool scripted{false};
  long frames{-1};
  std::string screenshot;
  std::string check;
  double min_fraction{0.05};
  int width{960}, height{720};
  std::string integrator{"implicit_euler"};
  std::string law;  // "", links or continuum
  bool panel{true};
  bool exercise_panel{false};
};

constexpr const char* kControls =
    "mouse: left-drag moves the tip in the view plane, shift+scroll or up/down arrows move it in "
    "depth, ctrl+left-click puts it on the surface, right-drag orbits, scroll zooms.\n"
    "keys: space toggles the spheres, r resets the instrument, esc quits. The panel picks the "
    "part, "
    "the integrator, each part's force law and material; pauses, resets; shows force and step "
    "time.";

// Parses the command line (CLI11): the exit status when the program should stop there (--help,
// --version: 0; a usage error: 2), else -1.
int parse(int argc, char** argv, Args& a) {
  CLI::App app(
      "Interactive viewer: press the tissue with a mouse-driven (or Touch, or scripted) "
      "instrument through the 1 kHz servo loop.",
      "fsm-viewer");
  app.footer(kControls);
  support::add_version_flag(app);
  app.add_option("--model", a.model,
                 "a model file, or a scene to build (default: the bundled uterus, built once and "
                 "cached in $FSM_CACHE_DIR or ~/.cache/fsm)");
  app.add_option("--device", a.device, "mouse, or touch (falls back to the mouse without one)")
      ->check(CLI::IsMember({"mouse", "touch"}))
      ->capture_default_str();
  app.add_flag("--scripted", a.scripted, "a scripted probe drives the instrument (no mouse)");
  app.add_option("--integrator", a.integrator, "the simulation's integrator")
      ->check(CLI::IsMember(integrator_names()))
      ->capture_default_str();
  app.add_option("--law", a.law,
                 "force law of every tetrahedral part: links (the paper's) or continuum")
      ->check(CLI::IsMember({"links", "continuum"}));
  app.add_flag("!--no-panel", a.panel, "hide the control panel");
  app.add_flag("--exercise-panel", a.exercise_panel,
               "test: issue the panel's requests on a schedule of frames (with --frames)");
  app.add_option("--frames", a.frames, "render N frames, then exit")->check(CLI::PositiveNumber);
  app.add_option("--screenshot", a.screenshot, "write the last frame as a PNG");
  std::string size;
  app.add_option("--size", size, "window size in pixels, WxH (default 960x720)");
  app.add_option("--check-screenshot", a.check,
                 "exit 0 when more than F of the PNG's pixels differ from its top-left one, 1 "
                 "otherwise; opens no window");
  app.add_option("--min-fraction", a.min_fraction, "F for --check-screenshot")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  const int status = support::parse_command_line(app, argc, argv);
  if (status >= 0) return status;
  if (!size.empty() && (std::sscanf(size.c_str(), "%dx%d", &a.width, &a.height) != 2 ||
                        a.width < 16 || a.height < 16)) {
    std::fprintf(stderr, "--size: wants WxH (at least 16x16), not '%s'\n", size.c_str());
    return 2;
  }
  return -1;
}

// ---- The model: as fsm-demo opens it (examples/common/model_cache.hpp); the builder is optional.

TissueModel<double> build_scene(const std::string& scene) {
#ifdef FSM_VIEWER_HAS_BUILDER
  std::printf("fsm-viewer: building %s (once; CGAL takes a while)\n", scene.c_str());
  std::fflush(stdout);
  return build::build_model(scene);
#else
  throw Error(scene, "fsm-viewer",
              "built without the model builder (fsm::build): pass --model FILE.fsm");
#endif
}

// ---- The scripted probe: presses each part in turn, from outside, for ten minutes.

std::vector<Waypoint> probe_script(const TissueModel<double>& model) {
  std::vector<Waypoint> script;
  const double slot = 2.5, total = 600;
  const std::vector<support::ProbeStop> plan = support::probing_plan(model);
  const support::ProbeTarget first =
      support::probe_target(model, *plan.front().part, kShaftRadius, kHalfLength, 0.003);
  script.push_back({0.0, first.away, first.orientation, 0});
  for (double t = 0; t < total;) {
    for (const support::ProbeStop& stop : plan) {
      const support::ProbeTarget tg =
          support::probe_target(model, *stop.part, kShaftRadius, kHalfLength, stop.depth);
      script.push_back({t + 0.25 * slot, tg.away, tg.orientation, 0});
      script.push_back({t + 0.5 * slot, tg.pressed, tg.orientation, 1});
      script.push_back({t + 0.7 * slot, tg.pressed, tg.orientation, 1});
      script.push_back({t + 0.95 * slot, tg.away, tg.orientation, 0});
      t += slot;
    }
  }
  return script;
}

// ---- The window's state, shared by the GLFW callbacks (window thread only).

struct Camera {
  V3 eye, forward, right, up;
  double tan_half_fov;
};

Camera camera_basis(const examples::OrbitCamera& c) {
  Camera b;
  b.eye = c.eye();
  b.forward = (c.target - b.eye).normalized();
  b.right = b.forward.cross(V3::UnitZ()).normalized();
  b.up = b.right.cross(b.forward);
  b.tan_half_fov = std::tan(c.fov_deg * kPi / 360.0);
  return b;
}

struct View {
  const collision::TriangleBvh<double>* bvh{nullptr};
  examples::OrbitCamera camera, home;
  bool mouse_drives{false};  // the instrument follows the mouse
  V3 tip{V3::Zero()};        // the instrument's tip (m)
  Eigen::Quaterniond orientation{Eigen::Quaterniond::Identity()};
  bool left{false}, right{false};
  double last_x{0}, last_y{0};
  bool show_spheres{false};

  // The pose origin (the capsule's centre) for the tip: the capsule's -z end is the tip.
  [[nodiscard]] V3 centre() const {
    return tip + orientation * V3(0, 0, kHalfLength + kShaftRadius);
  }
  // Points the instrument into the scene, its handle (+z) toward the eye and the lower right, as a
  // laparoscopic instrument comes in (seen end-on it would be a disc).
  void aim() {
    const Camera c = camera_basis(camera);
    const V3 handle = -c.forward + 0.6 * c.right - 0.4 * c.up;
    orientation = Eigen::Quaterniond::FromTwoVectors(V3::UnitZ(), handle.normalized());
  }
};

View& view_of(GLFWwindow* w) {
  return *static_cast<View*>(glfwGetWindowUserPointer(w));
}

// The ray through window point (x, y) (screen coordinates), from the eye.
V3 cursor_ray(GLFWwindow* w, const View& v, double x, double y) {
  int ww = 0, wh = 0;
  glfwGetWindowSize(w, &ww, &wh);
  const Camera c = camera_basis(v.camera);
  const double aspect = double(ww) / std::max(wh, 1);
  const double nx = 2 * x / std::max(ww, 1) - 1, ny = 1 - 2 * y / std::max(wh, 1);
  return (c.forward + c.right * (nx * c.tan_half_fov * aspect) + c.up * (ny * c.tan_half_fov))
      .normalized();
}

// Puts the tip 2 mm in front of the surface under the cursor (if there is surface there).
void pick(GLFWwindow* w, View& v, double x, double y) {
  const V3 eye = v.camera.eye(), dir = cursor_ray(w, v, x, y);
  if (const auto hit = v.bvh->ray_cast(eye, dir)) {
    v.tip = eye + dir * std::max(hit->distance - 0.002, 0.0);
    v.aim();
  }
}

// Moves the tip along the view direction (m; positive is away from the eye).
void push(View& v, double metres) {
  v.tip += camera_basis(v.camera).forward * metres;
}

void reset_instrument(View& v) {
  v.aim();
  const V3 eye = v.camera.eye(), dir = (v.camera.target - eye).normalized();
  const auto hit = v.bvh->ray_cast(eye, dir);
  v.tip = hit ? V3(eye + dir * (hit->distance - 0.01)) : V3(eye + dir * (0.7 * v.camera.distance));
}

// True when the panel has the mouse (or, for keys, the keyboard): the scene ignores the event.
bool panel_wants(bool keyboard) {
  if (ImGui::GetCurrentContext() == nullptr) return false;
  return keyboard ? ImGui::GetIO().WantCaptureKeyboard : ImGui::GetIO().WantCaptureMouse;
}

void on_button(GLFWwindow* w, int button, int action, int mods) {
  View& v = view_of(w);
  if (action == GLFW_PRESS && panel_wants(false)) return;
  double x = 0, y = 0;
  glfwGetCursorPos(w, &x, &y);
  v.last_x = x;
  v.last_y = y;
  if (button == GLFW_MOUSE_BUTTON_LEFT) {
    v.left = action == GLFW_PRESS;
    if (v.left && v.mouse_drives) {
      if (mods & GLFW_MOD_CONTROL)
        pick(w, v, x, y);
      else
        v.aim();  // grab: the instrument turns to point away from the eye
    }
  } else if (button == GLFW_MOUSE_BUTTON_RIGHT) {
    v.right = action == GLFW_PRESS;
  }
}

void on_cursor(GLFWwindow* w, double x, double y) {
  View& v = view_of(w);
  const double dx = x - v.last_x, dy = y - v.last_y;
  v.last_x = x;
  v.last_y = y;
  if (v.right) {
    v.camera.yaw -= 0.008 * dx;
    v.camera.pitch = std::clamp(v.camera.pitch + 0.008 * dy, -1.5, 1.5);
  } else if (v.left && v.mouse_drives) {
    // One pixel is this many metres at the tip's depth: the tip stays under the cursor.
    int ww = 0, wh = 0;
    glfwGetWindowSize(w, &ww, &wh);
    const Camera c = camera_basis(v.camera);
    const double depth = std::max((v.tip - c.eye).dot(c.forward), 1e-3);
    const double per_pixel = 2 * depth * c.tan_half_fov / std::max(wh, 1);
    v.tip += (c.right * dx - c.up * dy) * per_pixel;
  }
}

void on_scroll(GLFWwindow* w, double, double dy) {
  View& v = view_of(w);
  if (panel_wants(false)) return;
  if (v.mouse_drives && glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS)
    push(v, -0.002 * dy);  // scroll up pulls the tip toward the eye
  else
    v.camera.distance = std::clamp(v.camera.distance * std::pow(0.9, dy), 0.02, 5.0);
}

void on_key(GLFWwindow* w, int key, int, int action, int) {
  if (action != GLFW_PRESS || panel_wants(true)) return;
  View& v = view_of(w);
  if (key == GLFW_KEY_ESCAPE || key == GLFW_KEY_Q) glfwSetWindowShouldClose(w, GLFW_TRUE);
  if (key == GLFW_KEY_SPACE) v.show_spheres = !v.show_spheres;
  if (key == GLFW_KEY_R && v.mouse_drives) {
    v.camera = v.home;
    reset_instrument(v);
  }
}

// A line from the instrument (the proxy) to where the device is (the hand): the coupling spring.
// draw_scene leaves its projection and view set up (when it has no caption): draw in that frame.
void draw_coupling(const V3& proxy, const V3& device) {
  glDisable(GL_LIGHTING);
  glDisable(GL_DEPTH_TEST);
  glLineWidth(1.5f);
  glColor3f(0.3f, 0.9f, 1.0f);
  glBegin(GL_LINES);
  glVertex3d(proxy.x(), proxy.y(), proxy.z());
  glVertex3d(device.x(), device.y(), device.z());
  glEnd();
  glPointSize(6.0f);
  glBegin(GL_POINTS);
  glVertex3d(device.x(), device.y(), device.z());
  glEnd();
  glEnable(GL_DEPTH_TEST);
  glEnable(GL_LIGHTING);
}

// ---- The control panel (Dear ImGui).

struct PanelRequest {
  int go_to_part{-1};      // look at (and, with the mouse, put the instrument by) this part
  std::string integrator;  // switch to this integrator
  int law_part{-1};        // set this part's region to `law`
  ForceLaw law{ForceLaw::links};
  int material_part{-1};  // set this part's region to `material`
  Material<double> material;
  bool pause{false}, resume{false}, reset{false};
  [[nodiscard]] bool changes_simulation() const {
    return !integrator.empty() || law_part >= 0 || material_part >= 0 || pause || resume || reset;
  }
};

class Panel {
 public:
  Panel(const TissueModel<double>& model, Simulation<double>& sim, std::string integrator)
      : m_model(model), m_sim(sim), m_integrator(std::move(integrator)) {
    for (const Part& p : model.parts) m_part_names.push_back(p.name);
    load_material();
  }

  bool show_surface{true}, show_links{false}, paused{false};
  int applied{0}, refused{0};  // requests applied, and those the simulation refused

  // Keeps the force and step-time history of each new snapshot.
  void record(const ServoSnapshot& s) {
    if (s.time <= m_last_time) return;
    m_last_time = s.time;
    m_force.push_back(float(s.tissue_force.norm()));
    if (m_force.size() > 600) m_force.pop_front();
    m_steps.push_back(s.step_time);
    if (m_steps.size() > 600) m_steps.pop_front();
    if (!s.advanced) ++m_diverged;
  }

  PanelRequest draw(const ServoSnapshot& s, double fps, bool tripped, bool running,
                    bool& show_spheres) {
    PanelRequest r;
    ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowSize(ImVec2(430, 0), ImGuiCond_FirstUseEver);
    ImGui::Begin("libfsm", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::Text("%s: %d spheres, %d links, %d tetrahedra", m_model.name.c_str(),
                int(m_model.spheres.num_nodes()), int(m_model.spheres.num_links()),
                int(m_model.spheres.num_tetrahedra()));
    ImGui::Text("t = %.2f s   %.0f fps   %s", s.time, fps, running ? "running" : "paused");
    ImGui::Text("instrument force %.3f N", s.tissue_force.norm());
    std::vector<float> f(m_force.begin(), m_force.end());
    ImGui::PlotLines("##force", f.data(), int(f.size()), 0, "force (N), last 600 steps shown", 0.0f,
                     FLT_MAX, ImVec2(410, 60));
    std::vector<double> steps(m_steps.begin(), m_steps.end());
    double p50 = 0, worst = 0;
    if (!steps.empty()) {
      worst = *std::max_element(steps.begin(), steps.end());
      std::nth_element(steps.begin(), steps.begin() + long(steps.size() / 2), steps.end());
      p50 = steps[steps.size() / 2];
    }
    ImGui::Text("step (contacts + %s): p50 %.0f us, max %.0f us", m_integrator.c_str(), p50 * 1e6,
                worst * 1e6);
    if (tripped) ImGui::TextColored(ImVec4(1, 0.4f, 0.3f, 1), "force off: servo watchdog");
    if (m_diverged > 0)
      ImGui::TextColored(ImVec4(1, 0.7f, 0.2f, 1), "%d diverged steps (rolled back)", m_diverged);

    ImGui::Separator();
    ImGui::Checkbox("surface", &show_surface);
    ImGui::SameLine();
    ImGui::Checkbox("spheres", &show_spheres);
    ImGui::SameLine();
    ImGui::Checkbox("links", &show_links);
    if (ImGui::Button(paused ? "resume" : "pause")) (paused ? r.resume : r.pause) = true;
    ImGui::SameLine();
    if (ImGui::Button("reset to rest")) r.reset = true;

    ImGui::Separator();
    const std::vector<std::string> names = integrator_names();
    if (ImGui::BeginCombo("integrator", m_integrator.c_str())) {
      for (const std::string& n : names)
        if (ImGui::Selectable(n.c_str(), n == m_integrator) && n != m_integrator) r.integrator = n;
      ImGui::EndCombo();
    }
    if (ImGui::BeginCombo("part", m_part_names[std::size_t(m_part)].c_str())) {
      for (std::size_t k = 0; k < m_part_names.size(); ++k)
        if (ImGui::Selectable(m_part_names[k].c_str(), int(k) == m_part)) {
          m_part = int(k);
          load_material();
        }
      ImGui::EndCombo();
    }
    if (ImGui::Button("go to part")) r.go_to_part = m_part;
    const Part& part = m_model.parts[std::size_t(m_part)];
    const ForceLaw law = m_sim.model().region(part.region).law;
    int law_index = law == ForceLaw::continuum ? 1 : 0;
    const char* laws[] = {"links (the paper's)", "continuum (neo-Hookean)"};
    if (part.num_tetrahedra == 0) {
      ImGui::TextDisabled("law: links (a %s part has no tetrahedra)", to_string(part.topology));
    } else if (ImGui::Combo("law", &law_index, laws, 2) &&
               (law_index == 1) != (law == ForceLaw::continuum)) {
      r.law_part = m_part;
      r.law = law_index == 1 ? ForceLaw::continuum : ForceLaw::links;
    }
    ImGui::InputDouble("E (kPa)", &m_youngs_kpa, 0, 0, "%.2f");
    ImGui::InputDouble("viscosity (Pa s)", &m_viscosity, 0, 0, "%.3f");
    if (part.num_tetrahedra > 0) ImGui::InputDouble("Poisson's ratio", &m_poisson, 0, 0, "%.3f");
    if (ImGui::Button("apply material")) {
      r.material_part = m_part;
      r.material = m_sim.model().region(part.region).material;
      r.material.youngs_modulus = m_youngs_kpa * 1e3;
      r.material.viscosity = m_viscosity;
      r.material.poisson_ratio = m_poisson;
    }
    if (!m_message.empty()) ImGui::TextWrapped("%s", m_message.c_str());
    ImGui::End();
    return r;
  }

  // Applies a request to the simulation (the servo loop is stopped). A refused change (a material
  // out of range, a law the part cannot take) is shown in the panel, never thrown out of it.
  void apply(const PanelRequest& r,
             const std::function<std::unique_ptr<Integrator<double>>(const std::string&)>& make) {
    m_message.clear();
    try {
      if (!r.integrator.empty()) {
        m_sim.set_integrator(make(r.integrator));
        m_integrator = r.integrator;
        m_steps.clear();
      }
      if (r.law_part >= 0 || r.material_part >= 0) {
        if (r.law_part >= 0)
          m_sim.model().set_region_law(m_model.parts[std::size_t(r.law_part)].region, r.law);
        if (r.material_part >= 0)
          m_sim.model().set_region_material(m_model.parts[std::size_t(r.material_part)].region,
                                            r.material);
        m_sim.refresh();
        m_steps.clear();
      }
      if (r.reset) {
        m_sim.reset();
        m_force.clear();
        m_diverged = 0;
        m_last_time = -1;
      }
    } catch (const Error& e) {
      m_message = e.what();
      ++refused;
      load_material();
    }
    ++applied;
    if (r.pause) paused = true;
    if (r.resume) paused = false;
  }

 private:
  void load_material() {
    const Material<double>& m =
        m_sim.model().region(m_model.parts[std::size_t(m_part)].region).material;
    m_youngs_kpa = m.youngs_modulus / 1e3;
    m_viscosity = m.viscosity;
    m_poisson = m.poisson_ratio;
  }

  const TissueModel<double>& m_model;
  Simulation<double>& m_sim;
  std::string m_integrator;
  std::vector<std::string> m_part_names;
  int m_part{0};
  double m_youngs_kpa{0}, m_viscosity{0}, m_poisson{0};
  std::deque<float> m_force;
  std::deque<double> m_steps;
  double m_last_time{-1};
  int m_diverged{0};
  std::string m_message;
};

// --exercise-panel: the panel's requests on a schedule of frames, through the same path as clicks
// (for the Xvfb test): every part visited, integrators swapped, a law and a material changed, a
// material refused (E < 0), pause, resume, reset.
PanelRequest scripted_request(long frame, const TissueModel<double>& model) {
  PanelRequest r;
  const long k = frame - 2;
  if (k >= 0 && k < long(model.parts.size())) r.go_to_part = int(k);
  const long t = frame - 2 - long(model.parts.size());
  Material<double> m = model.spheres.region(model.parts.front().region).material;
  if (t == 0) r.integrator = "improved_euler";
  if (t == 2) r.integrator = "implicit_euler";
  if (t == 4) {
    r.law_part = 0;
    r.law = model.parts.front().num_tetrahedra > 0 ? ForceLaw::continuum : ForceLaw::links;
  }
  if (t == 6 || t == 8) {
    r.material_part = 0;
    r.material = m;
    r.material.youngs_modulus = t == 6 ? 20e3 : -1.0;  // the second is refused
  }
  if (t == 10) r.pause = true;
  if (t == 12) r.resume = true;
  if (t == 14) r.reset = true;
  return r;
}

int run(const Args& args) {
  glfwSetErrorCallback([](int code, const char* what) {
    std::fprintf(stderr, "fsm-viewer: GLFW %d: %s\n", code, what);
  });
  if (!glfwInit()) {
    std::fprintf(stderr, "fsm-viewer: no display (GLFW cannot initialise)\n");
    return kExitSkip;
  }
  struct Terminate {
    ~Terminate() { glfwTerminate(); }
  } terminate;

  // Load before opening the window (a first run builds the model).
  const TissueModel<double> model =
      support::open_model(args.model, support::source_data_dir(), build_scene, "fsm-viewer").model;
  if (model.skin.num_vertices() == 0 || model.parts.empty())
    throw Error(args.model, "fsm-viewer", "the model has no render surface to show");

  // The session, as in fsm-demo: simulation, contacts, a capsule instrument, a device, the loop.
  Simulation<double>::Options so;
  so.forces.drag = 5;  // the surrounding tissue and fluid (docs/physics.md section 9)
  // A step that fails the energy check is retried as two (then four) half steps before it counts
  // as diverged (and the servo loop's watchdog zeroes the force): a thin ligament flung by the
  // probe gained energy in one linearised 1 ms step (docs/haptics.md, "Under load").
  so.divergence.max_substep_halvings = 2;
  Simulation<double> sim(model.spheres, so);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = 1e-3;  // as fsm-demo: < 0.1 um from 1e-6 at a third of the CG iterations
  // The integrator and the force laws: the command line's now, the panel's later.
  auto make_stepper = [&](const std::string& name) -> std::unique_ptr<Integrator<double>> {
    if (name == "implicit_euler") return std::make_unique<ImplicitEulerIntegrator<double>>(io);
    return make_integrator<double>(name);
  };
  sim.set_integrator(make_stepper(args.integrator));
  if (!args.law.empty()) {
    for (const Part& p : model.parts)
      if (p.num_tetrahedra > 0)
        sim.model().set_region_law(p.region,
                                   args.law == "continuum" ? ForceLaw::continuum : ForceLaw::links);
    sim.refresh();
  }
  // The probe (2.5 mm radius) is smaller than the tetrahedral parts' vertex spacing: it meets
  // their faces, as in the demo (docs/physics.md section 8).
  collision::ContactOptions<double> contact_options;
  contact_options.face_contact = true;
  collision::ContactSolver<double> contacts(sim.model(), sim.forces(), contact_options);
  collision::Instrument<double> tool;
  tool.name = "probe";
  tool.shape = collision::CapsuleShape<double>{kShaftRadius, kHalfLength};
  const Index instrument = contacts.add_instrument(tool);

  Positions<double> surface = model.skin.rest.vertices;
  auto ws = model.skin.make_workspace();
  // For picking (ctrl+click): refitted to the skinned surface every new snapshot.
  collision::TriangleBvh<double> bvh(model.skin.rest.vertices, model.skin.rest.faces);

  View view;
  view.bvh = &bvh;
  view.camera = view.home = examples::frame_model(model);
  view.camera.distance = view.home.distance *= 0.8;  // frame_model leaves a wide margin
  reset_instrument(view);

  // Workspace: the model's box and a margin the capsule can be pulled out into.
  const V3 lo = model.skin.rest.vertices.colwise().minCoeff().transpose(),
           hi = model.skin.rest.vertices.colwise().maxCoeff().transpose();
  DeviceLimits limits;
  limits.workspace_min = lo - V3::Constant(0.1);
  limits.workspace_max = hi + V3::Constant(0.1);
  // Where the tip may go: the capsule's centre (kHalfLength + kShaftRadius from the tip) then
  // stays inside the workspace.
  const V3 reach_min = lo - V3::Constant(0.07), reach_max = hi + V3::Constant(0.07);
  examples::MouseDevice mouse(limits, {view.centre(), view.orientation, 0});
  std::unique_ptr<ScriptedHapticDevice> scripted;
  std::unique_ptr<HapticDevice> touch;
  ServoOptions options;
  HapticDevice* device = &mouse;
  std::string device_label = "mouse";
  if (args.scripted) {
    scripted =
        std::make_unique<ScriptedHapticDevice>(probe_script(model), limits, std::size_t(1) << 16);
    device = scripted.get();
    device_label = "scripted probe";
  } else if (args.device == "touch") {
    register_touch_device();
    touch = make_device("touch");
    device = touch.get();
    device_label = "touch";
    options.device_offset = view.camera.target;  // the Touch's centre at the model's
  }
  view.mouse_drives = device == &mouse;

  // The window: a compatibility-profile context for gl_scene's legacy drawing; multisampled when
  // the display has such visuals.
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 2);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
  glfwWindowHint(GLFW_SAMPLES, 4);
  const std::string title = "fsm-viewer: " + model.name;
  GLFWwindow* window = glfwCreateWindow(args.width, args.height, title.c_str(), nullptr, nullptr);
  if (window == nullptr) {
    glfwWindowHint(GLFW_SAMPLES, 0);
    window = glfwCreateWindow(args.width, args.height, title.c_str(), nullptr, nullptr);
  }
  if (window == nullptr) {
    std::fprintf(stderr, "fsm-viewer: no OpenGL 2.1 context\n");
    return kExitSkip;
  }
  glfwMakeContextCurrent(window);
  glfwSwapInterval(1);
  glfwSetWindowUserPointer(window, &view);
  glfwSetMouseButtonCallback(window, on_button);
  glfwSetCursorPosCallback(window, on_cursor);
  glfwSetScrollCallback(window, on_scroll);
  glfwSetKeyCallback(window, on_key);
  // The panel (Dear ImGui): its GLFW backend chains to the callbacks above.
  struct Gui {
    bool on;
    void shutdown() {
      if (!on) return;
      on = false;
      ImGui_ImplOpenGL2_Shutdown();
      ImGui_ImplGlfw_Shutdown();
      ImGui::DestroyContext();
    }
    ~Gui() { shutdown(); }
  } gui{args.panel};
  if (gui.on) {
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to the user's files
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(window, true);
    ImGui_ImplOpenGL2_Init();
  }
  Panel panel(model, sim, args.integrator);

  // The servo loop starts once the window is up (creating a GL context can take a while).
  auto loop = std::make_unique<ServoLoop>(sim, contacts, instrument, *device, options);
  try {
    loop->start();
  } catch (const Error& e) {
    if (device != touch.get() || touch == nullptr) throw;
    std::fprintf(stderr, "fsm-viewer: no Touch (%s); the mouse drives the instrument\n", e.what());
    loop.reset();
    device = &mouse;
    device_label = "mouse";
    view.mouse_drives = true;
    loop = std::make_unique<ServoLoop>(sim, contacts, instrument, mouse, ServoOptions{});
    loop->start();
  }
  struct Stop {
    ServoLoop& loop;
    ~Stop() { loop.stop(); }
  } stop{*loop};

  ServoSnapshot snap;
  bool have_snap = false;
  long frames = 0;
  double fps = 0;
  using Clock = std::chrono::steady_clock;
  auto last = Clock::now(), fps_start = last;
  long fps_frames = 0;
  // Without vsync (Xvfb, some drivers) frames are capped near 60 Hz, leaving the CPU to the servo
  // loop; with vsync the swap has already waited longer than this.
  const auto frame_period = std::chrono::microseconds(15000);
  while (!glfwWindowShouldClose(window)) {
    glfwPollEvents();
    const auto now = Clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    ++fps_frames;
    if (now - fps_start > std::chrono::milliseconds(500)) {
      fps = double(fps_frames) / std::chrono::duration<double>(now - fps_start).count();
      fps_start = now;
      fps_frames = 0;
    }
    if (view.mouse_drives) {
      // Up/down arrows: 3 cm/s in depth.
      if (glfwGetKey(window, GLFW_KEY_UP) == GLFW_PRESS) push(view, 0.03 * dt);
      if (glfwGetKey(window, GLFW_KEY_DOWN) == GLFW_PRESS) push(view, -0.03 * dt);
      view.tip = view.tip.cwiseMax(reach_min).cwiseMin(reach_max);
      mouse.set_target({view.centre(), view.orientation, view.left ? 1u : 0u});
    }
    if (loop->read_snapshot(snap)) {
      model.skin.evaluate(snap.positions, ws, surface);
      bvh.refit(surface);  // picking sees the deformed surface
      have_snap = true;
    }

    if (have_snap) panel.record(snap);
    PanelRequest request;
    if (gui.on) {
      ImGui_ImplOpenGL2_NewFrame();
      ImGui_ImplGlfw_NewFrame();
      ImGui::NewFrame();
      request = panel.draw(snap, fps, loop->tripped(), loop->running(), view.show_spheres);
      ImGui::Render();
    }
    if (args.exercise_panel) request = scripted_request(frames, model);

    examples::SceneFrame f;
    f.model = &model;
    f.surface = &surface;
    f.show_surface = panel.show_surface;
    f.show_links = panel.show_links;
    f.spheres = (view.show_spheres || panel.show_links) && have_snap ? &snap.positions : nullptr;
    f.has_instrument = true;
    f.instrument =
        have_snap ? snap.instrument : collision::Pose<double>{view.centre(), view.orientation};
    f.instrument_radius = kShaftRadius;
    f.instrument_half_length = kHalfLength;
    f.force = snap.tissue_force;
    f.arrow_scale = 0.04;  // m per N: 1 N is 4 cm, a third of the uterus
    int width = 0, height = 0;
    glfwGetFramebufferSize(window, &width, &height);
    examples::draw_scene(f, view.camera, width, height);
    if (have_snap) draw_coupling(snap.instrument.position, snap.device_position);
    char caption[200];
    std::snprintf(caption, sizeof caption, "%s  t = %.2f s  force %.2f N  %.0f fps%s",
                  device_label.c_str(), snap.time, snap.tissue_force.norm(), fps,
                  loop->tripped() ? "  [force off: servo watchdog]" : "");
    if (!gui.on)  // the panel shows the same
      examples::draw_text(caption, 12, 12, 2.0f, {0.9f, 0.9f, 0.9f}, width, height);
    if (gui.on) ImGui_ImplOpenGL2_RenderDrawData(ImGui::GetDrawData());
    if (view.mouse_drives && !gui.on)
      examples::draw_text(
          "left-drag: tip  shift+scroll, up/down: depth  ctrl+click: onto surface  "
          "right-drag: orbit  scroll: zoom  space: spheres  r: reset  esc: quit",
          12, float(height) - 20, 1.2f, {0.7f, 0.7f, 0.7f}, width, height);

    ++frames;
    const bool last_frame = args.frames > 0 && frames >= args.frames;
    if (last_frame && !args.screenshot.empty()) {
      glReadBuffer(GL_BACK);
      examples::write_png(args.screenshot, examples::read_pixels(width, height), width, height);
    }
    glfwSwapBuffers(window);
    if (last_frame) break;

    // What the panel asked for. Changing the simulation stops the servo loop (the force goes to
    // zero), applies the change and starts the loop again, which ramps the force back in.
    if (request.go_to_part >= 0) {
      const Part& p = model.parts[std::size_t(request.go_to_part)];
      view.camera.target = (have_snap ? snap.positions : model.spheres.rest_positions())
                               .middleRows(p.first_node, p.num_nodes)
                               .colwise()
                               .mean()
                               .transpose();
      if (view.mouse_drives && p.num_nodes > 0) {
        const support::ProbeTarget tg =
            support::probe_target(model, p, kShaftRadius, kHalfLength, 0.003);
        view.orientation = tg.orientation;
        view.tip = tg.away - tg.orientation * V3(0, 0, kHalfLength + kShaftRadius);
      }
    }
    if (request.changes_simulation()) {
      loop->stop();
      panel.apply(request, make_stepper);
      if (request.reset) {
        have_snap = false;
        surface = model.skin.rest.vertices;
      }
      if (!panel.paused) loop->start();
    }
    std::this_thread::sleep_until(now + frame_period);
  }
  loop->stop();
  gui.shutdown();
  glfwDestroyWindow(window);

  const ServoStats st = loop->stats();
  std::printf(
      "fsm-viewer: %ld frames, %.2f s simulated; servo %zu ticks, period p99 %.0f us, missed "
      "deadlines %zu, watchdog trips %zu, peak force %.2f N\n",
      frames, snap.time, st.ticks, st.period_p99 * 1e6, st.missed_deadlines, st.watchdog_trips,
      st.peak_force);
  std::printf("fsm-viewer: panel: %d requests applied, %d refused\n", panel.applied, panel.refused);
  if (!args.screenshot.empty()) std::printf("fsm-viewer: wrote %s\n", args.screenshot.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (const int status = parse(argc, argv, args); status >= 0) return status;
  try {
    if (!args.check.empty()) {
      const double f = examples::png_non_background_fraction(args.check);
      const bool ok = f > args.min_fraction;
      std::printf("fsm-viewer: %s: %.1f%% of the pixels are not background (%s %.1f%%)\n",
                  args.check.c_str(), 100 * f, ok ? "more than" : "NOT more than",
                  100 * args.min_fraction);
      return ok ? 0 : 1;
    }
    return run(args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fsm-viewer: %s\n", e.what());
    return 1;
  }
}
