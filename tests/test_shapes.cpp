// Instrument shapes against one sphere: the closed forms (sphere, capsule, cylinder) against the
// geometry worked by hand, the convex hull (libccd) against the exact distance to a box and a
// tetrahedron, pose invariance, bounding boxes, degenerate and non-finite input.

#include <random>

#include "common.hpp"
#include "fsm/collision/shapes.hpp"

namespace fsm::test {
namespace {

using namespace fsm::collision;
using V3 = Vector3<double>;

Pose<double> random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> a(-1, 1);
  Pose<double> p;
  p.position = V3(a(rng), a(rng), a(rng)) * 0.05;
  p.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(3 * a(rng), V3(a(rng), a(rng), a(rng)).normalized()));
  return p;
}

// Signed distance from p to the axis-aligned box [-h, h] and the outward normal at the nearest
// point.
std::pair<double, V3> box_distance(const V3& h, const V3& p) {
  const V3 q = p.cwiseAbs() - h;
  if (q.maxCoeff() > 0) {
    const V3 outside = q.cwiseMax(0.0);
    V3 n = outside.cwiseProduct(p.cwiseSign());
    return {outside.norm(), n.normalized()};
  }
  int axis = 0;
  q.maxCoeff(&axis);
  V3 n = V3::Zero();
  n[axis] = p[axis] >= 0 ? 1.0 : -1.0;
  return {q[axis], n};
}

ConvexHullShape<double> box_hull(const V3& h) {
  ConvexHullShape<double> s;
  s.points.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    s.points.row(i) =
        V3((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(), (i & 4) ? h.z() : -h.z());
  return s;
}

TEST(Shapes, SphereAgainstSphereByHand) {
  const Shape<double> ball = SphereShape<double>{0.01};
  Pose<double> pose;
  pose.position = V3(0.1, 0, 0);
  auto c = contact(ball, pose, V3(0.1, 0.014, 0), 0.005);
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->depth, 0.001, 1e-12);
  EXPECT_TRUE(c->normal.isApprox(V3::UnitY(), 1e-12));
  EXPECT_TRUE(c->point.isApprox(V3(0.1, 0.01, 0), 1e-12));
  EXPECT_FALSE(contact(ball, pose, V3(0.1, 0.0151, 0), 0.005));
  // Coincident centres: a defined, unit normal and the full depth.
  auto same = contact(ball, pose, pose.position, 0.005);
  ASSERT_TRUE(same);
  EXPECT_NEAR(same->normal.norm(), 1.0, 1e-12);
  EXPECT_NEAR(same->depth, 0.015, 1e-12);
}

TEST(Shapes, CapsuleSideEndAndZeroLength) {
  const Shape<double> shaft = CapsuleShape<double>{0.002, 0.03};
  Pose<double> pose;  // axis along z
  // Beside the shaft, anywhere along it: distance to the axis.
  for (double z : {-0.03, -0.01, 0.0, 0.029}) {
    auto c = contact(shaft, pose, V3(0.004, 0, z), 0.003);
    ASSERT_TRUE(c);
    EXPECT_NEAR(c->depth, 0.001, 1e-12);
    EXPECT_TRUE(c->normal.isApprox(V3::UnitX(), 1e-12));
  }
  // Beyond the end: distance to the end point, normal from it.
  auto e = contact(shaft, pose, V3(0.003, 0, 0.034), 0.0031);  // |(0.003, 0, 0.004)| = 0.005
  ASSERT_TRUE(e);
  EXPECT_NEAR(e->depth, 0.0051 - 0.005, 1e-12);
  EXPECT_TRUE(e->normal.isApprox(V3(0.6, 0, 0.8), 1e-12));
  auto e2 = contact(shaft, pose, V3(0.003, 0, 0.033), 0.003);
  ASSERT_TRUE(e2);
  EXPECT_NEAR(e2->depth, 0.005 - std::hypot(0.003, 0.003), 1e-12);
  EXPECT_TRUE(e2->normal.isApprox(V3(1, 0, 1).normalized(), 1e-12));
  // A zero-length capsule is a sphere.
  const Shape<double> dot = CapsuleShape<double>{0.002, 0.0};
  const Shape<double> ball = SphereShape<double>{0.002};
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.006, 0.006);
  for (int k = 0; k < 200; ++k) {
    const V3 p(u(rng), u(rng), u(rng));
    auto a = contact(dot, pose, p, 0.003);
    auto b = contact(ball, pose, p, 0.003);
    ASSERT_EQ(bool(a), bool(b));
    if (a) {
      EXPECT_NEAR(a->depth, b->depth, 1e-12);
    }
  }
}

