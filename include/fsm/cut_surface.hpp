#pragma once

/// @file cut_surface.hpp
/// @brief CutSurface: the render surface of a cut or torn model: the skin without the faces
/// that span a wound, and the wound's walls (docs/physics.md section 12).

#include <algorithm>
#include <array>
#include <vector>

#include "fsm/cutting.hpp"
#include "fsm/skinning.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/triangle_mesh.hpp"

namespace fsm {

/// @brief The faces to draw once links and tetrahedra are broken.
///
/// - **Skin faces** (`skin_faces()`, the skin's `rest.faces` order and size, so an index buffer
///   keeps its layout): a face is hidden, written as a degenerate triangle (its first vertex three
///   times), when one of its vertices is bound to spheres a broken link joins (a barycentric
///   vertex in a cut tetrahedron, a chain vertex across a broken chain link), or when the blade
///   swept through one of its edges (add_cut()). No visible face then spans the two sides of a
///   cut.
/// - **Walls** (`wall_faces()`, sphere indices: draw them over the model's positions): each face
///   of an intact tetrahedron whose neighbour across it was removed, oriented out of the intact
///   one. They show the wound's inside (one sphere radius inside the skin, where the spheres'
///   centres are).
///
/// The constructor allocates (every capacity); add_cut() and update() allocate nothing. Single
/// threaded: run it where the cut is made, hand the buffers to the renderer by copy.
template <typename Scalar>
class CutSurface {
 public:
  CutSurface(const SphereModel<Scalar>& model, const Skin<Scalar>& skin)
      : m_faces(skin.rest.faces), m_rest_faces(skin.rest.faces) {
    const Index L = model.num_links(), T = model.num_tetrahedra();
    const Index nv = skin.num_vertices(), nf = skin.rest.num_faces();
    m_num_links = L;
    m_num_tetrahedra = T;
    // Link lookup by node pair.
    std::vector<std::pair<std::uint64_t, Index>> keys;
    keys.reserve(std::size_t(L));
    const auto links = model.links();
    for (Index l = 0; l < L; ++l) keys.emplace_back(detail::edge_key(links(l, 0), links(l, 1)), l);
    std::sort(keys.begin(), keys.end());
    auto find_link = [&](Index a, Index b) -> Index {
      const auto it =
          std::lower_bound(keys.begin(), keys.end(), std::make_pair(detail::edge_key(a, b), 0));
      return it != keys.end() && it->first == detail::edge_key(a, b) ? it->second : Index(-1);
    };
    // The links each skin vertex depends on (CSR, link -> vertices).
    std::vector<std::pair<Index, Index>> link_vertex;
    for (Index v = 0; v < nv; ++v) {
      Index s[4] = {-1, -1, -1, -1};
      int count = 0;
      if (skin.kind[v] == std::uint8_t(SkinKind::barycentric)) {
        for (int k = 0; k < 4; ++k) s[count++] = skin.nodes(v, k);
      } else {
        s[count++] = skin.chain_nodes(skin.nodes(v, 0), 1);
        s[count++] = skin.chain_nodes(skin.nodes(v, 1), 1);
      }
      for (int a = 0; a < count; ++a)
        for (int b = a + 1; b < count; ++b) {
          if (s[a] == s[b]) continue;
          const Index l = find_link(s[a], s[b]);
          if (l >= 0) link_vertex.emplace_back(l, v);
        }
    }
    detail::build_csr(link_vertex, L, m_link_vertex_start, m_link_vertices, true);
    std::vector<std::pair<Index, Index>> vertex_face;
    for (Index f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k) vertex_face.emplace_back(skin.rest.faces(f, k), f);
    detail::build_csr(vertex_face, nv, m_vertex_face_start, m_vertex_faces, true);
    // Tetrahedron faces and their neighbours across them.
    const auto tets = model.tetrahedra();
    std::vector<std::pair<std::array<Index, 3>, Index>> tri;  // (sorted face, 4 t + local face)
    tri.reserve(4 * std::size_t(T));
    for (Index t = 0; t < T; ++t)
      for (int k = 0; k < 4; ++k) {
        std::array<Index, 3> f{tets(t, (k + 1) % 4), tets(t, (k + 2) % 4), tets(t, (k + 3) % 4)};
        std::sort(f.begin(), f.end());
        tri.emplace_back(f, 4 * t + k);
      }
    std::sort(tri.begin(), tri.end());
    m_neighbour.assign(4 * std::size_t(T), -1);
    for (std::size_t k = 0; k + 1 < tri.size(); ++k)
      if (tri[k].first == tri[k + 1].first) {
        m_neighbour[std::size_t(tri[k].second)] = tri[k + 1].second / 4;
        m_neighbour[std::size_t(tri[k + 1].second)] = tri[k].second / 4;
      }
    m_wall_slot.assign(4 * std::size_t(T), -1);
    m_walls.resize(4 * Index(T), 3);
    m_wall_owner.assign(4 * std::size_t(T), -1);
    m_hidden.assign(std::size_t(nf), 0);
    m_outcode.assign(std::size_t(nv), 0);
    m_link_seen.assign(std::size_t(L), 1);
    m_tet_seen.assign(std::size_t(T), 1);
    update(model);
  }

