// ContactSolver: the spatial hash finds the same contacts and forces as testing every sphere;
// momentum balance between instruments and tissue; the penalty, damping and friction laws; part
// contact; no tunnelling at 0.5 m/s and 1 kHz; degenerate input; sleeping.

#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <tuple>

#include "common.hpp"
#include "fsm/collision/contact.hpp"

namespace fsm::test {
namespace {

using namespace fsm::collision;
using V3 = Vector3<double>;

// Random spheres in a 4 cm box, three regions, random links between near neighbours of one region.
SphereModel<double> random_spheres(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> u(0, 0.04), r(0.001, 0.004);
  SphereModel<double> m;
  for (int k = 0; k < 3; ++k)
    m.add_region("r" + std::to_string(k), tissue<double>(10000.0 + 5000 * k));
  for (int i = 0; i < n; ++i) m.add_node(V3(u(rng), u(rng), u(rng)), r(rng), 0.001, i % 3);
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      if (i % 3 == j % 3 && (m.rest_positions().row(i) - m.rest_positions().row(j)).norm() < 0.006)
        m.add_link(i, j, 50.0, 0.1);
  // Move and shake them so parts interpenetrate beyond their rest overlap.
  std::normal_distribution<double> g(0, 0.003);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      m.positions()(i, c) += g(rng);
      m.velocities()(i, c) = 0.1 * g(rng) / 0.003;
    }
  return m;
}

std::vector<Instrument<double>> random_instruments(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 0.04), a(-1, 1);
  std::vector<Instrument<double>> out;
  Instrument<double> s;
  s.name = "ball";
  s.shape = SphereShape<double>{0.006};
  Instrument<double> c;
  c.name = "shaft";
  c.shape = CapsuleShape<double>{0.003, 0.02};
  Instrument<double> y;
  y.name = "cylinder";
  y.shape = CylinderShape<double>{0.004, 0.01};
  for (Instrument<double>* ins : {&s, &c, &y}) {
    ins->pose.position = V3(u(rng), u(rng), u(rng));
    ins->pose.orientation =
        Eigen::Quaterniond(Eigen::AngleAxisd(3 * a(rng), V3(a(rng), a(rng), a(rng)).normalized()));
    ins->linear_velocity = V3(a(rng), a(rng), a(rng)) * 0.1;
    ins->angular_velocity = V3(a(rng), a(rng), a(rng));
    out.push_back(*ins);
  }
  return out;
}

// The hash cell is floor(p / cell) without libm: integers, negative fractions (truncation would
// round them up), the clamp at +-2^28, and a NaN (no undefined conversion).
TEST(ContactSolver, HashCellIsTheFloorOfTheScaledPoint) {
  using fsm::collision::detail::hash_cell;
  const double inv = 1.0 / 0.002;  // 2 mm cells
  EXPECT_EQ(hash_cell(Eigen::RowVector3d(0.0, -0.0, 0.001), inv), Eigen::Vector3i(0, 0, 0));
  EXPECT_EQ(hash_cell(Eigen::RowVector3d(-0.001, -0.002, -0.0030001), inv),
            Eigen::Vector3i(-1, -1, -2));
  EXPECT_EQ(hash_cell(Eigen::RowVector3d(0.004, 0.0039999, -1e-12), inv),
            Eigen::Vector3i(2, 1, -1));
  const double big = 1e300, nan = std::numeric_limits<double>::quiet_NaN();
  const int lim = 1 << 28;
  EXPECT_EQ(hash_cell(Eigen::RowVector3d(big, -big, nan), inv), Eigen::Vector3i(lim, -lim, -lim));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 1000; ++k) {
    const Eigen::RowVector3d p(u(rng), u(rng), 1e-3 * u(rng));
    const Eigen::Vector3i c = hash_cell(p, inv);
    for (int a = 0; a < 3; ++a) EXPECT_EQ(c[a], int(std::floor(p[a] * inv))) << p;
  }
}

TEST(ContactSolver, SpatialHashMatchesBruteForce) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const SphereModel<double> m = random_spheres(rng, 150);
    const auto instruments = random_instruments(rng);
    ContactOptions<double> hashed, brute;
    hashed.part_friction = brute.part_friction = 0.3;
    brute.spatial_hash = false;
    ContactSolver<double> a(m, hashed), b(m, brute);
    for (const auto& ins : instruments) {
      a.add_instrument(ins);
      b.add_instrument(ins);
    }
    Positions<double> fa = Positions<double>::Zero(m.num_nodes(), 3), fb = fa;
    a.compute(m, fa);
    b.compute(m, fb);
    EXPECT_EQ(a.num_contacts(), b.num_contacts()) << trial;
    EXPECT_GT(b.num_contacts(), 0);
    EXPECT_LT((fa - fb).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, fb.cwiseAbs().maxCoeff()))
        << trial;
    for (Index k = 0; k < a.num_instruments(); ++k)
      EXPECT_TRUE(matrices_near(a.wrench(k).force, b.wrench(k).force, 1e-12));
    EXPECT_LT(a.candidates(), b.candidates());  // and it did less work
  }
}

// What the tissue gets, the instrument gets back: the sphere forces of instrument contacts sum to
// minus the instrument force, their moments about the pose origin to minus its torque; part
// contacts sum to zero.
TEST(ContactSolver, MomentumBalance) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    const SphereModel<double> m = random_spheres(rng, 150);
    const auto instruments = random_instruments(rng);
    ContactOptions<double> o;
    o.part_contact = false;
    ContactSolver<double> with_tools(m, o);
    for (const auto& ins : instruments) with_tools.add_instrument(ins);
    Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
    with_tools.compute(m, f);
    V3 total = f.colwise().sum().transpose();
    for (Index k = 0; k < with_tools.num_instruments(); ++k) total += with_tools.wrench(k).force;
    EXPECT_LT(total.norm(), 1e-12 * std::max(1.0, f.cwiseAbs().sum()));
    for (Index k = 0; k < with_tools.num_instruments(); ++k) {
      V3 moment = V3::Zero();
      for (Index c = 0; c < with_tools.num_contacts(); ++c) {
        const auto& ct = with_tools.contacts()[c];
        if (ct.instrument == k)
          moment += (ct.point - instruments[std::size_t(k)].pose.position).cross(ct.force);
      }
      EXPECT_TRUE(matrices_near((-moment).eval(), with_tools.wrench(k).torque, 1e-12));
    }
    ContactSolver<double> parts_only(m);
    Positions<double> g = Positions<double>::Zero(m.num_nodes(), 3);
    parts_only.compute(m, g);
    EXPECT_GT(parts_only.num_contacts(), 0);
    EXPECT_LT(g.colwise().sum().norm(), 1e-12 * std::max(1.0, g.cwiseAbs().sum()));
  }
}