TEST(Shapes, CylinderSideCapRimAndInside) {
  const Shape<double> cyl = CylinderShape<double>{0.004, 0.01};
  Pose<double> pose;
  auto side = contact(cyl, pose, V3(0, 0.006, 0.005), 0.003);
  ASSERT_TRUE(side);
  EXPECT_NEAR(side->depth, 0.001, 1e-12);
  EXPECT_TRUE(side->normal.isApprox(V3::UnitY(), 1e-12));
  auto cap = contact(cyl, pose, V3(0.002, 0, -0.012), 0.003);
  ASSERT_TRUE(cap);
  EXPECT_NEAR(cap->depth, 0.001, 1e-12);
  EXPECT_TRUE(cap->normal.isApprox(-V3::UnitZ(), 1e-12));
  EXPECT_TRUE(cap->point.isApprox(V3(0.002, 0, -0.01), 1e-12));
  // Past the rim: distance to the circle edge, not to either plane.
  auto rim = contact(cyl, pose, V3(0.006, 0, 0.012), 0.003);
  ASSERT_TRUE(rim);
  EXPECT_NEAR(rim->depth, 0.003 - std::hypot(0.002, 0.002), 1e-12);
  EXPECT_TRUE(rim->point.isApprox(V3(0.004, 0, 0.01), 1e-12));
  EXPECT_FALSE(contact(cyl, pose, V3(0.0063, 0, 0.0123), 0.003));  // |(0.0023, 0.0023)| > 0.003
  // A centre inside leaves through the nearest face: depth = r + distance to that face.
  auto in = contact(cyl, pose, V3(0.003, 0, 0.0), 0.001);
  ASSERT_TRUE(in);
  EXPECT_NEAR(in->depth, 0.002, 1e-12);
  EXPECT_TRUE(in->normal.isApprox(V3::UnitX(), 1e-12));
}

TEST(Shapes, RoundedCylinderMatchesTheRoundedProfileDistance) {
  // The rounded cylinder against the signed distance of its profile, a rectangle [0, R] x [-h, h]
  // in (rho, z) with corners of radius e: q = (rho - (R - e), |z| - (h - e)),
  // d = |max(q, 0)| + min(max(q_x, q_y), 0) - e. Depth r - d, normal its gradient (central
  // differences), point c - d n.
  const double R = 0.003, h = 0.005, e = 0.001;
  const Shape<double> cyl = CylinderShape<double>{R, h, e};
  auto profile = [&](const V3& p) {
    const double qx = std::hypot(p.x(), p.y()) - (R - e), qz = std::abs(p.z()) - (h - e);
    return std::hypot(std::max(qx, 0.0), std::max(qz, 0.0)) + std::min(std::max(qx, qz), 0.0) - e;
  };
  Pose<double> pose;
  pose.position = V3(0.01, -0.02, 0.005);
  pose.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, V3(1, 2, 3).normalized()));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.008, 0.008);
  int hits = 0, rims = 0;
  for (int k = 0; k < 4000; ++k) {
    const V3 p(u(rng), u(rng), u(rng));
    const double r = 0.0015, d = profile(p);
    const auto c = contact(cyl, pose, pose.to_world(p), r);
    if (d >= r - 1e-12) {
      EXPECT_FALSE(c && c->depth > 1e-12) << p.transpose();
      continue;
    }
    // Skip the medial surfaces, where the nearest point (and the gradient) is not unique.
    const double rho = std::hypot(p.x(), p.y());
    if (d < 0 && (std::abs((R - rho) - (h - std::abs(p.z()))) < 1e-5 || rho < 1e-5)) continue;
    ASSERT_TRUE(c) << p.transpose();
    ++hits;
    if (rho > R - e && std::abs(p.z()) > h - e) ++rims;
    EXPECT_NEAR(c->depth, r - d, 1e-12) << p.transpose();
    const double s = 1e-7;
    V3 g;
    for (int i = 0; i < 3; ++i)
      g[i] = (profile(p + s * V3::Unit(i)) - profile(p - s * V3::Unit(i))) / (2 * s);
    EXPECT_TRUE(c->normal.isApprox(pose.orientation * g.normalized(), 1e-6)) << p.transpose();
    EXPECT_TRUE(c->point.isApprox(pose.to_world(p) - d * c->normal, 1e-9)) << p.transpose();
  }
  EXPECT_GT(hits, 500);
  EXPECT_GT(rims, 50);  // the rounded rims themselves were sampled
  // Overall size unchanged; the flat end keeps its disc of radius R - e.
  auto cap = contact(cyl, Pose<double>{}, V3(R - e, 0, h + 0.0005), 0.001);
  ASSERT_TRUE(cap);
  EXPECT_NEAR(cap->depth, 0.0005, 1e-12);
  EXPECT_TRUE(cap->normal.isApprox(V3::UnitZ(), 1e-12));
  auto side = contact(cyl, Pose<double>{}, V3(R + 0.0005, 0, 0), 0.001);
  ASSERT_TRUE(side);
  EXPECT_NEAR(side->depth, 0.0005, 1e-12);
  // Zero edge radius is the sharp cylinder.
  const Shape<double> sharp = CylinderShape<double>{R, h};
  const Shape<double> zero = CylinderShape<double>{R, h, 0.0};
  const V3 beyond(0.0035, 0.001, 0.0055);
  EXPECT_DOUBLE_EQ(contact(sharp, Pose<double>{}, beyond, 0.001)->depth,
                   contact(zero, Pose<double>{}, beyond, 0.001)->depth);
  // Too large an edge radius is an error naming the field, and gives no contact.
  EXPECT_THROW(validate(Shape<double>(CylinderShape<double>{R, h, 0.004}), "tool"), Error);
  EXPECT_THROW(validate(Shape<double>(CylinderShape<double>{R, h, -1e-4}), "tool"), Error);
  EXPECT_FALSE(contact(Shape<double>(CylinderShape<double>{R, h, 0.004}), Pose<double>{},
                       V3(0, 0, 0), 0.001));
}

