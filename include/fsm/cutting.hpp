#pragma once

/// @file cutting.hpp
/// @brief Topology changes: a blade that cuts the links and tetrahedra it sweeps through, and
/// tearing of links (and the tetrahedra that share them) strained past their material's limit
/// (docs/physics.md section 12).
///
/// A broken link or removed tetrahedron stays in the model's arrays with its intact flag at 0
/// (SphereModel::link_intact(), tetrahedron_intact()): indices stay valid, nothing is allocated,
/// the nodes keep their mass. The force model then leaves it out (ForceModel::update_topology()).

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "fsm/detail/reserved_vector.hpp"
#include "fsm/error.hpp"
#include "fsm/sphere_model.hpp"
#include "fsm/types.hpp"

namespace fsm {

namespace detail {
/// The key of the undirected edge (a, b): the smaller index in the high half.
inline std::uint64_t edge_key(Index a, Index b) noexcept {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}
/// (row, item) pairs as a compressed row table: items of row r are items[start[r], start[r + 1])
/// (allocates: refresh-time only). The pairs are sorted in place; `unique` drops repeats.
inline void build_csr(std::vector<std::pair<Index, Index>>& pairs, Index rows,
                      std::vector<Index>& start, std::vector<Index>& items, bool unique = false) {
  std::sort(pairs.begin(), pairs.end());
  if (unique) pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  start.assign(std::size_t(rows) + 1, 0);
  items.clear();
  items.reserve(pairs.size());
  for (const auto& [r, item] : pairs) {
    ++start[std::size_t(r) + 1];
    items.push_back(item);
  }
  for (Index r = 0; r < rows; ++r) start[std::size_t(r) + 1] += start[std::size_t(r)];
}
/// Which sides of the box [lo, hi] point p lies beyond (Cohen and Sutherland's outcode: bit 2c
/// below, 2c + 1 above, on axis c). Segments or triangles whose points share a bit miss the box.
template <typename Scalar, typename Point>
std::uint8_t outcode(const Point& p, const Vector3<Scalar>& lo,
                     const Vector3<Scalar>& hi) noexcept {
  int code = 0;
  for (int c = 0; c < 3; ++c)
    code |= (int(p[c] < lo[c]) << (2 * c)) | (int(p[c] > hi[c]) << (2 * c + 1));
  return std::uint8_t(code);
}
}  // namespace detail

/// @brief A cutting edge (a segment, the blade's edge) swept over one step: from `start_a` -
/// `start_b` to `end_a` - `end_b` (m). It cuts what crosses the ruled surface between the two
/// segments (two triangles: start_a, start_b, end_b and start_a, end_b, end_a).
template <typename Scalar>
struct Blade {
  Vector3<Scalar> start_a{Vector3<Scalar>::Zero()}, start_b{Vector3<Scalar>::Zero()};
  Vector3<Scalar> end_a{Vector3<Scalar>::Zero()}, end_b{Vector3<Scalar>::Zero()};