// One sphere, one instrument: the static force is k delta (k = stiffness_ratio times the sphere's
// tissue stiffness, here m / (1 ms)^2 for a loose sphere); approaching adds damping, separating
// removes it but never pulls; sliding gives mu f_n against the slip.
TEST(ContactSolver, PenaltyDampingAndFrictionLaws) {
  SphereModel<double> m;
  const double E = 20000, r = 0.003, mass = 0.002;
  m.add_node(V3(0, 0, 0.0045), r, mass, m.add_region("tissue", tissue<double>(E)));
  Instrument<double> ball;
  ball.shape = SphereShape<double>{0.002};
  ball.friction = 0.4;
  ContactSolver<double> solver(m);
  const Index k = solver.add_instrument(ball);
  Positions<double> f = Positions<double>::Zero(1, 3);
  solver.compute(m, f);
  const double delta = 0.005 - 0.0045, kc = 100 * mass / 1e-6;  // default stiffness_ratio 100
  EXPECT_DOUBLE_EQ(solver.contact_stiffness(0), kc);
  EXPECT_NEAR(f(0, 2), kc * delta, 1e-12);
  EXPECT_NEAR(f(0, 0), 0.0, 1e-15);
  EXPECT_TRUE(matrices_near(solver.wrench(k).force, V3(-f.row(0).transpose()), 1e-14));
  // Approaching (sphere moving down onto the tool) adds damping.
  m.velocities()(0, 2) = -0.01;
  f.setZero();
  solver.compute(m, f);
  const double c = 2 * 0.5 * std::sqrt(kc * mass);
  EXPECT_NEAR(f(0, 2), kc * delta + c * 0.01, 1e-12);
  // Separating fast: the damping would pull; the force is clamped at zero.
  m.velocities()(0, 2) = 10.0;
  f.setZero();
  solver.compute(m, f);
  EXPECT_EQ(f(0, 2), 0.0);
  // Sliding along x at 0.1 m/s (>> the 1 mm/s regularisation): friction mu f_n against the slip.
  m.velocities().row(0) << 0.1, 0, 0;
  f.setZero();
  solver.compute(m, f);
  EXPECT_NEAR(f(0, 0), -0.4 * kc * delta, 1e-4 * kc * delta);
  // The tool moving instead of the sphere gives the opposite slip.
  m.velocities().setZero();
  solver.instrument(k).linear_velocity = V3(0.1, 0, 0);
  f.setZero();
  solver.compute(m, f);
  EXPECT_NEAR(f(0, 0), 0.4 * kc * delta, 1e-4 * kc * delta);
}

// A model or force array of another size than the solver was sized for is reported, not
// skipped in silence; refresh() sizes the solver again.
TEST(ContactSolver, ReportsAModelOfAnotherSize) {
  SphereModel<double> m = block<double>({2, 2, 2}, 0.004);
  Instrument<double> ball;
  ball.shape = SphereShape<double>{0.003};
  ball.pose.position = m.rest_positions().row(0).transpose();
  ContactSolver<double> solver(m);
  solver.add_instrument(ball);
  EXPECT_EQ(solver.num_nodes(), m.num_nodes());
  Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
  EXPECT_TRUE(solver.compute(m, f));
  EXPECT_GT(solver.num_contacts(), 0);
  Positions<double> short_f = Positions<double>::Zero(m.num_nodes() - 1, 3);
  EXPECT_FALSE(solver.compute(m, short_f));
  EXPECT_EQ(solver.num_contacts(), 0);
  EXPECT_EQ(short_f.norm(), 0.0);
  m.add_node(V3(1, 1, 1), 0.002, 0.001, 0);
  f.setZero(m.num_nodes(), 3);
  EXPECT_FALSE(solver.compute(m, f));
  EXPECT_EQ(f.norm(), 0.0);
  EXPECT_EQ(solver.project(m), -1);
  solver.refresh(m);
  EXPECT_EQ(solver.num_nodes(), m.num_nodes());
  EXPECT_TRUE(solver.compute(m, f));
  EXPECT_GT(solver.num_contacts(), 0);
  EXPECT_GE(solver.project(m), 1);
}

// Two parts touching at rest: no force at rest; pressed together they push apart, equal and
// opposite; linked pairs are left to their links.
TEST(ContactSolver, PartContactStartsAtTheRestConfiguration) {
  SphereModel<double> m = block<double>({2, 2, 2}, 0.004);
  const Index n = m.num_nodes();
  const Index other = m.add_region("other", tissue<double>());
  for (Index i = 0; i < n; ++i)
    m.add_node(m.rest_positions().row(i).transpose() + V3(0.0085, 0, 0), 0.002, 0.001, other);
  ContactSolver<double> solver(m);
  Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
  solver.compute(m, f);
  EXPECT_EQ(f.norm(), 0.0);                                        // at rest: in contact, no force
  for (Index i = n; i < 2 * n; ++i) m.positions()(i, 0) -= 0.001;  // push the second part in
  f.setZero();
  solver.compute(m, f);
  EXPECT_GT(solver.num_contacts(), 0);
  EXPECT_LT(f.topRows(n).col(0).sum(), 0);     // the first part is pushed -x
  EXPECT_GT(f.bottomRows(n).col(0).sum(), 0);  // the second +x
  EXPECT_LT(f.colwise().sum().norm(), 1e-12);
}

// The part-contact pair list (ContactOptions::verlet_skin) finds every contact a rescan finds, at
// every step, while the regions move at different speeds, one of them across the model into the
// others; and it rebuilds less often than a bound on the fastest sphere alone would (each region's
// moves are bounded apart, and far regions may move farther before their spheres could meet).
// Also with self contact (a region against itself counts its moves twice: here the crossing
// cluster meets a still one of its own region), and with more than 32 regions, where the list
// falls back to that one bound and rebuilds exactly when it says.
TEST(ContactSolver, PartContactListMatchesARescanAsRegionsMove) {
  for (const auto& [self_contact, extra_regions] :
       {std::pair{false, 0}, std::pair{true, 0}, std::pair{false, 40}}) {
    SCOPED_TRACE(testing::Message()
                 << "self contact " << self_contact << ", extra regions " << extra_regions);
    std::mt19937 rng(11);
    SphereModel<double> m = random_spheres(rng, 150);
    const Index moving = m.add_region("moving", tissue<double>());
    const Index first_moving = m.num_nodes();
    // A cluster about 2 cm beyond the others in x that crosses into them; with self contact it
    // stays 10 cm farther off, where it meets only a still cluster of its own region placed where
    // it ends, 3 mm above it (4 cm apart at rest, so not excluded as neighbours): only the region
    // against itself can ask for those rebuilds.
    const double away = self_contact ? 0.1 : 0.0;
    for (int i = 0; i < 20; ++i)
      m.add_node(V3(away + 0.07 + 0.002 * (i % 4), 0.02 + 0.003 * (i / 4 % 5), 0.02), 0.002, 0.001,
                 moving);
    for (int i = 0; i < (self_contact ? 20 : 0); ++i)
      m.add_node(V3(away + 0.03 + 0.002 * (i % 4), 0.02 + 0.003 * (i / 4 % 5), 0.023), 0.002, 0.001,
                 moving);
    for (int r = 0; r < extra_regions; ++r)  // regions without spheres
      m.add_region("empty" + std::to_string(r), tissue<double>());
    ContactOptions<double> listed, rescan;
    listed.self_contact = rescan.self_contact = self_contact;
    rescan.verlet_skin = 0;
    ContactSolver<double> a(m, listed), b(m, rescan);
    std::normal_distribution<double> jiggle(0, 1e-4);
    {  // both lists built at the start, where the count below starts from
      Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
      a.compute(m, f);
      b.compute(m, f);
    }
    const Index rebuilds0 = a.pair_list_rebuilds();
    int steps = 0, with_contacts = 0, all_spheres_bound = 0;
    Positions<double> built = m.positions();
    for (; steps < 200; ++steps) {
      for (Index i = 0; i < m.num_nodes(); ++i) {
        const bool fast = i >= first_moving && i < first_moving + 20;
        // The cluster crosses 4 cm toward the others in 100 steps, then stays; the rest jiggles
        // (region 0 ten times more than the others).
        if (fast && steps < 100) m.positions()(i, 0) -= 4e-4;
        const double scale =
            m.node_regions()[i] == moving ? 0.0 : (m.node_regions()[i] == 0 ? 1.0 : 0.1);
        for (int c = 0; c < 3; ++c) m.positions()(i, c) += scale * jiggle(rng);
      }
      // What a list rebuilt when any sphere moved half the skin would have done.
      if ((m.positions() - built).rowwise().norm().maxCoeff() > 0.5 * listed.verlet_skin) {
        ++all_spheres_bound;
        built = m.positions();
      }
      Positions<double> fa = Positions<double>::Zero(m.num_nodes(), 3), fb = fa;
      a.compute(m, fa);
      b.compute(m, fb);
      ASSERT_EQ(a.num_contacts(), b.num_contacts()) << steps;
      ASSERT_LT((fa - fb).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, fb.cwiseAbs().maxCoeff()))
          << steps;
      with_contacts += b.num_contacts() > 0;
    }
    EXPECT_EQ(with_contacts, steps);
    // The crossing cluster met the others (with self contact: its still twin) at the end.
    auto crossing = [&](Index i) { return i >= first_moving && i < first_moving + 20; };
    bool met = false, folded = false;
    for (Index k = 0; k < a.num_contacts(); ++k) {
      const Index i = a.contacts()[k].sphere, j = a.contacts()[k].other;
      if (j < 0 || crossing(i) == crossing(j)) continue;
      const bool twin = m.node_regions()[i] == moving && m.node_regions()[j] == moving;
      met = met || !twin;
      folded = folded || twin;
    }
    EXPECT_EQ(met, !self_contact);
    EXPECT_EQ(folded, self_contact);
    // From one build, the per-region bounds never ask for a rebuild before the one bound does
    // (each is at most twice the fastest move); over the run they ask for fewer here, and for
    // as many with self contact, where the crossing cluster's own moves count twice.
    const Index rebuilds = a.pair_list_rebuilds() - rebuilds0;
    EXPECT_GT(rebuilds, 1);
    if (extra_regions > 0)
      EXPECT_EQ(rebuilds, all_spheres_bound);
    else if (self_contact)
      EXPECT_LE(rebuilds, all_spheres_bound);
    else
      EXPECT_LT(rebuilds, all_spheres_bound);
    EXPECT_EQ(b.pair_list_rebuilds(), steps + 1);  // (no skin: a scan every step)
  }
}