TEST(Shapes, HullMatchesExactBoxDistanceInAndOut) {
  const V3 h(0.01, 0.004, 0.002);
  const Shape<double> hull = box_hull(h);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.016, 0.016);
  int hits = 0, inside = 0;
  for (int k = 0; k < 4000; ++k) {
    const V3 p(u(rng), u(rng) * 0.5, u(rng) * 0.4);
    const double r = 0.003;
    auto [d, n] = box_distance(h, p);
    auto c = contact(hull, Pose<double>{}, p, r);
    if (d >= r - 1e-12) {
      EXPECT_FALSE(c && c->depth > 1e-9) << "p=" << p.transpose() << " d=" << d;
      continue;
    }
    ASSERT_TRUE(c) << "p=" << p.transpose() << " d=" << d;
    ++hits;
    if (d < 0) ++inside;
    EXPECT_NEAR(c->depth, r - d, 1e-9) << "p=" << p.transpose();
    EXPECT_NEAR(c->normal.norm(), 1.0, 1e-9);
    EXPECT_GT(c->normal.dot(n), 1 - 1e-6) << "p=" << p.transpose();
    // The contact point is on the box surface.
    EXPECT_NEAR(box_distance(h, c->point).first, 0.0, 1e-9);
  }
  EXPECT_GT(hits, 500);
  EXPECT_GT(inside, 50);  // the EPA/MPR branch was exercised
}

TEST(Shapes, HullOfRegularTetrahedronInside) {
  // Inside a convex polytope the penetration is the smallest distance to a face plane.
  ConvexHullShape<double> t;
  t.points.resize(4, 3);
  t.points << 1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1;
  t.points *= 0.01;
  std::vector<std::pair<V3, double>> planes;  // outward unit normal, offset
  for (int f = 0; f < 4; ++f) {
    const V3 n = -V3(t.points.row(f)).normalized();  // the face opposite vertex f
    planes.push_back({n, n.dot(V3(t.points.row((f + 1) % 4)))});
  }
  const Shape<double> hull = t;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.004, 0.004);
  int inside = 0;
  for (int k = 0; k < 500; ++k) {
    const V3 p(u(rng), u(rng), u(rng));
    double best = -1e9;
    for (auto& [n, o] : planes) best = std::max(best, n.dot(p) - o);
    if (best >= -1e-6) continue;  // outside or on a face: not this test
    ++inside;
    auto c = contact(hull, Pose<double>{}, p, 0.001);
    ASSERT_TRUE(c);
    EXPECT_NEAR(c->depth, 0.001 - best, 1e-9);
  }
  EXPECT_GT(inside, 300);
}

