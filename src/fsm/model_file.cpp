#include "fsm/model_file.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <string_view>
#include <type_traits>
#include <utility>

// Byte-level layout, versioning policy and error meanings: docs/model_file.md. Keep them in step.

namespace fsm {

namespace {

// --- Constants of format versions 1 to 3
// ---------------------------------------------------------

// PNG-style: a non-ASCII first byte catches 7-bit transfers, CR LF catches newline conversion,
// 0x1A stops a DOS `type`.
constexpr std::array<unsigned char, 8> k_magic{0x89, 'F', 'S', 'M', '\r', '\n', 0x1A, '\n'};
constexpr std::size_t k_magic_size = 8;
constexpr std::size_t k_version_end = 12;          // magic + version: fixed in every format version
constexpr std::size_t k_header_size = 32;          // version 1's header
constexpr std::size_t k_header_crc_at = 28;        // the header CRC covers bytes [0, 28)
constexpr std::size_t k_section_header_size = 12;  // tag (4) + length (8)
// Flag bits 0-15 name features a reader must understand; bits 16-31 are hints it may ignore.
constexpr std::uint32_t k_required_flags = 0x0000FFFFu;
constexpr std::uint32_t k_max_count = std::numeric_limits<std::uint32_t>::max();
constexpr std::uint32_t k_max_rows = static_cast<std::uint32_t>(std::numeric_limits<Index>::max());

constexpr std::string_view k_tag_meta = "META";
constexpr std::string_view k_tag_regions = "REGN";
constexpr std::string_view k_tag_nodes = "NODE";
constexpr std::string_view k_tag_links = "LINK";
constexpr std::string_view k_tag_parts = "PART";
constexpr std::string_view k_tag_attachments = "ATCH";
constexpr std::string_view k_tag_skin = "SKIN";
constexpr std::string_view k_tag_tetrahedra = "TETS";  // from version 2
constexpr std::array<std::string_view, 8> k_known_tags{
    k_tag_meta,  k_tag_regions,     k_tag_nodes, k_tag_links,
    k_tag_parts, k_tag_attachments, k_tag_skin,  k_tag_tetrahedra};

// Whether a file of `version` has (and must have) the section `tag`.
bool in_version(std::string_view tag, std::uint32_t version) noexcept {
  return tag != k_tag_tetrahedra || version >= 2;
}

// --- CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, as in zlib, PNG and gzip) -----------

constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[n] = c;
  }
  return table;
}

constexpr std::array<std::uint32_t, 256> k_crc_table = make_crc_table();

std::uint32_t crc32(std::string_view bytes) noexcept {
  std::uint32_t c = 0xFFFFFFFFu;
  for (const char ch : bytes)
    c = k_crc_table[(c ^ static_cast<unsigned char>(ch)) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

// --- Little-endian primitives, byte by byte so the host's byte order never matters ------------

std::uint32_t get_u32(const char* p) noexcept {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(p[k]);
  return v;
}

std::uint64_t get_u64(const char* p) noexcept {
  std::uint64_t v = 0;
  for (int k = 7; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(p[k]);
  return v;
}

void put_u32(char* p, std::uint32_t v) noexcept {
  for (int k = 0; k < 4; ++k) p[k] = static_cast<char>(static_cast<unsigned char>(v >> (8 * k)));
}

void put_u64(char* p, std::uint64_t v) noexcept {
  for (int k = 0; k < 8; ++k) p[k] = static_cast<char>(static_cast<unsigned char>(v >> (8 * k)));
}

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08X", static_cast<unsigned>(v));
  return buf;
}

// A tag for messages: printable ASCII as is, anything else as \xNN.
std::string printable_tag(std::string_view tag) {
  std::string s;
  for (const char ch : tag) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7F && c != '\\' && c != '\'') {
      s += ch;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", static_cast<unsigned>(c));
      s += buf;
    }
  }
  return s;
}

std::string section_part(std::string_view tag) {
  return "section '" + printable_tag(tag) + "'";
}

// Bytes per stored element of each array element type.
template <typename T>
constexpr std::size_t encoded_size() {
  if constexpr (std::is_same_v<T, double>) {
    return 8;
  } else if constexpr (std::is_same_v<T, std::int32_t>) {
    return 4;
  } else {
    static_assert(std::is_same_v<T, std::uint8_t>, "arrays hold f64, i32 or u8");
    return 1;
  }
}