  /// @brief Hides every skin face with an edge the blade's swept surface crosses, `vertices` the
  /// skin's render vertices at the cut (Skin::evaluate). No allocation.
  Index add_cut(const Blade<Scalar>& blade,
                const Eigen::Ref<const Positions<Scalar>>& vertices) noexcept {
    if (blade.problem() != nullptr || vertices.rows() != Index(m_vertex_face_start.size()) - 1)
      return 0;
    const Vector3<Scalar> lo =
        blade.start_a.cwiseMin(blade.start_b).cwiseMin(blade.end_a).cwiseMin(blade.end_b);
    const Vector3<Scalar> hi =
        blade.start_a.cwiseMax(blade.start_b).cwiseMax(blade.end_a).cwiseMax(blade.end_b);
    // Each vertex's side of the blade's bounding box: a face whose three vertices share an
    // outside side cannot reach the blade (Cohen and Sutherland's outcodes).
    for (Index v = 0; v < vertices.rows(); ++v)
      m_outcode[std::size_t(v)] = detail::outcode<Scalar>(vertices.row(v), lo, hi);
    Index hidden = 0;
    for (Index f = 0; f < Index(m_rest_faces.rows()); ++f) {
      if (m_hidden[std::size_t(f)]) continue;
      if (m_outcode[std::size_t(m_rest_faces(f, 0))] & m_outcode[std::size_t(m_rest_faces(f, 1))] &
          m_outcode[std::size_t(m_rest_faces(f, 2))])
        continue;
      const Vector3<Scalar> a = vertices.row(m_rest_faces(f, 0)).transpose();
      const Vector3<Scalar> b = vertices.row(m_rest_faces(f, 1)).transpose();
      const Vector3<Scalar> c = vertices.row(m_rest_faces(f, 2)).transpose();
      if (segment_crosses_blade(a, b, blade) || segment_crosses_blade(b, c, blade) ||
          segment_crosses_blade(c, a, blade)) {
        hide(f);
        ++hidden;
      }
    }
    return hidden;
  }

  /// @brief Follows the model's broken links and removed tetrahedra (those since the last call):
  /// hides the skin faces bound across them and updates the walls. No allocation.
  void update(const SphereModel<Scalar>& model) noexcept {
    if (model.num_links() != m_num_links || model.num_tetrahedra() != m_num_tetrahedra) return;
    const auto link_intact = model.link_intact();
    for (Index l = 0; l < m_num_links; ++l) {
      if (link_intact[l] == m_link_seen[std::size_t(l)]) continue;
      m_link_seen[std::size_t(l)] = link_intact[l];
      if (link_intact[l]) continue;  // made whole again: see restore()
      for (Index k = m_link_vertex_start[std::size_t(l)];
           k < m_link_vertex_start[std::size_t(l) + 1]; ++k) {
        const Index v = m_link_vertices[std::size_t(k)];
        for (Index j = m_vertex_face_start[std::size_t(v)];
             j < m_vertex_face_start[std::size_t(v) + 1]; ++j)
          hide(m_vertex_faces[std::size_t(j)]);
      }
    }
    const auto tet_intact = model.tetrahedron_intact();
    for (Index t = 0; t < m_num_tetrahedra; ++t) {
      if (tet_intact[t] == m_tet_seen[std::size_t(t)] || tet_intact[t]) continue;
      m_tet_seen[std::size_t(t)] = 0;
      for (int k = 0; k < 4; ++k) {
        remove_wall(4 * t + k);  // its own walls go with it
        const Index n = m_neighbour[4 * std::size_t(t) + std::size_t(k)];
        if (n < 0 || !tet_intact[n]) continue;
        // The neighbour's face opposite t becomes a wall.
        for (int j = 0; j < 4; ++j)
          if (m_neighbour[4 * std::size_t(n) + std::size_t(j)] == t) add_wall(model, n, j);
      }
    }
  }