// Regions added, and spheres moved into them, after the solver was sized (without refresh()):
// the per-region arrays do not cover them, so the list falls back to the one bound for all (no
// write past their end, which ASan would report), and still finds what a rescan finds. The same
// for a region index that is no region's.
TEST(ContactSolver, RegionsAddedAfterRefreshFallBackToOneBound) {
  std::mt19937 rng(4);
  SphereModel<double> m = random_spheres(rng, 150);
  ContactOptions<double> listed, rescan;
  rescan.verlet_skin = 0;
  ContactSolver<double> a(m, listed), b(m, rescan);
  for (int k = 0; k < 3; ++k) {
    const Index r = m.add_region("late" + std::to_string(k), tissue<double>());
    for (Index i = k; i < m.num_nodes(); i += 7) m.node_regions()[i] = r;
  }
  std::normal_distribution<double> jiggle(0, 3e-4);
  for (int step = 0; step < 50; ++step) {
    for (Index i = 0; i < m.num_nodes(); ++i)
      for (int c = 0; c < 3; ++c) m.positions()(i, c) += jiggle(rng);
    Positions<double> fa = Positions<double>::Zero(m.num_nodes(), 3), fb = fa;
    ASSERT_TRUE(a.compute(m, fa));
    ASSERT_TRUE(b.compute(m, fb));
    ASSERT_EQ(a.num_contacts(), b.num_contacts()) << step;
    ASSERT_LT((fa - fb).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, fb.cwiseAbs().maxCoeff()))
        << step;
  }
  EXPECT_GT(a.pair_list_rebuilds(), 1);
  EXPECT_LT(a.pair_list_rebuilds(), 50);
  // A sphere whose region index is no region's (written through the map, never validated): the
  // list does not index its arrays by it (ASan, which runs this test, would report the write), and
  // its next rebuild, here at once, finds what a rescan finds.
  m.node_regions()[0] = m.num_regions() + 5;
  m.positions().row(0) += Eigen::RowVector3d(0.002, 0, 0);  // more than half the skin: a rebuild
  for (int step = 0; step < 5; ++step) {
    for (int c = 0; c < 3; ++c) m.positions()(0, c) += jiggle(rng);
    Positions<double> fa = Positions<double>::Zero(m.num_nodes(), 3), fb = fa;
    ASSERT_TRUE(a.compute(m, fa));
    ASSERT_TRUE(b.compute(m, fb));
    ASSERT_EQ(a.num_contacts(), b.num_contacts()) << step;
  }
}

// More candidate pairs than the list has room for (32 a sphere): each step scans instead and
// keeps no list, and still finds every contact. 100 + 100 spheres of two regions, 2 mm in radius,
// at rest 1 cm apart, squeezed into a 2 mm box: every one of the 10,000 pairs across the regions
// is within its threshold (4 mm).
TEST(ContactSolver, PartContactListThatDoesNotFitScansInstead) {
  SphereModel<double> m;
  m.add_region("a", tissue<double>());
  m.add_region("b", tissue<double>());
  for (int i = 0; i < 200; ++i)
    m.add_node(V3(0.01 * (i % 10), 0.01 * (i / 10 % 10), 0.01 * (i / 100)), 0.002, 0.001, i % 2);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0, 0.002);
  for (Index i = 0; i < m.num_nodes(); ++i)
    for (int c = 0; c < 3; ++c) m.positions()(i, c) = u(rng);
  ContactSolver<double> solver(m);
  for (int step = 0; step < 3; ++step) {
    Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
    ASSERT_TRUE(solver.compute(m, f));
    EXPECT_EQ(solver.candidates(), 10000);
    EXPECT_EQ(solver.narrow_tests(), 10000);
    EXPECT_TRUE(solver.overflowed());  // (the contact list holds 4,096; all forces applied)
    EXPECT_EQ(solver.pair_list_rebuilds(), step + 1);  // no list kept: a scan every step
    EXPECT_LT(f.colwise().sum().norm(), 1e-9 * f.cwiseAbs().maxCoeff());
    for (Index i = 0; i < m.num_nodes(); ++i) EXPECT_GT(f.row(i).norm(), 0.0) << i;
  }
}