// --- Writer ------------------------------------------------------------------------------------

class Writer {
 public:
  void u8(std::uint8_t v) { m_out.push_back(static_cast<char>(v)); }
  void u32(std::uint32_t v) {
    char b[4];
    put_u32(b, v);
    m_out.append(b, 4);
  }
  void u64(std::uint64_t v) {
    char b[8];
    put_u64(b, v);
    m_out.append(b, 8);
  }
  void i32(std::int32_t v) { u32(static_cast<std::uint32_t>(v)); }
  void f64(double v) {
    static_assert(sizeof(double) == 8 && std::numeric_limits<double>::is_iec559,
                  "the file stores IEEE 754 binary64");
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    u64(bits);
  }
  void count(std::size_t n, const std::string& what) {
    if (n > k_max_count) throw Error("", what, "too large for the model file (over 2^32 - 1)");
    u32(static_cast<std::uint32_t>(n));
  }
  void string(const std::string& s, const std::string& what) {
    count(s.size(), what);
    m_out.append(s);
  }

  /// Array: u32 rows, u32 cols, then the elements row by row.
  template <typename Derived>
  void matrix(const Eigen::DenseBase<Derived>& m, const std::string& what) {
    using T = typename Derived::Scalar;
    count(std::size_t(m.rows()), what);
    count(std::size_t(m.cols()), what);
    m_out.reserve(m_out.size() + std::size_t(m.size()) * encoded_size<T>());
    for (Eigen::Index r = 0; r < m.rows(); ++r)
      for (Eigen::Index c = 0; c < m.cols(); ++c) element(m.derived().coeff(r, c));
  }

  /// Starts a section; returns where its length goes, for end_section().
  std::size_t begin_section(std::string_view tag) {
    m_out.append(tag.data(), 4);
    const std::size_t at = m_out.size();
    u64(0);
    return at;
  }
  void end_section(std::size_t at) { put_u64(&m_out[at], std::uint64_t(m_out.size() - at - 8)); }

  std::string& bytes() noexcept { return m_out; }

 private:
  template <typename T>
  void element(T v) {
    if constexpr (std::is_same_v<T, double>) {
      f64(v);
    } else if constexpr (std::is_same_v<T, std::int32_t>) {
      i32(v);
    } else {
      static_assert(std::is_same_v<T, std::uint8_t>, "arrays hold f64, i32 or u8");
      u8(v);
    }
  }

  std::string m_out;
};

// --- Reader: never reads past its end, never allocates a size it has not checked ---------------

class Reader {
 public:
  Reader(std::string_view bytes, const std::string& file, std::string part)
      : m_bytes(bytes), m_file(file), m_part(std::move(part)) {}

  [[nodiscard]] std::size_t remaining() const noexcept { return m_bytes.size() - m_pos; }

  /// Throws the truncated error unless n more bytes are there.
  void need(std::uint64_t n, const char* what) const {
    if (n > remaining())
      throw Error(m_file, m_part,
                  "truncated: " + std::string(what) + " needs " + std::to_string(n) +
                      " bytes, only " + std::to_string(remaining()) + " remain");
  }

  std::string_view take(std::size_t n, const char* what) {
    need(n, what);
    const std::string_view s = m_bytes.substr(m_pos, n);
    m_pos += n;
    return s;
  }

  std::uint8_t u8(const char* what) {
    return static_cast<std::uint8_t>(static_cast<unsigned char>(take(1, what)[0]));
  }
  std::uint32_t u32(const char* what) { return get_u32(take(4, what).data()); }
  std::uint64_t u64(const char* what) { return get_u64(take(8, what).data()); }
  std::int32_t i32(const char* what) { return static_cast<std::int32_t>(u32(what)); }
  double f64(const char* what) { return bits_to_double(u64(what)); }

  std::string string(const char* what) {
    const std::uint32_t n = u32(what);
    return std::string(take(n, what));
  }