  /// @brief Shows every face again and removes every wall (after SphereModel::restore_topology()).
  void restore(const SphereModel<Scalar>& model) noexcept {
    m_faces = m_rest_faces;
    std::fill(m_hidden.begin(), m_hidden.end(), std::uint8_t(0));
    std::fill(m_wall_slot.begin(), m_wall_slot.end(), Index(-1));
    m_num_walls = 0;
    std::fill(m_link_seen.begin(), m_link_seen.end(), std::uint8_t(1));
    std::fill(m_tet_seen.begin(), m_tet_seen.end(), std::uint8_t(1));
    update(model);
  }

  /// @brief The skin's faces with the hidden ones degenerate (`|F| x 3`, the skin's layout).
  [[nodiscard]] const FaceArray& skin_faces() const noexcept { return m_faces; }
  /// @brief True if skin face f is hidden.
  [[nodiscard]] bool hidden(Index f) const noexcept { return m_hidden[std::size_t(f)] != 0; }
  [[nodiscard]] Index num_hidden() const noexcept {
    return Index(std::count(m_hidden.begin(), m_hidden.end(), std::uint8_t(1)));
  }
  /// @brief The walls: the first num_walls() rows are faces over the spheres (indices into the
  /// model's positions), counter-clockwise seen from the wound.
  [[nodiscard]] const FaceArray& wall_faces() const noexcept { return m_walls; }
  [[nodiscard]] Index num_walls() const noexcept { return m_num_walls; }

 private:
  void hide(Index f) noexcept {
    if (m_hidden[std::size_t(f)]) return;
    m_hidden[std::size_t(f)] = 1;
    m_faces.row(f).setConstant(m_rest_faces(f, 0));
  }
  // Face k (0-3, opposite node k) of tetrahedron t as a wall, oriented out of t.
  void add_wall(const SphereModel<Scalar>& model, Index t, int k) noexcept {
    const std::size_t key = 4 * std::size_t(t) + std::size_t(k);
    if (m_wall_slot[key] >= 0) return;
    const Index* v = model.tetrahedra().data() + 4 * std::ptrdiff_t(t);
    // A positively oriented tetrahedron's faces, outward: (1 2 3), (0 3 2), (0 1 3), (0 2 1).
    static constexpr int face[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    const Index slot = m_num_walls++;
    m_walls.row(slot) << v[face[k][0]], v[face[k][1]], v[face[k][2]];
    m_wall_owner[std::size_t(slot)] = Index(key);
    m_wall_slot[key] = slot;
  }
  void remove_wall(Index key) noexcept {
    const Index slot = m_wall_slot[std::size_t(key)];
    if (slot < 0) return;
    const Index last = --m_num_walls;
    m_walls.row(slot) = m_walls.row(last);
    m_wall_owner[std::size_t(slot)] = m_wall_owner[std::size_t(last)];
    m_wall_slot[std::size_t(m_wall_owner[std::size_t(slot)])] = slot;
    m_wall_slot[std::size_t(key)] = -1;
  }

  FaceArray m_faces, m_rest_faces;
  Index m_num_links{0}, m_num_tetrahedra{0};
  std::vector<Index> m_link_vertex_start, m_link_vertices;
  std::vector<Index> m_vertex_face_start, m_vertex_faces;
  std::vector<Index> m_neighbour;  // per (tetrahedron, face): the tetrahedron across, or -1
  std::vector<Index> m_wall_slot, m_wall_owner;
  FaceArray m_walls;
  Index m_num_walls{0};
  std::vector<std::uint8_t> m_hidden, m_link_seen, m_tet_seen;
  std::vector<std::uint8_t> m_outcode;  // per skin vertex (add_cut)
};

}  // namespace fsm
