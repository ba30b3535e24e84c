#pragma once

/// @file build/mesh_io.hpp
/// @brief Reading surface meshes (OBJ, OFF, STL, PLY), checking them, and repairing them on
/// request (part of fsm::build, GPL-3.0-or-later; CGAL stays inside src/builder).

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fsm/triangle_mesh.hpp"

namespace fsm::build {

/// @brief The mesh file formats read_mesh() reads.
enum class MeshFormat { obj, off, stl, ply };

/// @brief The format of a path by its extension (case-insensitive), or nullopt.
std::optional<MeshFormat> mesh_format(const std::string& path);

/// @brief A mesh file's content as written: points and polygons (indices into the points), before
/// welding and triangulation.
struct PolygonSoup {
  std::vector<std::array<double, 3>> points;       ///< in the file's units
  std::vector<std::vector<std::size_t>> polygons;  ///< each at least 3 indices, all < points.size()
};

/// @brief Parses the bytes of a mesh file (untrusted input). Every count the file declares is
/// checked against the bytes that remain before anything is allocated for it; coordinates must
/// be finite and indices in range. fsm::Error naming `file` and, in `reason()`, the line (text
/// formats) or byte offset (binary) and what is wrong there, e.g. "line 12: z coordinate 'nan'
/// is not finite (NaN, infinite or too large)".
///
/// OBJ: `v` and `f` statements (1-based or negative indices; other statements are ignored). OFF:
/// `OFF`, `COFF`, `NOFF` (text). STL: binary or ASCII. PLY: ASCII or binary of either byte order,
/// any scalar types, vertex `x y z`, face `vertex_indices` (or `vertex_index`); other elements
/// and properties are skipped.
PolygonSoup parse_mesh(std::string_view bytes, MeshFormat format, const std::string& file = "");

/// @brief What inspect_mesh() found in one surface mesh.
struct MeshReport {
  std::string file;  ///< Where it came from ("" when built in memory).
  Index vertices{0}, faces{0};
  Index components{0};               ///< Connected components (by shared edges).
  Index boundary_edges{0};           ///< Edges on one face only; 0 for a closed mesh.
  Index non_manifold_edges{0};       ///< Edges on three or more faces.
  Index non_manifold_vertices{0};    ///< Vertices whose faces do not form one fan.
  Index degenerate_faces{0};         ///< Zero-area faces or faces repeating a vertex.
  Index self_intersections{0};       ///< Intersecting face pairs found (counting stops at 1000).
  bool outward_oriented{false};      ///< Closed, and its normals point out (positive volume).
  double area{0};                    ///< m^2
  double volume{0};                  ///< m^3, signed; meaningful for a closed mesh
  std::vector<std::string> repairs;  ///< What repair steps changed (filled by the builder).

  [[nodiscard]] bool closed() const noexcept { return boundary_edges == 0; }
  [[nodiscard]] bool manifold() const noexcept {
    return non_manifold_edges == 0 && non_manifold_vertices == 0;
  }
  /// @brief True for a closed, manifold, non-self-intersecting, non-degenerate, outward mesh:
  /// what a volume filling needs.
  [[nodiscard]] bool bounds_a_volume() const noexcept {
    return closed() && manifold() && self_intersections == 0 && degenerate_faces == 0 &&
           outward_oriented;
  }
  /// @brief The defects, in words ("3 boundary edges (open)", ...); empty when none.
  [[nodiscard]] std::vector<std::string> defects() const;
};

/// @brief Reads a triangle (or polygon, then triangulated) mesh from OBJ, OFF, STL, PLY or glTF,
/// chosen by the file extension, and scales its coordinates by `scale` (to metres). Duplicate
/// vertices are merged. fsm::Error naming the file for a missing or unreadable file, an unknown
/// extension, an empty mesh or non-finite coordinates.
///
/// Only exactly coincident vertices are welded and vertices no face uses dropped; faces are kept
/// as they are (degenerate, duplicated, inconsistently oriented), for inspect_mesh() to report.
/// Polygons with more than three vertices are split without new vertices (minimal area).
/// Extensions are case-insensitive; STL may be ASCII or binary.
///
/// glTF 2.0 (`.gltf` with its buffers, or `.glb`) is read through assimp (read_gltf()): `nodes`
/// names the nodes to take (each with its subtree, under its node transforms); empty takes the
/// whole scene. `nodes` must be empty for the other formats.
TriangleMesh<double> read_mesh(const std::string& path, double scale = 1.0,
                               const std::vector<std::string>& nodes = {});

/// @brief The triangles of a glTF 2.0 file (`bytes` is its content, `path` where it is, for its
/// buffers and for messages): the named nodes and their subtrees (all nodes when `nodes` is
/// empty), each vertex moved by its node's world transform (composed in double). fsm::Error naming
/// the file, the node and the reason for: malformed JSON or GLB framing, no mesh, a node name that
/// does not exist (the message lists those that do), a required extension that changes the
/// geometry's encoding and that this build cannot decode, point or line primitives, a vertex that
/// is not finite, or anything assimp cannot read (its message).
PolygonSoup read_gltf(const std::string& bytes, const std::string& path,
                      const std::vector<std::string>& nodes = {});

/// @brief Writes a mesh as OBJ, OFF, STL or PLY by extension; fsm::Error on failure.
///
/// OBJ and OFF are written as text with 17 significant digits (doubles round-trip exactly), PLY as
/// binary doubles, STL as binary single precision.
void write_mesh(const std::string& path, const TriangleMesh<double>& mesh);

/// @brief Checks a mesh for the defects listed in MeshReport. Works on any triangle soup
/// (non-manifold, inconsistently oriented); an empty mesh gives a report with no faces.
/// fsm::Error naming `file` for a face index out of range or a non-finite vertex.
MeshReport inspect_mesh(const TriangleMesh<double>& mesh, const std::string& file = "");

/// @brief Reorients the faces of a closed mesh (or polygon soup that can be made one) so that it
/// bounds a volume with outward normals; fsm::Error when that is impossible.
///
/// Only face windings change: vertices and faces keep their order. Nested shells are oriented so
/// that inner ones bound cavities. fsm::Error naming `file` when the mesh is empty, open,
/// non-manifold, has a face repeating a vertex, or is not orientable.
TriangleMesh<double> orient_outward(const TriangleMesh<double>& mesh, const std::string& file = "");

/// @brief Alpha wrapping (CGAL Alpha_wrap_3) of one or more meshes, open or overlapping, into one
/// closed, manifold, outward surface that contains them. `alpha` (m) is the size of the smallest
/// feature kept, `offset` (m) the distance of the wrap from the input.
///
/// The result can have several components: inputs farther apart than about `alpha`, or, for a
/// small `alpha`, an inner cavity. fsm::Error for a non-positive or non-finite `alpha` or
/// `offset`, an invalid input mesh, or no input triangles.
TriangleMesh<double> alpha_wrap(const std::vector<TriangleMesh<double>>& meshes, double alpha,
                                double offset);

}  // namespace fsm::build
