// TriangleBvh: the two per-triangle tests against independent references, then every query of the
// tree against brute force over all faces (which uses the same per-triangle tests, so the answers
// must be identical bit for bit: the tree may only skip work, never change a result), before and
// after refit. The global operator new is replaced by a counting one to check that refit and the
// queries do not allocate.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <random>
#include <vector>

#include "common.hpp"
#include "fsm/collision/triangle_bvh.hpp"

#include "counting_allocator.hpp"  // replaces global operator new/delete in this test

namespace fsm::collision {
namespace {

using test::near;

template <typename Scalar>
using V3 = Vector3<Scalar>;

template <typename Scalar>
V3<Scalar> row(const Positions<Scalar>& v, Index i) {
  return v.row(i).transpose();
}

// ---------------------------------------------------------------------------------------------
// Meshes
// ---------------------------------------------------------------------------------------------

// A closed, outward-oriented UV sphere (`rings` latitude bands, `sectors` longitudes) of radius
// `radius` (m) about `centre`, each vertex's radius scaled by 1 + jitter * U(-1, 1).
template <typename Scalar>
TriangleMesh<Scalar> bumpy_sphere(int rings, int sectors, double radius, const V3<double>& centre,
                                  double jitter, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const double pi = 3.14159265358979323846;
  TriangleMesh<Scalar> m;
  const Index nv = 2 + (rings - 1) * sectors;
  m.vertices.resize(nv, 3);
  auto put = [&](Index i, const V3<double>& dir) {
    m.vertices.row(i) =
        (centre + radius * (1 + jitter * u(rng)) * dir).template cast<Scalar>().transpose();
  };
  put(0, V3<double>(0, 0, 1));
  for (int r = 1; r < rings; ++r)
    for (int s = 0; s < sectors; ++s) {
      const double th = pi * r / rings, ph = 2 * pi * s / sectors;
      put(1 + (r - 1) * sectors + s,
          V3<double>(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  put(nv - 1, V3<double>(0, 0, -1));
  std::vector<Index> f;
  auto ring = [&](int r, int s) { return Index(1 + (r - 1) * sectors + (s % sectors)); };
  for (int s = 0; s < sectors; ++s) f.insert(f.end(), {0, ring(1, s), ring(1, s + 1)});
  for (int r = 1; r < rings - 1; ++r)
    for (int s = 0; s < sectors; ++s) {
      f.insert(f.end(), {ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
      f.insert(f.end(), {ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
    }
  for (int s = 0; s < sectors; ++s)
    f.insert(f.end(), {nv - 1, ring(rings - 1, s + 1), ring(rings - 1, s)});
  m.faces = Eigen::Map<const FaceArray>(f.data(), Index(f.size() / 3), 3);
  return m;
}

// `n` independent triangles (3n vertices) of sizes from 0.1 mm to 2 cm, scattered in a 5 cm box
// whose corner is at 0.2 m from the origin (so coordinates are not all small).
template <typename Scalar>
TriangleMesh<Scalar> triangle_soup(Index n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1), s(-1, 1);
  TriangleMesh<Scalar> m;
  m.vertices.resize(3 * n, 3);
  m.faces.resize(n, 3);
  for (Index f = 0; f < n; ++f) {
    const V3<double> c = V3<double>(0.2, 0.1, -0.05) + 0.05 * V3<double>(u(rng), u(rng), u(rng));
    const double size = 1e-4 * std::pow(200.0, u(rng));
    for (int k = 0; k < 3; ++k) {
      m.vertices.row(3 * f + k) =
          (c + size * V3<double>(s(rng), s(rng), s(rng))).template cast<Scalar>().transpose();
      m.faces(f, k) = 3 * f + k;
    }
  }
  return m;
}

// A smooth deformation (a bend and a squash, up to ~20 % of the size) plus noise of `noise` (m)
// per coordinate: the kind of motion skinning produces, and enough to reorder centroids.
template <typename Scalar>
Positions<Scalar> deform(const Positions<Scalar>& v, double noise, std::mt19937& rng) {
  std::normal_distribution<double> g(0, 1);
  const V3<double> lo = v.colwise().minCoeff().template cast<double>().transpose();
  const V3<double> hi = v.colwise().maxCoeff().template cast<double>().transpose();
  const double size = (hi - lo).maxCoeff();
  Positions<Scalar> out(v.rows(), 3);
  for (Index i = 0; i < v.rows(); ++i) {
    const V3<double> p = v.row(i).template cast<double>().transpose();
    const V3<double> q = (p - lo) / size;
    V3<double> d(0.2 * size * std::sin(3 * q.y()), 0.1 * size * q.x() * q.z(),
                 -0.15 * size * q.z() * q.z());
    d += noise * V3<double>(g(rng), g(rng), g(rng));
    out.row(i) = (p + d).template cast<Scalar>().transpose();
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Brute force over all faces, with the same per-triangle tests as the tree.
// ---------------------------------------------------------------------------------------------

template <typename Scalar>
std::optional<RayHit<Scalar>> brute_ray_cast(const TriangleMesh<Scalar>& m, const V3<Scalar>& o,
                                             const V3<Scalar>& d, Scalar max_distance) {
  std::optional<RayHit<Scalar>> best;
  const V3<Scalar> unit = d.normalized();
  for (Index f = 0; f < m.num_faces(); ++f) {
    auto hit = intersect_ray_triangle<Scalar>(o, unit, row(m.vertices, m.faces(f, 0)),
                                              row(m.vertices, m.faces(f, 1)),
                                              row(m.vertices, m.faces(f, 2)), max_distance);
    if (hit && (!best || hit->distance < best->distance)) {  // ties: the first (smallest) face
      best = hit;
      best->face = f;
    }
  }
  return best;
}

template <typename Scalar>
std::vector<Index> brute_faces_near(const TriangleMesh<Scalar>& m, const V3<Scalar>& c, Scalar r) {
  std::vector<Index> out;
  for (Index f = 0; f < m.num_faces(); ++f) {
    const V3<Scalar> q = closest_point_on_triangle<Scalar>(c, row(m.vertices, m.faces(f, 0)),
                                                           row(m.vertices, m.faces(f, 1)),
                                                           row(m.vertices, m.faces(f, 2)));
    if ((c - q).squaredNorm() <= r * r) out.push_back(f);
  }
  return out;
}

// A uniformly random point of face f.
template <typename Scalar>
V3<Scalar> point_on_face(const TriangleMesh<Scalar>& m, Index f, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  double s = u(rng), t = u(rng);
  if (s + t > 1) s = 1 - s, t = 1 - t;
  const V3<double> a = m.vertices.row(m.faces(f, 0)).template cast<double>().transpose();
  const V3<double> b = m.vertices.row(m.faces(f, 1)).template cast<double>().transpose();
  const V3<double> c = m.vertices.row(m.faces(f, 2)).template cast<double>().transpose();
  return (a + s * (b - a) + t * (c - a)).template cast<Scalar>();
}

struct QueryStats {
  int rays{0}, hits{0}, limited_misses{0}, spheres{0}, nonempty{0}, truncated{0};
};

// Random rays and spheres against tree and brute force; every answer must be identical.
template <typename Scalar>
QueryStats compare_with_brute_force(const TriangleBvh<Scalar>& bvh, const TriangleMesh<Scalar>& m,
                                    std::mt19937& rng, int queries) {
  QueryStats st;
  std::uniform_real_distribution<double> u(0, 1), s(-1, 1);
  std::uniform_int_distribution<Index> face(0, m.num_faces() - 1);
  const V3<double> lo = m.vertices.colwise().minCoeff().template cast<double>().transpose();
  const V3<double> hi = m.vertices.colwise().maxCoeff().template cast<double>().transpose();
  const double size = (hi - lo).maxCoeff();
  const Scalar inf = std::numeric_limits<Scalar>::infinity();
  auto random_point = [&](double margin) {
    V3<double> p;
    for (int k = 0; k < 3; ++k)
      p[k] = lo[k] - margin * size + (hi[k] - lo[k] + 2 * margin * size) * u(rng);
    return p.template cast<Scalar>().eval();
  };
  for (int q = 0; q < queries; ++q) {
    // Rays: from anywhere around the surface, half aimed at a random point of a random face (so
    // there are many hits), a few at a vertex exactly (shared by several faces: ties); directions
    // of random, non-unit length; a third limited to a random distance.
    const V3<Scalar> o = random_point(0.3);
    V3<Scalar> d;
    const int kind = q % 6;
    if (kind < 3)
      d = point_on_face(m, face(rng), rng) - o;
    else if (kind == 3)
      d = row(m.vertices, m.faces(face(rng), int(u(rng) * 3) % 3)) - o;
    else
      d = V3<double>(s(rng), s(rng), s(rng)).template cast<Scalar>();
    d *= Scalar(std::pow(10.0, 2 * s(rng)));
    if (!(d.squaredNorm() > 0)) continue;
    const Scalar max_distance = q % 3 == 0 ? Scalar(2 * size * u(rng)) : inf;
    const auto expected = brute_ray_cast(m, o, d, max_distance);
    const auto got = bvh.ray_cast(o, d, max_distance);
    ++st.rays;
    EXPECT_EQ(expected.has_value(), got.has_value()) << "ray " << q;
    if (expected && got) {
      ++st.hits;
      EXPECT_EQ(expected->face, got->face) << "ray " << q;
      EXPECT_EQ(expected->distance, got->distance) << "ray " << q;
      EXPECT_EQ(expected->u, got->u) << "ray " << q;
      EXPECT_EQ(expected->v, got->v) << "ray " << q;
      EXPECT_LE(got->distance, max_distance);
    }
    if (!expected && max_distance < inf && brute_ray_cast(m, o, d, inf)) ++st.limited_misses;

    // Spheres: centred near a random face (or anywhere), radius up to 15 % of the size; the
    // output buffer is sometimes too small.
    const V3<Scalar> c =
        q % 4 == 0 ? random_point(0.2)
                   : (point_on_face(m, face(rng), rng) +
                      (0.05 * size * V3<double>(s(rng), s(rng), s(rng))).template cast<Scalar>())
                         .eval();
    const Scalar r = Scalar(0.15 * size * u(rng) * u(rng));
    const std::vector<Index> want = brute_faces_near(m, c, r);
    const Index capacity = q % 5 == 0 ? Index(want.size() / 2) : Index(want.size() + 3);
    std::vector<Index> out(size_t(capacity) + 1, -7);
    const Index n = bvh.faces_near(c, r, out.data(), capacity);
    ++st.spheres;
    st.nonempty += want.empty() ? 0 : 1;
    EXPECT_EQ(Index(want.size()), n) << "sphere " << q;
    const Index written = std::min(n, capacity);
    std::vector<Index> got_faces(out.begin(), out.begin() + written);
    for (size_t i = size_t(written); i < out.size(); ++i) EXPECT_EQ(out[i], -7) << "overrun";
    std::sort(got_faces.begin(), got_faces.end());
    EXPECT_TRUE(std::adjacent_find(got_faces.begin(), got_faces.end()) == got_faces.end());
    if (written == n) {
      EXPECT_EQ(want, got_faces) << "sphere " << q;
    } else {
      ++st.truncated;
      EXPECT_TRUE(std::includes(want.begin(), want.end(), got_faces.begin(), got_faces.end()));
    }
  }
  return st;
}

// The tree's structure, and every box equal (exactly) to the bounds of its faces' corners
// recomputed from scratch at `vertices`.
template <typename Scalar>
void expect_exact_tree(const TriangleBvh<Scalar>& bvh, const TriangleMesh<Scalar>& m) {
  const auto& nodes = bvh.nodes();
  const auto& order = bvh.face_order();
  ASSERT_EQ(order.size(), size_t(m.num_faces()));
  std::vector<Index> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (Index i = 0; i < m.num_faces(); ++i) ASSERT_EQ(sorted[size_t(i)], i) << "not a permutation";
  ASSERT_FALSE(nodes.empty());
  EXPECT_EQ(nodes[0].first, 0);
  EXPECT_EQ(nodes[0].count, m.num_faces());
  int leaves = 0;
  for (size_t n = 0; n < nodes.size(); ++n) {
    const auto& node = nodes[n];
    V3<Scalar> lo = V3<Scalar>::Constant(std::numeric_limits<Scalar>::infinity());
    V3<Scalar> hi = -lo;
    for (Index i = node.first; i < node.first + node.count; ++i)
      for (int k = 0; k < 3; ++k) {
        lo = lo.cwiseMin(row(m.vertices, m.faces(order[size_t(i)], k)));
        hi = hi.cwiseMax(row(m.vertices, m.faces(order[size_t(i)], k)));
      }
    EXPECT_EQ(lo, node.lo) << "node " << n;
    EXPECT_EQ(hi, node.hi) << "node " << n;
    if (node.is_leaf()) {
      ++leaves;
      EXPECT_GE(node.count, 1);
      EXPECT_LE(node.count, TriangleBvh<Scalar>::max_leaf_faces);
    } else {
      const auto& l = nodes[size_t(node.left)];
      const auto& r = nodes[size_t(node.right)];
      EXPECT_EQ(node.left, Index(n) + 1);
      EXPECT_GT(node.right, node.left);
      EXPECT_EQ(l.first, node.first);
      EXPECT_EQ(r.first, l.first + l.count);
      EXPECT_EQ(l.count + r.count, node.count);
      EXPECT_LE(std::abs(l.count - r.count), 1) << "median split halves the faces";
    }
  }
  EXPECT_EQ(size_t(2 * leaves - 1), nodes.size());
}

// ---------------------------------------------------------------------------------------------
// Per-triangle tests
// ---------------------------------------------------------------------------------------------

template <typename Scalar>
class TriangleBvhTest : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(TriangleBvhTest, Scalars);

// Tolerances of the per-triangle tests against references computed differently: a few hundred
// ulps of the coordinates (the triangles are well shaped, so nothing amplifies rounding further).
template <typename Scalar>
double tol() {
  return std::is_same_v<Scalar, float> ? 2e-4 : 1e-11;
}

// Independent reference: project onto the plane (barycentrics from the 2 x 2 normal equations,
// in double); inside -> that point; else the nearest of the three edges.
V3<double> reference_closest(const V3<double>& p, const V3<double>& a, const V3<double>& b,
                             const V3<double>& c) {
  const V3<double> e0 = b - a, e1 = c - a;
  Eigen::Matrix2d g;
  g << e0.dot(e0), e0.dot(e1), e0.dot(e1), e1.dot(e1);
  if (g.determinant() > 1e-12 * g.trace() * g.trace()) {
    const Eigen::Vector2d w = g.ldlt().solve(Eigen::Vector2d(e0.dot(p - a), e1.dot(p - a)));
    if (w.minCoeff() >= 0 && w.sum() <= 1) return a + w[0] * e0 + w[1] * e1;
  }
  auto seg = [&](const V3<double>& x, const V3<double>& y) {
    const double l2 = (y - x).squaredNorm();
    const double t = l2 > 0 ? std::clamp((p - x).dot(y - x) / l2, 0.0, 1.0) : 0.0;
    return V3<double>(x + t * (y - x));
  };
  V3<double> best = seg(a, b);
  for (const V3<double>& q : {seg(b, c), seg(c, a)})
    if ((p - q).squaredNorm() < (p - best).squaredNorm()) best = q;
  return best;
}

TYPED_TEST(TriangleBvhTest, ClosestPointMatchesIndependentReference) {
  using S = TypeParam;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  auto rnd = [&](double scale) {
    return V3<double>(scale * u(rng), scale * u(rng), scale * u(rng));
  };
  int interior = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const V3<double> a = rnd(1), b = a + rnd(0.5), c = a + rnd(0.5);
    // Half the points above or below the face, half anywhere around.
    double s0 = 0.5 * (u(rng) + 1), t0 = 0.5 * (u(rng) + 1);
    if (s0 + t0 > 1) s0 = 1 - s0, t0 = 1 - t0;
    const V3<double> p = trial % 2 ? V3<double>(a + rnd(1))
                                   : V3<double>(a + s0 * (b - a) + t0 * (c - a) +
                                                u(rng) * (b - a).cross(c - a).normalized());
    const V3<S> q = closest_point_on_triangle<S>(p.template cast<S>(), a.template cast<S>(),
                                                 b.template cast<S>(), c.template cast<S>());
    // Compare on the rounded inputs the function saw.
    const V3<double> ad = a.template cast<S>().template cast<double>(),
                     bd = b.template cast<S>().template cast<double>(),
                     cd = c.template cast<S>().template cast<double>(),
                     pd = p.template cast<S>().template cast<double>();
    const V3<double> ref = reference_closest(pd, ad, bd, cd);
    EXPECT_TRUE(test::matrices_near(q.template cast<double>(), ref, tol<S>())) << "trial " << trial;
    // The answer is no farther than any sampled point of the triangle.
    const double d = (pd - q.template cast<double>()).norm();
    for (int k = 0; k < 20; ++k) {
      double s = 0.5 * (u(rng) + 1), t = 0.5 * (u(rng) + 1);
      if (s + t > 1) s = 1 - s, t = 1 - t;
      EXPECT_LE(d, (pd - (ad + s * (bd - ad) + t * (cd - ad))).norm() + tol<S>());
    }
    const V3<double> n = (bd - ad).cross(cd - ad).normalized();
    interior += std::abs((pd - ref).normalized().dot(n)) > 1 - 1e-9 ? 1 : 0;
  }
  EXPECT_GT(interior, 1000) << "the face region must be exercised, not just edges and vertices";
}

TYPED_TEST(TriangleBvhTest, ClosestPointOnDegenerateTriangles) {
  using S = TypeParam;
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 500; ++trial) {
    const V3<double> a(u(rng), u(rng), u(rng)), dir(u(rng), u(rng), u(rng)),
        p(u(rng), u(rng), u(rng));
    // Collinear (c between, or beyond, a and b), two coincident vertices, all three coincident.
    const std::array<std::array<V3<double>, 3>, 4> tris = {
        {{a, a + dir, a + 0.3 * dir}, {a, a + dir, a + 2.0 * dir}, {a, a, a + dir}, {a, a, a}}};
    for (const auto& t : tris) {
      const V3<S> q =
          closest_point_on_triangle<S>(p.template cast<S>(), t[0].template cast<S>(),
                                       t[1].template cast<S>(), t[2].template cast<S>());
      ASSERT_TRUE(q.allFinite());
      const V3<double> ref = reference_closest(p, t[0], t[1], t[2]);
      EXPECT_TRUE(near((p - q.template cast<double>()).norm(), (p - ref).norm(), 10 * tol<S>(),
                       10 * tol<S>()))
          << "trial " << trial;
    }
  }
}

// Against Möller-Trumbore (a different algorithm) on rays aimed at points safely inside or
// outside: same t and barycentrics, and hit iff inside and t <= max_t.
TYPED_TEST(TriangleBvhTest, RayTriangleMatchesMollerTrumbore) {
  using S = TypeParam;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1, 1);
  auto rnd = [&](double scale) {
    return V3<double>(scale * u(rng), scale * u(rng), scale * u(rng));
  };
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const V3<S> a = rnd(1).template cast<S>(),
                b = (a.template cast<double>() + rnd(0.5)).template cast<S>(),
                c = (a.template cast<double>() + rnd(0.5)).template cast<S>();
    const V3<double> ad = a.template cast<double>(), bd = b.template cast<double>(),
                     cd = c.template cast<double>();
    if ((bd - ad).cross(cd - ad).norm() < 0.05) continue;  // well-shaped only
    // Target at barycentrics (1 - s - t, s, t), inside with margin 0.02 or outside by 0.02.
    double s = 0.5 * (u(rng) + 1), t = 0.5 * (u(rng) + 1);
    if (trial % 2 == 0 && s + t > 1) s = 1 - s, t = 1 - t;
    const double w = 1 - s - t;
    const bool inside = std::min({s, t, w}) > 0.02;
    if (!inside && std::min({s, t, w}) > -0.02) continue;
    const V3<double> target = ad + s * (bd - ad) + t * (cd - ad);
    const V3<S> o = (target + rnd(2)).template cast<S>();
    const V3<S> d =
        ((target - o.template cast<double>()) * std::pow(10.0, u(rng))).template cast<S>();
    // Möller-Trumbore in double on the same (rounded) inputs.
    const V3<double> od = o.template cast<double>(), dd = d.template cast<double>();
    const V3<double> e1 = bd - ad, e2 = cd - ad, pv = dd.cross(e2);
    const double det = e1.dot(pv);
    if (std::abs(det) < 1e-3 * dd.norm() * e1.norm() * e2.norm()) continue;  // grazing
    const V3<double> tv = od - ad, qv = tv.cross(e1);
    const double mu = tv.dot(pv) / det, mv = dd.dot(qv) / det, mt = e2.dot(qv) / det;
    const S max_t = S(trial % 3 == 0 ? mt * (1 + 0.5 * u(rng)) : 1e30);
    const auto hit = intersect_ray_triangle<S>(o, d, a, b, c, max_t);
    const bool expect_hit = inside && mt <= double(max_t);
    if (std::abs(mt - double(max_t)) < 1e-3 * mt) continue;  // too close to the limit to call
    ASSERT_EQ(expect_hit, hit.has_value()) << "trial " << trial;
    if (hit) {
      ++hits;
      EXPECT_EQ(hit->face, -1);
      EXPECT_TRUE(near(hit->distance, mt, 20 * tol<S>()));
      EXPECT_TRUE(near(hit->u, mu, 0, 20 * tol<S>()));
      EXPECT_TRUE(near(hit->v, mv, 0, 20 * tol<S>()));
    } else {
      ++misses;
    }
  }
  EXPECT_GT(hits, 500);
  EXPECT_GT(misses, 500);
}

TYPED_TEST(TriangleBvhTest, RayTriangleInPlaneOrDegenerateMisses) {
  using S = TypeParam;
  const V3<S> a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // In the triangle's plane, through its interior.
  EXPECT_FALSE(intersect_ray_triangle<S>(V3<S>(-1, S(0.25), 0), V3<S>(1, 0, 0), a, b, c));
  // Behind the origin, and beyond max_t.
  EXPECT_FALSE(intersect_ray_triangle<S>(V3<S>(S(0.2), S(0.2), 1), V3<S>(0, 0, 1), a, b, c));
  EXPECT_FALSE(
      intersect_ray_triangle<S>(V3<S>(S(0.2), S(0.2), 1), V3<S>(0, 0, -1), a, b, c, S(0.5)));
  // Inclusive bounds: at exactly max_t, and from an origin on the triangle (t = 0).
  EXPECT_TRUE(intersect_ray_triangle<S>(V3<S>(S(0.2), S(0.2), 1), V3<S>(0, 0, -1), a, b, c, S(1)));
  EXPECT_TRUE(intersect_ray_triangle<S>(V3<S>(S(0.2), S(0.2), 0), V3<S>(0, 0, 1), a, b, c));
  // A zero direction.
  EXPECT_FALSE(intersect_ray_triangle<S>(V3<S>(S(0.2), S(0.2), 1), V3<S>(0, 0, 0), a, b, c));
  // Zero-area triangles: a point, and a segment crossed by the ray.
  EXPECT_FALSE(intersect_ray_triangle<S>(V3<S>(0, 0, 1), V3<S>(0, 0, -1), a, a, a));
  EXPECT_FALSE(
      intersect_ray_triangle<S>(V3<S>(S(0.5), 0, 1), V3<S>(0, 0, -1), a, b, V3<S>(2, 0, 0)));
  // Edges and vertices belong to the triangle, from either side.
  for (const V3<S>& p : {a, b, c, V3<S>(S(0.5), 0, 0), V3<S>(S(0.5), S(0.5), 0)}) {
    EXPECT_TRUE(intersect_ray_triangle<S>(V3<S>(p.x(), p.y(), 2), V3<S>(0, 0, -1), a, b, c));
    EXPECT_TRUE(intersect_ray_triangle<S>(V3<S>(p.x(), p.y(), -2), V3<S>(0, 0, 3), a, b, c));
  }
}

// An edge function that rounds to zero in float is recomputed exactly (in double): the ray
// through (0, 0) misses (a, b, c) by 2^-46 across edge bc, and hits (d, c, b), its neighbour
// across that edge. Without the recomputation both would be hit.
TEST(TriangleBvhFloat, EdgeFunctionRoundingToZeroIsResolved) {
  const float e = std::ldexp(1.0f, -23);
  const V3<float> a(-1, 1, 0), b(1 + 2 * e, 1 + e, 0), c(-(1 + e), -1, 0), d(1, -1, 0);
  ASSERT_EQ(c.x() * b.y() - c.y() * b.x(), 0.0f) << "the float edge function must cancel";
  const V3<float> o(0, 0, -1), dir(0, 0, 1);
  EXPECT_FALSE(intersect_ray_triangle<float>(o, dir, a, b, c));
  EXPECT_TRUE(intersect_ray_triangle<float>(o, dir, d, c, b));
}

// ---------------------------------------------------------------------------------------------
// The tree
// ---------------------------------------------------------------------------------------------

TYPED_TEST(TriangleBvhTest, QueriesMatchBruteForceBeforeAndAfterRefit) {
  using S = TypeParam;
  std::mt19937 rng(21);
  std::vector<TriangleMesh<S>> meshes;
  meshes.push_back(bumpy_sphere<S>(24, 40, 0.03, V3<double>(0.01, -0.02, 0.15), 0.15, rng));
  meshes.push_back(triangle_soup<S>(1500, rng));
  for (const auto& rest : meshes) {
    TriangleBvh<S> bvh(rest.vertices, rest.faces);
    ASSERT_EQ(bvh.num_faces(), rest.num_faces());
    expect_exact_tree(bvh, rest);
    QueryStats st = compare_with_brute_force(bvh, rest, rng, 600);
    TriangleMesh<S> moved = rest;
    for (int frame = 0; frame < 3; ++frame) {
      moved.vertices = deform(moved.vertices, 0.002, rng);
      ASSERT_TRUE(bvh.refit(moved.vertices));
      expect_exact_tree(bvh, moved);
      const QueryStats s2 = compare_with_brute_force(bvh, moved, rng, 300);
      st.hits += s2.hits, st.rays += s2.rays, st.limited_misses += s2.limited_misses;
      st.nonempty += s2.nonempty, st.truncated += s2.truncated;
    }
    // The comparisons must exercise hits, misses, the distance limit and truncation.
    EXPECT_GT(st.hits, st.rays / 4);
    EXPECT_LT(st.hits, st.rays - st.rays / 10);
    EXPECT_GT(st.limited_misses, 10);
    EXPECT_GT(st.nonempty, 300);
    EXPECT_GT(st.truncated, 20);
  }
}

TYPED_TEST(TriangleBvhTest, RefittedBoxesEqualFreshlyBuiltOnes) {
  using S = TypeParam;
  std::mt19937 rng(22);
  const auto rest = bumpy_sphere<S>(16, 24, 0.03, V3<double>(0, 0, 0.1), 0.1, rng);
  TriangleBvh<S> bvh(rest.vertices, rest.faces);
  const TriangleBvh<S> fresh = bvh;
  const auto moved = deform(rest.vertices, 0.003, rng);
  ASSERT_TRUE(bvh.refit(moved));
  // Same topology, new boxes; the root box is the bounds of the moved vertices whatever the
  // topology, so it equals that of a tree built fresh on them.
  const TriangleBvh<S> built_on_moved(moved, rest.faces);
  EXPECT_EQ(bvh.nodes()[0].lo, built_on_moved.nodes()[0].lo);
  EXPECT_EQ(bvh.nodes()[0].hi, built_on_moved.nodes()[0].hi);
  EXPECT_EQ(bvh.nodes()[0].lo, moved.colwise().minCoeff().transpose());
  EXPECT_NE(bvh.nodes()[0].lo, fresh.nodes()[0].lo) << "the deformation must move the box";
  TriangleMesh<S> m{moved, rest.faces};
  expect_exact_tree(bvh, m);
  // Refitting back to the rest pose gives exactly the boxes of the tree built there.
  ASSERT_TRUE(bvh.refit(rest.vertices));
  ASSERT_EQ(bvh.nodes().size(), fresh.nodes().size());
  EXPECT_EQ(bvh.face_order(), fresh.face_order());
  for (size_t n = 0; n < fresh.nodes().size(); ++n) {
    EXPECT_EQ(bvh.nodes()[n].lo, fresh.nodes()[n].lo) << "node " << n;
    EXPECT_EQ(bvh.nodes()[n].hi, fresh.nodes()[n].hi) << "node " << n;
  }
  // A vertex array of another size is refused and leaves the tree as it was.
  const Positions<S> wrong = rest.vertices.topRows(rest.vertices.rows() - 1);
  EXPECT_FALSE(bvh.refit(wrong));
  EXPECT_FALSE(bvh.refit(moved.replicate(2, 1)));
  for (size_t n = 0; n < fresh.nodes().size(); ++n)
    EXPECT_EQ(bvh.nodes()[n].lo, fresh.nodes()[n].lo);
}

TYPED_TEST(TriangleBvhTest, MissesAndMaxDistance) {
  using S = TypeParam;
  std::mt19937 rng(23);
  const V3<double> centre(0.02, 0.01, 0.1);
  const auto m = bumpy_sphere<S>(12, 16, 0.03, centre, 0.0, rng);
  const TriangleBvh<S> bvh(m.vertices, m.faces);
  const V3<S> o = (centre + V3<double>(0.1, 0.0, 0.0)).template cast<S>();
  // Pointing away, and passing beside the sphere: nothing.
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(1, 0, 0)));
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(0, 0, 1)));
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(-1, S(0.5), 0)));
  // Towards the centre: the outer side, about 0.07 m away, whatever the direction's length.
  const auto hit = bvh.ray_cast(o, V3<S>(-1, 0, 0));
  ASSERT_TRUE(hit);
  EXPECT_TRUE(near(hit->distance, 0.07, 0.02));  // the facets are inside the sphere by < 2 %
  for (S scale : {S(1e-3), S(7), S(1e4)}) {
    const auto h = bvh.ray_cast(o, V3<S>(-scale, 0, 0));
    ASSERT_TRUE(h);
    EXPECT_EQ(h->face, hit->face);
    EXPECT_EQ(h->distance, hit->distance);
  }
  // The limit is inclusive.
  EXPECT_TRUE(bvh.ray_cast(o, V3<S>(-1, 0, 0), hit->distance));
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(-1, 0, 0), hit->distance * (1 - S(1e-4))));
  EXPECT_TRUE(bvh.ray_cast(o, V3<S>(-1, 0, 0), hit->distance * (1 + S(1e-4))));
  // Bad rays.
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(0, 0, 0)));
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(-1, 0, 0), S(-1)));
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(-1, 0, 0), std::numeric_limits<S>::quiet_NaN()));
  EXPECT_FALSE(bvh.ray_cast(V3<S>::Constant(std::numeric_limits<S>::quiet_NaN()), V3<S>(-1, 0, 0)));
  EXPECT_FALSE(bvh.ray_cast(o, V3<S>(-std::numeric_limits<S>::infinity(), 0, 0)));
  // From inside the closed surface, every ray hits, also rays aimed exactly at vertices and edge
  // midpoints (shared by several faces): the test is watertight.
  std::uniform_real_distribution<double> u(-1, 1);
  const auto bumpy = bumpy_sphere<S>(16, 24, 0.03, centre, 0.1, rng);
  const TriangleBvh<S> closed(bumpy.vertices, bumpy.faces);
  for (int i = 0; i < 3000; ++i) {
    // Close enough to the centre that the surface is star-shaped from there: the first hit
    // along a ray aimed at a vertex or an edge is that point.
    const V3<S> from = (centre + 0.003 * V3<double>(u(rng), u(rng), u(rng))).template cast<S>();
    const Index f = Index(i % bumpy.num_faces());
    const V3<S> va = row(bumpy.vertices, bumpy.faces(f, i % 3)),
                vb = row(bumpy.vertices, bumpy.faces(f, (i + 1) % 3));
    const V3<S> dir = i % 3 == 0   ? V3<S>(va - from)
                      : i % 3 == 1 ? V3<S>((va + vb) / S(2) - from)
                                   : V3<double>(u(rng), u(rng), u(rng)).template cast<S>();
    const auto h = closed.ray_cast(from, dir);
    ASSERT_TRUE(h) << "ray " << i << " escaped";
    if (i % 3 == 0) {
      EXPECT_TRUE(near(h->distance, (va - from).norm(), 1e-3)) << "ray " << i;
    } else if (i % 3 == 1) {
      EXPECT_TRUE(near(h->distance, ((va + vb) / S(2) - from).norm(), 1e-3)) << "ray " << i;
    }
  }
  // faces_near: a sphere that does not reach the surface finds nothing; negative radius nothing.
  EXPECT_EQ(bvh.faces_near(centre.template cast<S>(), S(0.02), nullptr, 0), 0);
  EXPECT_EQ(bvh.faces_near(o, S(-1), nullptr, 0), 0);
  EXPECT_GT(bvh.faces_near(centre.template cast<S>(), S(0.04), nullptr, 0), 0);
}

