#pragma once

/// @file skinning.hpp
/// @brief Skin: render surfaces bound to the spheres, and their allocation-free evaluation.

#include <string>
#include <vector>

#include "fsm/error.hpp"
#include "fsm/triangle_mesh.hpp"
#include "fsm/types.hpp"

namespace fsm {

/// @brief How a render vertex follows the spheres.
enum class SkinKind : std::uint8_t {
  /// Barycentric in a tetrahedron of a tetrahedral part: \f$\mathbf{v} = \sum_k w_k
  /// \mathbf{x}_{n_k}\f$ (weights sum to 1; slightly negative for a vertex just outside the
  /// filling, which is an exact affine extrapolation).
  barycentric = 0,
  /// On a sphere chain of an axis part: a point at parameter s between two chain nodes plus a rest
  /// offset carried by the rotation interpolated between the nodes' rotations.
  chain = 1,
};

/// @brief Render surfaces (one per part) bound to the spheres of a model.
///
/// Per render vertex: `kind`; `nodes` and `weights` (`|S| x 4`): for barycentric vertices the
/// tetrahedron's four sphere indices and weights; for chain vertices `(a, b, -1, -1)` indices into
/// the chain-node table and weights `(1 - s, s, 0, 0)`; `offsets` (`|S| x 3`, m): for chain
/// vertices the rest offset from the axis point, else 0.
///
/// The chain-node table (`|A|` rows): `chain_nodes` `(prev, node, next)` sphere indices (prev =
/// node at a chain start, next = node at an end) and `chain_rest_tangents` (unit). A chain node's
/// rotation is the one that turns its rest tangent into its current tangent with no twist about
/// it (the rotation-minimising choice; a chain of spheres cannot represent twist); a chain vertex
/// uses the normalised linear blend of its two nodes' rotations (as quaternions).
///
/// With the spheres at rest every rotation is the identity and every barycentric combination
/// returns its vertex, so evaluate() reproduces `rest` to rounding.
template <typename Scalar>
struct Skin {
  /// One part's render surface inside the concatenated `rest` mesh.
  struct Surface {
    std::string name;
    Index first_vertex{0}, num_vertices{0};
    Index first_face{0}, num_faces{0};
  };

  /// Per-call scratch (one quaternion per chain node); make it with make_workspace().
  struct Workspace {
    Eigen::Matrix<Scalar, Eigen::Dynamic, 4, Eigen::RowMajor> rotation;
  };

  TriangleMesh<Scalar> rest;  ///< All render surfaces at rest, concatenated.
  std::vector<Surface> surfaces;
  Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1> kind;
  Eigen::Matrix<Index, Eigen::Dynamic, 4, Eigen::RowMajor> nodes;
  Eigen::Matrix<Scalar, Eigen::Dynamic, 4, Eigen::RowMajor> weights;
  Positions<Scalar> offsets;
  Eigen::Matrix<Index, Eigen::Dynamic, 3, Eigen::RowMajor> chain_nodes;
  Positions<Scalar> chain_rest_tangents;

  [[nodiscard]] Index num_vertices() const noexcept { return rest.num_vertices(); }
  [[nodiscard]] Workspace make_workspace() const {
    return Workspace{decltype(Workspace::rotation)(chain_nodes.rows(), 4)};
  }

  /// @brief Checks sizes, kinds, index ranges (`num_spheres` spheres) and finiteness; throws
  /// fsm::Error naming the surface and vertex.
  void validate(Index num_spheres) const;

  /// @brief Deformed render vertices for sphere positions `spheres` (`|V| x 3`) into `out`
  /// (`|S| x 3`). Allocates nothing; `ws` must come from make_workspace() of this skin.
  void evaluate(const Eigen::Ref<const Positions<Scalar>>& spheres, Workspace& ws,
                Eigen::Ref<Positions<Scalar>> out) const noexcept;
};

extern template struct Skin<float>;
extern template struct Skin<double>;

}  // namespace fsm

#include "fsm/impl/skinning-inl.hpp"