  /// @brief Why the blade is not valid (a non-finite point, an edge of zero length at the start
  /// or the end), or nullptr. A blade that does not move is valid and cuts nothing.
  [[nodiscard]] const char* problem() const noexcept {
    if (!(start_a.allFinite() && start_b.allFinite() && end_a.allFinite() && end_b.allFinite()))
      return "an end point is not finite";
    if (!((start_b - start_a).norm() > Scalar(0)) || !((end_b - end_a).norm() > Scalar(0)))
      return "its edge has zero length";
    return nullptr;
  }
  /// @brief fsm::Error ("blade", problem()) if the blade is not valid.
  void validate() const {
    if (const char* p = problem()) throw Error("", "blade", p);
  }
};

/// @brief True if the segment p-q crosses the triangle a, b, c (touching counts). No allocation.
/// Möller and Trumbore's test on the segment's parameter in [0, 1]; a degenerate triangle is
/// crossed by nothing.
template <typename Scalar>
[[nodiscard]] bool segment_crosses_triangle(const Vector3<Scalar>& p, const Vector3<Scalar>& q,
                                            const Vector3<Scalar>& a, const Vector3<Scalar>& b,
                                            const Vector3<Scalar>& c) noexcept {
  const Vector3<Scalar> d = q - p, e1 = b - a, e2 = c - a;
  const Vector3<Scalar> s = d.cross(e2);
  const Scalar det = e1.dot(s);
  const Scalar scale = e1.norm() * e2.norm() * d.norm();
  if (!(std::abs(det) > std::numeric_limits<Scalar>::epsilon() * Scalar(16) * scale))
    return false;  // parallel, or degenerate
  const Scalar inv = Scalar(1) / det;
  const Vector3<Scalar> t = p - a;
  const Scalar u = t.dot(s) * inv;
  if (u < Scalar(0) || u > Scalar(1)) return false;
  const Vector3<Scalar> r = t.cross(e1);
  const Scalar v = d.dot(r) * inv;
  if (v < Scalar(0) || u + v > Scalar(1)) return false;
  const Scalar w = e2.dot(r) * inv;  // the segment's parameter
  return w >= Scalar(0) && w <= Scalar(1);
}

/// @brief True if the segment p-q crosses the surface the blade swept.
template <typename Scalar>
[[nodiscard]] bool segment_crosses_blade(const Vector3<Scalar>& p, const Vector3<Scalar>& q,
                                         const Blade<Scalar>& blade) noexcept {
  return segment_crosses_triangle(p, q, blade.start_a, blade.start_b, blade.end_b) ||
         segment_crosses_triangle(p, q, blade.start_a, blade.end_b, blade.end_a);
}

/// @brief What a cut or a tear changed.
struct TopologyChange {
  Index links_cut{0};        ///< Links the blade crossed.
  Index tetrahedra_cut{0};   ///< Tetrahedra with an edge the blade crossed.
  Index links_torn{0};       ///< Links strained past their tear strain.
  Index tetrahedra_torn{0};  ///< Tetrahedra that shared a torn link.
  /// After a change: the pieces the model is in (joined by links that carry force or by intact
  /// continuum tetrahedra), and how many of them hold no fixed node (they fall: allowed, and
  /// reported). 0 and 0 when nothing changed.
  Index pieces{0}, loose_pieces{0};
  /// The blade was not valid (Blade::validate() says why): nothing changed.
  bool rejected{false};
  [[nodiscard]] bool any() const noexcept {
    return links_cut + tetrahedra_cut + links_torn + tetrahedra_torn > 0;
  }
  TopologyChange& operator+=(const TopologyChange& o) noexcept {
    links_cut += o.links_cut;
    tetrahedra_cut += o.tetrahedra_cut;
    links_torn += o.links_torn;
    tetrahedra_torn += o.tetrahedra_torn;
    if (o.pieces > 0) {
      pieces = o.pieces;
      loose_pieces = o.loose_pieces;
    }
    rejected = rejected || o.rejected;
    return *this;
  }
};

/// @brief Cuts and tears a SphereModel's links and tetrahedra in the real-time step.
///
/// refresh() (allocates) builds which tetrahedra share each link, the links' tear strains (the
/// smallest of the link's own SphereModel::tear_strain() and its two nodes' regions'
/// Material::tear_strain; writable per link afterwards) and room for the event lists; cut() and
/// tear() then allocate nothing, never throw, and are deterministic (links and tetrahedra are
/// visited in index order).
template <typename Scalar>
class TopologyEditor {
 public:
  TopologyEditor() = default;
  explicit TopologyEditor(const SphereModel<Scalar>& model) { refresh(model); }

