// A peer in the benchmark suite: Bullet's deformable bodies (btDeformableMultiBodyDynamicsWorld,
// btDeformableNeoHookeanForce, implicit backward Euler with one Newton iteration, CG, double
// precision) stepping the same tetrahedral mesh at the same 1 ms step under the same load as
// libfsm (implicit Euler, block-Jacobi CG; the link law and the continuum law), on one core.
// Built only when Bullet is found (Debian libbullet-dev, its bullet-float64 build).
//
// Meshes: a 20 mm cube (Freudenthal lattice, 2.5 mm: 729 nodes, 3,072 tetrahedra) fixed at its
// bottom face, and the bundled uterus's body part (its tetrahedra and their nodes) fixed where
// the bundled model fixes it plus its lowest tenth (alone, the body has no other support): a
// soft cantilever, bending-dominated. Load: gravity, 9.81 m/s^2 along -z on the cube and across
// the body's long axis (-x) on the body. Material: E =
// 13.15 kPa (the paper's small-strain modulus), nu = 0.45, 1050 kg/m^3, lumped masses shared;
// Bullet's Lame parameters from the same E and nu, its damping factor 0.05.
// Counters: sag_mm, the mean displacement along the load of the top face (cube) or of every free
// node (body) after settling 1.5 s (FSM_BENCH_SETTLE overrides; the smoke test runs 0.01 s); nodes,
// tetrahedra; for libfsm the CG iterations per step. FSM_BENCH_TRACE: the sag every 0.5 s of
// settling on stderr. FSM_BENCH_DUMP=DIR: the meshes as JSON for
// the CalculiX reference of the static sag (validation/peer_reference.py).

#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btDeformableNeoHookeanForce.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <benchmark/benchmark.h>
#include <btBulletDynamicsCommon.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include <cstdlib>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "common.hpp"
#include "fsm/builder/builder.hpp"
#include "fsm_support/model_cache.hpp"

