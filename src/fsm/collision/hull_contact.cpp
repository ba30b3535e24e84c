// The convex hull's narrow phase against one sphere: a point-hull GJK distance, an EPA for the
// penetration, and libccd's MPR where EPA runs out of room. The only file that uses libccd.

#include "hull_contact.hpp"

#include <ccd/ccd.h>
#include <ccd/vec3.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fsm::collision::detail {
namespace {

// ------------------------------------------------------------------------------------------------
// Convex hull. Everything runs in double, in the hull's local frame, translated to the mean of the
// points and divided by the hull's size, so that the absolute tolerances below (and libccd's, which
// are absolute) are relative to the hull.
// ------------------------------------------------------------------------------------------------

using V3 = Eigen::Vector3d;

template <typename Scalar>
struct HullFrame {
  const Scalar* points;  // row-major |P| x 3, local frame (m)
  Index count;
  V3 origin;     // mean of the points (m, local)
  double scale;  // 1 / size (1/m)
  V3 interior;   // MPR's interior point of the hull (normalised)
  V3 centre;     // the sphere centre (normalised)

  [[nodiscard]] V3 point(Index i) const noexcept {
    const Scalar* q = points + 3 * std::ptrdiff_t(i);
    return (V3(static_cast<double>(q[0]), static_cast<double>(q[1]), static_cast<double>(q[2])) -
            origin) *
           scale;
  }
  /// Support point of the hull in direction `d` (normalised frame).
  [[nodiscard]] V3 support(const V3& d) const noexcept { return point(support_index(d)); }
  [[nodiscard]] Index support_index(const V3& d) const noexcept {
    Index best = 0;
    double best_dot = -std::numeric_limits<double>::infinity();
    for (Index i = 0; i < count; ++i) {
      const Scalar* q = points + 3 * std::ptrdiff_t(i);
      const double s = d.x() * double(q[0]) + d.y() * double(q[1]) + d.z() * double(q[2]);
      if (s > best_dot) {
        best_dot = s;
        best = i;
      }
    }
    return best;
  }
};

// libccd callbacks: object 1 is the hull, object 2 the sphere centre (a point; the radius is added
// afterwards, which keeps the Minkowski difference a polytope, where MPR's portal ends exactly on a
// face).
template <typename Scalar>
void ccd_hull_support(const void* obj, const ccd_vec3_t* dir, ccd_vec3_t* out) {
  const auto& h = *static_cast<const HullFrame<Scalar>*>(obj);
  const V3 s = h.support(V3(dir->v[0], dir->v[1], dir->v[2]));
  ccdVec3Set(out, s.x(), s.y(), s.z());
}
template <typename Scalar>
void ccd_hull_centre(const void* obj, ccd_vec3_t* out) {
  const auto& h = *static_cast<const HullFrame<Scalar>*>(obj);
  ccdVec3Set(out, h.interior.x(), h.interior.y(), h.interior.z());
}
template <typename Scalar>
void ccd_point_support(const void* obj, const ccd_vec3_t*, ccd_vec3_t* out) {
  const auto& h = *static_cast<const HullFrame<Scalar>*>(obj);
  ccdVec3Set(out, h.centre.x(), h.centre.y(), h.centre.z());
}
template <typename Scalar>
void ccd_point_centre(const void* obj, ccd_vec3_t* out) {
  const auto& h = *static_cast<const HullFrame<Scalar>*>(obj);
  ccdVec3Set(out, h.centre.x(), h.centre.y(), h.centre.z());
}

// Normalised-frame tolerances (the hull's size is 1).
constexpr double kTouch = 1e-12;        // closer than this, the centre is on the surface
constexpr double kGjkRelative = 1e-13;  // GJK stops when |v|^2 - v.w <= this |v|^2
constexpr int kGjkIterations = 128;
constexpr double kMprTolerance = 1e-12;  // portal advance below which MPR stops
constexpr double kOnFace = 1e-9;         // a verified MPR witness lies within this of a face
constexpr double kRayOffset = 1e-3;      // interior points for extra MPR rays: centre - this * u

/// Closest point to the origin on a simplex of 1 to 4 points; reduces the simplex to the smallest
/// face containing it. Returns false when the origin is inside a tetrahedron.
struct Simplex {
  V3 w[4];
  int size{0};

