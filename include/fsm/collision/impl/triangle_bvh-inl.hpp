#pragma once

// Definitions for fsm/collision/triangle_bvh.hpp.

#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <numeric>
#include <string>
#include <utility>

#include "fsm/error.hpp"

namespace fsm::collision {

namespace detail {

// The precision the watertight test falls back to when an edge function rounds to zero. For
// float, products of two floats are exact in double, so the fallback is exact (the paper's case);
// for double, long double (x87 extended on x86-64) only narrows the window.
template <typename Scalar>
struct WiderScalar {
  using type = double;
};
template <>
struct WiderScalar<double> {
  using type = long double;
};

// A ray prepared for the watertight test (Woop et al. 2013, section 3): the axis kz along which
// the direction is largest, and the shear that maps the direction to +z.
template <typename Scalar>
struct WatertightRay {
  Vector3<Scalar> origin;
  int kx{0}, ky{1}, kz{2};
  Scalar sx{0}, sy{0}, sz{1};

  WatertightRay(const Vector3<Scalar>& o, const Vector3<Scalar>& d) noexcept : origin(o) {
    d.cwiseAbs().maxCoeff(&kz);
    kx = kz == 2 ? 0 : kz + 1;
    ky = kx == 2 ? 0 : kx + 1;
    // Keeps the projected winding (the paper's back-face convention; with two-sided faces only
    // the sign of det depends on it).
    if (d[kz] < Scalar(0)) std::swap(kx, ky);
    sx = d[kx] / d[kz];
    sy = d[ky] / d[kz];
    sz = Scalar(1) / d[kz];
  }

  // Hit of triangle (a, b, c) (each 3 scalars) at 0 <= t <= t_max: sets t and the barycentric
  // weights of b and c.
  bool intersect(const Scalar* a, const Scalar* b, const Scalar* c, Scalar t_max, Scalar& t,
                 Scalar& u, Scalar& v) const noexcept {
    const Scalar az_ = a[kz] - origin[kz], bz_ = b[kz] - origin[kz], cz_ = c[kz] - origin[kz];
    const Scalar ax = a[kx] - origin[kx] - sx * az_, ay = a[ky] - origin[ky] - sy * az_;
    const Scalar bx = b[kx] - origin[kx] - sx * bz_, by = b[ky] - origin[ky] - sy * bz_;
    const Scalar cx = c[kx] - origin[kx] - sx * cz_, cy = c[ky] - origin[ky] - sy * cz_;
    // Scaled barycentric weights of a, b, c: twice the signed areas of the projected
    // sub-triangles (the edge functions).
    Scalar wa = cx * by - cy * bx;
    Scalar wb = ax * cy - ay * cx;
    Scalar wc = bx * ay - by * ax;
    if (wa == Scalar(0) || wb == Scalar(0) || wc == Scalar(0)) {
      using Wide = typename WiderScalar<Scalar>::type;
      wa = Scalar(Wide(cx) * Wide(by) - Wide(cy) * Wide(bx));
      wb = Scalar(Wide(ax) * Wide(cy) - Wide(ay) * Wide(cx));
      wc = Scalar(Wide(bx) * Wide(ay) - Wide(by) * Wide(ax));
    }
    // Mixed signs: the projected point is outside. Zero weights (edges, vertices) stay inside.
    if ((wa < Scalar(0) || wb < Scalar(0) || wc < Scalar(0)) &&
        (wa > Scalar(0) || wb > Scalar(0) || wc > Scalar(0)))
      return false;
    const Scalar det = wa + wb + wc;
    if (det == Scalar(0)) return false;  // in the triangle's plane, or zero area
    const Scalar hit_t = (wa * (sz * az_) + wb * (sz * bz_) + wc * (sz * cz_)) / det;
    // NaN fails both comparisons; an overflow to infinity (a grazing ray) is no hit.
    if (!(hit_t >= Scalar(0) && hit_t <= t_max) || hit_t == std::numeric_limits<Scalar>::infinity())
      return false;
    t = hit_t;
    u = wb / det;
    v = wc / det;
    return true;
  }
};

// Ray-box slab test against [0, limit], conservative under rounding: the far distance is
// widened by 1 + 2 gamma(3) (Ize, "Robust BVH ray traversal", JCGT 2(2), 2013), so a box that
// the ray touches, even one of zero thickness, is never missed.
template <typename Scalar>
struct SlabRay {
  Vector3<Scalar> origin, inverse;
  std::array<bool, 3> parallel{};  // direction component so small that 1 / d is not finite