// A flat grid in z = 0: boxes of zero thickness, rays with zero direction components, and rays
// through vertices (shared by six faces) and edges (two faces). The hit is the smallest face
// index among those at the (equal) nearest distance.
TYPED_TEST(TriangleBvhTest, EdgeAndVertexHitsOnAFlatGrid) {
  using S = TypeParam;
  const int n = 20;
  const S h = S(0.005);
  TriangleMesh<S> m;
  m.vertices.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.vertices.row(j * (n + 1) + i) << S(i) * h, S(j) * h, S(0);
  m.faces.resize(2 * n * n, 3);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Index v = j * (n + 1) + i, f = 2 * (j * n + i);
      m.faces.row(f) << v, v + 1, v + n + 2;
      m.faces.row(f + 1) << v, v + n + 2, v + n + 1;
    }
  const TriangleBvh<S> bvh(m.vertices, m.faces);
  int ties = 0;
  for (int j = 0; j <= 2 * n; ++j)
    for (int i = 0; i <= 2 * n; ++i) {
      const V3<S> o(S(i) * h / 2, S(j) * h / 2, S(0.01));
      for (const V3<S>& d : {V3<S>(0, 0, -1), V3<S>(0, 0, S(-0.3))}) {
        const auto want = brute_ray_cast(m, o, d, std::numeric_limits<S>::infinity());
        const auto got = bvh.ray_cast(o, d);
        ASSERT_TRUE(want && got) << i << ", " << j;
        EXPECT_EQ(want->face, got->face) << i << ", " << j;
        EXPECT_EQ(want->distance, got->distance) << i << ", " << j;
        // Every face containing the point is hit, at the same distance up to rounding; the
        // tree returns the nearest as computed, the smallest index among equals.
        int containing = 0;
        for (Index f = 0; f < m.num_faces(); ++f)
          if (auto hf = intersect_ray_triangle<S>(
                  o, d.normalized().eval(), row(m.vertices, m.faces(f, 0)),
                  row(m.vertices, m.faces(f, 1)), row(m.vertices, m.faces(f, 2)))) {
            ++containing;
            EXPECT_TRUE(near(hf->distance, 0.01, 4 * std::numeric_limits<S>::epsilon()));
            EXPECT_GE(hf->distance, got->distance);
            if (hf->distance == got->distance) {
              EXPECT_GE(f, got->face);
            }
          }
        ties += containing > 1 ? 1 : 0;
        // The points are on edges or vertices: 1 (boundary edge) to 6 (inner vertex) faces.
        EXPECT_GE(containing, 1);
        EXPECT_LE(containing, 6);
      }
    }
  EXPECT_GT(ties, 800);
  // Rays in the grid's plane never hit it (the faces are edge-on); from the side, none either.
  EXPECT_FALSE(bvh.ray_cast(V3<S>(-h, S(0.3) * h, 0), V3<S>(1, 0, 0)));
  EXPECT_FALSE(bvh.ray_cast(V3<S>(S(0.5) * h, S(0.5) * h, 0), V3<S>(1, 1, 0)));
  // Just off the grid's edge, straight down: a miss; on the edge: a hit.
  EXPECT_FALSE(bvh.ray_cast(V3<S>(S(n) * h * S(1.001), h, 1), V3<S>(0, 0, -1)));
  EXPECT_TRUE(bvh.ray_cast(V3<S>(S(n) * h, h, 1), V3<S>(0, 0, -1)));
  // faces_near at a vertex with radius 0 finds the six faces around it.
  std::array<Index, 8> out{};
  EXPECT_EQ(bvh.faces_near(row(m.vertices, 5 * (n + 1) + 5), S(0), out.data(), 8), 6);
}

