#pragma once

// Render-surface binding (see fsm/skinning.hpp for how the runtime evaluates it).

#include <vector>

#include "fsm/tetrahedral_mesh.hpp"

namespace fsm::build::detail {

/// For each point, the tetrahedron containing it (or the one it is least outside of, nearby) and
/// its barycentric weights; node indices offset by `first_node`.
void bind_barycentric(const TetrahedralMesh<double>& mesh, Index first_node,
                      const Positions<double>& points,
                      Eigen::Ref<Eigen::Matrix<Index, -1, 4, Eigen::RowMajor>> nodes,
                      Eigen::Ref<Eigen::Matrix<double, -1, 4, Eigen::RowMajor>> weights);

/// A chain part's node table and, per point, its nearest segment.
struct ChainBinding {
  Eigen::Matrix<Index, -1, 3, Eigen::RowMajor> chain_nodes;  ///< (prev, node, next), model indices
  Positions<double> tangents;                                ///< rest unit tangents
  Eigen::Matrix<Index, -1, 2, Eigen::RowMajor> entries;      ///< per point: two chain-table rows
  Eigen::VectorXd s;                                         ///< per point: parameter in [0, 1]
  Positions<double> offsets;                                 ///< per point: rest offset (m)
};
ChainBinding bind_chain(const Positions<double>& centres,
                        const std::vector<std::vector<Index>>& branches, Index first_node,
                        const Positions<double>& points);

}  // namespace fsm::build::detail