  /// @brief Re-derives everything from the model (allocates). Per-link tear strains set by hand
  /// are replaced by the materials' values.
  void refresh(const SphereModel<Scalar>& model) {
    const Index L = model.num_links(), T = model.num_tetrahedra();
    m_num_links = L;
    m_num_tetrahedra = T;
    const auto links = model.links();
    const auto region = model.node_regions();
    m_tear.resize(L);
    for (Index l = 0; l < L; ++l)
      m_tear[l] =
          std::min({model.tear_strain()[l], model.region(region[links(l, 0)]).material.tear_strain,
                    model.region(region[links(l, 1)]).material.tear_strain});
    // The tetrahedra at each link (CSR): match the tetrahedra's edges to the links.
    std::vector<std::pair<std::uint64_t, Index>> keys;  // (edge key, tetrahedron)
    keys.reserve(6 * std::size_t(T));
    const auto tets = model.tetrahedra();
    for (Index t = 0; t < T; ++t)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b)
          keys.emplace_back(detail::edge_key(tets(t, a), tets(t, b)), t);
    std::sort(keys.begin(), keys.end());
    m_link_tet_start.assign(std::size_t(L) + 1, 0);
    m_link_tets.clear();
    for (Index l = 0; l < L; ++l) {
      const std::uint64_t key = detail::edge_key(links(l, 0), links(l, 1));
      auto it = std::lower_bound(keys.begin(), keys.end(), std::make_pair(key, Index(-1)));
      for (; it != keys.end() && it->first == key; ++it) m_link_tets.push_back(it->second);
      m_link_tet_start[std::size_t(l) + 1] = Index(m_link_tets.size());
    }
    m_broken_links.clear();
    m_broken_links.reserve(std::size_t(L));
    m_removed_tetrahedra.clear();
    m_removed_tetrahedra.reserve(std::size_t(T));
    m_tearable.reserve(std::size_t(L));
    m_tear_length2.reserve(std::size_t(L));
    update_tearable(model);
    const std::size_t n = std::size_t(model.num_nodes());
    m_outcode.resize(n);
    m_label.assign(n, 0);
    m_label_fixed.assign(2 * n + 1, 0);  // the labels of count_pieces() and one per split
    m_anchor.assign(2 * n + 1, -1);
    m_touched.clear();
    m_touched.reserve(2 * n + 1);
    m_seen.assign(n, 0);
    m_generation = 0;
    m_front_a.resize(n);
    m_front_b.resize(n);
    m_labelled = false;
    m_tet_continuum.resize(std::size_t(T));
    for (Index t = 0; t < T; ++t)
      m_tet_continuum[std::size_t(t)] = model.region(region[tets(t, 0)]).law == ForceLaw::continuum;
    // Each node's links and continuum tetrahedra (CSR), for the pieces' searches.
    std::vector<std::pair<Index, Index>> at;
    at.reserve(2 * std::size_t(L));
    for (Index l = 0; l < L; ++l) {
      at.emplace_back(links(l, 0), l);
      at.emplace_back(links(l, 1), l);
    }
    detail::build_csr(at, model.num_nodes(), m_node_link_start, m_node_links);
    at.clear();
    for (Index t = 0; t < T; ++t)
      if (m_tet_continuum[std::size_t(t)])
        for (int k = 0; k < 4; ++k) at.emplace_back(tets(t, k), t);
    detail::build_csr(at, model.num_nodes(), m_node_tet_start, m_node_tets);
  }

  /// @brief Counts the pieces of the model from scratch, joined by the links with `force_link`
  /// set (ForceModel::force_links()) and by the intact tetrahedra of continuum regions, into
  /// `change.pieces`, and those without a fixed node into `change.loose_pieces`; labels every
  /// node with its piece (piece()). O(|V| + |L| + |T|), no allocation. Simulation calls it at
  /// refresh and when fixed flags change; after a cut or a tear, update_pieces() does the same work
  /// incrementally.
  void count_pieces(const SphereModel<Scalar>& model, const std::vector<std::uint8_t>& force_link,
                    TopologyChange& change) noexcept {
    const Index n = model.num_nodes();
    if (std::size_t(n) != m_label.size() || force_link.size() != std::size_t(m_num_links) ||
        !sized_for(model))
      return;
    // Breadth-first from each node not reached yet, in index order: each piece is labelled with
    // its smallest node.
    const std::uint32_t mark = next_mark();
    std::fill(m_label_fixed.begin(), m_label_fixed.end(), Index(0));
    const auto fixed = model.fixed();
    m_pieces = m_loose = 0;
    for (Index root = 0; root < n; ++root) {
      if (m_seen[std::size_t(root)] == mark) continue;
      m_seen[std::size_t(root)] = mark;
      m_front_a[0] = root;
      std::size_t size = 1;
      for (std::size_t head = 0; head < size; ++head) {
        const Index u = m_front_a[head];
        m_label[std::size_t(u)] = root;
        m_label_fixed[std::size_t(root)] += fixed[u];
        for_each_neighbour(model, force_link, u, [&](Index v) {
          if (m_seen[std::size_t(v)] != mark) {
            m_seen[std::size_t(v)] = mark;
            m_front_a[size++] = v;
          }
          return false;
        });
      }
      ++m_pieces;
      m_loose += Index(m_label_fixed[std::size_t(root)] == 0);
    }
    m_next_label = n;
    m_labelled = true;
    change.pieces = m_pieces;
    change.loose_pieces = m_loose;
  }

