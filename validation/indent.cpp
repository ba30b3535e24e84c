// fsm-indent: the paper's indentation experiment (docs/physics.md section 10.6) on a model built by
// the library's own builder from a scene, for the validation against a reference FEM
// (docs/validation.md).
//
//   fsm-indent SCENE.json --case compression|punch|sphere|cylinder|rounded_cylinder
//              [--law links|continuum]
//              [--nu NU] [--smoothing element|face|edge|node] [--element-share A] [--depth MM]
//              [--speed MM_PER_MIN] [--samples N] [--dt S]
//              [--integrator NAME] [--stiffness-scale F] [--poisson NU | --kappa PA]
//              [--density-scale F] [--out CSV]
//
// The scene's single part is a 20 x 20 x 10 mm block (z up). Its lowest layer of spheres is fixed
// (bottom bonded). The tool moves down at the given speed:
// - bonded (the loaded spheres held in x and y and moved down): "compression" = the top layer (a
//   platen over the whole top), "punch" = the top spheres within 2 mm of the top's centre in x and
//   y (a 4 x 4 mm flat punch);
// - through contact (ContactSolver, frictionless, as a user's instrument): "sphere" = a rigid ball
//   of radius 5 mm, "cylinder" = a rigid flat-ended cylinder of radius 3 mm (axis z),
//   "rounded_cylinder" = the same cylinder with its rim rounded to 1 mm (a flat end of radius
//   2 mm), each over the top's centre and touching the top at the start.
// --law continuum gives the part the continuum law (neo-Hookean tetrahedra) with Poisson's ratio
// --nu (default 0.49); --law links (the default) keeps the paper's link network, optionally with
// the volume term (--poisson / --kappa). The force on the tool (bonded: the z-sum of the internal
// forces on the loaded spheres; contact: the z force of the instrument's wrench) is sampled at
// `samples` equal steps of the displacement (at 5 mm/min to 2.5 mm, 30 samples = 1 Hz). Gravity
// is off (the reference has none). Prints a JSON summary on stdout. For the contact indenters it
// also reports how deep any sphere centre (`max_penetration_m`) and any point of the filling's
// boundary faces (`max_face_penetration_m`, sampled at each force sample) got inside the tool: the
// vertex contact holds the centres out, while the flat faces between them may cut through a rim.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/scene.hpp"
#include "fsm/fsm.hpp"
#include "fsm/volume_term.hpp"
#include "fsm_support/cli.hpp"