TEST(Shapes, ContactIsInvariantUnderPose) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.015, 0.015);
  const std::vector<Shape<double>> shapes = {
      SphereShape<double>{0.005}, CapsuleShape<double>{0.003, 0.01},
      CylinderShape<double>{0.004, 0.008}, box_hull(V3(0.01, 0.005, 0.003))};
  for (const auto& s : shapes) {
    for (int k = 0; k < 300; ++k) {
      const Pose<double> pose = random_pose(rng);
      const V3 local(u(rng), u(rng), u(rng));
      auto a = contact(s, Pose<double>{}, local, 0.004);
      auto b = contact(s, pose, pose.to_world(local), 0.004);
      ASSERT_EQ(bool(a), bool(b));
      if (!a) continue;
      EXPECT_NEAR(a->depth, b->depth, 1e-9);
      EXPECT_TRUE((pose.orientation * a->normal).isApprox(b->normal, 1e-6));
      EXPECT_TRUE(pose.to_world(a->point).isApprox(b->point, 1e-6));
    }
  }
}

TEST(Shapes, BoundingBoxContainsEveryContactPoint) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-0.03, 0.03);
  const std::vector<Shape<double>> shapes = {
      SphereShape<double>{0.005}, CapsuleShape<double>{0.003, 0.01},
      CylinderShape<double>{0.004, 0.008}, box_hull(V3(0.01, 0.005, 0.003))};
  for (const auto& s : shapes) {
    const Pose<double> pose = random_pose(rng);
    auto [lo, hi] = bounding_box(s, pose);
    int n = 0;
    for (int k = 0; k < 2000; ++k) {
      const V3 p = pose.position + V3(u(rng), u(rng), u(rng));
      auto c = contact(s, pose, p, 0.03);
      if (!c) continue;
      ++n;
      EXPECT_TRUE((c->point.array() >= lo.array() - 1e-12).all() &&
                  (c->point.array() <= hi.array() + 1e-12).all());
      // Spheres touching the shape overlap its box.
      EXPECT_TRUE(((p.array() + 0.03) >= lo.array()).all() &&
                  ((p.array() - 0.03) <= hi.array()).all());
    }
    EXPECT_GT(n, 100);
  }
}

TEST(Shapes, NonFiniteInputGivesNoContact) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Shape<double>> shapes = {
      SphereShape<double>{0.005}, CapsuleShape<double>{0.003, 0.01},
      CylinderShape<double>{0.004, 0.008}, box_hull(V3(0.01, 0.005, 0.003))};
  for (const auto& s : shapes) {
    EXPECT_FALSE(contact(s, Pose<double>{}, V3(nan, 0, 0), 0.001));
    EXPECT_FALSE(contact(s, Pose<double>{}, V3(0, 0, 0), nan));
    Pose<double> bad;
    bad.position = V3(0, nan, 0);
    EXPECT_FALSE(contact(s, bad, V3(0, 0, 0), 0.001));
    bad = Pose<double>{};
    bad.orientation.coeffs() << nan, 0, 0, 1;
    EXPECT_FALSE(contact(s, bad, V3(0, 0, 0), 0.001));
  }
}

TEST(Shapes, ValidateNamesTheInstrumentAndReason) {
  auto message = [](const Shape<double>& s) {
    try {
      validate(s, "grasper");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message(SphereShape<double>{-0.001}).find("grasper"), std::string::npos);
  EXPECT_NE(
      message(CapsuleShape<double>{0.001, std::numeric_limits<double>::infinity()}).find("grasper"),
      std::string::npos);
  EXPECT_NE(message(CylinderShape<double>{0.001, -1.0}).find("grasper"), std::string::npos);
  ConvexHullShape<double> flat;
  flat.points.resize(4, 3);
  flat.points << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0;
  EXPECT_NE(message(flat).find("grasper"), std::string::npos);
  ConvexHullShape<double> few;
  few.points.resize(3, 3);
  few.points << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  EXPECT_FALSE(message(few).empty());
  EXPECT_TRUE(message(CapsuleShape<double>{0.0, 0.0}).empty());  // a point is allowed
  EXPECT_TRUE(message(box_hull(V3(0.01, 0.01, 0.01))).empty());
}

TEST(Shapes, FloatAgreesWithDouble) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-0.012, 0.012);
  for (int k = 0; k < 500; ++k) {
    const V3 p(u(rng), u(rng), u(rng));
    auto d = contact(Shape<double>{CapsuleShape<double>{0.003, 0.008}}, Pose<double>{}, p, 0.004);
    auto f = contact(Shape<float>{CapsuleShape<float>{0.003f, 0.008f}}, Pose<float>{},
                     Vector3<float>(p.cast<float>()), 0.004f);
    if (d && d->depth > 1e-6) {
      ASSERT_TRUE(f);
      EXPECT_NEAR(f->depth, d->depth, 1e-6);
    }
  }
}

}  // namespace
}  // namespace fsm::test