  void keep(std::initializer_list<int> idx) noexcept {
    V3 t[4];
    int k = 0;
    for (int i : idx) t[k++] = w[i];
    for (int i = 0; i < k; ++i) w[i] = t[i];
    size = k;
  }

  static V3 segment(const V3& a, const V3& b, int& region) noexcept {
    const V3 ab = b - a;
    const double l2 = ab.squaredNorm();
    const double t = l2 > 0 ? -a.dot(ab) / l2 : 0.0;
    if (t <= 0) {
      region = 1;  // a
      return a;
    }
    if (t >= 1) {
      region = 2;  // b
      return b;
    }
    region = 3;  // both
    return a + t * ab;
  }

  // Ericson, "Real-Time Collision Detection", 5.1.5, with the origin as the query point. `mask`
  // gets the vertices (bits 0, 1, 2) of the nearest feature.
  static V3 triangle(const V3& a, const V3& b, const V3& c, int& mask) noexcept {
    const V3 ab = b - a, ac = c - a;
    const double d1 = -ab.dot(a), d2 = -ac.dot(a);
    if (d1 <= 0 && d2 <= 0) {
      mask = 1;
      return a;
    }
    const double d3 = -ab.dot(b), d4 = -ac.dot(b);
    if (d3 >= 0 && d4 <= d3) {
      mask = 2;
      return b;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
      mask = 3;
      return a + d1 / (d1 - d3) * ab;
    }
    const double d5 = -ab.dot(c), d6 = -ac.dot(c);
    if (d6 >= 0 && d5 <= d6) {
      mask = 4;
      return c;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
      mask = 5;
      return a + d2 / (d2 - d6) * ac;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
      mask = 6;
      return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
    }
    const double sum = va + vb + vc;
    if (!(sum > 1e-300)) {
      // Degenerate (collinear) triangle: the nearest of its edges.
      int r1 = 0, r2 = 0, r3 = 0;
      const V3 p1 = segment(a, b, r1), p2 = segment(a, c, r2), p3 = segment(b, c, r3);
      const double n1 = p1.squaredNorm(), n2 = p2.squaredNorm(), n3 = p3.squaredNorm();
      if (n1 <= n2 && n1 <= n3) {
        mask = r1 == 1 ? 1 : r1 == 2 ? 2 : 3;
        return p1;
      }
      if (n2 <= n3) {
        mask = r2 == 1 ? 1 : r2 == 2 ? 4 : 5;
        return p2;
      }
      mask = r3 == 1 ? 2 : r3 == 2 ? 4 : 6;
      return p3;
    }
    mask = 7;
    return a + (vb / sum) * ab + (vc / sum) * ac;
  }

  void keep_mask(int mask, int i0, int i1, int i2) noexcept {
    int idx[3];
    int k = 0;
    if (mask & 1) idx[k++] = i0;
    if (mask & 2) idx[k++] = i1;
    if (mask & 4) idx[k++] = i2;
    V3 t[3];
    for (int i = 0; i < k; ++i) t[i] = w[idx[i]];
    for (int i = 0; i < k; ++i) w[i] = t[i];
    size = k;
  }