namespace {

struct Args {
  std::string scene;
  std::string load_case = "compression";
  std::string law = "links";
  std::string contact = "vertices";   // how the contact indenters meet the block
  std::string smoothing = "element";  // continuum law: how the deviatoric strain is measured
  double element_share = 0.1;         // continuum law, smoothed: the element strain's share
  double nu = 0.49;
  double depth = 2.5e-3;     // m
  double speed = 5e-3 / 60;  // m/s
  int samples = 30;          //
  double dt = 1e-3;          // s
  double dt_fraction = 0;    // > 0: dt = this x the stable step, capped at dt
  std::string integrator = "implicit_euler";
  double stiffness_scale = 1;  //
  double poisson = 0;          // 0 = no volume term
  double kappa = -1;           // Pa; < 0 = from poisson
  double density_scale = 1;    //
  std::string out;
};

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr, "fsm-indent: %s\nRun with --help for more information.\n", why.c_str());
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  CLI::App app(
      "The paper's indentation experiment on a one-part scene: a displacement-controlled "
      "tool presses the block; prints a JSON summary (docs/validation.md).",
      "fsm-indent");
  fsm::support::add_version_flag(app);
  double depth_mm = a.depth * 1e3, speed_mm_min = a.speed * 1e3 * 60;
  app.add_option("scene", a.scene, "a one-part scene (JSON)")->required();
  app.add_option("--case", a.load_case, "the load")
      ->check(CLI::IsMember({"compression", "punch", "sphere", "cylinder", "rounded_cylinder"}))
      ->capture_default_str();
  app.add_option("--contact", a.contact,
                 "contact cases: the block meets the tool at its vertices or at sample points on "
                 "its boundary faces (ContactOptions::face_contact)")
      ->check(CLI::IsMember({"vertices", "faces"}))
      ->capture_default_str();
  app.add_option("--law", a.law, "force law")
      ->check(CLI::IsMember({"links", "continuum"}))
      ->capture_default_str();
  app.add_option("--nu", a.nu, "Poisson's ratio of the continuum law")->capture_default_str();
  app.add_option("--smoothing", a.smoothing,
                 "continuum law: the deviatoric strain per element or smoothed over faces "
                 "(ForceModel::Options::strain_smoothing)")
      ->check(CLI::IsMember({"element", "face", "edge", "node"}))
      ->capture_default_str();
  app.add_option("--element-share", a.element_share,
                 "continuum law, smoothed strain: the element strain's share of the deviatoric "
                 "energy (ForceModel::Options::smoothing_element_share)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--depth", depth_mm, "indentation depth (mm)")
      ->check(fsm::support::positive_number())
      ->capture_default_str();
  app.add_option("--speed", speed_mm_min, "tool speed (mm/min)")
      ->check(fsm::support::positive_number())
      ->capture_default_str();
  app.add_option("--samples", a.samples, "force samples along the depth")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--dt", a.dt, "time step (s)")
      ->check(fsm::support::positive_number())
      ->capture_default_str();
  app.add_option("--dt-fraction", a.dt_fraction,
                 "> 0: the step is this fraction of the stable step, capped at --dt");
  app.add_option("--integrator", a.integrator, "integrator name")
      ->check(CLI::IsMember(fsm::integrator_names()))
      ->capture_default_str();
  app.add_option("--stiffness-scale", a.stiffness_scale, "a factor on the link stiffness")
      ->check(fsm::support::positive_number());
  app.add_option("--poisson", a.poisson, "link law: a volume term for this Poisson's ratio");
  app.add_option("--kappa", a.kappa, "link law: a volume term of this bulk modulus (Pa)");
  app.add_option("--density-scale", a.density_scale, "a factor on the density (mass scaling)")
      ->check(fsm::support::positive_number());
  app.add_option("--out", a.out, "write the force-displacement curve as CSV");
  if (const int status = fsm::support::parse_command_line(app, argc, argv); status >= 0)
    std::exit(status);
  a.depth = depth_mm * 1e-3;
  a.speed = speed_mm_min * 1e-3 / 60;
  if (a.law == "continuum" && (a.poisson > 0 || a.kappa > 0))
    usage("the volume term (--poisson, --kappa) is for the link law; give --nu");
  if (!(a.depth > 0) || !(a.speed > 0) || !(a.dt > 0) || a.samples < 1 ||
      !(a.stiffness_scale > 0) || !(a.density_scale > 0))
    usage("depth, speed, dt, samples, scales must be positive");
  return a;
}

// The boundary faces of a tetrahedral filling: faces of exactly one tetrahedron (node indices).
std::vector<std::array<fsm::Index, 3>> boundary_faces(const fsm::SphereModel<double>& model) {
  std::vector<std::array<fsm::Index, 3>> faces;
  const auto tets = model.tetrahedra();
  faces.reserve(4 * std::size_t(tets.rows()));
  for (fsm::Index t = 0; t < tets.rows(); ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<fsm::Index, 3> f{};
      for (int k = 0, m = 0; k < 4; ++k)
        if (k != skip) f[std::size_t(m++)] = tets(t, k);
      std::sort(f.begin(), f.end());
      faces.push_back(f);
    }
  std::sort(faces.begin(), faces.end());
  std::vector<std::array<fsm::Index, 3>> once;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j - i == 1) once.push_back(faces[i]);
    i = j;
  }
  return once;
}