TYPED_TEST(TriangleBvhTest, DegenerateTrianglesDoNotCrash) {
  using S = TypeParam;
  std::mt19937 rng(24);
  auto m = bumpy_sphere<S>(12, 16, 0.03, V3<double>(0, 0, 0), 0.1, rng);
  // Collapse a third of the faces: a repeated vertex (a segment), all three the same (a point),
  // or a third vertex on the line of the other two.
  const Index nv = m.num_vertices();
  m.vertices.conservativeResize(nv + m.num_faces(), 3);
  for (Index f = 0; f < m.num_faces(); f += 3) {
    const int kind = (f / 3) % 3;
    if (kind == 0) m.faces(f, 2) = m.faces(f, 0);
    if (kind == 1) m.faces(f, 1) = m.faces(f, 2) = m.faces(f, 0);
    if (kind == 2) {
      m.vertices.row(nv + f) =
          (S(0.25) * m.vertices.row(m.faces(f, 0)) + S(0.75) * m.vertices.row(m.faces(f, 1)));
      m.faces(f, 2) = nv + f;
    }
  }
  for (Index i = nv; i < m.vertices.rows(); ++i)
    if (!(m.faces.array() == i).any()) m.vertices.row(i) = m.vertices.row(0);
  TriangleBvh<S> bvh(m.vertices, m.faces);
  expect_exact_tree(bvh, m);
  compare_with_brute_force(bvh, m, rng, 300);
  // Everything at one point: every box is a point.
  TriangleMesh<S> point{Positions<S>::Constant(m.num_vertices(), 3, S(0.01)), m.faces.topRows(40)};
  ASSERT_TRUE(bvh.refit(Positions<S>::Constant(m.num_vertices(), 3, S(0.01))));
  EXPECT_FALSE(bvh.ray_cast(V3<S>(0, 0, 0), V3<S>(1, 1, 1)));
  EXPECT_EQ(bvh.faces_near(V3<S>::Constant(S(0.01)), S(0), nullptr, 0), m.num_faces());
  EXPECT_EQ(bvh.faces_near(V3<S>::Zero(), S(0.01), nullptr, 0), 0);
  const TriangleBvh<S> all_equal(point.vertices, point.faces);  // every centroid the same
  EXPECT_EQ(all_equal.depth(), 4);  // 40 faces -> 20, 10, 5, 3 -> leaves
  std::array<Index, 64> out{};
  EXPECT_EQ(all_equal.faces_near(V3<S>::Constant(S(0.01)), S(1e-3), out.data(), 64), 40);
}