  /// The point of the simplex nearest the origin; false if the origin is inside it (4 points).
  bool closest(V3& v) noexcept {
    switch (size) {
      case 1:
        v = w[0];
        return true;
      case 2: {
        int region = 0;
        v = segment(w[0], w[1], region);
        if (region == 1) keep({0});
        if (region == 2) keep({1});
        return true;
      }
      case 3: {
        int mask = 0;
        v = triangle(w[0], w[1], w[2], mask);
        keep_mask(mask, 0, 1, 2);
        return true;
      }
      default: {
        // Tetrahedron: the origin is inside unless it is beyond one of the faces.
        static constexpr int faces[4][4] = {{0, 1, 2, 3}, {0, 1, 3, 2}, {0, 2, 3, 1}, {1, 2, 3, 0}};
        const double volume = (w[1] - w[0]).cross(w[2] - w[0]).dot(w[3] - w[0]);
        const double size3 = std::max({(w[1] - w[0]).squaredNorm(), (w[2] - w[0]).squaredNorm(),
                                       (w[3] - w[0]).squaredNorm()});
        const bool flat = std::abs(volume) <= 1e-14 * size3 * std::sqrt(size3);
        double best = std::numeric_limits<double>::infinity();
        int best_face = -1, best_mask = 0;
        V3 best_v = V3::Zero();
        for (int f = 0; f < 4; ++f) {
          const V3& a = w[faces[f][0]];
          const V3& b = w[faces[f][1]];
          const V3& c = w[faces[f][2]];
          const V3& d = w[faces[f][3]];
          const V3 n = (b - a).cross(c - a);
          const double side_origin = -n.dot(a);
          const double side_other = n.dot(d - a);
          // Beyond this face: the origin and the opposite vertex are on different sides.
          if (!flat && side_origin * side_other >= 0) continue;
          int mask = 0;
          const V3 p = triangle(a, b, c, mask);
          if (p.squaredNorm() < best) {
            best = p.squaredNorm();
            best_face = f;
            best_mask = mask;
            best_v = p;
          }
        }
        if (best_face < 0) return false;  // inside every face
        keep_mask(best_mask, faces[best_face][0], faces[best_face][1], faces[best_face][2]);
        v = best_v;
        return true;
      }
    }
  }
};

struct HullDistance {
  bool touching;  // the centre is inside the hull or within kTouch of it
  V3 v;           // nearest hull point minus the centre (normalised), when not touching
};

/// GJK (Gilbert, Johnson and Keerthi 1988) distance between the point `h.centre` and the hull, in
/// the form of van den Bergen (1999): the simplex's nearest point v, the support point w in -v,
/// stop when |v|^2 - v.w is below a relative tolerance (exact termination on a polytope, where w
/// repeats). Stops early, returning nullopt, once the lower bound v.w / |v| shows the distance
/// exceeds `reach`.
template <typename Scalar>
std::optional<HullDistance> gjk_distance(const HullFrame<Scalar>& h, double reach) noexcept {
  Simplex s;
  s.w[0] = h.point(0) - h.centre;
  s.size = 1;
  V3 v = s.w[0];
  double vv = v.squaredNorm();
  for (int it = 0; it < kGjkIterations; ++it) {
    if (vv <= kTouch * kTouch) return HullDistance{true, v};
    const V3 w = h.support(-v) - h.centre;
    const double vw = v.dot(w);
    if (vw > 0 && vw * vw > reach * reach * vv) return std::nullopt;  // lower bound > reach
    if (vv - vw <= kGjkRelative * vv) break;
    bool repeated = false;
    for (int i = 0; i < s.size; ++i) repeated = repeated || s.w[i] == w;
    if (repeated) break;
    s.w[s.size++] = w;
    V3 next;
    if (!s.closest(next)) return HullDistance{true, V3::Zero()};
    const double next_vv = next.squaredNorm();
    if (next_vv >= vv) break;  // no progress: rounding floor reached
    v = next;
    vv = next_vv;
  }
  if (vv <= kTouch * kTouch) return HullDistance{true, v};
  return HullDistance{false, v};
}

/// One MPR run from the interior point `h.interior`: the hull-boundary point it reaches from the
/// centre and the unit direction to it, or nothing. Only results verified to lie on a supporting
/// plane (a face) are returned, so every answer is a true boundary point and its distance an upper
/// bound of the penetration.
template <typename Scalar>
bool mpr_candidate(const HullFrame<Scalar>& h, double& depth, V3& dir) noexcept {
  ccd_t ccd;
  CCD_INIT(&ccd);
  ccd.support1 = ccd_hull_support<Scalar>;
  ccd.support2 = ccd_point_support<Scalar>;
  ccd.center1 = ccd_hull_centre<Scalar>;
  ccd.center2 = ccd_point_centre<Scalar>;
  ccd.max_iterations = 200;
  ccd.mpr_tolerance = kMprTolerance;
  ccd_real_t d = 0;
  ccd_vec3_t ccd_dir, pos;
  if (ccdMPRPenetration(&h, &h, &ccd, &d, &ccd_dir, &pos) != 0) return false;
  const V3 n(ccd_dir.v[0], ccd_dir.v[1], ccd_dir.v[2]);
  if (!(d > 0) || !std::isfinite(d) || !n.allFinite() || std::abs(n.norm() - 1) > 1e-6)
    return false;
  // libccd: moving object 2 (the centre) by d * n separates it, so centre + d n is on the
  // boundary and n points out of the hull. Verify that the plane through it with normal n
  // supports the hull (MPR can stop on a portal that is not a face when its interior point is
  // not interior).
  const V3 n_unit = n.normalized();
  const V3 q = h.centre + d * n_unit;
  if (h.support(n_unit).dot(n_unit) - q.dot(n_unit) > kOnFace) return false;
  depth = d;
  dir = n_unit;
  return true;
}

/// Penetration of the centre into the hull (normalised): the distance to the nearest face and the
/// outward normal. libccd's MPR gives the face that the ray from an interior point through the
/// centre leaves by; the ray from the mean of the points can leave by a far face of an elongated
/// hull, so rays along the local axes through the centre, and then along the best normal so far,
/// are tried as well and the nearest verified face wins.
template <typename Scalar>
bool mpr_penetration(HullFrame<Scalar>& h, double& depth, V3& dir) noexcept {
  depth = std::numeric_limits<double>::infinity();
  bool found = false;
  auto try_ray = [&](const V3& interior) {
    h.interior = interior;
    double d = 0;
    V3 n;
    if (mpr_candidate(h, d, n) && d < depth) {
      depth = d;
      dir = n;
      found = true;
    }
  };
  try_ray(V3::Zero());  // the mean of the points
  for (int axis = 0; axis < 3; ++axis)
    for (double sign : {1.0, -1.0}) try_ray(h.centre - kRayOffset * sign * V3::Unit(axis));
  for (int refine = 0; refine < 2 && found; ++refine) {
    const double before = depth;
    try_ray(h.centre - kRayOffset * dir);
    if (!(depth < before * (1 - 1e-12))) break;
  }
  return found;
}

// Capacity of the EPA polytope (on the stack: about 20 kB). A closed triangulated polytope with V
// vertices has 2V - 4 faces and at most 3V - 6 edges.
constexpr int kEpaVertices = 128;
constexpr int kEpaFaces = 2 * kEpaVertices;
constexpr int kEpaEdges = 3 * kEpaVertices;
constexpr double kEpaTolerance = 1e-12;  // a face is on the hull when no point is further out

enum class EpaStatus { exact, overflow, failed };

struct EpaFace {
  int v[3];
  V3 n;           // unit outward normal
  double offset;  // n . x on the face
  double depth;   // offset - n . centre: how far behind the face the centre is
  bool alive;
};

/// Penetration of the centre into the hull by the expanding polytope algorithm (van den Bergen
/// 2001) on the hull's points, with fixed-size storage so it never allocates. The polytope Q grows
/// inside the hull from a tetrahedron of support points; each step takes the face of Q nearest
/// the centre (the least `depth`, which is negative while the centre is outside Q), adds the
/// hull's support point in its normal and replaces the faces it sees by a fan from the horizon.
/// When the support point is no further out than the face, that face lies on the hull, and as
/// Q is inside the hull and contains the centre it is the nearest face of the hull: exact.
/// `overflow` (capacity reached) leaves the nearest face of Q so far, a lower bound.
template <typename Scalar>
EpaStatus epa_penetration(const HullFrame<Scalar>& h, double& depth, V3& normal) noexcept {
  V3 vert[kEpaVertices];
  Index source[kEpaVertices];
  EpaFace face[kEpaFaces];
  int edge[kEpaEdges][2];
  int nv = 0, nf = 0;

  auto add_vertex = [&](Index i) {
    source[nv] = i;
    vert[nv] = h.point(i);
    return nv++;
  };
  auto add_face = [&](int a, int b, int c) {
    EpaFace& f = face[nf++];
    f.v[0] = a;
    f.v[1] = b;
    f.v[2] = c;
    const V3 n = (vert[b] - vert[a]).cross(vert[c] - vert[a]);
    const double len = n.norm();
    f.n = len > 0 ? V3(n / len) : V3::Zero();
    f.offset = f.n.dot(vert[a]);
    // A face without area (never made from points seen above a face, but rounding) is never the
    // nearest; it is replaced as soon as a neighbour is.
    f.depth = len > 0 ? f.offset - f.n.dot(h.centre) : std::numeric_limits<double>::infinity();
    f.alive = true;
  };

  // Initial tetrahedron: support points along an axis, then off that line, then off that plane.
  Index ia = 0, ib = 0;
  bool spread = false;
  for (int axis = 0; axis < 3 && !spread; ++axis) {
    ia = h.support_index(V3::Unit(axis));
    ib = h.support_index(-V3::Unit(axis));
    spread = (h.point(ia) - h.point(ib)).squaredNorm() > 1e-18;
  }
  if (!spread) return EpaStatus::failed;
  const V3 pa = h.point(ia), pb = h.point(ib);
  const V3 ab = (pb - pa).normalized();
  const V3 d1 = ab.unitOrthogonal(), d2 = ab.cross(d1);
  Index ic = ia;
  double best = 0;
  for (const V3& d : {d1, V3(-d1), d2, V3(-d2)}) {
    const Index i = h.support_index(d);
    const double off_line = ab.cross(h.point(i) - pa).norm();
    if (off_line > best) best = off_line, ic = i;
  }
  if (!(best > 1e-9)) return EpaStatus::failed;
  const V3 pc = h.point(ic);
  const V3 up = ab.cross(pc - pa).normalized();
  Index id = ia;
  best = 0;
  for (const V3& d : {up, V3(-up)}) {
    const Index i = h.support_index(d);
    const double off_plane = std::abs(up.dot(h.point(i) - pa));
    if (off_plane > best) best = off_plane, id = i;
  }
  if (!(best > 1e-9)) return EpaStatus::failed;  // a flat hull (validate() rejects those)
  int a = add_vertex(ia), b = add_vertex(ib), c = add_vertex(ic);
  const int d = add_vertex(id);
  if ((vert[b] - vert[a]).cross(vert[c] - vert[a]).dot(vert[d] - vert[a]) > 0) std::swap(b, c);
  add_face(a, b, c);
  add_face(a, d, b);
  add_face(a, c, d);
  add_face(b, d, c);

  int nearest = 0;
  for (int iteration = 0; iteration < kEpaVertices; ++iteration) {
    nearest = -1;
    for (int f = 0; f < nf; ++f)
      if (face[f].alive && (nearest < 0 || face[f].depth < face[nearest].depth)) nearest = f;
    if (nearest < 0) return EpaStatus::failed;
    const EpaFace& fn = face[nearest];
    const Index iw = h.support_index(fn.n);
    const V3 w = h.point(iw);
    bool known = false;
    for (int k = 0; k < nv; ++k) known = known || source[k] == iw;
    if (known || fn.n.dot(w) - fn.offset <= kEpaTolerance) {
      depth = fn.depth;
      normal = fn.n;
      return EpaStatus::exact;
    }
    if (nv == kEpaVertices) break;
    const int iv = add_vertex(iw);

    // Remove the faces w sees; their boundary (edges seen once) is the horizon.
    int ne = 0;
    bool edges_full = false;
    for (int f = 0; f < nf; ++f) {
      EpaFace& g = face[f];
      if (!g.alive || !(g.n.dot(w) - g.offset > kEpaTolerance || f == nearest)) continue;
      g.alive = false;
      for (int k = 0; k < 3; ++k) {
        const int e0 = g.v[k], e1 = g.v[(k + 1) % 3];
        int found = -1;
        for (int m = 0; m < ne && found < 0; ++m)
          if (edge[m][0] == e1 && edge[m][1] == e0) found = m;
        if (found >= 0) {
          edge[found][0] = edge[ne - 1][0];
          edge[found][1] = edge[ne - 1][1];
          --ne;
        } else if (ne < kEpaEdges) {
          edge[ne][0] = e0;
          edge[ne][1] = e1;
          ++ne;
        } else {
          edges_full = true;
        }
      }
    }
    if (edges_full) break;
    if (nf + ne > kEpaFaces) {
      int kept = 0;
      for (int f = 0; f < nf; ++f)
        if (face[f].alive) face[kept++] = face[f];
      nf = kept;
      if (nf + ne > kEpaFaces) break;
    }
    for (int m = 0; m < ne; ++m) add_face(edge[m][0], edge[m][1], iv);
    nearest = -1;
  }
  // Out of room: the nearest face of Q so far (a lower bound of the depth).
  if (nearest < 0) {
    for (int f = 0; f < nf; ++f)
      if (face[f].alive && (nearest < 0 || face[f].depth < face[nearest].depth)) nearest = f;
  }
  if (nearest < 0 || !(face[nearest].n.squaredNorm() > 0)) return EpaStatus::failed;
  depth = face[nearest].depth;
  normal = face[nearest].n;
  return EpaStatus::overflow;
}

}  // namespace

