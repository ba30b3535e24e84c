#pragma once

/// @file collision/triangle_bvh.hpp
/// @brief An AABB tree over a triangle surface whose vertices move (the skinned render surface):
/// built once, refitted per frame, queried for ray casts (picking) and for triangles near a
/// sphere (surface contact). Also the two exact per-triangle tests the queries are made of.

#include <limits>
#include <optional>
#include <vector>

#include "fsm/triangle_mesh.hpp"

namespace fsm::collision {

/// @brief A ray hit: which face, the distance along the ray and the barycentric coordinates of
/// the hit in the face (u, v for vertices 1 and 2; 1 - u - v for vertex 0).
///
/// For TriangleBvh::ray_cast, `distance` is the Euclidean distance (m) from the ray's origin to
/// the hit point. For intersect_ray_triangle it is the ray parameter t (hit = origin + t
/// direction), which is the same thing for a unit direction.
template <typename Scalar>
struct RayHit {
  Index face{-1};
  Scalar distance{0};
  Scalar u{0}, v{0};
};

/// @brief The watertight ray-triangle test of Woop, Benthin and Wald, "Watertight ray/triangle
/// intersection", JCGT 2(1), 2013.
///
/// The ray is origin + t direction with 0 <= t <= max_t; the triangle's vertices are a, b, c (m),
/// either winding (no back-face culling). Points on an edge or a vertex belong to the triangle, and
/// the test is watertight: a ray through an edge or a vertex shared by triangles hits at least one
/// of them (usually all), so it never slips through a closed surface. Edge functions that round to
/// zero are recomputed in higher precision (double for float, long double for double), as in the
/// paper. A ray in the triangle's plane, and a triangle of zero area, give no hit (unless rounding
/// leaves a non-zero projected area; the reported point then still lies on the triangle).
///
/// @param origin ray origin (m), finite
/// @param direction ray direction, finite and non-zero; any length (t is in units of its length)
/// @param a, b, c the triangle's vertices (m)
/// @param max_t largest t accepted (infinity for an unbounded ray)
/// @return the hit with `distance` = t and barycentric `u`, `v` of b and c (`face` is -1), or
/// nothing.
template <typename Scalar>
[[nodiscard]] std::optional<RayHit<Scalar>> intersect_ray_triangle(
    const Vector3<Scalar>& origin, const Vector3<Scalar>& direction, const Vector3<Scalar>& a,
    const Vector3<Scalar>& b, const Vector3<Scalar>& c,
    Scalar max_t = std::numeric_limits<Scalar>::infinity()) noexcept;

/// @brief The point of the closed triangle (a, b, c) nearest to `p` (m).
///
/// Voronoi-region walk of Ericson, "Real-Time Collision Detection" (2005), section 5.1.5. A
/// degenerate triangle (collinear or coincident vertices) is handled as the union of its three
/// edges, so the result is always finite for finite input.
template <typename Scalar>
[[nodiscard]] Vector3<Scalar> closest_point_on_triangle(const Vector3<Scalar>& p,
                                                        const Vector3<Scalar>& a,
                                                        const Vector3<Scalar>& b,
                                                        const Vector3<Scalar>& c) noexcept;

/// @brief A binary AABB tree over the faces of a triangle surface.
///
/// build() (allocates) fixes the tree's topology from the faces and current vertices: top-down,
/// each node's faces split in two halves at the median of their centroids along the longest axis
/// of the node's centroid box, down to leaves of at most `max_leaf_faces` faces. refit()
/// (allocates nothing) recomputes every box bottom-up for new vertex positions of the same
/// surface, in O(|F|); the boxes are then exactly the bounds of the current triangles. Queries
/// allocate nothing, never throw and may run concurrently (they only read the tree).
///
/// The tree keeps its own copy of the triangles' corners in leaf order (`|F| x 9` scalars,
/// refreshed by refit()), so queries read contiguous memory and never see the caller's arrays.
///
/// Traversal uses a fixed stack of `max_depth` entries. The median split halves the face count
/// at every level, so the deepest leaf is at depth ceil(log2(|F| / max_leaf_faces)) <= 29 for any
/// |F| < 2^31; build() would also turn any node at depth `max_depth - 1` into a leaf, so the stack
/// can never overflow.
template <typename Scalar>
class TriangleBvh {
 public:
  /// Most faces in a leaf (a node with more is split).
  static constexpr Index max_leaf_faces = 4;
  /// Size of the traversal stack, and one more than the deepest leaf's depth can ever be.
  static constexpr int max_depth = 64;

  /// @brief A node of the tree. Nodes are stored in depth-first order (a parent before its
  /// children, the left child right after its parent), the root first.
  struct Node {
    Vector3<Scalar> lo, hi;     ///< box corners (m): the exact bounds of the subtree's triangles
    Index left{-1}, right{-1};  ///< children, or -1 for a leaf
    Index first{0}, count{0};   ///< the subtree's faces: face_order()[first, first + count)
    [[nodiscard]] bool is_leaf() const noexcept { return left < 0; }
  };

  TriangleBvh() = default;
  /// @brief Builds over `faces` at `vertices`; see build().
  TriangleBvh(const Eigen::Ref<const Positions<Scalar>>& vertices, const FaceArray& faces);

