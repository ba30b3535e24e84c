#pragma once

/// @file triangle_mesh.hpp
/// @brief TriangleMesh: an indexed triangle surface (render surfaces, input meshes), and
/// allocation-free vertex normals.

#include <cmath>
#include <string>

#include "fsm/error.hpp"
#include "fsm/types.hpp"

namespace fsm {

/// @brief Row-major `|F| x 3` array of triangles (vertex indices, counter-clockwise seen from
/// outside).
using FaceArray = Eigen::Matrix<Index, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// @brief An indexed triangle mesh: vertices (`|V| x 3`, m) and faces (`|F| x 3`).
template <typename Scalar>
struct TriangleMesh {
  Positions<Scalar> vertices;
  FaceArray faces;

  [[nodiscard]] Index num_vertices() const noexcept { return Index(vertices.rows()); }
  [[nodiscard]] Index num_faces() const noexcept { return Index(faces.rows()); }

  /// @brief Throws fsm::Error naming `what` for an empty mesh, a non-finite vertex or a face
  /// index out of range.
  void validate(const std::string& what) const {
    if (vertices.rows() == 0 || faces.rows() == 0) throw Error("", what, "triangle mesh is empty");
    if (!vertices.allFinite()) throw Error("", what, "a vertex is not finite");
    if ((faces.array() < 0).any() || (faces.array() >= Index(vertices.rows())).any())
      throw Error("", what,
                  "a face index is out of range [0, " + std::to_string(vertices.rows()) + ")");
  }

  /// @brief Signed volume (m^3) enclosed by a closed, outward-oriented mesh.
  [[nodiscard]] Scalar volume() const noexcept {
    Scalar v(0);
    for (Index f = 0; f < num_faces(); ++f) {
      const Vector3<Scalar> a = vertices.row(faces(f, 0)).transpose();
      const Vector3<Scalar> b = vertices.row(faces(f, 1)).transpose();
      const Vector3<Scalar> c = vertices.row(faces(f, 2)).transpose();
      v += a.dot(b.cross(c));
    }
    return v / Scalar(6);
  }
};

/// @brief Area-weighted vertex normals of `faces` over `vertices` into `normals` (`|V| x 3`,
/// unit length; zero for a vertex on no non-degenerate face). Allocates nothing.
template <typename Scalar>
void compute_vertex_normals(const Eigen::Ref<const Positions<Scalar>>& vertices,
                            const FaceArray& faces,
                            Eigen::Ref<Positions<Scalar>> normals) noexcept {
  normals.setZero();
  for (Index f = 0; f < Index(faces.rows()); ++f) {
    const Index a = faces(f, 0), b = faces(f, 1), c = faces(f, 2);
    const Vector3<Scalar> n = (vertices.row(b) - vertices.row(a))
                                  .transpose()
                                  .cross((vertices.row(c) - vertices.row(a)).transpose());
    normals.row(a) += n.transpose();
    normals.row(b) += n.transpose();
    normals.row(c) += n.transpose();
  }
  for (Index v = 0; v < Index(normals.rows()); ++v) {
    const Scalar len = normals.row(v).norm();
    if (len > Scalar(0)) normals.row(v) *= Scalar(1) / len;  // one division, not three
  }
}

}  // namespace fsm