  /// @brief After the last cut() or tear() (its broken_links() and removed_tetrahedra()): splits
  /// the pieces they disconnected and reports the counts in `change`, as count_pieces() would.
  /// For each broken link, and each removed continuum tetrahedron, whose nodes were in one piece, a
  /// search spreads from both ends at once until the two fronts meet (still one piece: it stops
  /// within the wound's neighbourhood) or one runs out (that side is a new piece, the smaller
  /// one). Falls back to count_pieces() when not labelled yet. No allocation.
  void update_pieces(const SphereModel<Scalar>& model, const std::vector<std::uint8_t>& force_link,
                     TopologyChange& change) noexcept {
    if (!m_labelled || std::size_t(model.num_nodes()) != m_label.size()) {
      count_pieces(model, force_link, change);
      return;
    }
    // Every node that lost a connection is checked against an anchor of its piece: a node of the
    // piece's that is still known to hold together. When the anchor's side is the one cut off,
    // the node checked becomes the anchor of what is left of the old piece.
    m_touched.clear();
    auto consider = [&](Index u) {
      const Index label = m_label[std::size_t(u)];
      Index& anchor = m_anchor[std::size_t(label)];
      if (anchor < 0) {
        anchor = u;
        m_touched.push_back(label);
        return;
      }
      if (anchor == u) return;
      const Index a = anchor;
      const int moved = split(model, force_link, a, u);
      if (moved == 0) return;
      const Index mover = moved == 1 ? a : u;
      const Index fresh = m_label[std::size_t(mover)];
      m_anchor[std::size_t(fresh)] = mover;
      m_touched.push_back(fresh);
      if (moved == 1) m_anchor[std::size_t(label)] = u;  // the old piece goes on without a's side
    };
    const auto links = model.links();
    for (const Index l : m_broken_links) {
      consider(links(l, 0));
      consider(links(l, 1));
    }
    const auto tets = model.tetrahedra();
    for (const Index t : m_removed_tetrahedra)
      if (m_tet_continuum[std::size_t(t)])
        for (int k = 0; k < 4; ++k) consider(tets(t, k));
    for (const Index label : m_touched) m_anchor[std::size_t(label)] = -1;
    change.pieces = m_pieces;
    change.loose_pieces = m_loose;
  }

  /// @brief The piece of node i (a label shared by the nodes of one piece), as count_pieces() or
  /// update_pieces() left it.
  [[nodiscard]] Index piece(Index i) const noexcept { return m_label[std::size_t(i)]; }

  /// @brief The strain (l - l0) / l0 past which each link tears (`|L|`; infinity = never).
  /// Writable: call refresh_tearing(model) after editing it.
  Eigen::Map<ScalarArray<Scalar>> tear_strains() noexcept { return {m_tear.data(), m_num_links}; }
  [[nodiscard]] Eigen::Map<const ScalarArray<Scalar>> tear_strains() const noexcept {
    return {m_tear.data(), m_num_links};
  }
  /// @brief Re-reads tear_strains() after it was edited (`model`: its rest lengths turn the
  /// strains into lengths). Throws fsm::Error for a tear strain that is not positive (NaN
  /// included).
  void refresh_tearing(const SphereModel<Scalar>& model) {
    for (Index l = 0; l < m_num_links; ++l)
      if (!(m_tear[l] > Scalar(0)))
        throw Error("", "link " + std::to_string(l),
                    "tear strain " + std::to_string(m_tear[l]) +
                        " must be positive (infinity = never tears)");
    update_tearable(model);
  }
  /// @brief True when some link has a finite tear strain (else tear() has nothing to do).
  [[nodiscard]] bool tears() const noexcept { return m_tears; }