  /// Reads an array stored by Writer::matrix into `m`, whose column count is fixed at compile
  /// time; the row count must fit an Index.
  template <typename Matrix>
  void matrix(Matrix& m, const char* what) {
    using T = typename Matrix::Scalar;
    static_assert(Matrix::ColsAtCompileTime != Eigen::Dynamic, "columns are fixed by the format");
    constexpr auto want_cols = std::uint32_t(Matrix::ColsAtCompileTime);
    const std::uint32_t rows = u32(what);
    const std::uint32_t cols = u32(what);
    if (cols != want_cols)
      throw malformed(std::string(what) + " has " + std::to_string(cols) + " columns, expected " +
                      std::to_string(want_cols));
    if (rows > k_max_rows)
      throw malformed(std::string(what) + " has " + std::to_string(rows) +
                      " rows, more than an Index can count");
    const std::uint64_t n = std::uint64_t(rows) * cols;
    need(n * encoded_size<T>(), what);  // before any allocation
    m.resize(Eigen::Index(rows), Eigen::Index(cols));
    const char* p = m_bytes.data() + m_pos;
    for (Eigen::Index r = 0; r < m.rows(); ++r)
      for (Eigen::Index c = 0; c < m.cols(); ++c, p += encoded_size<T>()) {
        if constexpr (std::is_same_v<T, double>) {
          m(r, c) = bits_to_double(get_u64(p));
        } else if constexpr (std::is_same_v<T, std::int32_t>) {
          m(r, c) = static_cast<std::int32_t>(get_u32(p));
        } else {
          m(r, c) = static_cast<std::uint8_t>(static_cast<unsigned char>(*p));
        }
      }
    m_pos += std::size_t(n * encoded_size<T>());
  }

  /// A known section must be read to its last byte.
  void finish() const {
    if (remaining() != 0)
      throw malformed(std::to_string(remaining()) + " bytes left over after its last field");
  }

  [[nodiscard]] Error malformed(const std::string& why) const {
    return Error(m_file, m_part, "malformed: " + why);
  }

 private:
  static double bits_to_double(std::uint64_t bits) noexcept {
    double v = 0;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }

  std::string_view m_bytes;
  std::size_t m_pos{0};
  const std::string& m_file;
  std::string m_part;
};

// --- Sections ----------------------------------------------------------------------------------

// The sphere arrays as stored, before the SphereModel is rebuilt from them.
struct StoredNodes {
  Positions<double> positions, velocities, rest_positions;
  ScalarArray<double> masses, radii;
  Eigen::Matrix<Index, Eigen::Dynamic, 1> regions;
  Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1> fixed;
};

struct StoredLinks {
  LinkArray links;
  ScalarArray<double> rest_lengths, stiffness, damping, large_stiffness, switch_strain;
  ScalarArray<double> tear_strain;  // version 4; empty before
};

void write_material(Writer& w, const Material<double>& m) {
  w.f64(m.density);
  w.f64(m.youngs_modulus);
  w.f64(m.viscosity);
  w.f64(m.large_strain_modulus);
  w.f64(m.switch_strain);
  w.f64(m.poisson_ratio);  // version 3
  w.f64(m.tear_strain);    // version 4
}

Material<double> read_material(Reader& r, std::uint32_t version) {
  Material<double> m;
  m.density = r.f64("density");
  m.youngs_modulus = r.f64("youngs_modulus");
  m.viscosity = r.f64("viscosity");
  m.large_strain_modulus = r.f64("large_strain_modulus");
  m.switch_strain = r.f64("switch_strain");
  if (version >= 3) m.poisson_ratio = r.f64("poisson_ratio");
  if (version >= 4) m.tear_strain = r.f64("tear_strain");
  return m;
}