TYPED_TEST(TriangleBvhTest, BadInputAndEmptyTree) {
  using S = TypeParam;
  std::mt19937 rng(25);
  const auto m = bumpy_sphere<S>(6, 8, 0.03, V3<double>(0, 0, 0), 0.1, rng);
  TriangleBvh<S> bvh(m.vertices, m.faces);
  const auto before = bvh.face_order();
  FaceArray bad = m.faces;
  bad(3, 1) = m.num_vertices();
  EXPECT_THROW(bvh.build(m.vertices, bad), Error);
  bad(3, 1) = -1;
  EXPECT_THROW(bvh.build(m.vertices, bad), Error);
  Positions<S> nan = m.vertices;
  nan(2, 1) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_THROW(bvh.build(nan, m.faces), Error);
  EXPECT_EQ(bvh.face_order(), before) << "a failed build leaves the tree unchanged";
  EXPECT_EQ(bvh.num_faces(), m.num_faces());
  EXPECT_EQ(bvh.num_vertices(), m.num_vertices());

  TriangleBvh<S> empty;
  EXPECT_EQ(empty.num_faces(), 0);
  EXPECT_FALSE(empty.ray_cast(V3<S>::Zero(), V3<S>(1, 0, 0)));
  EXPECT_EQ(empty.faces_near(V3<S>::Zero(), S(1), nullptr, 0), 0);
  empty.build(m.vertices, FaceArray(0, 3));
  EXPECT_EQ(empty.num_faces(), 0);
  EXPECT_TRUE(empty.nodes().empty());
  EXPECT_TRUE(empty.refit(m.vertices));
  EXPECT_FALSE(empty.ray_cast(V3<S>::Zero(), V3<S>(1, 0, 0)));
  EXPECT_EQ(empty.faces_near(V3<S>::Zero(), S(1), nullptr, 0), 0);
}