  /// @brief Builds the tree (topology and boxes) over `faces` at `vertices`.
  ///
  /// @param vertices `|V| x 3` vertex positions (m), finite
  /// @param faces `|F| x 3` vertex indices in [0, |V|); zero faces give an empty tree that no
  /// query finds anything in. Degenerate (zero-area) faces are allowed.
  /// @throws fsm::Error naming the bad vertex or face; the tree is then unchanged.
  void build(const Eigen::Ref<const Positions<Scalar>>& vertices, const FaceArray& faces);

  /// @brief Moves the surface: copies the triangles' corners from `vertices` and recomputes all
  /// boxes bottom-up, in O(|F|). Allocates nothing; the topology is kept.
  ///
  /// @param vertices `|V| x 3` new vertex positions (m) of the surface given to build() (same
  /// |V|). They should be finite: a non-finite vertex makes query results unspecified (but safe).
  /// @return false, leaving the tree unchanged, when |V| differs from build()'s.
  bool refit(const Eigen::Ref<const Positions<Scalar>>& vertices) noexcept;

  /// @brief The nearest hit of a ray with the surface (picking).
  ///
  /// The ray starts at `origin` and runs along `direction`, which may have any non-zero length:
  /// it is normalised here, and `distance` in the result and `max_distance` are both Euclidean
  /// distances from `origin` (m). A face is hit when intersect_ray_triangle(origin,
  /// direction.normalized(), ...) hits it at 0 <= distance <= max_distance: both bounds are
  /// inclusive (a face through the origin is hit at distance 0), edges and vertices belong to
  /// their faces and the test is watertight (a ray never slips between two faces that share an
  /// edge or a vertex), and faces are two-sided. Among hits at the same distance (a ray through a
  /// shared edge or vertex), the face with the smallest index is returned, so the result does not
  /// depend on the tree. The children of a node are visited nearest box first.
  ///
  /// @param origin ray origin (m)
  /// @param direction ray direction (any non-zero length)
  /// @param max_distance largest distance (m) accepted; infinity by default
  /// @return the hit, or nothing: no face within `max_distance`, an empty tree, a zero or
  /// non-finite direction, a non-finite origin or a negative or NaN `max_distance`.
  [[nodiscard]] std::optional<RayHit<Scalar>> ray_cast(
      const Vector3<Scalar>& origin, const Vector3<Scalar>& direction,
      Scalar max_distance = std::numeric_limits<Scalar>::infinity()) const noexcept;

  /// @brief Faces whose triangle (not merely its box) comes within `radius` of `centre`:
  /// those with |centre - closest_point_on_triangle(centre, ...)|^2 <= radius^2.
  ///
  /// @param centre sphere centre (m)
  /// @param radius sphere radius (m); negative or NaN finds nothing, 0 finds the faces through
  /// `centre`
  /// @param out where the face indices go, in the tree's (deterministic, unsorted) order; the
  /// first `capacity` found are written, the rest only counted. May be null if `capacity` is 0.
  /// @param capacity how many entries `out` holds
  /// @return how many faces there are (which may exceed `capacity`).
  Index faces_near(const Vector3<Scalar>& centre, Scalar radius, Index* out,
                   Index capacity) const noexcept;

  /// @brief Number of faces |F|.
  [[nodiscard]] Index num_faces() const noexcept { return Index(m_order.size()); }
  /// @brief Number of vertices |V| that build() saw, and that refit() expects.
  [[nodiscard]] Index num_vertices() const noexcept { return m_num_vertices; }
  /// @brief The nodes, root first (empty for an empty tree); for debug drawing and tests.
  [[nodiscard]] const std::vector<Node>& nodes() const noexcept { return m_nodes; }
  /// @brief Face indices in tree order: node n covers faces face_order()[n.first, n.first +
  /// n.count).
  [[nodiscard]] const std::vector<Index>& face_order() const noexcept { return m_order; }
  /// @brief Depth of the deepest leaf (0 for a single leaf or an empty tree).
  [[nodiscard]] int depth() const noexcept { return m_depth; }

 private:
  using Corners = Eigen::Matrix<Scalar, Eigen::Dynamic, 9, Eigen::RowMajor>;

  Index build_node(const Positions<Scalar>& centroids, Index first, Index count, int depth);
  void refit_boxes(const Eigen::Ref<const Positions<Scalar>>& vertices) noexcept;

  std::vector<Node> m_nodes;
  std::vector<Index> m_order;  ///< face index at each tree position
  FaceArray m_face_vertices;   ///< `|F| x 3`: the faces' vertex indices in tree order
  Corners m_corners;           ///< `|F| x 9`: the faces' corners (a, b, c) in tree order (m)
  Index m_num_vertices{0};
  int m_depth{0};
  /// Largest |coordinate| of the root box (m): sets the rounding slack of the culling tests.
  Scalar m_scale{0};
};

extern template class TriangleBvh<float>;
extern template class TriangleBvh<double>;

}  // namespace fsm::collision

#include "fsm/collision/impl/triangle_bvh-inl.hpp"