void write_sections(Writer& w, const TissueModel<double>& model) {
  const SphereModel<double>& s = model.spheres;

  std::size_t at = w.begin_section(k_tag_meta);
  w.string(model.name, "name");
  w.string(model.report_json, "report_json");
  w.end_section(at);

  at = w.begin_section(k_tag_regions);
  w.count(s.regions().size(), "regions");
  for (const Region<double>& region : s.regions()) {
    w.string(region.name, "region name");
    write_material(w, region.material);
    w.u8(static_cast<std::uint8_t>(region.law));  // version 3
  }
  w.end_section(at);

  at = w.begin_section(k_tag_nodes);
  w.matrix(s.positions(), "positions");
  w.matrix(s.velocities(), "velocities");
  w.matrix(s.rest_positions(), "rest positions");
  w.matrix(s.masses(), "masses");
  w.matrix(s.radii(), "radii");
  w.matrix(s.node_regions(), "node regions");
  w.matrix(s.fixed(), "fixed flags");
  w.end_section(at);

  at = w.begin_section(k_tag_links);
  w.matrix(s.links(), "links");
  w.matrix(s.rest_lengths(), "rest lengths");
  w.matrix(s.stiffness(), "stiffness");
  w.matrix(s.damping(), "damping");
  w.matrix(s.large_stiffness(), "large stiffness");
  w.matrix(s.switch_strain(), "switch strain");
  w.matrix(s.tear_strain(), "tear strain");  // version 4
  w.end_section(at);

  at = w.begin_section(k_tag_parts);
  w.count(model.parts.size(), "parts");
  for (const Part& p : model.parts) {
    w.string(p.name, "part name");
    w.u8(static_cast<std::uint8_t>(p.topology));
    w.i32(p.region);
    w.f64(p.radius);
    w.i32(p.first_node);
    w.i32(p.num_nodes);
    w.i32(p.first_link);
    w.i32(p.num_links);
    w.i32(p.surface);
    w.i32(p.first_tetrahedron);
    w.i32(p.num_tetrahedra);
  }
  w.end_section(at);

  at = w.begin_section(k_tag_attachments);
  w.i32(model.first_attachment_link);
  w.i32(model.num_attachment_links);
  w.end_section(at);

  const Skin<double>& skin = model.skin;
  at = w.begin_section(k_tag_skin);
  w.matrix(skin.rest.vertices, "skin rest vertices");
  w.matrix(skin.rest.faces, "skin faces");
  w.count(skin.surfaces.size(), "skin surfaces");
  for (const Skin<double>::Surface& f : skin.surfaces) {
    w.string(f.name, "surface name");
    w.i32(f.first_vertex);
    w.i32(f.num_vertices);
    w.i32(f.first_face);
    w.i32(f.num_faces);
  }
  w.matrix(skin.kind, "skin kinds");
  w.matrix(skin.nodes, "skin nodes");
  w.matrix(skin.weights, "skin weights");
  w.matrix(skin.offsets, "skin offsets");
  w.matrix(skin.chain_nodes, "chain nodes");
  w.matrix(skin.chain_rest_tangents, "chain rest tangents");
  w.end_section(at);

  at = w.begin_section(k_tag_tetrahedra);
  w.matrix(s.tetrahedra(), "tetrahedra");
  w.end_section(at);
}

void read_meta(Reader& r, TissueModel<double>& model) {
  model.name = r.string("name");
  model.report_json = r.string("report_json");
}

std::vector<Region<double>> read_regions(Reader& r, std::uint32_t version) {
  std::vector<Region<double>> regions;
  const std::uint32_t n = r.u32("region count");
  // No reserve: each region takes at least 44 bytes, so the loop ends with the bytes.
  for (std::uint32_t k = 0; k < n; ++k) {
    Region<double> region;
    region.name = r.string("region name");
    region.material = read_material(r, version);
    if (version >= 3) {
      const std::uint8_t law = r.u8("force law");
      if (law > static_cast<std::uint8_t>(ForceLaw::continuum))
        throw r.malformed("region '" + region.name + "' has unknown force law " +
                          std::to_string(law));
      region.law = static_cast<ForceLaw>(law);
    }
    regions.push_back(std::move(region));
  }
  return regions;
}

StoredNodes read_nodes(Reader& r) {
  StoredNodes n;
  r.matrix(n.positions, "positions");
  r.matrix(n.velocities, "velocities");
  r.matrix(n.rest_positions, "rest positions");
  r.matrix(n.masses, "masses");
  r.matrix(n.radii, "radii");
  r.matrix(n.regions, "node regions");
  r.matrix(n.fixed, "fixed flags");
  const Eigen::Index count = n.rest_positions.rows();
  const std::pair<const char*, Eigen::Index> rows[] = {
      {"positions", n.positions.rows()},  {"velocities", n.velocities.rows()},
      {"masses", n.masses.rows()},        {"radii", n.radii.rows()},
      {"node regions", n.regions.rows()}, {"fixed flags", n.fixed.rows()}};
  for (const auto& [what, got] : rows)
    if (got != count)
      throw r.malformed(std::string(what) + " has " + std::to_string(got) +
                        " rows, rest positions " + std::to_string(count));
  return n;
}