// The median split halves the faces at every level, so the depth is ceil(log2(|F| / 4)), far
// inside the traversal stack, for any input, including all centroids equal.
TYPED_TEST(TriangleBvhTest, DepthIsLogarithmic) {
  using S = TypeParam;
  std::mt19937 rng(26);
  for (Index nf : {1, 4, 5, 9, 1000, 100000}) {
    const auto m = triangle_soup<S>(nf, rng);
    const TriangleBvh<S> bvh(m.vertices, m.faces);
    const int expected = nf <= 4 ? 0 : int(std::ceil(std::log2(double(nf) / 4)));
    EXPECT_EQ(bvh.depth(), expected) << nf << " faces";
    EXPECT_LT(bvh.depth(), TriangleBvh<S>::max_depth);
    if (nf <= 1000) expect_exact_tree(bvh, m);
  }
  // The same triangle 1000 times: no axis separates the centroids, the split still halves.
  TriangleMesh<S> same;
  same.vertices = Positions<S>::Random(3, 3);
  same.faces = FaceArray::Zero(1000, 3);
  same.faces.col(1).setConstant(1);
  same.faces.col(2).setConstant(2);
  const TriangleBvh<S> bvh(same.vertices, same.faces);
  EXPECT_EQ(bvh.depth(), 8);
  std::vector<Index> out(1000);
  EXPECT_EQ(bvh.faces_near(row(same.vertices, 0), S(0), out.data(), 1000), 1000);
  const auto hit =
      bvh.ray_cast(((row(same.vertices, 0) + row(same.vertices, 1) + row(same.vertices, 2)) / S(3) +
                    V3<S>(0, 0, 5))
                       .eval(),
                   V3<S>(0, 0, -1));
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->face, 0) << "ties go to the smallest face index";
}