  /// @brief Breaks every intact link whose segment at the model's positions crosses the blade's
  /// swept surface, and removes every intact tetrahedron with an edge that does. The lists of
  /// broken links and removed tetrahedra are cleared first. Does nothing if the model changed size
  /// since refresh(). No allocation; never throws (validate the blade beforehand).
  TopologyChange cut(SphereModel<Scalar>& model, const Blade<Scalar>& blade) noexcept {
    TopologyChange change;
    clear_events();
    if (!sized_for(model) || std::size_t(model.num_nodes()) != m_outcode.size()) return change;
    const Vector3<Scalar> lo =
        blade.start_a.cwiseMin(blade.start_b).cwiseMin(blade.end_a).cwiseMin(blade.end_b);
    const Vector3<Scalar> hi =
        blade.start_a.cwiseMax(blade.start_b).cwiseMax(blade.end_a).cwiseMax(blade.end_b);
    const auto x = model.positions();
    // Each node's side of the blade's bounding box (Cohen and Sutherland's outcodes): a segment
    // whose two ends share an outside side cannot reach the blade.
    for (Index i = 0; i < model.num_nodes(); ++i)
      m_outcode[std::size_t(i)] = detail::outcode<Scalar>(x.row(i), lo, hi);
    const auto links = model.links();
    auto intact = model.link_intact();
    auto crosses = [&](Index i, Index j) {
      if (m_outcode[std::size_t(i)] & m_outcode[std::size_t(j)]) return false;
      return segment_crosses_blade<Scalar>(x.row(i).transpose(), x.row(j).transpose(), blade);
    };
    for (Index l = 0; l < m_num_links; ++l) {
      if (!intact[l] || !crosses(links(l, 0), links(l, 1))) continue;
      intact[l] = 0;
      ++change.links_cut;
      m_broken_links.push_back(l);  // at most |L| per event: within the capacity refresh() made
    }
    const auto tets = model.tetrahedra();
    auto tet_intact = model.tetrahedron_intact();
    for (Index t = 0; t < m_num_tetrahedra; ++t) {
      if (!tet_intact[t]) continue;
      if (m_outcode[std::size_t(tets(t, 0))] & m_outcode[std::size_t(tets(t, 1))] &
          m_outcode[std::size_t(tets(t, 2))] & m_outcode[std::size_t(tets(t, 3))])
        continue;  // all four on one outside side
      bool cut = false;
      for (int a = 0; a < 4 && !cut; ++a)
        for (int b = a + 1; b < 4 && !cut; ++b) cut = crosses(tets(t, a), tets(t, b));
      if (!cut) continue;
      tet_intact[t] = 0;
      ++change.tetrahedra_cut;
      m_removed_tetrahedra.push_back(t);  // at most |T| per event: within the capacity
    }
    return change;
  }

  /// @brief Breaks every intact link stretched past its tear strain at the model's positions, and
  /// removes the intact tetrahedra that share it. Clears the lists first. No allocation.
  TopologyChange tear(SphereModel<Scalar>& model) noexcept {
    TopologyChange change;
    clear_events();
    if (!m_tears || !sized_for(model)) return change;
    const auto x = model.positions();
    const auto links = model.links();
    auto intact = model.link_intact();
    auto tet_intact = model.tetrahedron_intact();
    for (std::size_t k = 0; k < m_tearable.size(); ++k) {
      const Index l = m_tearable[k];
      if (!intact[l]) continue;
      const Scalar* p = x.data() + 3 * std::ptrdiff_t(links(l, 0));
      const Scalar* q = x.data() + 3 * std::ptrdiff_t(links(l, 1));
      const Scalar dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
      if (!(dx * dx + dy * dy + dz * dz > m_tear_length2[k])) continue;
      intact[l] = 0;
      ++change.links_torn;
      m_broken_links.push_back(l);
      for (Index j = m_link_tet_start[std::size_t(l)]; j < m_link_tet_start[std::size_t(l) + 1];
           ++j) {
        const Index t = m_link_tets[std::size_t(j)];
        if (!tet_intact[t]) continue;
        tet_intact[t] = 0;
        ++change.tetrahedra_torn;
        m_removed_tetrahedra.push_back(t);
      }
    }
    return change;
  }