  SlabRay(const Vector3<Scalar>& o, const Vector3<Scalar>& d) noexcept : origin(o) {
    for (int k = 0; k < 3; ++k) {
      inverse[k] = Scalar(1) / d[k];
      parallel[size_t(k)] = !std::isfinite(inverse[k]);
    }
  }

  bool hits(const Vector3<Scalar>& lo, const Vector3<Scalar>& hi, Scalar limit,
            Scalar& t_enter) const noexcept {
    constexpr Scalar eps = std::numeric_limits<Scalar>::epsilon() / 2;  // unit roundoff
    constexpr Scalar widen = Scalar(1) + Scalar(2) * (3 * eps) / (Scalar(1) - 3 * eps);
    Scalar t0 = Scalar(0), t1 = limit;
    for (int k = 0; k < 3; ++k) {
      if (parallel[size_t(k)]) {
        // The ray stays in the plane x_k = origin_k: inside the slab or never.
        if (origin[k] < lo[k] || origin[k] > hi[k]) return false;
        continue;
      }
      Scalar a = (lo[k] - origin[k]) * inverse[k], b = (hi[k] - origin[k]) * inverse[k];
      if (a > b) std::swap(a, b);
      t0 = a > t0 ? a : t0;
      t1 = b < t1 ? b : t1;
    }
    t_enter = t0;
    return t0 <= t1 * widen;
  }
};

// Squared distance from p to the box [lo, hi].
template <typename Scalar>
Scalar squared_distance_to_box(const Vector3<Scalar>& p, const Vector3<Scalar>& lo,
                               const Vector3<Scalar>& hi) noexcept {
  Scalar d2(0);
  for (int k = 0; k < 3; ++k) {
    const Scalar below = lo[k] - p[k], above = p[k] - hi[k];
    const Scalar d = below > Scalar(0) ? below : (above > Scalar(0) ? above : Scalar(0));
    d2 += d * d;
  }
  return d2;
}

// The point of segment [a, b] nearest to p; a zero-length segment gives a.
template <typename Scalar>
Vector3<Scalar> closest_point_on_segment(const Vector3<Scalar>& p, const Vector3<Scalar>& a,
                                         const Vector3<Scalar>& b) noexcept {
  const Vector3<Scalar> ab = b - a;
  const Scalar len2 = ab.squaredNorm();
  if (!(len2 > Scalar(0))) return a;
  const Scalar s = std::clamp(ab.dot(p - a) / len2, Scalar(0), Scalar(1));
  return a + s * ab;
}

// Rounding slack (m) for culling: a box is kept when it is within this of passing the test, so
// that rounding in the box test and in the exact per-face test can never disagree in a way that
// loses a face. 64 ulps of the largest coordinate involved is far more than either test's error.
template <typename Scalar>
Scalar culling_slack(Scalar scale) noexcept {
  return Scalar(64) * std::numeric_limits<Scalar>::epsilon() * scale;
}

}  // namespace detail

template <typename Scalar>
std::optional<RayHit<Scalar>> intersect_ray_triangle(
    const Vector3<Scalar>& origin, const Vector3<Scalar>& direction, const Vector3<Scalar>& a,
    const Vector3<Scalar>& b, const Vector3<Scalar>& c, Scalar max_t) noexcept {
  if (!(direction.squaredNorm() > Scalar(0))) return std::nullopt;
  const detail::WatertightRay<Scalar> ray(origin, direction);
  RayHit<Scalar> hit;
  if (!ray.intersect(a.data(), b.data(), c.data(), max_t, hit.distance, hit.u, hit.v))
    return std::nullopt;
  return hit;
}

template <typename Scalar>
Vector3<Scalar> closest_point_on_triangle(const Vector3<Scalar>& p, const Vector3<Scalar>& a,
                                          const Vector3<Scalar>& b,
                                          const Vector3<Scalar>& c) noexcept {
  // Ericson (2005), 5.1.5: test the vertex regions, then the edge regions, then the face.
  const Vector3<Scalar> ab = b - a, ac = c - a, ap = p - a;
  const Scalar d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= Scalar(0) && d2 <= Scalar(0)) return a;
  const Vector3<Scalar> bp = p - b;
  const Scalar d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= Scalar(0) && d4 <= d3) return b;
  const Scalar vc = d1 * d4 - d3 * d2;
  if (vc <= Scalar(0) && d1 >= Scalar(0) && d3 <= Scalar(0)) {
    const Scalar den = d1 - d3;
    if (den > Scalar(0)) return a + (d1 / den) * ab;
  }
  const Vector3<Scalar> cp = p - c;
  const Scalar d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= Scalar(0) && d5 <= d6) return c;
  const Scalar vb = d5 * d2 - d1 * d6;
  if (vb <= Scalar(0) && d2 >= Scalar(0) && d6 <= Scalar(0)) {
    const Scalar den = d2 - d6;
    if (den > Scalar(0)) return a + (d2 / den) * ac;
  }
  const Scalar va = d3 * d6 - d5 * d4;
  if (va <= Scalar(0) && d4 - d3 >= Scalar(0) && d5 - d6 >= Scalar(0)) {
    const Scalar den = (d4 - d3) + (d5 - d6);
    if (den > Scalar(0)) return b + ((d4 - d3) / den) * (c - b);
  }
  // The face region. va + vb + vc = |ab x ac|^2 (Lagrange's identity), which cancels for a thin
  // triangle: below sqrt(eps) |ab|^2 |ac|^2 (an angle of about 1 degree in float) the region
  // tests above may have misjudged by rounding, so the nearest of the face point and the three
  // edges is taken. For a degenerate triangle (zero area) the face point does not exist and the
  // edges are its whole surface.
  const Scalar den = va + vb + vc;
  const bool inside = va > Scalar(0) && vb > Scalar(0) && vc > Scalar(0);
  const Vector3<Scalar> q_face =
      inside ? Vector3<Scalar>(a + (vb / den) * ab + (vc / den) * ac) : a;
  if (inside &&
      den > std::sqrt(std::numeric_limits<Scalar>::epsilon()) * ab.squaredNorm() * ac.squaredNorm())
    return q_face;
  Vector3<Scalar> best = q_face;
  Scalar best_d2 = (p - q_face).squaredNorm();
  for (const Vector3<Scalar>& q :
       {detail::closest_point_on_segment(p, a, b), detail::closest_point_on_segment(p, b, c),
        detail::closest_point_on_segment(p, c, a)}) {
    const Scalar dq = (p - q).squaredNorm();
    if (dq < best_d2) best = q, best_d2 = dq;
  }
  return best;
}