TYPED_TEST(TriangleBvhTest, RefitAndQueriesDoNotAllocate) {
  using S = TypeParam;
  std::mt19937 rng(27);
  const auto m = bumpy_sphere<S>(24, 40, 0.03, V3<double>(0, 0, 0), 0.1, rng);
  TriangleBvh<S> bvh(m.vertices, m.faces);
  const Positions<S> moved = deform(m.vertices, 0.001, rng);
  std::vector<V3<S>> origins, directions;
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 200; ++i) {
    origins.push_back((0.01 * V3<double>(u(rng), u(rng), u(rng))).template cast<S>());
    directions.push_back(V3<double>(u(rng), u(rng), u(rng)).template cast<S>());
  }
  std::vector<Index> out(64);
  long hits = 0, found = 0;
  g_allocations = 0;
  g_counting = true;
  for (int frame = 0; frame < 4; ++frame) {
    const bool ok = bvh.refit(frame % 2 ? m.vertices : moved);
    hits += ok ? 0 : -1000000;
    for (size_t i = 0; i < origins.size(); ++i) {
      hits += bvh.ray_cast(origins[i], directions[i]) ? 1 : 0;
      found += bvh.faces_near(origins[i], S(0.02), out.data(), Index(out.size()));
    }
  }
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_GT(hits, 600);  // from inside the (closed) surface, nearly all hit
  EXPECT_GT(found, 100);
  // The counter works: a build allocates.
  g_allocations = 0;
  g_counting = true;
  bvh.build(m.vertices, m.faces);
  g_counting = false;
  EXPECT_GT(g_allocations.load(), 0);
}

}  // namespace
}  // namespace fsm::collision
