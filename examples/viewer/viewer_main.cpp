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

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "fsm/fsm.hpp"
#include "fsm/haptics/touch_device.hpp"
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
};

void usage() {
  std::printf(
      "usage: fsm-viewer [--model FILE.fsm|SCENE.json] [--device mouse|touch] [--scripted]\n"
      "                  [--frames N] [--screenshot PATH.png] [--size WxH]\n"
      "       fsm-viewer --check-screenshot PATH.png [--min-fraction F]\n"
      "  --model F             a model file, or a scene to build (default: the bundled uterus,\n"
      "                        built once and cached in $FSM_CACHE_DIR or ~/.cache/fsm)\n"
      "  --device D            mouse (default) or touch (falls back to the mouse without one)\n"
      "  --scripted            a scripted probe drives the instrument (no mouse)\n"
      "  --frames N            render N frames, then exit\n"
      "  --screenshot P        write the last frame as a PNG\n"
      "  --size WxH            window size in pixels (default 960x720)\n"
      "  --check-screenshot P  exit 0 when more than F of the PNG's pixels differ from its\n"
      "                        top-left one (default F = 0.05), 1 otherwise; opens no window\n"
      "mouse: left-drag moves the tip in the view plane, shift+scroll or up/down arrows move it\n"
      "in depth, ctrl+left-click puts it on the surface, right-drag orbits, scroll zooms.\n"
      "keys: space toggles the spheres, r resets the instrument, esc quits.\n");
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string s = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw Error("", "fsm-viewer", s + " needs a value");
      return argv[++i];
    };
    if (s == "--model") {
      a.model = value();
    } else if (s == "--device") {
      a.device = value();
      if (a.device != "mouse" && a.device != "touch")
        throw Error("", "fsm-viewer",
                    "--device must be 'mouse' or 'touch', not '" + a.device + "'");
    } else if (s == "--scripted") {
      a.scripted = true;
    } else if (s == "--frames") {
      a.frames = std::atol(value().c_str());
      if (a.frames < 1) throw Error("", "fsm-viewer", "--frames must be at least 1");
    } else if (s == "--screenshot") {
      a.screenshot = value();
    } else if (s == "--size") {
      const std::string v = value();
      if (std::sscanf(v.c_str(), "%dx%d", &a.width, &a.height) != 2 || a.width < 16 ||
          a.height < 16)
        throw Error("", "fsm-viewer", "--size wants WxH (at least 16x16), not '" + v + "'");
    } else if (s == "--check-screenshot") {
      a.check = value();
    } else if (s == "--min-fraction") {
      a.min_fraction = std::atof(value().c_str());
    } else if (s == "--help" || s == "-h") {
      usage();
      std::exit(0);
    } else {
      throw Error("", "fsm-viewer", "unknown argument '" + s + "' (try --help)");
    }
  }
  return a;
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
  const support::ProbeTarget first =
      support::probe_target(model, model.parts.front(), kShaftRadius, kHalfLength, 0.003);
  script.push_back({0.0, first.away, first.orientation, 0});
  for (double t = 0; t < total;) {
    for (const Part& p : model.parts) {
      if (p.num_nodes == 0) continue;
      const double depth = p.name == "body" || p.name == "fibroid" ? 0.004 : 0.0025;
      const support::ProbeTarget tg =
          support::probe_target(model, p, kShaftRadius, kHalfLength, depth);
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

void on_button(GLFWwindow* w, int button, int action, int mods) {
  View& v = view_of(w);
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
  if (v.mouse_drives && glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS)
    push(v, -0.002 * dy);  // scroll up pulls the tip toward the eye
  else
    v.camera.distance = std::clamp(v.camera.distance * std::pow(0.9, dy), 0.02, 5.0);
}

void on_key(GLFWwindow* w, int key, int, int action, int) {
  if (action != GLFW_PRESS) return;
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
  Simulation<double> sim(model.spheres, so);
  ImplicitEulerIntegrator<double>::Options io;
  io.tolerance = 1e-3;  // as fsm-demo: < 0.1 um from 1e-6 at a third of the CG iterations
  sim.set_integrator(std::make_unique<ImplicitEulerIntegrator<double>>(io));
  collision::ContactSolver<double> contacts(sim.model(), sim.forces());
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

    examples::SceneFrame f;
    f.model = &model;
    f.surface = &surface;
    f.spheres = view.show_spheres && have_snap ? &snap.positions : nullptr;
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
    examples::draw_text(caption, 12, 12, 2.0f, {0.9f, 0.9f, 0.9f}, width, height);
    if (view.mouse_drives)
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
    std::this_thread::sleep_until(now + frame_period);
  }
  glfwDestroyWindow(window);

  loop->stop();
  const ServoStats st = loop->stats();
  std::printf(
      "fsm-viewer: %ld frames, %.2f s simulated; servo %zu ticks, period p99 %.0f us, missed "
      "deadlines %zu, watchdog trips %zu, peak force %.2f N\n",
      frames, snap.time, st.ticks, st.period_p99 * 1e6, st.missed_deadlines, st.watchdog_trips,
      st.peak_force);
  if (!args.screenshot.empty()) std::printf("fsm-viewer: wrote %s\n", args.screenshot.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const Args args = parse(argc, argv);
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