StoredLinks read_links(Reader& r, std::uint32_t version) {
  StoredLinks l;
  r.matrix(l.links, "links");
  r.matrix(l.rest_lengths, "rest lengths");
  r.matrix(l.stiffness, "stiffness");
  r.matrix(l.damping, "damping");
  r.matrix(l.large_stiffness, "large stiffness");
  r.matrix(l.switch_strain, "switch strain");
  if (version >= 4) r.matrix(l.tear_strain, "tear strain");
  const Eigen::Index count = l.links.rows();
  if (version < 4) l.tear_strain.setConstant(count, std::numeric_limits<double>::infinity());
  const std::pair<const char*, Eigen::Index> rows[] = {
      {"rest lengths", l.rest_lengths.rows()},
      {"stiffness", l.stiffness.rows()},
      {"damping", l.damping.rows()},
      {"large stiffness", l.large_stiffness.rows()},
      {"switch strain", l.switch_strain.rows()},
      {"tear strain", l.tear_strain.rows()}};
  for (const auto& [what, got] : rows)
    if (got != count)
      throw r.malformed(std::string(what) + " has " + std::to_string(got) + " rows, links " +
                        std::to_string(count));
  return l;
}

std::vector<Part> read_parts(Reader& r, std::uint32_t version) {
  std::vector<Part> parts;
  const std::uint32_t n = r.u32("part count");
  for (std::uint32_t k = 0; k < n; ++k) {
    Part p;
    p.name = r.string("part name");
    const std::uint8_t topology = r.u8("topology");
    if (topology > static_cast<std::uint8_t>(Topology::packing))
      throw r.malformed("part '" + p.name + "' has unknown topology " + std::to_string(topology));
    p.topology = static_cast<Topology>(topology);
    p.region = r.i32("part region");
    p.radius = r.f64("part radius");
    p.first_node = r.i32("first node");
    p.num_nodes = r.i32("node count");
    p.first_link = r.i32("first link");
    p.num_links = r.i32("link count");
    p.surface = r.i32("surface");
    if (version >= 2) {
      p.first_tetrahedron = r.i32("first tetrahedron");
      p.num_tetrahedra = r.i32("tetrahedron count");
    }
    parts.push_back(std::move(p));
  }
  return parts;
}

void read_attachments(Reader& r, TissueModel<double>& model) {
  model.first_attachment_link = r.i32("first attachment link");
  model.num_attachment_links = r.i32("attachment link count");
}

void read_skin(Reader& r, Skin<double>& skin) {
  r.matrix(skin.rest.vertices, "skin rest vertices");
  r.matrix(skin.rest.faces, "skin faces");
  const std::uint32_t n = r.u32("surface count");
  for (std::uint32_t k = 0; k < n; ++k) {
    Skin<double>::Surface f;
    f.name = r.string("surface name");
    f.first_vertex = r.i32("first vertex");
    f.num_vertices = r.i32("vertex count");
    f.first_face = r.i32("first face");
    f.num_faces = r.i32("face count");
    skin.surfaces.push_back(std::move(f));
  }
  r.matrix(skin.kind, "skin kinds");
  r.matrix(skin.nodes, "skin nodes");
  r.matrix(skin.weights, "skin weights");
  r.matrix(skin.offsets, "skin offsets");
  r.matrix(skin.chain_nodes, "chain nodes");
  r.matrix(skin.chain_rest_tangents, "chain rest tangents");
}