// The onset of the contact law (PenaltyContact::onset): without it the plain penalty; with it
// s = d^2 / 2e below e and d - e/2 beyond, continuous with its slope at 0 and at e; the damping
// ramps in with the slope, so a contact that barely touches neither pushes nor pulls hard. The
// stiffness matrix holds its slope (checked against central differences of the forces).
TEST(ContactLaw, OnsetIsContinuousWithItsSlopeAndMatchesTheStiffnessMatrix) {
  PenaltyContact<double> c;
  c.node = 0;
  c.normal = V3::UnitZ();
  c.node_start = V3::Zero();
  c.stiffness = 200;
  c.damping = 0.3;
  c.friction_speed = 1e-3;
  auto force = [&](double depth, double vn, double onset) {
    c.depth = depth;
    c.onset = onset;
    const double x[3] = {0, 0, 0}, v[3] = {0, 0, vn};  // vn < 0: moving into the tool
    double fn;
    V3 slip;
    return fsm::detail::contact_force(c, x, v, 0.0, fn, slip).z();
  };
  const double e = 1e-4;
  for (double d : {0.0, 3e-5, 2e-4})  // no onset: k d (clamped at zero), damping at once
    EXPECT_DOUBLE_EQ(force(d, -0.01, 0), std::max(0.0, 200 * d + 0.3 * 0.01));
  // Before touching nothing, however fast it comes (a near contact: ContactOptions::
  // detection_margin); k d + c |vn| would be +0.0028 N here.
  EXPECT_EQ(force(-1e-6, -0.01, 0), 0.0);
  EXPECT_EQ(force(-1e-4, -0.01, 0), 0.0);
  EXPECT_EQ(force(-1e-6, -0.01, e), 0.0);  // not touching: nothing, however fast it comes
  EXPECT_NEAR(force(5e-5, 0, e), 200 * 5e-5 * 5e-5 / (2 * e), 1e-15);
  EXPECT_NEAR(force(3e-4, 0, e), 200 * (3e-4 - e / 2), 1e-15);
  // Continuity of the force and of its slope at 0 and at e.
  const double eps = 1e-10;
  for (double at : {0.0, e}) {
    EXPECT_NEAR(force(at - eps, 0, e), force(at + eps, 0, e), 1e-7);
    const double left = (force(at, 0, e) - force(at - eps, 0, e)) / eps;
    const double right = (force(at + eps, 0, e) - force(at, 0, e)) / eps;
    EXPECT_NEAR(left, right, 200 * 1e-4);
  }
  // The stiffness matrix of a force model with one such contact, against central differences.
  SphereModel<double> m;
  m.add_region("r", tissue<double>());
  m.add_node(V3::Zero(), 0.001, 1e-4, 0);
  ForceModel<double> fm(m);
  fm.reserve_contacts(1);
  for (double d : {2e-5, 7e-5, 4e-4}) {
    c.depth = d;
    c.onset = e;
    fm.clear_contacts();
    ASSERT_TRUE(fm.add_contact(c));
    const Eigen::MatrixXd K = Eigen::MatrixXd(fm.stiffness_matrix(m, JacobianForm::definite));
    Positions<double> x = m.positions(), f(1, 3);
    const double step = 1e-9;
    x(0, 2) = step;
    fm.evaluate(m, x, m.velocities(), f);
    const double fp = f(0, 2);
    x(0, 2) = -step;
    fm.evaluate(m, x, m.velocities(), f);
    const double fd = (fp - f(0, 2)) / (2 * step);
    EXPECT_NEAR(K(2, 2), fd, 1e-6 * 200) << "depth " << d;
    EXPECT_NEAR(K(2, 2), -200 * std::min(d / e, 1.0), 1e-9) << "depth " << d;
  }
}

// Parts that touch at rest sit at their contact's threshold. A block resting on a fixed block under
// gravity is carried by part contacts alone. With the default onset the contacts still carry its
// weight, steadily, and let it sink at most half the onset deeper than the plain penalty does (the
// law past the onset is the plain one shifted by half the onset).
TEST(ContactSolver, PartsTouchingAtRestCarryTheWeightWithTheOnset) {
  auto run = [](double onset) {
    SphereModel<double> m = block<double>({3, 3, 1}, 0.004);
    const Index n = m.num_nodes();
    for (Index i = 0; i < n; ++i) m.set_fixed(i);
    const Index top = m.add_region("top", tissue<double>());
    const TetrahedralMesh<double> lattice =
        make_cube_lattice<double>(V3(0, 0, 0.0035), Eigen::Vector3i(3, 3, 1), 0.004);
    add_tetrahedral_part(m, lattice, top, 0.002);  // 0.5 mm into the fixed block's top layer
    Simulation<double>::Options o;
    o.forces.drag = 5;
    Simulation<double> sim(m, o);
    ContactOptions<double> co;
    co.part_contact_onset = onset;
    ContactSolver<double> solver(sim.model(), sim.forces(), co);
    double weight = 0;
    for (Index i = n; i < sim.model().num_nodes(); ++i) weight += sim.model().masses()[i] * 9.81;
    std::vector<double> carried;
    for (int s = 0; s < 600; ++s) {
      solver.compute(sim.model(), sim.forces());
      EXPECT_TRUE(sim.step(1e-3).advanced());
      solver.collect(sim.forces());
      if (s < 400) continue;
      double fz = 0;  // contact force on the upper block
      for (Index k = 0; k < solver.num_contacts(); ++k) {
        const Contact<double>& c = solver.contacts()[k];
        if (c.other < 0) continue;
        fz += (c.sphere >= n ? 1.0 : -1.0) * c.force.z();
      }
      carried.push_back(fz / weight);
    }
    double mean = 0, worst = 0;
    for (double r : carried) mean += r / double(carried.size());
    for (double r : carried) worst = std::max(worst, std::abs(r - mean));
    const auto x = sim.model().positions().bottomRows(sim.model().num_nodes() - n);
    const auto x0 = sim.model().rest_positions().bottomRows(sim.model().num_nodes() - n);
    const double sink = (x0.col(2) - x.col(2)).mean();
    return std::make_tuple(mean, worst, sink);
  };
  const double onset = ContactOptions<double>().part_contact_onset;
  const auto [mean, worst, sink] = run(onset);
  const auto [plain_mean, plain_worst, plain_sink] = run(0.0);
  EXPECT_NEAR(mean, 1.0, 0.02);
  EXPECT_LT(worst, 0.02);
  EXPECT_NEAR(plain_mean, 1.0, 0.02);
  EXPECT_GT(sink, plain_sink);
  EXPECT_LT(sink - plain_sink, 0.5 * onset * 0.0035 + 1e-6);  // threshold: the 3.5 mm rest distance
}

// A layer of 5 mm spheres (a linked sheet held at its rim) and a 2 mm ball moving through it at
// 0.5 m/s, stepped at 1 kHz: 0.5 mm per step, a tenth of a sphere. No sphere may pass through the
// ball: penetration stays below the sphere radius at every step; with position projection it stays
// at zero after each projection.
TEST(ContactSolver, NoTunnellingAtHalfAMetrePerSecond) {
  for (bool project : {false, true}) {
    SphereModel<double> sheet;
    const Index reg = sheet.add_region("sheet", tissue<double>(13150, 10.26));
    const int n = 7;
    const double h = 0.005, r = 0.0025;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) sheet.add_node(V3(h * (i - 3), h * (j - 3), 0), r, 3e-4, reg);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        if (i + 1 < n) sheet.add_link(j * n + i, j * n + i + 1, 20.0, 0.02);
        if (j + 1 < n) sheet.add_link(j * n + i, (j + 1) * n + i, 20.0, 0.02);
        if (i + 1 < n && j + 1 < n) sheet.add_link(j * n + i, (j + 1) * n + i + 1, 10.0, 0.01);
        if (i == 0 || j == 0 || i == n - 1 || j == n - 1) sheet.set_fixed(j * n + i);
      }
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    Simulation<double> sim(sheet, o);
    ContactSolver<double> solver(sim.model(), sim.forces());
    Instrument<double> tool;
    tool.shape = SphereShape<double>{0.002};
    tool.pose.position = V3(0.0007, -0.0004, 0.006);
    tool.linear_velocity = V3(0, 0, -0.5);
    const Index k = solver.add_instrument(tool);
    double deepest = 0, peak_force = 0;
    for (int s = 0; s < 30; ++s) {  // 15 mm: through the layer's plane and 10 mm on
      solver.instrument(k).pose.position += 1e-3 * solver.instrument(k).linear_velocity;
      solver.compute(sim.model(), sim.forces());
      ASSERT_TRUE(sim.step(1e-3).advanced()) << s;
      solver.collect(sim.forces());
      if (project) solver.project(sim.model());
      // Penetration after the step, and no sphere centre on the far side of the ball's centre
      // within the ball's shadow.
      const V3 c = solver.instrument(k).pose.position;
      for (Index i = 0; i < sim.model().num_nodes(); ++i) {
        const V3 x = sim.model().positions().row(i).transpose();
        const double pen = 0.002 + r - (x - c).norm();
        deepest = std::max(deepest, pen);
        if (std::hypot(x.x() - c.x(), x.y() - c.y()) < 0.002) {
          EXPECT_LT(x.z(), c.z()) << "step " << s;
        }
      }
      peak_force = std::max(peak_force, solver.wrench(k).force.norm());
    }
    EXPECT_LT(deepest, project ? 1e-9 : r) << "project " << project;
    EXPECT_GT(peak_force, 0.05) << "the sheet did push back";
  }
}