template <typename Scalar>
std::optional<LocalContact<double>> hull_local(const ConvexHullShape<Scalar>& hull,
                                               const Vector3<Scalar>& p_local, Scalar r) noexcept {
  const Index count = Index(hull.points.rows());
  if (count == 0) return std::nullopt;
  const Scalar* data = hull.points.data();

  // One pass: bounding box (for the size and a quick rejection) and mean.
  V3 lo = V3::Constant(std::numeric_limits<double>::infinity());
  V3 hi = -lo;
  V3 sum = V3::Zero();
  for (Index i = 0; i < count; ++i) {
    const V3 q(static_cast<double>(data[3 * i]), static_cast<double>(data[3 * i + 1]),
               static_cast<double>(data[3 * i + 2]));
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
    sum += q;
  }
  if (!lo.allFinite() || !hi.allFinite() || !sum.allFinite()) return std::nullopt;
  const V3 p = p_local.template cast<double>();
  const double rd = double(r);
  const V3 outside = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  if (outside.squaredNorm() >= rd * rd) return std::nullopt;

  const V3 mean = sum / double(count);
  const double size = (hi - lo).norm();
  if (!(size > 0)) {
    // Every point is the same point: a ball of radius zero.
    const V3 v = p - mean;
    const double d = v.norm();
    const V3 n = d > 0 ? V3(v / d) : V3::UnitZ();
    return LocalContact<double>{d, n, mean};
  }

  HullFrame<Scalar> h{data, count, mean, 1.0 / size, V3::Zero(), (p - mean) / size};
  const auto gjk = gjk_distance(h, rd / size);
  if (!gjk) return std::nullopt;
  if (!gjk->touching) {
    const double d = gjk->v.norm();
    const V3 n = -gjk->v / d;
    return LocalContact<double>{d * size, n, mean + (h.centre + gjk->v) * size};
  }
  double depth = 0;
  V3 n;
  const EpaStatus epa = epa_penetration(h, depth, n);
  if (epa == EpaStatus::exact) {
    depth = std::max(depth, 0.0);
    return LocalContact<double>{-depth * size, n, mean + (h.centre + depth * n) * size};
  }
  // Out of room (a hull of many points, a centre near its middle): libccd's MPR, whose faces are
  // verified, else the EPA polytope's nearest face.
  double mpr_depth = 0;
  V3 mpr_n;
  if (mpr_penetration(h, mpr_depth, mpr_n))
    return LocalContact<double>{-mpr_depth * size, mpr_n,
                                mean + (h.centre + mpr_depth * mpr_n) * size};
  if (epa == EpaStatus::overflow) {
    depth = std::max(depth, 0.0);
    return LocalContact<double>{-depth * size, n, mean + (h.centre + depth * n) * size};
  }
  // On the surface (or a flat hull, which validate() rejects): no face was verified. Push out
  // along GJK's last direction, else away from the mean, else +z.
  if (gjk->v.squaredNorm() > 0)
    n = -gjk->v.normalized();
  else if (h.centre.squaredNorm() > 0)
    n = h.centre.normalized();
  else
    n = V3::UnitZ();
  return LocalContact<double>{0.0, n, p};
}

template std::optional<LocalContact<double>> hull_local<float>(const ConvexHullShape<float>&,
                                                               const Vector3<float>&,
                                                               float) noexcept;
template std::optional<LocalContact<double>> hull_local<double>(const ConvexHullShape<double>&,
                                                                const Vector3<double>&,
                                                                double) noexcept;

}  // namespace fsm::collision::detail