// Rebuilds the SphereModel through its public API, so its invariants hold and every value is
// checked as add_region / add_node / add_link check it. Throws fsm::Error without a file name.
SphereModel<double> rebuild_spheres(const std::vector<Region<double>>& regions,
                                    const StoredNodes& n, const StoredLinks& l,
                                    const TetrahedronArray& tets) {
  SphereModel<double> s;
  for (const Region<double>& region : regions)
    s.add_region(region.name, region.material, region.law);
  const auto num_nodes = Index(n.rest_positions.rows());
  const auto num_links = Index(l.links.rows());
  s.reserve(num_nodes, num_links);
  for (Index i = 0; i < num_nodes; ++i)
    s.add_node(n.rest_positions.row(i).transpose(), n.radii[i], n.masses[i], n.regions[i]);
  for (Index i = 0; i < num_nodes; ++i) {
    if (n.fixed[i] <= 1) {
      s.set_fixed(i, n.fixed[i] == 1);
    } else {
      s.fixed()[i] = n.fixed[i];  // left for validate() to refuse with its own message
    }
  }
  // After set_fixed(), which zeroes a fixed node's velocity: the file's values are the truth.
  s.positions() = n.positions;
  s.velocities() = n.velocities;
  for (Index k = 0; k < num_links; ++k)
    s.add_link(l.links(k, 0), l.links(k, 1),
               VoigtLink<double>{l.rest_lengths[k], l.stiffness[k], l.damping[k],
                                 l.large_stiffness[k], l.switch_strain[k]});
  s.tear_strain() = l.tear_strain;  // checked with the rest by the model's validate()
  for (Index t = 0; t < Index(tets.rows()); ++t)
    s.add_tetrahedron(tets(t, 0), tets(t, 1), tets(t, 2), tets(t, 3));
  return s;
}

TissueModel<double> parse(std::string_view bytes, const std::string& file) {
  // 1. What kind of file: magic, then the version, whose place never changes.
  if (bytes.empty()) throw Error(file, "", "empty file (0 bytes); not a model file");
  const std::size_t magic_seen = std::min(bytes.size(), k_magic_size);
  if (std::memcmp(bytes.data(), k_magic.data(), magic_seen) != 0)
    throw Error(file, "", "not an fsm model file (bad magic bytes)");
  const auto truncated_header = [&] {
    return Error(file, "header",
                 "truncated: the header needs " + std::to_string(k_header_size) +
                     " bytes, the file has " + std::to_string(bytes.size()));
  };
  if (bytes.size() < k_version_end) throw truncated_header();
  const std::uint32_t version = get_u32(bytes.data() + k_magic_size);
  if (version == 0) throw Error(file, "header", "corrupt: format version 0 does not exist");
  if (version > model_file_version)
    throw Error(file, "",
                "model file version " + std::to_string(version) + " is newer than this runtime (" +
                    std::to_string(model_file_version) + ")");

  // 2. The rest of the header (the same in versions 1 and 2).
  if (bytes.size() < k_header_size) throw truncated_header();
  const std::uint32_t header_crc = get_u32(bytes.data() + k_header_crc_at);
  const std::uint32_t header_crc_now = crc32(bytes.substr(0, k_header_crc_at));
  if (header_crc != header_crc_now)
    throw Error(file, "header",
                "corrupt: CRC-32 of the header is " + hex32(header_crc_now) + ", the file says " +
                    hex32(header_crc));
  const std::uint32_t flags = get_u32(bytes.data() + 12);
  if ((flags & k_required_flags) != 0)
    throw Error(file, "header",
                "uses features this runtime does not support (flags " + hex32(flags) + ")");
  const std::uint64_t payload_size = get_u64(bytes.data() + 16);
  const std::uint32_t payload_crc = get_u32(bytes.data() + 24);
  const std::size_t available = bytes.size() - k_header_size;
  if (payload_size > available)
    throw Error(file, "payload",
                "truncated: the header declares " + std::to_string(payload_size) +
                    " payload bytes, the file holds " + std::to_string(available));
  if (payload_size < available)
    throw Error(file, "payload",
                "corrupt: " + std::to_string(available - payload_size) +
                    " unexpected bytes after the payload");
  const std::string_view payload = bytes.substr(k_header_size, std::size_t(payload_size));
  const std::uint32_t payload_crc_now = crc32(payload);
  if (payload_crc != payload_crc_now)
    throw Error(file, "payload",
                "corrupt: CRC-32 of the payload is " + hex32(payload_crc_now) +
                    ", the header says " + hex32(payload_crc));

  // 3. Section framing: known sections once each, unknown ones skipped.
  std::map<std::string_view, std::string_view> sections;
  Reader framing(payload, file, "payload");
  while (framing.remaining() > 0) {
    framing.need(k_section_header_size, "a section header");
    const std::string_view tag = framing.take(4, "a section tag");
    const std::uint64_t length = framing.u64("a section length");
    if (length > framing.remaining())
      throw Error(file, section_part(tag),
                  "truncated: the section declares " + std::to_string(length) + " bytes, only " +
                      std::to_string(framing.remaining()) + " remain in the payload");
    const std::string_view body = framing.take(std::size_t(length), "a section");
    bool known = false;
    for (const std::string_view t : k_known_tags)
      known = known || (t == tag && in_version(t, version));
    if (!known) continue;  // a later version's addition
    if (!sections.emplace(tag, body).second)
      throw Error(file, section_part(tag), "malformed: the section appears twice");
  }
  for (const std::string_view t : k_known_tags)
    if (in_version(t, version) && sections.find(t) == sections.end())
      throw Error(file, section_part(t), "malformed: the section is missing");

  // 4. Section contents.
  TissueModel<double> model;
  auto section = [&](std::string_view tag, auto&& read) {
    Reader r(sections.at(tag), file, section_part(tag));
    read(r);
    r.finish();
  };
  std::vector<Region<double>> regions;
  StoredNodes nodes;
  StoredLinks links;
  TetrahedronArray tets(0, 4);
  section(k_tag_meta, [&](Reader& r) { read_meta(r, model); });
  section(k_tag_regions, [&](Reader& r) { regions = read_regions(r, version); });
  section(k_tag_nodes, [&](Reader& r) { nodes = read_nodes(r); });
  section(k_tag_links, [&](Reader& r) { links = read_links(r, version); });
  section(k_tag_parts, [&](Reader& r) { model.parts = read_parts(r, version); });
  section(k_tag_attachments, [&](Reader& r) { read_attachments(r, model); });
  section(k_tag_skin, [&](Reader& r) { read_skin(r, model.skin); });
  if (version >= 2) section(k_tag_tetrahedra, [&](Reader& r) { r.matrix(tets, "tetrahedra"); });

  // 5. The model itself, checked as any model is; the checker's message names the file.
  try {
    model.spheres = rebuild_spheres(regions, nodes, links, tets);
    model.validate();
  } catch (const Error& e) {
    throw Error(file, e.part(), e.reason());
  }
  return model;
}

}  // namespace