namespace fsm::bench {
namespace {

constexpr double k_g = 9.81;  // the load: gravity, along -z (cube) or -x (uterus body)
constexpr double k_nu = 0.45;
// Settling time before the sag is read and the steps are timed (s); FSM_BENCH_SETTLE overrides it
// (the smoke test runs 0.01 s).
double settle_steps() {
  const char* s = std::getenv("FSM_BENCH_SETTLE");
  return (s ? std::atof(s) : 1.5) * 1e3;
}
// FSM_BENCH_TRACE set: the sag every 0.5 s of settling, on stderr (is it at rest?).
void trace(const char* who, int step, double sag) {
  if (std::getenv("FSM_BENCH_TRACE") && (step + 1) % 500 == 0)
    std::fprintf(stderr, "%s t = %.1f s: sag %.6g mm\n", who, 1e-3 * (step + 1), 1e3 * sag);
}

// The mesh both simulators step: vertices, tetrahedra, per-node mass and fixed flags.
struct SharedMesh {
  TetrahedralMesh<double> mesh;
  std::vector<double> mass;
  std::vector<char> fixed;
  std::vector<Index> measured;          // the nodes whose mean sag is reported
  Vector3<double> gravity{0, 0, -k_g};  // the load (m/s^2)
  // The mean displacement of the measured nodes along the load's direction.
  template <typename Positions>
  [[nodiscard]] double sag(const Positions& x) const {
    const Vector3<double> down = gravity.normalized();
    double sum = 0;
    for (const Index i : measured)
      sum +=
          down.dot(Vector3<double>(x(i, 0), x(i, 1), x(i, 2)) - mesh.vertices.row(i).transpose());
    return sum / double(measured.size());
  }
};

Material<double> tissue() {
  Material<double> m = support::paper::linear_tissue<double>();
  m.poisson_ratio = k_nu;
  return m;
}

// libfsm's model of the mesh: one sphere per vertex, one link per edge, lumped masses.
SphereModel<double> fsm_model(const SharedMesh& s) {
  SphereModel<double> m;
  add_tetrahedral_part(m, s.mesh, m.add_region("tissue", tissue()), 0.00125);
  for (Index i = 0; i < m.num_nodes(); ++i)
    if (s.fixed[std::size_t(i)]) m.set_fixed(i);
  return m;
}

SharedMesh cube() {
  SharedMesh s;
  s.mesh = make_cube_lattice(Vector3<double>::Zero().eval(), Eigen::Vector3i(8, 8, 8), 0.0025);
  const SphereModel<double> m = [&] {
    SphereModel<double> t;
    add_tetrahedral_part(t, s.mesh, t.add_region("tissue", tissue()), 0.00125);
    return t;
  }();
  for (Index i = 0; i < m.num_nodes(); ++i) {
    s.mass.push_back(m.masses()[i]);
    const double z = s.mesh.vertices(i, 2);
    s.fixed.push_back(z < 1e-6);
    if (z > 0.02 - 1e-6) s.measured.push_back(i);
  }
  return s;
}

// The bundled uterus's body part: its tetrahedra renumbered onto the nodes they use.
SharedMesh uterus_body() {
  const TissueModel<double>& model = support::bundled_uterus(
      [](const std::string& scene) { return build::build_model(scene); }, "bench_bullet");
  const Part& body = model.part("body");
  const auto tets = model.part_tetrahedra(body);
  std::vector<Index> local(std::size_t(model.spheres.num_nodes()), -1);
  std::vector<Index> global;
  for (Index t = 0; t < tets.rows(); ++t)
    for (int k = 0; k < 4; ++k)
      if (local[std::size_t(tets(t, k))] < 0) {
        local[std::size_t(tets(t, k))] = Index(global.size());
        global.push_back(tets(t, k));
      }
  SharedMesh s;
  s.mesh.vertices.resize(Index(global.size()), 3);
  for (std::size_t i = 0; i < global.size(); ++i)
    s.mesh.vertices.row(Index(i)) = model.spheres.rest_positions().row(global[i]);
  s.mesh.tetrahedra.resize(tets.rows(), 4);
  for (Index t = 0; t < tets.rows(); ++t)
    for (int k = 0; k < 4; ++k) s.mesh.tetrahedra(t, k) = local[std::size_t(tets(t, k))];
  SphereModel<double> m;
  add_tetrahedral_part(m, s.mesh, m.add_region("tissue", tissue()), 0.00125);
  for (std::size_t i = 0; i < global.size(); ++i) {
    s.mass.push_back(m.masses()[Index(i)]);
    const bool fixed = model.spheres.fixed()[global[i]] != 0;
    s.fixed.push_back(fixed);
    if (!fixed) s.measured.push_back(Index(i));
  }
  // The bundled body is held by its attachments to the other parts; alone it needs its own
  // support: fix its lowest 10 % (the cervix end) as well. The body's long axis is z: loaded
  // along it, the body is a column on its narrow end under its own weight, which most likely
  // buckles or tips (CalculiX found no static equilibrium past 30-54 % of gravity on this mesh);
  // loaded across it (-x), a cantilever.
  s.gravity = Vector3<double>(-k_g, 0, 0);
  double zmin = s.mesh.vertices.col(2).minCoeff(), zmax = s.mesh.vertices.col(2).maxCoeff();
  s.measured.clear();
  for (std::size_t i = 0; i < global.size(); ++i) {
    if (s.mesh.vertices(Index(i), 2) < zmin + 0.1 * (zmax - zmin)) s.fixed[i] = 1;
    if (!s.fixed[i]) s.measured.push_back(Index(i));
  }
  return s;
}

// FSM_BENCH_DUMP=DIR writes each shared mesh as DIR/peer_<name>.json (vertices in m, tetrahedra,
// fixed flags, the measured nodes, the material and the load), for the CalculiX reference of the
// static sag (validation/peer_reference.py).
void dump(const SharedMesh& s, const char* name) {
  const char* dir = std::getenv("FSM_BENCH_DUMP");
  if (!dir) return;
  nlohmann::json j;
  const Material<double> mat = tissue();
  j["name"] = name;
  j["youngs_modulus_pa"] = mat.youngs_modulus;
  j["poisson_ratio"] = k_nu;
  j["density"] = mat.density;
  j["gravity"] = {s.gravity.x(), s.gravity.y(), s.gravity.z()};
  for (Index i = 0; i < s.mesh.vertices.rows(); ++i)
    j["vertices"].push_back({s.mesh.vertices(i, 0), s.mesh.vertices(i, 1), s.mesh.vertices(i, 2)});
  for (Index t = 0; t < s.mesh.tetrahedra.rows(); ++t)
    j["tetrahedra"].push_back({s.mesh.tetrahedra(t, 0), s.mesh.tetrahedra(t, 1),
                               s.mesh.tetrahedra(t, 2), s.mesh.tetrahedra(t, 3)});
  for (std::size_t i = 0; i < s.fixed.size(); ++i)
    if (s.fixed[i]) j["fixed"].push_back(i);
  j["measured"] = s.measured;
  const std::string path = std::string(dir) + "/peer_" + name + ".json";
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw Error("bench_bullet: cannot write " + path);
  const std::string text = j.dump();
  std::fwrite(text.data(), 1, text.size(), f);
  std::fclose(f);
}

const SharedMesh& shared(int which) {
  static const SharedMesh c = [] {
    SharedMesh m = cube();
    dump(m, "cube");
    return m;
  }();
  if (which == 0) return c;
  static const SharedMesh u = [] {
    SharedMesh m = uterus_body();
    dump(m, "uterus_body");
    return m;
  }();
  return u;
}

// Bullet's deformable solver set as libfsm's: one Newton iteration (linearised backward Euler) and
// CG to r^T M^-1 r <= 1e-12 (Bullet's default is its machine epsilon).
struct PeerSolver : btDeformableBodySolver {
  PeerSolver() {
    m_maxNewtonIterations = 1;
    m_cg.setTolerance(btScalar(1e-12));
  }
};

// Bullet's world with the mesh as one deformable body.
struct BulletScene {
  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<PeerSolver> body_solver;
  std::unique_ptr<btDeformableMultiBodyConstraintSolver> solver;
  std::unique_ptr<btDeformableMultiBodyDynamicsWorld> world;
  std::unique_ptr<btDeformableGravityForce> gravity;
  std::unique_ptr<btDeformableNeoHookeanForce> elasticity;
  btSoftBody* body{nullptr};  // owned by the world's arrays; deleted in the destructor