// A plate 40 mm wide whose top face is at z = -r: a sphere of radius r centred at height g is g
// outside it (the near-contact tests).
Instrument<double> plate_below(double r) {
  Instrument<double> plate;
  plate.shape = CylinderShape<double>{0.02, 0.005};
  plate.pose.position = V3(0, 0, -r - 0.005);
  return plate;
}

// Near contacts (ContactOptions::detection_margin): a sphere just outside an instrument at a
// step's start, which the step carries in, joins the step's later contact passes and ends at the
// surface; without them it is free for the whole step and ends deep inside (the negative control).
// This is what let spheres under a rounded rim sink 0.2-0.3 mm into it every other step
// (docs/validation.md). A near contact pushes nothing before it touches and is not listed.
TEST(ContactSolver, NearContactJoinsTheStepThatCarriesTheSphereIn) {
  std::vector<double> inside;
  for (const double margin : {0.0, ContactOptions<double>{}.detection_margin}) {
    SphereModel<double> m;
    const Index reg = m.add_region("r", tissue<double>(13150, 10.26));
    const double r = 0.002;                      // radius: the near zone is margin r = 0.5 mm thick
    m.add_node(V3(0, 0, 0.0003), r, 1e-4, reg);  // centre 0.3 mm above the plate, sphere 2.3 mm
    m.velocities().row(0) = V3(0, 0, -0.5).transpose();  // 0.5 mm per 1 ms step, downward
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    Simulation<double> sim(m, o);
    ContactOptions<double> co;
    co.detection_margin = margin;
    co.tetrahedral_surface = false;  // (no tetrahedra: it meets the tool at its radius anyway)
    ContactSolver<double> solver(sim.model(), sim.forces(), co);
    const Index k = solver.add_instrument(plate_below(r));  // the sphere is 0.3 mm out
    solver.compute(sim.model(), sim.forces());
    EXPECT_EQ(solver.num_contacts(), 0);  // a near contact is not a contact
    EXPECT_EQ(solver.wrench(k).force.norm(), 0.0);
    ASSERT_TRUE(sim.step(1e-3).advanced());
    solver.collect(sim.forces());
    const double z = sim.model().positions()(0, 2);
    inside.push_back(-z);  // how far the centre went below z = 0 (the sphere's surface below -r)
  }
  EXPECT_GT(inside[0], 1.5e-4) << "without near contacts the step carries it 0.2 mm in";
  EXPECT_LT(inside[1], 5e-6) << "the near contact joined the step and held it out";
}

// A near contact that the step does not carry in does nothing: a sphere at rest 0.3 mm outside a
// plate stays where it is (its penalty law, k times a negative depth, must not enter the step's
// right-hand side as a pull), and an explicit step softens it without counting it as a contact.
TEST(ContactSolver, NearContactAtRestOutsideIsNotPulledNorCounted) {
  for (const std::string integrator : {"implicit_euler", "symplectic_euler"}) {
    for (const double gap : {3e-4, -3e-4}) {  // outside (a near contact), inside (a contact)
      SphereModel<double> m;
      const Index reg = m.add_region("r", tissue<double>(13150, 10.26));
      const double r = 0.002;
      m.add_node(V3(0, 0, gap), r, 1e-4, reg);
      Simulation<double>::Options o;
      o.forces.gravity.setZero();
      o.integrator = integrator;
      Simulation<double> sim(m, o);
      ContactOptions<double> co;
      co.tetrahedral_surface = false;
      ContactSolver<double> solver(sim.model(), sim.forces(), co);
      solver.add_instrument(plate_below(r));
      solver.compute(sim.model(), sim.forces());
      ASSERT_EQ(sim.forces().num_contacts(), 1) << integrator << " " << gap;
      const StepReport<double> rep = sim.step(1e-3);
      ASSERT_TRUE(rep.advanced());
      if (integrator == "symplectic_euler") {  // k = 1e4 N/m > m / (2 h^2) = 50 N/m: softened
        EXPECT_EQ(rep.softened_contacts, gap > 0 ? 0 : 1) << gap;
      }
      if (gap > 0) {
        EXPECT_EQ(sim.model().positions()(0, 2), gap) << integrator;
        EXPECT_EQ(sim.model().velocities().row(0).norm(), 0.0) << integrator;
      } else {
        EXPECT_GT(sim.model().velocities()(0, 2), 0.0) << integrator;  // pushed out
      }
    }
  }
}

// A contact left out of the step's last solve reports what the step applied through it: nothing.
// With a single contact pass, a near contact that the step carries in ends inside the plate; its
// penalty at that state (k x 0.2 mm = 2 N) was never applied, and reporting it would be a one-step
// spike in the instrument's wrench (0.64 N on the validation's ball). The next step pushes it out.
TEST(ContactSolver, ContactOutsideTheLastSolveReportsNoForce) {
  SphereModel<double> m;
  const Index reg = m.add_region("r", tissue<double>(13150, 10.26));
  const double r = 0.002;
  m.add_node(V3(0, 0, 0.0003), r, 1e-4, reg);
  m.velocities().row(0) = V3(0, 0, -0.5).transpose();
  Simulation<double>::Options o;
  o.forces.gravity.setZero();
  ImplicitEulerIntegrator<double>::Options io;
  io.max_contact_passes = 1;
  Simulation<double> sim(m, std::make_unique<ImplicitEulerIntegrator<double>>(io), o);
  ContactOptions<double> co;
  co.tetrahedral_surface = false;
  ContactSolver<double> solver(sim.model(), sim.forces(), co);
  const Index k = solver.add_instrument(plate_below(r));
  solver.compute(sim.model(), sim.forces());
  ASSERT_TRUE(sim.step(1e-3).advanced());
  solver.collect(sim.forces());
  ASSERT_LT(sim.model().positions()(0, 2), -1e-4);  // carried 0.2 mm in: no pass caught it
  EXPECT_EQ(solver.wrench(k).force.norm(), 0.0);
  EXPECT_EQ(solver.num_contacts(), 0);
  solver.compute(sim.model(), sim.forces());    // the next step sees it and pushes it out
  EXPECT_LT(solver.wrench(k).force.z(), -1.0);  // on the plate: down
}