  /// @brief The links broken, and the tetrahedra removed, by the last cut() or tear(), in index
  /// order.
  [[nodiscard]] const std::vector<Index>& broken_links() const noexcept { return m_broken_links; }
  [[nodiscard]] const std::vector<Index>& removed_tetrahedra() const noexcept {
    return m_removed_tetrahedra;
  }
  void clear_events() noexcept {
    m_broken_links.clear();
    m_removed_tetrahedra.clear();
  }
  /// @brief The tetrahedra that have link l as an edge.
  [[nodiscard]] std::pair<const Index*, const Index*> tetrahedra_at_link(Index l) const noexcept {
    const Index* base = m_link_tets.data();
    return {base + m_link_tet_start[std::size_t(l)], base + m_link_tet_start[std::size_t(l) + 1]};
  }

 private:
  // The links that can tear, and the squared length past which each does.
  void update_tearable(const SphereModel<Scalar>& model) {
    m_tearable.clear();
    m_tear_length2.clear();
    const auto l0 = model.rest_lengths();
    for (Index l = 0; l < m_num_links; ++l) {
      if (!(m_tear[l] < std::numeric_limits<Scalar>::infinity())) continue;
      const Scalar limit = l0[l] * (Scalar(1) + m_tear[l]);
      m_tearable.push_back(l);
      m_tear_length2.push_back(limit * limit);
    }
    m_tears = !m_tearable.empty();
  }