  explicit BulletScene(const SharedMesh& s) : shared(s) {
    config = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
    dispatcher = std::make_unique<btCollisionDispatcher>(config.get());
    broadphase = std::make_unique<btDbvtBroadphase>();
    body_solver = std::make_unique<PeerSolver>();
    solver = std::make_unique<btDeformableMultiBodyConstraintSolver>();
    solver->setDeformableSolver(body_solver.get());
    world = std::make_unique<btDeformableMultiBodyDynamicsWorld>(
        dispatcher.get(), broadphase.get(), solver.get(), config.get(), body_solver.get());
    const btVector3 g(s.gravity.x(), s.gravity.y(), s.gravity.z());
    world->setGravity(g);
    world->getWorldInfo().m_gravity = g;
    const auto n = Index(s.mesh.vertices.rows());
    std::vector<btVector3> x(static_cast<std::size_t>(n));
    std::vector<btScalar> m(static_cast<std::size_t>(n));
    for (Index i = 0; i < n; ++i) {
      x[std::size_t(i)] =
          btVector3(s.mesh.vertices(i, 0), s.mesh.vertices(i, 1), s.mesh.vertices(i, 2));
      m[std::size_t(i)] = s.fixed[std::size_t(i)] ? 0 : s.mass[std::size_t(i)];
    }
    body = new btSoftBody(&world->getWorldInfo(), int(n), x.data(), m.data());
    std::set<std::pair<int, int>> edges;
    for (Index t = 0; t < s.mesh.tetrahedra.rows(); ++t) {
      int v[4];
      for (int k = 0; k < 4; ++k) v[k] = int(s.mesh.tetrahedra(t, k));
      body->appendTetra(v[0], v[1], v[2], v[3]);
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) edges.insert(std::minmax(v[a], v[b]));
    }
    for (const auto& [a, b] : edges) body->appendLink(a, b, nullptr, true);
    btSoftBodyHelpers::generateBoundaryFaces(body);
    body->initializeDmInverse();
    body->m_tetraScratches.resize(body->m_tetras.size());
    body->m_tetraScratchesTn.resize(body->m_tetras.size());
    body->m_cfg.collisions = 0;  // no contacts in this scene
    // Never put to sleep: a sleeping body stops short of its equilibrium (with the default, the
    // cube's sag froze at 0.162 mm from 1 s to 2 s, then at 0.151 mm).
    body->setActivationState(DISABLE_DEACTIVATION);
    world->addSoftBody(body);
    const Material<double> mat = tissue();
    const double E = mat.youngs_modulus;
    const double mu = E / (2 * (1 + k_nu)), lambda = E * k_nu / ((1 + k_nu) * (1 - 2 * k_nu));
    gravity = std::make_unique<btDeformableGravityForce>(g);
    world->addForce(body, gravity.get());
    elasticity = std::make_unique<btDeformableNeoHookeanForce>(mu, lambda, 0.05);
    world->addForce(body, elasticity.get());
    world->setImplicit(true);
    world->setLineSearch(false);
    // Fixed nodes as projections (Baraff-Witkin filtered CG): with the default Lagrange-multiplier
    // path, Bullet 3.24's implicit solve leaves a body whose fixed nodes have zero mass at rest.
    world->setUseProjection(true);
  }
  ~BulletScene() {
    if (world && body) {
      world->removeSoftBody(body);
      delete body;
    }
  }
  BulletScene(const BulletScene&) = delete;
  BulletScene& operator=(const BulletScene&) = delete;