// A step that is rolled back leaves the contacts' forces where the rollback leaves the model: at
// the state the step started from. The servo loop moves its proxy by the wrench collect() reports
// after every step, and the forces of a rejected implicit solve (8.8e4 N on one sphere) flung
// fsm-demo's probe 3 m (--law continuum --contact vertices). Here symplectic Euler at three times
// its stable step blows up while a plate presses the block: the first rejected step must report
// the wrench it started from.
TEST(ContactSolver, RolledBackStepReportsTheWrenchItStartedFrom) {
  std::mt19937 rng(71);
  Simulation<double>::Options o;
  o.integrator = "symplectic_euler";
  o.forces.gravity.setZero();
  Simulation<double> sim(random_model<double>(rng, {3, 3, 3}, 0.2), o);
  ContactOptions<double> co;
  co.tetrahedral_surface = false;  // the 5 mm spheres meet the plate at their radius
  ContactSolver<double> solver(sim.model(), sim.forces(), co);
  Instrument<double> plate;
  plate.shape = CylinderShape<double>{0.05, 0.005};
  plate.pose.position = V3(0.015, 0.015, -0.009);  // top face at z = -4 mm: the bottom layer in it
  const Index k = solver.add_instrument(plate);
  const double dt = 3 * sim.stable_time_step();
  int rejected = 0;
  for (int s = 0; s < 5000 && rejected == 0; ++s) {
    solver.compute(sim.model(), sim.forces());
    const Vector3<double> before = solver.wrench(k).force;
    const StepReport<double> r = sim.step(dt);
    solver.collect(sim.forces());
    if (r.status != StepStatus::diverged) continue;
    ++rejected;
    EXPECT_GT(before.norm(), 0.0) << "the plate pressed at the step's start";
    EXPECT_EQ(solver.wrench(k).force, before) << "step " << s;
  }
  EXPECT_EQ(rejected, 1);
}

TEST(ContactSolver, DegenerateInputGivesDefinedResults) {
  SphereModel<double> m = block<double>({2, 2, 2}, 0.004);
  ContactSolver<double> solver(m);
  Instrument<double> point_capsule;  // zero length: a ball
  point_capsule.shape = CapsuleShape<double>{0.003, 0.0};
  point_capsule.pose.position = V3(0.004, 0.004, 0.0095);
  const Index k = solver.add_instrument(point_capsule);
  Positions<double> f = Positions<double>::Zero(m.num_nodes(), 3);
  solver.compute(m, f);
  EXPECT_GT(solver.num_contacts(), 0);
  EXPECT_TRUE(f.allFinite());
  // A NaN pose set later: no contact, no NaN anywhere.
  solver.instrument(k).pose.position.x() = std::nan("");
  f.setZero();
  solver.compute(m, f);
  EXPECT_EQ(solver.num_contacts(), 0);
  EXPECT_TRUE(f.allFinite());
  EXPECT_TRUE(solver.wrench(k).force.allFinite());
  // A NaN pose or a negative radius at registration: a clear error.
  Instrument<double> bad;
  bad.name = "bad";
  bad.pose.position = V3(std::nan(""), 0, 0);
  EXPECT_THROW(solver.add_instrument(bad), Error);
  bad.pose.position.setZero();
  bad.shape = SphereShape<double>{-0.001};
  EXPECT_THROW(solver.add_instrument(bad), Error);
  // Coincident spheres of two parts: a defined normal (from their rest offset), finite forces.
  SphereModel<double> two;
  const Index a = two.add_region("a", tissue<double>()), b = two.add_region("b", tissue<double>());
  two.add_node(V3(0, 0, 0), 0.002, 0.001, a);
  two.add_node(V3(0.003, 0, 0), 0.002, 0.001, b);
  two.positions().row(1) = two.positions().row(0);
  ContactSolver<double> pair(two);
  Positions<double> g = Positions<double>::Zero(2, 3);
  pair.compute(two, g);
  ASSERT_EQ(pair.num_contacts(), 1);
  EXPECT_TRUE(g.allFinite());
  EXPECT_GT(g(1, 0), 0);  // pushed apart along their rest offset
}

// A light part buried in a heavy one (a fibroid in the body) is pressed by many spheres at once:
// a contact stiffness far beyond what an explicit force tolerates at 1 ms. Implicit Euler takes
// the contacts into its solve and settles at full stiffness; an explicit integrator gets the
// contacts capped to its step (StepReport::softened_contacts) and stays bounded.
TEST(ContactSolver, BuriedLightPartSettlesImplicitlyAndIsCappedExplicitly) {
  auto run = [](const std::string& integrator, double dt, int steps) {
    SphereModel<double> m = block<double>({4, 4, 4}, 0.005);
    for (Index i = 0; i < m.num_nodes(); ++i)
      if (m.rest_positions()(i, 2) < 1e-9) m.set_fixed(i);
    const Index inner = m.add_region("buried", tissue<double>(20000.0));
    const Index b = m.add_node(V3(0.01, 0.01, 0.01), 0.004, 2e-5, inner);  // overlaps ~20 spheres
    m.positions()(b, 0) += 0.0015;  // displaced from its rest seat: contact forces push it back
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    o.integrator = integrator;
    Simulation<double> sim(m, o);
    ContactOptions<double> co;
    co.part_stiffness_ratio = 100;  // parts as stiff as instruments: the hard case
    ContactSolver<double> solver(sim.model(), sim.forces(), co);
    double late_speed = 0;
    Index softened = 0;
    bool ok = true;
    for (int s = 0; s < steps && ok; ++s) {
      solver.compute(sim.model(), sim.forces());
      const StepReport<double> r = sim.step(dt);
      solver.collect(sim.forces());
      ok = r.advanced() && sim.model().positions().allFinite();
      softened = std::max(softened, r.softened_contacts);
      if (s >= steps * 9 / 10)
        late_speed = std::max(late_speed, sim.model().velocities().row(b).norm());
    }
    return std::make_tuple(ok, late_speed, softened);
  };
  const auto [ok, speed, softened] = run("implicit_euler", 1e-3, 1000);
  EXPECT_TRUE(ok);
  EXPECT_LT(speed, 1e-3);  // m/s after 0.9 s: settled (it started 1.5 mm off its seat)
  EXPECT_EQ(softened, 0);
  const auto [eok, espeed, esoftened] = run("symplectic_euler", 1e-4, 3000);
  EXPECT_TRUE(eok);
  EXPECT_GT(esoftened, 0);
  EXPECT_LT(espeed, 0.1);
}

// A W x W x H block of h lattice cells (tetrahedra), its bottom fixed, on the continuum law at
// nu = 0.45.
SphereModel<double> continuum_block(double W, double H, double h) {
  Material<double> mat = tissue<double>();
  mat.poisson_ratio = 0.45;
  SphereModel<double> m;
  const Index r = m.add_region("block", mat);
  const int c = int(std::lround(W / h)), cz = int(std::lround(H / h));
  add_tetrahedral_part(m, make_cube_lattice(V3(0, 0, 0), Eigen::Vector3i(c, c, cz), h), r, h / 2);
  for (Index i = 0; i < m.num_nodes(); ++i)
    if (m.rest_positions()(i, 2) < 1e-9) m.set_fixed(i);
  m.set_region_law(r, ForceLaw::continuum);
  return m;
}