template <typename Scalar>
TriangleBvh<Scalar>::TriangleBvh(const Eigen::Ref<const Positions<Scalar>>& vertices,
                                 const FaceArray& faces) {
  build(vertices, faces);
}

template <typename Scalar>
void TriangleBvh<Scalar>::build(const Eigen::Ref<const Positions<Scalar>>& vertices,
                                const FaceArray& faces) {
  const Index nv = Index(vertices.rows()), nf = Index(faces.rows());
  for (Index i = 0; i < nv; ++i)
    if (!vertices.row(i).allFinite())
      throw Error("", "TriangleBvh", "vertex " + std::to_string(i) + " is not finite");
  for (Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k)
      if (faces(f, k) < 0 || faces(f, k) >= nv)
        throw Error("", "TriangleBvh",
                    "face " + std::to_string(f) + " has vertex index " +
                        std::to_string(faces(f, k)) + ", not in [0, " + std::to_string(nv) + ")");

  // Build into a fresh tree and swap, so that a throw (bad_alloc) leaves *this unchanged.
  TriangleBvh t;
  t.m_num_vertices = nv;
  t.m_order.resize(size_t(nf));
  std::iota(t.m_order.begin(), t.m_order.end(), Index(0));
  if (nf > 0) {
    Positions<Scalar> centroids(nf, 3);
    for (Index f = 0; f < nf; ++f)
      centroids.row(f) =
          (vertices.row(faces(f, 0)) + vertices.row(faces(f, 1)) + vertices.row(faces(f, 2))) /
          Scalar(3);
    t.m_nodes.reserve(2 * size_t(nf) - 1);
    t.build_node(centroids, 0, nf, 0);
  }
  t.m_face_vertices.resize(nf, 3);
  for (Index i = 0; i < nf; ++i) t.m_face_vertices.row(i) = faces.row(t.m_order[size_t(i)]);
  t.m_corners.resize(nf, 9);
  t.refit_boxes(vertices);
  *this = std::move(t);
}