  void step() { world->stepSimulation(btScalar(1e-3), 1, btScalar(1e-3)); }
  [[nodiscard]] double sag() const {
    return shared.sag([this](Index i, int c) { return double(body->m_nodes[int(i)].m_x[c]); });
  }
  const SharedMesh& shared;
};

void BM_BulletNeoHookeanStep(benchmark::State& state) {
  const SharedMesh& s = shared(int(state.range(0)));
  BulletScene scene(s);
  const std::string who = "bullet mesh " + std::to_string(state.range(0));
  for (int k = 0; k < int(settle_steps()); ++k) {
    scene.step();
    trace(who.c_str(), k, scene.sag());
  }
  const double sag = scene.sag();
  for (auto _ : state) scene.step();
  state.counters["sag_mm"] = 1e3 * sag;
  state.counters["nodes"] = double(s.mesh.vertices.rows());
  state.counters["tetrahedra"] = double(s.mesh.tetrahedra.rows());
}
BENCHMARK(BM_BulletNeoHookeanStep)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("uterus_body")
    ->Unit(benchmark::kMicrosecond);

// libfsm on the same mesh, load and step: implicit Euler (block-Jacobi CG), the link law (0), the
// continuum law (1) or the continuum law with node-smoothed deviatoric strains (2).
void BM_FsmSameMeshStep(benchmark::State& state) {
  const SharedMesh& s = shared(int(state.range(0)));
  SphereModel<double> model = fsm_model(s);
  if (state.range(1) != 0) model.set_region_law(0, ForceLaw::continuum);
  Simulation<double>::Options o;
  o.integrator = "implicit_euler";
  o.forces.gravity = s.gravity;
  // Drag 5/s (as the servo loop's models): the paper's viscosity alone damps the body's first
  // bending mode by well under 1 % of critical, so it would still swing at the sag's reading.
  // Drag does not change the static equilibrium.
  o.forces.drag = 5;
  if (state.range(1) == 2) o.forces.strain_smoothing = StrainSmoothing::node;
  Simulation<double> sim(std::move(model), o);
  const std::string who =
      "libfsm mesh " + std::to_string(state.range(0)) + " law " + std::to_string(state.range(1));
  for (int k = 0; k < int(settle_steps()); ++k) {
    sim.step(1e-3);
    trace(who.c_str(), k, s.sag(sim.model().positions()));
  }
  const double sag = s.sag(sim.model().positions());
  long iterations = 0, steps = 0;
  for (auto _ : state) {
    iterations += sim.step(1e-3).solver_iterations;
    ++steps;
  }
  state.counters["sag_mm"] = 1e3 * sag;
  state.counters["cg_iters"] = double(iterations) / double(std::max(steps, 1L));
  state.counters["nodes"] = double(s.mesh.vertices.rows());
  state.counters["tetrahedra"] = double(s.mesh.tetrahedra.rows());
}
BENCHMARK(BM_FsmSameMeshStep)
    ->ArgsProduct({{0, 1}, {0, 1, 2}})
    ->ArgNames({"uterus_body", "continuum"})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fsm::bench