// Contact that holds at every resolution: a rigid ball (R = 5 mm, frictionless) pressed 1 mm into
// a 12 x 12 x 6 mm block (continuum law, E = 13.15 kPa, nu = 0.45, bottom fixed) and held, at
// lattice spacings 3, 2, 1.5 and 1 mm, implicit Euler at 2 ms. The force must converge as the
// spacing shrinks, not fall (the penalty is a ratio of each sphere's own stiffness, in the solve);
// no sphere centre ends inside the ball by more than 1 % of the depth; the wrench balances the
// contact forces. Measured (Release): 0.0536, 0.0670, 0.0723, 0.0721 N, centres at most 0.3 um in.
TEST(ContactSolver, BallForceConvergesAsTheSpacingShrinks) {
  const double W = 0.012, H = 0.006, R = 0.005, D = 0.001, dt = 2e-3;
  const int load = 100, hold = 50;
  std::vector<double> force;
  for (const double h : {0.003, 0.002, 0.0015, 0.001}) {
    SCOPED_TRACE(h);
    const SphereModel<double> m = continuum_block(W, H, h);
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    Simulation<double> sim(m, o);
    ContactSolver<double> solver(sim.model(), sim.forces());
    Instrument<double> ball;
    ball.shape = SphereShape<double>{R};
    ball.friction = 0;
    ball.pose.position = V3(W / 2, W / 2, H + R);
    const Index k = solver.add_instrument(ball);
    double deepest = 0;
    for (int s = 0; s < load + hold; ++s) {
      Instrument<double>& tool = solver.instrument(k);
      tool.pose.position.z() = H + R - D * std::min(1.0, double(s) / load);
      tool.linear_velocity = V3(0, 0, s < load ? -D / (load * dt) : 0.0);
      solver.compute(sim.model(), sim.forces());
      const StepReport<double> rep = sim.step(dt);
      solver.collect(sim.forces());
      ASSERT_EQ(rep.status, StepStatus::ok) << "step " << s;
      tool.pose.position.z() = H + R - D * std::min(1.0, double(s + 1) / load);
      for (Index i = 0; i < sim.model().num_nodes(); ++i)
        deepest = std::max(
            deepest, R - (sim.model().positions().row(i).transpose() - tool.pose.position).norm());
    }
    EXPECT_LT(deepest, 0.01 * D);
    Vector3<double> sum = Vector3<double>::Zero();
    for (Index q = 0; q < solver.num_contacts(); ++q) sum += solver.contacts()[q].force;
    EXPECT_LT((sum + solver.wrench(k).force).norm(), 1e-12);
    force.push_back(solver.wrench(k).force.z());
  }
  ASSERT_EQ(force.size(), 4u);
  for (std::size_t q = 1; q < force.size(); ++q)
    EXPECT_GT(force[q], 0.98 * force[q - 1]) << "the force falls as the spacing shrinks";
  EXPECT_NEAR(force[3], force[2], 0.03 * force[2]);  // converged within 3 % at 1.5 -> 1 mm
}

// Face contact (ContactOptions::face_contact): a block of 5 mm lattice cells and a 1 mm ball, far
// smaller than the vertex spacing. The block's top is z = 10 mm.
SphereModel<double> coarse_block() {
  SphereModel<double> m;
  const Index r = m.add_region("block", tissue<double>());
  add_tetrahedral_part(m, make_cube_lattice(V3(0, 0, 0), Eigen::Vector3i(4, 4, 2), 0.005), r,
                       0.0025);
  for (Index i = 0; i < m.num_nodes(); ++i)
    if (m.rest_positions()(i, 2) < 1e-9) m.set_fixed(i);
  return m;
}

// The same 1 mm ball against coarse_block() through the vertex contact and the face contact.
struct BallOnCoarseBlock {
  SphereModel<double> m = coarse_block();
  ForceModel<double> fv{m}, ff{m};
  ContactSolver<double> by_vertex{m, fv}, by_face{m, ff, face_options()};
  BallOnCoarseBlock() {
    Instrument<double> ball;
    ball.shape = SphereShape<double>{0.001};
    ball.friction = 0;
    by_vertex.add_instrument(ball);
    by_face.add_instrument(ball);
  }
  static ContactOptions<double> face_options() {
    ContactOptions<double> o;
    o.face_contact = true;
    return o;
  }
  // Both solvers' contacts with the ball's centre at p; false if either refused the model.
  bool press(const V3& p) {
    by_vertex.instrument(0).pose.position = p;
    by_face.instrument(0).pose.position = p;
    return by_vertex.compute(m, fv) && by_face.compute(m, ff);
  }
};

// Between vertices the ball slips through the vertex contact and is held by the faces; the
// face contact's forces balance the instrument's wrench (force and torque).
TEST(ContactSolver, FaceContactHoldsAProbeSmallerThanTheVertexSpacing) {
  BallOnCoarseBlock b;
  const V3 centre(0.0065, 0.0077, 0.010 + 0.001 - 0.0005);  // 0.5 mm into a top face
  ASSERT_TRUE(b.press(centre));
  EXPECT_EQ(b.by_vertex.num_contacts(), 0);  // no vertex within 1 mm: the probe would pass through
  ASSERT_GE(b.by_face.num_contacts(), 3);
  const Wrench<double>& w = b.by_face.wrench(0);
  EXPECT_GT(w.force.z(), 0.0);  // the tissue pushes the probe back up
  EXPECT_LT(std::hypot(w.force.x(), w.force.y()), 0.2 * w.force.z());
  V3 f = V3::Zero(), t = V3::Zero();
  double bound = 0;
  for (Index q = 0; q < b.by_face.num_contacts(); ++q) {
    const Contact<double>& c = b.by_face.contacts()[q];
    EXPECT_LT(c.normal.z(), -0.8);  // each vertex pushed into the block
    f += c.force;
    t += (c.point - centre).cross(c.force);
    bound += b.by_face.contact_stiffness(c.sphere) * 0.0005;
  }
  EXPECT_LT((f + w.force).norm(), 1e-12 * w.force.norm());
  EXPECT_LT((t + w.torque).norm(), 1e-12 * w.force.norm());
  // The samples inside the ball carry part of the face's area: less than the three vertices'
  // full stiffness at the ball's depth.
  EXPECT_LT(w.force.z(), bound);
}

// Slid at a fixed depth across faces, edges and vertices, the face contact's force never drops to
// zero and changes continuously; the vertex contact's drops to zero between vertices.
TEST(ContactSolver, FaceContactForceIsContinuousAsTheProbeSlides) {
  BallOnCoarseBlock b;
  std::vector<double> fz, vz;
  for (int s = 0; s <= 200; ++s) {  // 10 mm along a line crossing edges and passing a vertex
    ASSERT_TRUE(b.press(V3(0.0048 + 0.00005 * s, 0.0050 + 0.00002 * s, 0.010 + 0.001 - 0.0003)));
    fz.push_back(b.by_face.wrench(0).force.z());
    vz.push_back(b.by_vertex.wrench(0).force.z());
  }
  const double mean = std::accumulate(fz.begin(), fz.end(), 0.0) / double(fz.size());
  double jump = 0;
  for (std::size_t s = 1; s < fz.size(); ++s) jump = std::max(jump, std::abs(fz[s] - fz[s - 1]));
  EXPECT_GT(*std::min_element(fz.begin(), fz.end()), 0.2 * mean);
  EXPECT_LT(jump, 0.1 * mean);                              // 50 um steps
  EXPECT_EQ(*std::min_element(vz.begin(), vz.end()), 0.0);  // the negative control
}