std::string serialize_model(const TissueModel<double>& model) {
  model.validate();
  Writer w;
  w.bytes().assign(k_header_size, '\0');
  write_sections(w, model);
  std::string& out = w.bytes();
  const std::string_view payload = std::string_view(out).substr(k_header_size);
  std::memcpy(&out[0], k_magic.data(), k_magic_size);
  put_u32(&out[8], model_file_version);
  put_u32(&out[12], 0);  // flags: none defined
  put_u64(&out[16], std::uint64_t(payload.size()));
  put_u32(&out[24], crc32(payload));
  put_u32(&out[k_header_crc_at], crc32(std::string_view(out).substr(0, k_header_crc_at)));
  return out;
}

TissueModel<double> deserialize_model(const std::string& bytes, const std::string& file) {
  return parse(bytes, file);
}

void save_model(const std::string& path, const TissueModel<double>& model) {
  std::string bytes;
  try {
    bytes = serialize_model(model);
  } catch (const Error& e) {
    throw Error(path, e.part(), e.reason());
  }
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr)
    throw Error(path, "", std::string("cannot open for writing: ") + std::strerror(errno));
  const std::size_t written = std::fwrite(bytes.data(), 1, bytes.size(), f);
  const int write_errno = errno;
  const bool write_ok = written == bytes.size();
  const bool close_ok = std::fclose(f) == 0;
  const int close_errno = errno;
  if (!write_ok || !close_ok) {
    std::remove(path.c_str());  // a partial file would only be refused later as truncated
    throw Error(
        path, "",
        std::string("cannot write: ") + std::strerror(write_ok ? close_errno : write_errno));
  }
}

TissueModel<double> load_model(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr)
    throw Error(path, "", std::string("cannot open for reading: ") + std::strerror(errno));
  std::string bytes;
  char buffer[1 << 14];
  std::size_t got = 0;
  while ((got = std::fread(buffer, 1, sizeof buffer, f)) > 0) bytes.append(buffer, got);
  const bool read_error = std::ferror(f) != 0;
  const int read_errno = errno;
  std::fclose(f);
  if (read_error) throw Error(path, "", std::string("cannot read: ") + std::strerror(read_errno));
  return parse(bytes, path);
}

}  // namespace fsm