template <typename Scalar>
Index TriangleBvh<Scalar>::build_node(const Positions<Scalar>& centroids, Index first, Index count,
                                      int depth) {
  const Index id = Index(m_nodes.size());
  m_nodes.emplace_back();
  m_nodes.back().first = first;
  m_nodes.back().count = count;
  m_depth = std::max(m_depth, depth);
  if (count <= max_leaf_faces || depth >= max_depth - 1) return id;

  const auto begin = m_order.begin() + first, end = begin + count;
  Vector3<Scalar> lo = centroids.row(*begin).transpose(), hi = lo;
  for (auto it = begin; it != end; ++it) {
    lo = lo.cwiseMin(centroids.row(*it).transpose());
    hi = hi.cwiseMax(centroids.row(*it).transpose());
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  // Ties (equal centroids) are broken by face index, so the build is deterministic.
  std::nth_element(begin, begin + count / 2, end, [&](Index x, Index y) {
    const Scalar cx = centroids(x, axis), cy = centroids(y, axis);
    return cx < cy || (cx == cy && x < y);
  });
  const Index left = build_node(centroids, first, count / 2, depth + 1);
  const Index right = build_node(centroids, first + count / 2, count - count / 2, depth + 1);
  m_nodes[size_t(id)].left = left;
  m_nodes[size_t(id)].right = right;
  return id;
}

template <typename Scalar>
bool TriangleBvh<Scalar>::refit(const Eigen::Ref<const Positions<Scalar>>& vertices) noexcept {
  if (Index(vertices.rows()) != m_num_vertices) return false;
  refit_boxes(vertices);
  return true;
}

template <typename Scalar>
void TriangleBvh<Scalar>::refit_boxes(
    const Eigen::Ref<const Positions<Scalar>>& vertices) noexcept {
  // Children come after their parent, so a reverse sweep sees both children before the parent.
  for (size_t n = m_nodes.size(); n-- > 0;) {
    Node& node = m_nodes[n];
    if (node.is_leaf()) {  // its faces' corners copied, and their box, in one pass
      if (node.count <= 0) {
        node.lo = node.hi = Vector3<Scalar>::Zero();
        continue;
      }
      Vector3<Scalar> lo = vertices.row(m_face_vertices(node.first, 0)).transpose(), hi = lo;
      for (Index i = node.first; i < node.first + node.count; ++i)
        for (int k = 0; k < 3; ++k) {
          const Vector3<Scalar> p = vertices.row(m_face_vertices(i, k)).transpose();
          m_corners.row(i).template segment<3>(3 * k) = p.transpose();
          lo = lo.cwiseMin(p);
          hi = hi.cwiseMax(p);
        }
      node.lo = lo;
      node.hi = hi;
    } else {
      const Node& l = m_nodes[size_t(node.left)];
      const Node& r = m_nodes[size_t(node.right)];
      node.lo = l.lo.cwiseMin(r.lo);
      node.hi = l.hi.cwiseMax(r.hi);
    }
  }
  m_scale = m_nodes.empty() ? Scalar(0)
                            : std::max(m_nodes[0].lo.cwiseAbs().maxCoeff(),
                                       m_nodes[0].hi.cwiseAbs().maxCoeff());
}

template <typename Scalar>
std::optional<RayHit<Scalar>> TriangleBvh<Scalar>::ray_cast(const Vector3<Scalar>& origin,
                                                            const Vector3<Scalar>& direction,
                                                            Scalar max_distance) const noexcept {
  const Scalar len2 = direction.squaredNorm();
  if (m_nodes.empty() || !(max_distance >= Scalar(0)) || !(len2 > Scalar(0)) ||
      !std::isfinite(len2) || !origin.allFinite())
    return std::nullopt;
  const Vector3<Scalar> dir = direction.normalized();
  const detail::WatertightRay<Scalar> ray(origin, dir);
  const detail::SlabRay<Scalar> slab(origin, dir);
  const Scalar slack = detail::culling_slack(origin.cwiseAbs().maxCoeff() + m_scale);
  const Scalar inf = std::numeric_limits<Scalar>::infinity();

  RayHit<Scalar> best;
  best.distance = max_distance;
  // Boxes are culled against the best distance so far, widened by the slack, so a face at a
  // tie with the best (a shared edge) is still tested and the smallest index wins.
  auto limit = [&] {
    return best.distance == inf
               ? inf
               : best.distance + slack + std::numeric_limits<Scalar>::epsilon() * best.distance;
  };

  struct Entry {
    Index node;
    Scalar t;
  };
  std::array<Entry, size_t(max_depth)> stack;
  int top = 0;
  Scalar t_root(0);
  if (!slab.hits(m_nodes[0].lo, m_nodes[0].hi, limit(), t_root)) return std::nullopt;
  Index node = 0;
  for (;;) {
    const Node& n = m_nodes[size_t(node)];
    if (n.is_leaf()) {
      for (Index i = n.first; i < n.first + n.count; ++i) {
        const Scalar* p = m_corners.row(i).data();
        Scalar t, u, v;
        if (!ray.intersect(p, p + 3, p + 6, best.distance, t, u, v)) continue;
        const Index face = m_order[size_t(i)];
        if (t < best.distance || best.face < 0 || face < best.face) best = {face, t, u, v};
      }
    } else {
      Scalar tl(0), tr(0);
      const Scalar lim = limit();
      const Node& l = m_nodes[size_t(n.left)];
      const Node& r = m_nodes[size_t(n.right)];
      const bool hl = slab.hits(l.lo, l.hi, lim, tl), hr = slab.hits(r.lo, r.hi, lim, tr);
      if (hl && hr) {
        // Nearest first; the other waits on the stack with its entry distance.
        const bool right_first = tr < tl;
        stack[size_t(top++)] = right_first ? Entry{n.left, tl} : Entry{n.right, tr};
        node = right_first ? n.right : n.left;
        continue;
      }
      if (hl || hr) {
        node = hl ? n.left : n.right;
        continue;
      }
    }
    // Pop the next box still nearer than the best hit.
    for (;;) {
      if (top == 0) return best.face >= 0 ? std::optional<RayHit<Scalar>>(best) : std::nullopt;
      const Entry e = stack[size_t(--top)];
      if (e.t <= limit()) {
        node = e.node;
        break;
      }
    }
  }
}

template <typename Scalar>
Index TriangleBvh<Scalar>::faces_near(const Vector3<Scalar>& centre, Scalar radius, Index* out,
                                      Index capacity) const noexcept {
  if (m_nodes.empty() || !(radius >= Scalar(0)) || !centre.allFinite()) return 0;
  const Scalar r2 = radius * radius;
  const Scalar reach =
      radius + detail::culling_slack(centre.cwiseAbs().maxCoeff() + m_scale + radius);
  const Scalar reach2 = reach * reach;
  auto overlaps = [&](const Node& n) {
    return detail::squared_distance_to_box(centre, n.lo, n.hi) <= reach2;
  };

  Index found = 0;
  std::array<Index, size_t(max_depth)> stack;
  int top = 0;
  if (!overlaps(m_nodes[0])) return 0;
  Index node = 0;
  for (;;) {
    const Node& n = m_nodes[size_t(node)];
    if (n.is_leaf()) {
      for (Index i = n.first; i < n.first + n.count; ++i) {
        const Eigen::Map<const Vector3<Scalar>> a(m_corners.row(i).data()),
            b(m_corners.row(i).data() + 3), c(m_corners.row(i).data() + 6);
        const Vector3<Scalar> q = closest_point_on_triangle<Scalar>(centre, a, b, c);
        if ((centre - q).squaredNorm() <= r2) {
          if (found < capacity) out[found] = m_order[size_t(i)];
          ++found;
        }
      }
    } else {
      const bool hl = overlaps(m_nodes[size_t(n.left)]), hr = overlaps(m_nodes[size_t(n.right)]);
      if (hl && hr) {
        stack[size_t(top++)] = n.right;
        node = n.left;
        continue;
      }
      if (hl || hr) {
        node = hl ? n.left : n.right;
        continue;
      }
    }
    if (top == 0) return found;
    node = stack[size_t(--top)];
  }
}

}  // namespace fsm::collision