// The face contact under a flat-ended cylinder (sharp rim) pressed 1 mm into a block of 1 mm
// tetrahedra on the continuum law, implicit: every step is accepted. A face contact's vertex sums
// samples that switch on and off along its faces; while such contacts could leave the solve
// between contact passes, steps threw the surface and were rolled back (PenaltyContact::
// stays_in_solve; before it, the sharp cylinder on docs/validation.md's cylindrical specimen at
// 1,536 spheres rolled back 98 of 1,000 steps).
TEST(ContactSolver, FaceContactHoldsUnderAFlatEndAtFineSpacing) {
  const double W = 0.012, H = 0.005, h = 0.001, D = 0.001, dt = 1e-3;
  const int load = 250;
  const SphereModel<double> m = continuum_block(W, H, h);
  Simulation<double>::Options o;
  o.forces.gravity.setZero();
  Simulation<double> sim(m, o);
  ContactOptions<double> co;
  co.face_contact = true;
  ContactSolver<double> solver(sim.model(), sim.forces(), co);
  Instrument<double> tool;
  tool.shape = CylinderShape<double>{0.003, 0.005, 0.0};
  tool.friction = 0;
  const double cz = H + 0.005;  // the flat end on the top at the start
  tool.pose.position = V3(W / 2 + 0.0002, W / 2 + 0.0003, cz);  // off the lattice's symmetry
  const Index k = solver.add_instrument(tool);
  int rejected = 0;
  for (int s = 0; s < load; ++s) {
    Instrument<double>& t = solver.instrument(k);
    t.pose.position.z() = cz - D * double(s) / load;
    t.linear_velocity = V3(0, 0, -D / (load * dt));
    solver.compute(sim.model(), sim.forces());
    const StepReport<double> rep = sim.step(dt);
    solver.collect(sim.forces());
    rejected += rep.status == StepStatus::ok ? 0 : 1;
  }
  EXPECT_EQ(rejected, 0);
  EXPECT_GT(solver.wrench(k).force.z(), 0.0);  // the block pushes the tool back up
}

// With face contact on, an interior node that an instrument reaches (the tissue has folded past
// the surface vertices, as under a sharp rim) stays in the step's solve like the face contacts:
// dropped between passes, it was thrown out of the tissue (the cylindrical specimen's sharp rim
// at 5,254 spheres, docs/validation.md). The vertex contact keeps its rule.
TEST(ContactSolver, InteriorNodeReachedWithFaceContactStaysInTheSolve) {
  const SphereModel<double> m = continuum_block(0.006, 0.004, 0.001);
  Index inner = -1;
  for (Index i = 0; i < m.num_nodes(); ++i)
    if ((m.rest_positions().row(i).transpose() - V3(0.003, 0.003, 0.002)).norm() < 1e-9) inner = i;
  ASSERT_GE(inner, 0);
  for (const bool faces : {true, false}) {
    SCOPED_TRACE(faces);
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    Simulation<double> sim(m, o);
    ContactOptions<double> co;
    co.face_contact = faces;
    ContactSolver<double> solver(sim.model(), sim.forces(), co);
    Instrument<double> tool;
    tool.shape = SphereShape<double>{0.0004};  // around the interior node only
    tool.pose.position = V3(0.003, 0.003, 0.0021);
    solver.add_instrument(tool);
    solver.compute(sim.model(), sim.forces());
    int found = 0;
    for (Index k = 0; k < sim.forces().num_contacts(); ++k) {
      const PenaltyContact<double>& c = sim.forces().contacts()[k];
      if (c.node != inner) continue;
      ++found;
      EXPECT_GT(c.depth, 0.0);
      EXPECT_EQ(c.stays_in_solve, faces);
    }
    EXPECT_EQ(found, 1);
    // What the flag does: a step takes the contact into its solve; a later pass whose end state
    // has the node 1 mm clear of the tool keeps it there with face contact on, drops it without.
    ASSERT_TRUE(sim.step(1e-3).advanced());
    Positions<double> x_end = sim.model().positions();
    x_end(inner, 2) -= 0.001;
    for (Index k = 0; k < sim.forces().num_contacts(); ++k) {
      if (sim.forces().contacts()[k].node == inner) {
        ASSERT_TRUE(sim.forces().contacts()[k].in_solve);
      }
    }
    sim.forces().update_contact_set(sim.model(), x_end.data(), 1e-3);
    for (Index k = 0; k < sim.forces().num_contacts(); ++k) {
      if (sim.forces().contacts()[k].node == inner) {
        EXPECT_EQ(sim.forces().contacts()[k].in_solve, faces);
      }
    }
  }
}

TEST(ContactSolver, RejectsABadFaceSampleSpacing) {
  const SphereModel<double> m = coarse_block();
  for (const double s : {0.0, -1e-3, std::numeric_limits<double>::infinity(),
                         std::numeric_limits<double>::quiet_NaN()}) {
    ContactOptions<double> o;
    o.face_sample_spacing = s;
    EXPECT_THROW(ContactSolver<double>(m, o), Error) << s;
  }
}

// Sleeping: a part far from the instrument stops integrating once quiet and wakes when touched;
// a sleeping simulation matches an awake one where the instrument works.
TEST(Sleeping, QuietPartsSleepAndWakeOnContact) {
  SphereModel<double> m = block<double>({3, 3, 2}, 0.005);
  const Index n = m.num_nodes();
  const Index far = m.add_region("far", tissue<double>());
  for (Index i = 0; i < n; ++i)
    m.add_node(m.rest_positions().row(i).transpose() + V3(0.05, 0, 0), m.radii()[i], m.masses()[i],
               far);
  for (Index l = 0, L = m.num_links(); l < L; ++l)
    m.add_link(m.links()(l, 0) + n, m.links()(l, 1) + n, m.link(l));
  for (Index i = 0; i < 2 * n; ++i)
    if (m.rest_positions()(i, 2) < 1e-9) m.set_fixed(i);
  Simulation<double>::Options o;
  o.sleep.enabled = true;
  Simulation<double> sim(m, o);
  ContactSolver<double> solver(sim.model(), sim.forces());
  Instrument<double> tool;
  // Tetrahedral parts meet instruments at their vertices (ContactOptions::tetrahedral_surface):
  // a ball wider than a lattice face's half-diagonal (3.5 mm) rests on its four corners.
  tool.shape = SphereShape<double>{0.004};
  tool.pose.position = V3(0.0075, 0.0075, 0.0115);
  const Index k = solver.add_instrument(tool);
  auto step = [&] {
    solver.compute(sim.model(), sim.forces());
    const StepReport<double> r = sim.step(1e-3);
    solver.collect(sim.forces());
    return r;
  };
  // Stroking the first block (1 mm along x over the run); the second sags under gravity,
  // settles, then sleeps.
  for (int s = 0; s < 400; ++s) {
    solver.instrument(k).pose.position.x() = 0.0075 + 0.001 * s / 400.0;
    solver.instrument(k).linear_velocity = V3(0.001 / 0.4, 0, 0);
    ASSERT_TRUE(step().advanced());
  }
  EXPECT_TRUE(sim.asleep(far));
  EXPECT_FALSE(sim.asleep(0));  // the one under the moving instrument keeps working
  const Positions<double> frozen = sim.model().positions().middleRows(n, n);
  for (int s = 0; s < 20; ++s) ASSERT_TRUE(step().advanced());
  EXPECT_EQ(sim.model().positions().middleRows(n, n), frozen);  // not integrated
  Index active = 0;
  for (const auto& [a, b] : sim.forces().active_links()) active += b - a;
  EXPECT_LE(active, sim.model().num_links() / 2);  // its links are skipped
  // Move the instrument onto the sleeping block: it wakes and yields.
  solver.instrument(k).pose.position = V3(0.0575, 0.0075, 0.0115);
  for (int s = 0; s < 20; ++s) ASSERT_TRUE(step().advanced());
  EXPECT_FALSE(sim.asleep(far));
  EXPECT_GT((sim.model().positions().middleRows(n, n) - frozen).norm(), 1e-5);
}

}  // namespace
}  // namespace fsm::test