  // Whether a and b (one piece until now) are still joined; if not, the side whose search ran out
  // first becomes a new piece. Two breadth-first fronts, expanded one node each in turn. Returns
  // 0 (joined), 1 (a's side became a new piece) or 2 (b's side did).
  int split(const SphereModel<Scalar>& model, const std::vector<std::uint8_t>& force_link, Index a,
            Index b) noexcept {
    if (a == b || m_label[std::size_t(a)] != m_label[std::size_t(b)]) return 0;
    const std::uint32_t mark_a = next_mark(), mark_b = next_mark();
    std::size_t head_a = 0, head_b = 0, size_a = 1, size_b = 1;
    m_front_a[0] = a;
    m_front_b[0] = b;
    m_seen[std::size_t(a)] = mark_a;
    m_seen[std::size_t(b)] = mark_b;
    // Expands one node of a front; true when it touched the other front.
    auto expand = [&](std::vector<Index>& front, std::size_t& head, std::size_t& size,
                      std::uint32_t mine, std::uint32_t other) {
      return for_each_neighbour(model, force_link, front[head++], [&](Index v) {
        if (m_seen[std::size_t(v)] == other) return true;
        if (m_seen[std::size_t(v)] != mine) {
          m_seen[std::size_t(v)] = mine;
          front[size++] = v;
        }
        return false;
      });
    };
    for (;;) {
      if (head_a == size_a) {
        relabel(model, m_front_a, size_a, m_label[std::size_t(a)]);
        return 1;
      }
      if (expand(m_front_a, head_a, size_a, mark_a, mark_b)) return 0;
      if (head_b == size_b) {
        relabel(model, m_front_b, size_b, m_label[std::size_t(b)]);
        return 2;
      }
      if (expand(m_front_b, head_b, size_b, mark_b, mark_a)) return 0;
    }
  }
  // A fresh mark for m_seen (the marks of earlier searches then mean nothing).
  std::uint32_t next_mark() noexcept {
    if (m_generation == std::numeric_limits<std::uint32_t>::max()) {
      std::fill(m_seen.begin(), m_seen.end(), std::uint32_t(0));
      m_generation = 0;
    }
    return ++m_generation;
  }
  // Calls visit(v) for each node v joined to u (by a link that carries force or an intact
  // continuum tetrahedron) until it returns true; returns whether it did.
  template <typename Visit>
  bool for_each_neighbour(const SphereModel<Scalar>& model,
                          const std::vector<std::uint8_t>& force_link, Index u,
                          Visit visit) const noexcept {
    const auto links = model.links();
    for (Index k = m_node_link_start[std::size_t(u)]; k < m_node_link_start[std::size_t(u) + 1];
         ++k) {
      const Index l = m_node_links[std::size_t(k)];
      if (force_link[std::size_t(l)] && visit(links(l, 0) == u ? links(l, 1) : links(l, 0)))
        return true;
    }
    const auto tets = model.tetrahedra();
    const auto intact = model.tetrahedron_intact();
    for (Index k = m_node_tet_start[std::size_t(u)]; k < m_node_tet_start[std::size_t(u) + 1];
         ++k) {
      const Index t = m_node_tets[std::size_t(k)];
      if (!intact[t]) continue;
      for (int c = 0; c < 4; ++c)
        if (tets(t, c) != u && visit(tets(t, c))) return true;
    }
    return false;
  }
  // The first `size` nodes of `front` leave piece `old` for a new one.
  void relabel(const SphereModel<Scalar>& model, const std::vector<Index>& front, std::size_t size,
               Index old) noexcept {
    if (std::size_t(m_next_label) >= m_label_fixed.size()) return;  // cannot happen: < n splits
    const Index label = m_next_label++;
    const auto fixed = model.fixed();
    Index held = 0;
    for (std::size_t k = 0; k < size; ++k) {
      m_label[std::size_t(front[k])] = label;
      held += fixed[front[k]];
    }
    const bool old_loose = m_label_fixed[std::size_t(old)] == 0;
    m_label_fixed[std::size_t(old)] -= held;
    m_label_fixed[std::size_t(label)] = held;
    ++m_pieces;
    m_loose += Index(held == 0) + Index(!old_loose && m_label_fixed[std::size_t(old)] == 0);
  }

  [[nodiscard]] bool sized_for(const SphereModel<Scalar>& model) const noexcept {
    return model.num_links() == m_num_links && model.num_tetrahedra() == m_num_tetrahedra;
  }

  Index m_num_links{0}, m_num_tetrahedra{0};
  ScalarArray<Scalar> m_tear;
  bool m_tears{false};
  std::vector<Index> m_tearable;       // links with a finite tear strain, in index order
  std::vector<Scalar> m_tear_length2;  // per tearable link: (l0 (1 + tear strain))^2
  std::vector<Index> m_link_tet_start, m_link_tets;
  // Refilled by events within the capacity refresh() reserved (a copy keeps it).
  detail::ReservedVector<Index> m_broken_links, m_removed_tetrahedra;
  // The pieces: a label per node, fixed nodes per label, the counts; the nodes' links and
  // continuum tetrahedra and the two fronts of update_pieces()' searches.
  std::vector<Index> m_label, m_label_fixed;
  std::vector<Index> m_anchor;              // per label: a node known to be in it (update_pieces)
  detail::ReservedVector<Index> m_touched;  // the labels update_pieces() gave an anchor
  Index m_pieces{0}, m_loose{0}, m_next_label{0};
  bool m_labelled{false};
  std::vector<Index> m_node_link_start, m_node_links, m_node_tet_start, m_node_tets;
  std::vector<Index> m_front_a, m_front_b;
  std::vector<std::uint32_t> m_seen;
  std::uint32_t m_generation{0};
  std::vector<std::uint8_t> m_outcode;        // per node: its side of the blade's box (cut)
  std::vector<std::uint8_t> m_tet_continuum;  // per tetrahedron: in a continuum region
};

}  // namespace fsm