// JSON has no inf or NaN: null instead.
std::string json_number(double x) {
  if (!std::isfinite(x)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", x);
  return b;
}

int run(const Args& a) {
  using namespace fsm;
  const build::Scene scene = build::load_scene(a.scene);
  if (scene.parts.size() != 1) usage("the scene must have exactly one part");
  build::BuildReport report;
  TissueModel<double> tissue = build::build_model(a.scene, &report);
  SphereModel<double>& model = tissue.spheres;
  const Index n = model.num_nodes();
  const bool contact =
      a.load_case == "sphere" || a.load_case == "cylinder" || a.load_case == "rounded_cylinder";
  if (a.law == "continuum") {
    // E as the scene gives it, nu as asked: the law takes them as they are (no factor).
    Material<double> m = model.region(0).material;
    m.poisson_ratio = a.nu;
    model.set_region_material(0, m);
    model.set_region_law(0, ForceLaw::continuum);
  }

  // The global calibration factor multiplies every link's constants (stiffness and damping, so
  // the retardation time is unchanged).
  model.stiffness() *= a.stiffness_scale;
  model.large_stiffness() *= a.stiffness_scale;
  model.damping() *= a.stiffness_scale;
  model.masses() *= a.density_scale;

  // The block's extent from the rest positions.
  const auto rest = model.rest_positions();
  const double zmin = rest.col(2).minCoeff(), zmax = rest.col(2).maxCoeff();
  const double cx = 0.5 * (rest.col(0).minCoeff() + rest.col(0).maxCoeff());
  const double cy = 0.5 * (rest.col(1).minCoeff() + rest.col(1).maxCoeff());
  const double tol = 1e-6;  // m: surface vertices of the filling lie on the box faces
  std::vector<Index> driven;
  for (Index i = 0; i < n; ++i) {
    model.set_fixed(i, rest(i, 2) <= zmin + tol);  // the lowest layer, whatever the scene fixed
    if (!contact && rest(i, 2) >= zmax - tol) {
      const bool in_punch =
          std::abs(rest(i, 0) - cx) <= 2e-3 + tol && std::abs(rest(i, 1) - cy) <= 2e-3 + tol;
      if (a.load_case == "compression" || in_punch) {
        driven.push_back(i);
        model.set_fixed(i);
      }
    }
  }
  if (!contact && driven.empty()) throw Error(a.scene, "", "no sphere under the tool");

  // Optional volume term on the filling's tetrahedra (tetrahedral parts only; the model keeps
  // them).
  VolumeTerm<double> volume;
  double kappa = 0;
  if (a.poisson > 0 || a.kappa > 0) {
    const build::PartSpec& spec = scene.parts[0];
    if (tissue.spheres.num_tetrahedra() == 0)
      throw Error(a.scene, spec.name, "the volume term needs a tetrahedral part");
    // kappa for the target Poisson's ratio at the network's (scaled) shear modulus.
    kappa = a.kappa >= 0 ? a.kappa
                         : VolumeTerm<double>::bulk_modulus_for(
                               spec.material.youngs_modulus * a.stiffness_scale, a.poisson);
    volume = VolumeTerm<double>(TetrahedronArray(tissue.spheres.tetrahedra()), rest, kappa);
  }

  Simulation<double>::Options opt;
  opt.integrator = a.integrator;
  opt.forces.gravity.setZero();
  opt.forces.strain_smoothing = a.smoothing == "face"   ? StrainSmoothing::face
                                : a.smoothing == "edge" ? StrainSmoothing::edge
                                : a.smoothing == "node" ? StrainSmoothing::node
                                                        : StrainSmoothing::element;
  opt.forces.smoothing_element_share = a.element_share;
  Simulation<double> sim(std::move(model), opt);
  // The contact indenters: frictionless, as a user's instrument (default ContactOptions but for
  // --contact).
  collision::ContactOptions<double> contact_options;
  contact_options.face_contact = a.contact == "faces";
  collision::ContactSolver<double> contacts(sim.model(), sim.forces(), contact_options);
  collision::Instrument<double> tool;
  tool.friction = 0;
  const double radius = a.load_case == "sphere" ? 5e-3 : 3e-3;
  const double half_length = 5e-3;  // cylinder: 10 mm long, its flat end on the top at the start
  if (a.load_case == "sphere")
    tool.shape = collision::SphereShape<double>{radius};
  else  // rounded_cylinder: the same with 1 mm rims (validation/fem.py, EDGE_R)
    tool.shape = collision::CylinderShape<double>{radius, half_length,
                                                  a.load_case == "rounded_cylinder" ? 1e-3 : 0.0};
  const double start_z = zmax + (a.load_case == "sphere" ? radius : half_length);
  tool.pose.position = Vector3<double>(cx, cy, start_z);
  tool.linear_velocity = Vector3<double>(0, 0, -a.speed);
  const Index tool_index = contact ? contacts.add_instrument(tool) : Index(-1);
  long softened = 0, inverted_steps = 0, iterations = 0, unconverged = 0;
  // How deep any sphere centre got inside the tool over the run (m): the contact must hold the
  // tissue out (a penalty leaves a small penetration, a fixed share of the deformation).
  double max_penetration = 0;
  auto track_clearance = [&] {
    const auto& ins = contacts.instrument(tool_index);
    const auto x = sim.model().positions();
    for (Index i = 0; i < x.rows(); ++i) {
      const auto c =
          collision::contact(ins.shape, ins.pose, Vector3<double>(x.row(i).transpose()), 0.0);
      if (c) max_penetration = std::max(max_penetration, c->depth);
    }
  };
  // How deep any point of the boundary faces got inside the tool (m), at the force samples: each
  // face sampled at the 45 points of a barycentric grid of step 1/8 (vertices, edges, interior).
  const std::vector<std::array<Index, 3>> faces =
      contact ? boundary_faces(sim.model()) : std::vector<std::array<Index, 3>>{};
  double max_face_penetration = 0;
  auto track_face_clearance = [&] {
    const auto& ins = contacts.instrument(tool_index);
    const auto x = sim.model().positions();
    constexpr int m = 8;
    for (const auto& f : faces) {
      const Vector3<double> xa = x.row(f[0]).transpose(), xb = x.row(f[1]).transpose(),
                            xc = x.row(f[2]).transpose();
      for (int u = 0; u <= m; ++u)
        for (int v = 0; u + v <= m; ++v) {
          const Vector3<double> p =
              (double(u) * xa + double(v) * xb + double(m - u - v) * xc) / double(m);
          if (const auto hit = collision::contact(ins.shape, ins.pose, p, 0.0))
            max_face_penetration = std::max(max_face_penetration, hit->depth);
        }
    }
  };
  const double omega_v2 = volume.num_tetrahedra() > 0
                              ? volume.omega_max_squared(sim.model().masses(), sim.model().fixed())
                              : 0.0;

  // The step: dt, or a fraction of the largest stable step of the scheme (Simulation's estimate)
  // and of the explicit volume term (h omega_V < 2), whichever is smaller.
  double dt = a.dt;
  if (a.dt_fraction > 0) {
    double limit = double(sim.stable_time_step());
    if (omega_v2 > 0) limit = std::min(limit, 2.0 / std::sqrt(omega_v2));
    if (std::isfinite(limit)) dt = std::min(dt, a.dt_fraction * limit);
  }
  const double t_end = a.depth / a.speed;
  const long steps = std::lround(std::ceil(t_end / dt - 1e-9));
  std::vector<double> sample_d, sample_f;
  sample_d.push_back(0);
  sample_f.push_back(0);
  int next_sample = 1, diverged = 0, recovered = 0;
  double step_seconds = 0, volume_seconds = 0;
  Positions<double> link_force(n, 3);

  // Force on the tool. Bonded: the internal forces (links or elements, and the volume term) on the
  // loaded spheres, in z. Contact: the z force of the instrument's end-of-step wrench.
  auto tool_force = [&]() {
    if (contact) return contacts.wrench(tool_index).force.z();
    const auto& m = sim.model();
    sim.forces().evaluate(m, m.positions(), m.velocities(), link_force);
    link_force -= sim.external_forces();  // the volume term's stale copy: recomputed below
    if (volume.num_tetrahedra() > 0) volume.add_forces(m.positions(), link_force);
    double fz = 0;
    for (Index i : driven) fz += link_force(i, 2);
    return fz;  // the tissue pushes the tool up: positive in compression
  };

  std::vector<double> step_times;  // s; the median is robust to other load on the machine
  step_times.reserve(std::size_t(steps));
  bool finite = true;
  for (long s = 1; s <= steps; ++s) {
    const double t = std::min(t_end, double(s) * dt);
    const double d = a.speed * t;
    auto x = sim.model().positions();
    for (Index i : driven) x(i, 2) = sim.model().rest_positions()(i, 2) - d;
    const auto t0 = std::chrono::steady_clock::now();
    if (contact) {  // the tool at the step's start; the contacts move it through the step
      contacts.instrument(tool_index).pose.position.z() =
          start_z - a.speed * std::min(t_end, double(s - 1) * dt);
      contacts.compute(sim.model(), sim.forces());
    }
    if (volume.num_tetrahedra() > 0) {
      auto fe = sim.external_forces();
      fe.setZero();
      volume.add_forces(sim.model().positions(), fe);
    }
    const auto t1 = std::chrono::steady_clock::now();
    const StepReport<double> r = sim.step(dt);
    if (contact) contacts.collect(sim.forces());
    const auto t2 = std::chrono::steady_clock::now();
    softened = std::max<long>(softened, r.softened_contacts);
    if (contact) {
      // The tool where the step left it (its start plus the step's motion).
      contacts.instrument(tool_index).pose.position.z() = start_z - a.speed * t;
      track_clearance();
    }
    inverted_steps += r.inverted_elements > 0;
    iterations += r.solver_iterations;
    unconverged += r.unconverged_solves;
    volume_seconds += std::chrono::duration<double>(t1 - t0).count();
    step_seconds += std::chrono::duration<double>(t2 - t0).count();
    step_times.push_back(std::chrono::duration<double>(t2 - t0).count());
    diverged += r.status == StepStatus::diverged;
    recovered += r.status == StepStatus::recovered;
    if (!sim.model().positions().allFinite()) {
      finite = false;
      break;
    }
    while (next_sample <= a.samples &&
           d >= a.depth * double(next_sample) / a.samples - 1e-12 * a.depth) {
      sample_d.push_back(d);
      sample_f.push_back(tool_force());
      if (contact) track_face_clearance();
      ++next_sample;
    }
  }

  if (!a.out.empty()) {
    std::ofstream f(a.out);
    if (!f) throw Error(a.out, "", "cannot write");
    f << "displacement_mm,force_N\n";
    char line[96];
    for (std::size_t k = 0; k < sample_d.size(); ++k) {
      std::snprintf(line, sizeof line, "%.6f,%.6g\n", sample_d[k] * 1e3, sample_f[k]);
      f << line;
    }
  }
  const auto& q = report.parts[0].quality;
  std::nth_element(step_times.begin(), step_times.begin() + long(step_times.size() / 2),
                   step_times.end());
  const double median_step = step_times.empty() ? 0.0 : step_times[step_times.size() / 2];
  std::printf(
      "{\"scene\": \"%s\", \"topology\": \"%s\", \"case\": \"%s\", \"integrator\": \"%s\", "
      "\"dt\": %.6g, \"spheres\": %d, \"links\": %d, \"tetrahedra\": %d, \"fixed\": %d, "
      "\"driven\": %zu, \"stiffness_scale\": %.6g, \"kappa\": %.6g, \"poisson\": %.4g, "
      "\"steps\": %ld, \"diverged\": %d, \"recovered\": %d, \"finite\": %s, "
      "\"mean_step_us\": %.4g, \"median_step_us\": %.4g, \"volume_term_us\": %.4g, \"omega_max\": "
      "%.6g, "
      "\"omega_volume\": %.6g, \"stable_dt\": %s, \"mean_edge_m\": %.6g, "
      "\"final_force_N\": %s, \"samples\": %zu, \"law\": \"%s\", \"nu\": %.4g, "
      "\"softened_contacts\": %ld, \"inverted_steps\": %ld, \"max_penetration_m\": %s, "
      "\"max_face_penetration_m\": %s, "
      "\"mean_iterations\": %.4g, \"unconverged_solves\": %ld, \"smoothing\": \"%s\", "
      "\"element_share\": %.4g}\n",
      a.scene.c_str(), to_string(tissue.parts[0].topology), a.load_case.c_str(),
      a.integrator.c_str(), dt, sim.model().num_nodes(), sim.model().num_links(), q.tetrahedra,
      sim.model().num_fixed(), driven.size(), a.stiffness_scale, kappa, a.poisson, steps, diverged,
      recovered, finite ? "true" : "false", 1e6 * step_seconds / double(steps), 1e6 * median_step,
      1e6 * volume_seconds / double(steps), sim.spectral_bound().omega_max, std::sqrt(omega_v2),
      json_number(double(sim.stable_time_step())).c_str(), q.mean_edge,
      json_number(sample_f.back()).c_str(), sample_d.size(), a.law.c_str(),
      a.law == "continuum" ? a.nu : 0.0, softened, inverted_steps,
      json_number(contact ? max_penetration : std::nan("")).c_str(),
      json_number(contact && !faces.empty() ? max_face_penetration : std::nan("")).c_str(),
      double(iterations) / double(std::max(steps, 1L)), unconverged, a.smoothing.c_str(),
      a.smoothing == "element" ? 1.0 : a.element_share);
  return finite && diverged == 0 ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  try {
    return run(a);
  } catch (const fsm::Error& e) {
    std::fprintf(stderr, "fsm-indent: %s\n", e.what());
    return 1;
  }
}
