// The model file: an exact round trip, and a clear fsm::Error (never a crash, a hang or a huge
// allocation) for every kind of bad file. The tests patch bytes through their own reading of the
// layout in docs/model_file.md and their own bitwise CRC-32, so they check the documented format,
// not the implementation against itself.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "common.hpp"
#include "fsm/fsm.hpp"

namespace fsm {
namespace {

constexpr std::size_t k_header = 32;  // docs/model_file.md: the version 1 header

// --- Independent helpers: little-endian fields, a bitwise CRC-32, the section list ------------

std::uint32_t reference_crc32(const std::string& bytes, std::size_t begin, std::size_t end) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = begin; i < end; ++i) {
    c ^= static_cast<unsigned char>(bytes[i]);
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

std::uint64_t get_le(const std::string& b, std::size_t at, int n) {
  std::uint64_t v = 0;
  for (int k = n - 1; k >= 0; --k)
    v = (v << 8) | static_cast<unsigned char>(b[at + std::size_t(k)]);
  return v;
}

void put_le(std::string& b, std::size_t at, std::uint64_t v, int n) {
  for (int k = 0; k < n; ++k)
    b[at + std::size_t(k)] = static_cast<char>(static_cast<unsigned char>(v >> (8 * k)));
}

/// Makes the header agree with the payload again: length, payload CRC, header CRC.
void refresh_header(std::string& b) {
  put_le(b, 16, b.size() - k_header, 8);
  put_le(b, 24, reference_crc32(b, k_header, b.size()), 4);
  put_le(b, 28, reference_crc32(b, 0, 28), 4);
}

struct Section {
  std::string tag;
  std::size_t header;  ///< Offset of the tag in the file.
  std::size_t body;    ///< Offset of the first byte after the length.
  std::size_t length;
};

std::vector<Section> sections(const std::string& b) {
  std::vector<Section> out;
  std::size_t at = k_header;
  while (at < b.size()) {
    Section s{b.substr(at, 4), at, at + 12, std::size_t(get_le(b, at + 4, 8))};
    out.push_back(s);
    at = s.body + s.length;
  }
  EXPECT_EQ(at, b.size()) << "sections do not tile the payload";
  return out;
}

Section section(const std::string& b, const std::string& tag) {
  for (const Section& s : sections(b))
    if (s.tag == tag) return s;
  ADD_FAILURE() << "no section " << tag;
  return {};
}

/// The fsm::Error that f throws; a test failure if it throws none.
template <typename F>
Error error_from(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "no fsm::Error was thrown";
  return Error("no error");
}

bool starts_with(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

std::string temp_path(const std::string& stem) {
  static std::random_device rd;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return ::testing::TempDir() + "fsm_model_file_" + info->name() + "_" + stem + "_" +
         std::to_string(rd()) + ".fsm";
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// --- Bit-for-bit comparison ----------------------------------------------------------------

template <typename T>
bool same_bits(const T& a, const T& b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

template <typename A, typename B>
::testing::AssertionResult same_array(const Eigen::DenseBase<A>& a, const Eigen::DenseBase<B>& b) {
  static_assert(std::is_same_v<typename A::Scalar, typename B::Scalar>, "same element type");
  if (a.rows() != b.rows() || a.cols() != b.cols())
    return ::testing::AssertionFailure()
           << "shape " << a.rows() << "x" << a.cols() << " vs " << b.rows() << "x" << b.cols();
  for (Eigen::Index r = 0; r < a.rows(); ++r)
    for (Eigen::Index c = 0; c < a.cols(); ++c) {
      const auto x = a.derived().coeff(r, c), y = b.derived().coeff(r, c);
      if (!same_bits(x, y))
        return ::testing::AssertionFailure()
               << "entry (" << r << ", " << c << ") differs: " << +x << " vs " << +y;
    }
  return ::testing::AssertionSuccess();
}

void expect_same_material(const Material<double>& a, const Material<double>& b,
                          const std::string& what) {
  EXPECT_TRUE(same_bits(a.density, b.density)) << what;
  EXPECT_TRUE(same_bits(a.youngs_modulus, b.youngs_modulus)) << what;
  EXPECT_TRUE(same_bits(a.viscosity, b.viscosity)) << what;
  EXPECT_TRUE(same_bits(a.large_strain_modulus, b.large_strain_modulus)) << what;
  EXPECT_TRUE(same_bits(a.switch_strain, b.switch_strain)) << what;
  EXPECT_TRUE(same_bits(a.poisson_ratio, b.poisson_ratio)) << what;
  EXPECT_TRUE(same_bits(a.tear_strain, b.tear_strain)) << what;
}

/// Every field of two models: strings and enums equal, arrays bit for bit (the tetrahedra unless
/// told not to: a version 1 file has none).
void expect_identical(const TissueModel<double>& a, const TissueModel<double>& b,
                      bool compare_tetrahedra = true) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.report_json, b.report_json);
  const SphereModel<double>& s = a.spheres;
  const SphereModel<double>& t = b.spheres;
  ASSERT_EQ(s.num_regions(), t.num_regions());
  for (Index r = 0; r < s.num_regions(); ++r) {
    EXPECT_EQ(s.region(r).name, t.region(r).name);
    expect_same_material(s.region(r).material, t.region(r).material, s.region(r).name);
    EXPECT_EQ(s.region(r).law, t.region(r).law) << s.region(r).name;
  }
  EXPECT_TRUE(same_array(s.positions(), t.positions())) << "positions";
  EXPECT_TRUE(same_array(s.velocities(), t.velocities())) << "velocities";
  EXPECT_TRUE(same_array(s.rest_positions(), t.rest_positions())) << "rest positions";
  EXPECT_TRUE(same_array(s.masses(), t.masses())) << "masses";
  EXPECT_TRUE(same_array(s.radii(), t.radii())) << "radii";
  EXPECT_TRUE(same_array(s.node_regions(), t.node_regions())) << "node regions";
  EXPECT_TRUE(same_array(s.fixed(), t.fixed())) << "fixed";
  EXPECT_TRUE(same_array(s.links(), t.links())) << "links";
  EXPECT_TRUE(same_array(s.rest_lengths(), t.rest_lengths())) << "rest lengths";
  EXPECT_TRUE(same_array(s.stiffness(), t.stiffness())) << "stiffness";
  EXPECT_TRUE(same_array(s.damping(), t.damping())) << "damping";
  EXPECT_TRUE(same_array(s.large_stiffness(), t.large_stiffness())) << "large stiffness";
  EXPECT_TRUE(same_array(s.switch_strain(), t.switch_strain())) << "switch strain";
  EXPECT_TRUE(same_array(s.tear_strain(), t.tear_strain())) << "tear strain";

  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (std::size_t k = 0; k < a.parts.size(); ++k) {
    const Part& p = a.parts[k];
    const Part& q = b.parts[k];
    EXPECT_EQ(p.name, q.name);
    EXPECT_EQ(p.topology, q.topology) << p.name;
    EXPECT_EQ(p.region, q.region) << p.name;
    EXPECT_TRUE(same_bits(p.radius, q.radius)) << p.name;
    EXPECT_EQ(p.first_node, q.first_node) << p.name;
    EXPECT_EQ(p.num_nodes, q.num_nodes) << p.name;
    EXPECT_EQ(p.first_link, q.first_link) << p.name;
    EXPECT_EQ(p.num_links, q.num_links) << p.name;
    EXPECT_EQ(p.surface, q.surface) << p.name;
    EXPECT_EQ(p.first_tetrahedron, q.first_tetrahedron) << p.name;
    EXPECT_EQ(p.num_tetrahedra, q.num_tetrahedra) << p.name;
  }
  if (compare_tetrahedra) {
    EXPECT_TRUE(same_array(s.tetrahedra(), t.tetrahedra())) << "tetrahedra";
  }
  EXPECT_EQ(a.first_attachment_link, b.first_attachment_link);
  EXPECT_EQ(a.num_attachment_links, b.num_attachment_links);

  const Skin<double>& u = a.skin;
  const Skin<double>& v = b.skin;
  EXPECT_TRUE(same_array(u.rest.vertices, v.rest.vertices)) << "skin rest vertices";
  EXPECT_TRUE(same_array(u.rest.faces, v.rest.faces)) << "skin faces";
  ASSERT_EQ(u.surfaces.size(), v.surfaces.size());
  for (std::size_t k = 0; k < u.surfaces.size(); ++k) {
    EXPECT_EQ(u.surfaces[k].name, v.surfaces[k].name);
    EXPECT_EQ(u.surfaces[k].first_vertex, v.surfaces[k].first_vertex);
    EXPECT_EQ(u.surfaces[k].num_vertices, v.surfaces[k].num_vertices);
    EXPECT_EQ(u.surfaces[k].first_face, v.surfaces[k].first_face);
    EXPECT_EQ(u.surfaces[k].num_faces, v.surfaces[k].num_faces);
  }
  EXPECT_TRUE(same_array(u.kind, v.kind)) << "skin kinds";
  EXPECT_TRUE(same_array(u.nodes, v.nodes)) << "skin nodes";
  EXPECT_TRUE(same_array(u.weights, v.weights)) << "skin weights";
  EXPECT_TRUE(same_array(u.offsets, v.offsets)) << "skin offsets";
  EXPECT_TRUE(same_array(u.chain_nodes, v.chain_nodes)) << "chain nodes";
  EXPECT_TRUE(same_array(u.chain_rest_tangents, v.chain_rest_tangents)) << "chain tangents";
}

// --- The test model ------------------------------------------------------------------------

/// Three filled parts (a linear tetrahedral body, a bilinear tetrahedral part, an axis chain), an
/// empty fourth part, attachment links, fixed nodes, moving nodes, and a skin with barycentric
/// and chain vertices. Values include -0.0, a subnormal and +infinity.
TissueModel<double> make_model() {
  TissueModel<double> m;
  m.name = "uterus \xC3\xA9prouvette";                                // UTF-8
  static const char report[] = "{\"parts\": 4, \"note\": \"a\0b\"}";  // an embedded NUL
  m.report_json = std::string(report, sizeof report - 1);
  SphereModel<double>& s = m.spheres;

  Material<double> stiff = test::tissue<double>(20000.0, 5.0);
  stiff.large_strain_modulus = 68380.0;
  stiff.switch_strain = 0.1;
  const Index body = s.add_region("body", test::tissue<double>());
  const Index ovary = s.add_region("ovary", stiff);
  const Index tube = s.add_region("tube", test::tissue<double>(9000.0, 2.5));

  const TetrahedralMesh<double> body_mesh =
      make_cube_lattice(Vector3<double>(0, 0, 0), Eigen::Vector3i(3, 2, 2), 0.01);
  const PartRange a = add_tetrahedral_part(s, body_mesh, body, 0.005);
  const PartRange b = add_tetrahedral_part(
      s, make_cube_lattice(Vector3<double>(0.04, 0, 0), Eigen::Vector3i(2, 2, 1), 0.008), ovary,
      0.004);

  // An axis part: a chain of four spheres along -x with rod links.
  const Index chain = s.num_nodes();
  const Index chain_link = s.num_links();
  const double r_tube = 0.003;
  for (int k = 0; k < 4; ++k)
    s.add_node(Vector3<double>(-0.01 - 0.006 * k, 0.005, 0.005), r_tube, 1e-4 * (k + 1), tube);
  for (int k = 0; k < 3; ++k)
    s.add_link(chain + k, chain + k + 1,
               rod_link(s.region(tube).material, 3.141592653589793 * r_tube * r_tube, 0.006));

  // Attachments: body's x = 0.03 face to ovary's x = 0.04 face, and the chain to the body.
  m.first_attachment_link = s.num_links();
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      s.add_link(3 + 4 * (j + 3 * k), b.first_node + 3 * (j + 3 * k), 50.0, 0.01);
  s.add_link(chain, 0, 80.0, 0.0);
  m.num_attachment_links = s.num_links() - m.first_attachment_link;

  for (Index i : {0, 4, 8, chain + 3}) s.set_fixed(i);
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Index i = 0; i < s.num_nodes(); ++i) {
    s.masses()[i] *= 1.0 + 0.5 * u(rng);
    for (int c = 0; c < 3; ++c) {
      s.positions()(i, c) += 1e-4 * u(rng);
      if (!s.fixed()[i]) s.velocities()(i, c) = 0.05 * u(rng);
    }
  }
  s.velocities()(1, 2) = -0.0;
  s.velocities()(2, 0) = std::numeric_limits<double>::denorm_min();

  m.parts.push_back({"body", Topology::tetrahedral, body, 0.005, a.first_node, a.num_nodes,
                     a.first_link, a.num_links, 0, a.first_tetrahedron, a.num_tetrahedra});
  m.parts.push_back({"ovary", Topology::grid, ovary, 0.004, b.first_node, b.num_nodes, b.first_link,
                     b.num_links, -1});
  m.parts.push_back({"tube_left", Topology::axis, tube, r_tube, chain, 4, chain_link, 3, 1});
  m.parts.push_back({"pad", Topology::packing, body, 0.002, 0, 0, 0, 0, -1});

  // Skin: a tetrahedron's surface bound barycentrically to the body's first tetrahedron (one
  // vertex just outside, with a negative weight), and a triangle bound to the chain.
  Skin<double>& skin = m.skin;
  const Index n_skin = 7;
  skin.rest.vertices.resize(n_skin, 3);
  skin.rest.faces.resize(5, 3);
  skin.rest.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3, 4, 5, 6;
  skin.kind.resize(n_skin);
  skin.nodes.resize(n_skin, 4);
  skin.weights.resize(n_skin, 4);
  skin.offsets = Positions<double>::Zero(n_skin, 3);
  const Eigen::Matrix<double, 4, 4> bary =
      (Eigen::Matrix<double, 4, 4>() << 0.7, 0.1, 0.1, 0.1, 0.1, 0.7, 0.1, 0.1, 0.1, 0.1, 0.7, 0.1,
       -0.05, 0.35, 0.35, 0.35)
          .finished();
  for (Index v = 0; v < 4; ++v) {
    skin.kind[v] = std::uint8_t(SkinKind::barycentric);
    skin.nodes.row(v) = body_mesh.tetrahedra.row(0);
    skin.weights.row(v) = bary.row(v);
    skin.rest.vertices.row(v).setZero();
    for (int k = 0; k < 4; ++k)
      skin.rest.vertices.row(v) += bary(v, k) * s.rest_positions().row(skin.nodes(v, k));
  }
  skin.chain_nodes.resize(4, 3);
  skin.chain_rest_tangents.resize(4, 3);
  for (Index k = 0; k < 4; ++k) {
    skin.chain_nodes.row(k) << chain + std::max<Index>(k - 1, 0), chain + k,
        chain + std::min<Index>(k + 1, 3);
    skin.chain_rest_tangents.row(k) << -1.0, 0.0, 0.0;
  }
  const double s_param[3] = {0.25, 0.5, 0.9};
  const Vector3<double> offset[3] = {{0.0, 0.003, 0.0}, {0.0, 0.0, -0.003}, {0.0, 0.002, 0.002}};
  for (Index v = 4; v < n_skin; ++v) {
    const Index k = v - 4;
    const double t = s_param[k];
    skin.kind[v] = std::uint8_t(SkinKind::chain);
    skin.nodes.row(v) << k, k + 1, -1, -1;
    skin.weights.row(v) << 1 - t, t, 0, 0;
    skin.offsets.row(v) = offset[k].transpose();
    skin.rest.vertices.row(v) = (1 - t) * s.rest_positions().row(chain + k) +
                                t * s.rest_positions().row(chain + k + 1) + offset[k].transpose();
  }
  skin.surfaces.push_back({"body_surface", 0, 4, 0, 4});
  skin.surfaces.push_back({"tube_surface", 4, 3, 4, 1});
  return m;
}

class ModelFile : public ::testing::Test {
 protected:
  void SetUp() override {
    m_model = make_model();
    ASSERT_NO_THROW(m_model.validate());
    // What makes the round trip meaningful: linear (infinite switch strain) and bilinear links,
    // fixed and moving nodes, both skin kinds.
    ASSERT_TRUE(m_model.spheres.has_bilinear_links());
    ASSERT_TRUE(std::isinf(m_model.spheres.switch_strain()[0]));
    ASSERT_GT(m_model.spheres.num_fixed(), 0);
    ASSERT_GT(m_model.spheres.velocities().cwiseAbs().maxCoeff(), 0.0);
    m_bytes = serialize_model(m_model);
  }

  TissueModel<double> m_model;
  std::string m_bytes;
};

// --- Layout --------------------------------------------------------------------------------

TEST(ModelFileCrc, ReferenceCrcMatchesTheStandardCheckValue) {
  // The check value of CRC-32/ISO-HDLC (IEEE 802.3, zlib): the test's own CRC is the standard.
  EXPECT_EQ(reference_crc32("123456789", 0, 9), 0xCBF43926u);
}

TEST_F(ModelFile, HeaderFollowsTheDocumentedLayout) {
  const unsigned char magic[8] = {0x89, 'F', 'S', 'M', '\r', '\n', 0x1A, '\n'};
  ASSERT_GT(m_bytes.size(), k_header);
  EXPECT_EQ(std::memcmp(m_bytes.data(), magic, 8), 0);
  EXPECT_EQ(get_le(m_bytes, 8, 4), model_file_version);
  EXPECT_EQ(get_le(m_bytes, 12, 4), 0u);
  EXPECT_EQ(get_le(m_bytes, 16, 8), m_bytes.size() - k_header);
  EXPECT_EQ(get_le(m_bytes, 24, 4), reference_crc32(m_bytes, k_header, m_bytes.size()));
  EXPECT_EQ(get_le(m_bytes, 28, 4), reference_crc32(m_bytes, 0, 28));
  std::vector<std::string> tags;
  for (const Section& s : sections(m_bytes)) tags.push_back(s.tag);
  EXPECT_EQ(tags, (std::vector<std::string>{"META", "REGN", "NODE", "LINK", "PART", "ATCH", "SKIN",
                                            "TETS"}));
  // The tetrahedra (version 2): one |T| x 4 i32 array.
  const Section tets = section(m_bytes, "TETS");
  const auto num_tets = std::uint64_t(m_model.spheres.num_tetrahedra());
  ASSERT_GT(num_tets, 0u);
  EXPECT_EQ(get_le(m_bytes, tets.body, 4), num_tets);
  EXPECT_EQ(get_le(m_bytes, tets.body + 4, 4), 4u);
  EXPECT_EQ(tets.length, 8 + num_tets * 4 * 4);
  // The link section: |L| x 2 i32 rows, then six |L| x 1 f64 arrays.
  const Section link = section(m_bytes, "LINK");
  const auto num_links = std::uint64_t(m_model.spheres.num_links());
  EXPECT_EQ(get_le(m_bytes, link.body, 4), num_links);
  EXPECT_EQ(get_le(m_bytes, link.body + 4, 4), 2u);
  EXPECT_EQ(link.length, (8 + num_links * 2 * 4) + 6 * (8 + num_links * 8));
}

// --- Round trip ----------------------------------------------------------------------------

TEST_F(ModelFile, RoundTripIsBitExact) {
  const TissueModel<double> back = deserialize_model(m_bytes, "mem.fsm");
  expect_identical(m_model, back);
  EXPECT_EQ(serialize_model(back), m_bytes) << "writing the loaded model gives the same bytes";
}

TEST_F(ModelFile, SaveLoadEqualsSerializeDeserialize) {
  const std::string path = temp_path("roundtrip");
  save_model(path, m_model);
  EXPECT_EQ(read_bytes(path), m_bytes);
  const TissueModel<double> from_file = load_model(path);
  const TissueModel<double> from_memory = deserialize_model(m_bytes);
  expect_identical(from_file, from_memory);
  expect_identical(m_model, from_file);
  std::remove(path.c_str());
}

TEST(ModelFileEmpty, DefaultModelRoundTrips) {
  const TissueModel<double> empty;
  const TissueModel<double> back = deserialize_model(serialize_model(empty));
  expect_identical(empty, back);
  EXPECT_EQ(back.spheres.num_nodes(), 0);
}

TEST_F(ModelFile, UnknownSectionsAreSkipped) {
  // A later version's sections: one between known sections, an empty one at the end.
  std::string b = m_bytes;
  const Section regn = section(b, "REGN");
  std::string extra = "XTRA";
  extra.append(8, '\0');
  put_le(extra, 4, 5, 8);
  extra += "hello";
  b.insert(regn.header, extra);
  b += std::string("ZZZZ", 4) + std::string(8, '\0');
  refresh_header(b);
  ASSERT_EQ(sections(b).size(), 10u);
  expect_identical(m_model, deserialize_model(b, "extra.fsm"));
}

// --- Errors --------------------------------------------------------------------------------

TEST(ModelFileErrors, MissingFileNamesTheFile) {
  const std::string path = ::testing::TempDir() + "no_such_dir_fsm/model.fsm";
  const Error e = error_from([&] { (void)load_model(path); });
  EXPECT_EQ(e.file(), path);
  EXPECT_TRUE(starts_with(e.reason(), "cannot open for reading")) << e.what();
}

TEST(ModelFileErrors, EmptyFileIsNotAModel) {
  const std::string path = temp_path("empty");
  write_bytes(path, "");
  const Error e = error_from([&] { (void)load_model(path); });
  EXPECT_EQ(e.file(), path);
  EXPECT_NE(e.reason().find("empty"), std::string::npos) << e.what();
  std::remove(path.c_str());
}

TEST(ModelFileErrors, DirectoryIsUnreadable) {
  const Error e = error_from([&] { (void)load_model(::testing::TempDir()); });
  EXPECT_EQ(e.file(), ::testing::TempDir());
  EXPECT_TRUE(starts_with(e.reason(), "cannot read")) << e.what();
}

TEST(ModelFileErrors, OtherFileHasBadMagic) {
  for (const std::string& text :
       {std::string("solid cube\nfacet normal 0 0 1\n"), std::string("x"), std::string(64, '\0')}) {
    const Error e = error_from([&] { (void)deserialize_model(text, "cube.stl"); });
    EXPECT_EQ(e.file(), "cube.stl");
    EXPECT_EQ(e.reason(), "not an fsm model file (bad magic bytes)");
  }
}

TEST_F(ModelFile, TruncationAtEveryHeaderOffset) {
  for (std::size_t cut = 1; cut < k_header; ++cut) {
    const Error e = error_from([&] { (void)deserialize_model(m_bytes.substr(0, cut), "t.fsm"); });
    EXPECT_TRUE(starts_with(e.reason(), "truncated")) << "cut at " << cut << ": " << e.what();
    EXPECT_EQ(e.file(), "t.fsm");
  }
}

TEST_F(ModelFile, TruncationThroughThePayload) {
  std::vector<std::size_t> cuts;
  for (std::size_t cut = k_header; cut < m_bytes.size(); cut += 37) cuts.push_back(cut);
  for (const Section& s : sections(m_bytes)) {  // at and around every section boundary
    cuts.push_back(s.header);
    cuts.push_back(s.header + 5);
    cuts.push_back(s.body);
    cuts.push_back(s.body + 1);
  }
  cuts.push_back(m_bytes.size() - 1);
  for (const std::size_t cut : cuts) {
    const Error e = error_from([&] { (void)deserialize_model(m_bytes.substr(0, cut), "t.fsm"); });
    EXPECT_TRUE(starts_with(e.reason(), "truncated")) << "cut at " << cut << ": " << e.what();
  }
  // Through the file API too.
  const std::string path = temp_path("truncated");
  write_bytes(path, m_bytes.substr(0, m_bytes.size() / 2));
  const Error e = error_from([&] { (void)load_model(path); });
  EXPECT_EQ(e.file(), path);
  EXPECT_TRUE(starts_with(e.reason(), "truncated")) << e.what();
  std::remove(path.c_str());
}

TEST_F(ModelFile, ByteFlipsInThePayloadAreCorrupt) {
  std::vector<std::size_t> at;
  for (std::size_t i = k_header; i < m_bytes.size(); i += 29) at.push_back(i);
  at.push_back(m_bytes.size() - 1);
  for (const std::size_t i : at)
    for (const unsigned mask : {0x01u, 0x80u, 0xFFu}) {
      std::string b = m_bytes;
      b[i] = static_cast<char>(static_cast<unsigned char>(b[i]) ^ mask);
      const Error e = error_from([&] { (void)deserialize_model(b, "c.fsm"); });
      EXPECT_TRUE(starts_with(e.reason(), "corrupt: CRC-32 of the payload"))
          << "byte " << i << " ^ " << mask << ": " << e.what();
    }
}

TEST_F(ModelFile, ByteFlipsInTheHeaderAreRefused) {
  for (std::size_t i = 0; i < k_header; ++i) {
    std::string b = m_bytes;
    b[i] = static_cast<char>(static_cast<unsigned char>(b[i]) ^ 0x10u);
    const Error e = error_from([&] { (void)deserialize_model(b, "h.fsm"); });
    EXPECT_EQ(e.file(), "h.fsm") << "byte " << i;
  }
  // A stale header CRC alone is reported as such.
  std::string b = m_bytes;
  put_le(b, 28, get_le(b, 28, 4) ^ 1u, 4);
  const Error e = error_from([&] { (void)deserialize_model(b); });
  EXPECT_TRUE(starts_with(e.reason(), "corrupt: CRC-32 of the header")) << e.what();
}

TEST_F(ModelFile, NewerVersionIsRefused) {
  ASSERT_EQ(model_file_version, 4u);
  std::string b = m_bytes;
  put_le(b, 8, 5, 4);
  refresh_header(b);  // a well-formed version 5 file as far as version 4 can tell
  const Error e = error_from([&] { (void)deserialize_model(b, "v5.fsm"); });
  EXPECT_EQ(e.file(), "v5.fsm");
  EXPECT_EQ(e.reason(), "model file version 5 is newer than this runtime (4)");
  // Even a version 5 file too short for a version 4 header: the version is read first.
  const Error short_e = error_from([&] { (void)deserialize_model(b.substr(0, 12), "v5.fsm"); });
  EXPECT_EQ(short_e.reason(), "model file version 5 is newer than this runtime (4)");
}

TEST_F(ModelFile, RequiredFlagsAreRefusedOptionalFlagsIgnored) {
  std::string b = m_bytes;
  put_le(b, 12, 0x00010000u, 4);  // an optional hint
  refresh_header(b);
  expect_identical(m_model, deserialize_model(b));
  put_le(b, 12, 0x00000001u, 4);  // a feature this runtime lacks
  refresh_header(b);
  const Error e = error_from([&] { (void)deserialize_model(b); });
  EXPECT_NE(e.reason().find("does not support"), std::string::npos) << e.what();
}

TEST_F(ModelFile, TrailingBytesAreCorrupt) {
  const Error e = error_from([&] { (void)deserialize_model(m_bytes + "junk"); });
  EXPECT_EQ(e.reason(), "corrupt: 4 unexpected bytes after the payload");
}

TEST_F(ModelFile, MalformedStructureIsNamed) {
  // Valid CRCs, sound framing, but content that does not fit the version 1 layout.
  const auto refused = [](std::string b) {
    refresh_header(b);
    return error_from([&] { (void)deserialize_model(b, "m.fsm"); });
  };
  {
    std::string b = m_bytes;  // bytes left over at the end of a known section
    const Section atch = section(b, "ATCH");
    b.insert(atch.body + atch.length, "pad!");
    put_le(b, atch.header + 4, atch.length + 4, 8);
    const Error e = refused(b);
    EXPECT_EQ(e.part(), "section 'ATCH'");
    EXPECT_EQ(e.reason(), "malformed: 4 bytes left over after its last field");
  }
  {
    std::string b = m_bytes;  // positions stored with 4 columns
    put_le(b, section(b, "NODE").body + 4, 4, 4);
    const Error e = refused(b);
    EXPECT_EQ(e.part(), "section 'NODE'");
    EXPECT_EQ(e.reason(), "malformed: positions has 4 columns, expected 3");
  }
  {
    std::string b = m_bytes;  // one rest length fewer than links
    const Section link = section(b, "LINK");
    const auto l = std::size_t(m_model.spheres.num_links());
    const std::size_t rest_lengths = link.body + 8 + 8 * l;
    put_le(b, rest_lengths, l - 1, 4);
    b.erase(rest_lengths + 8, 8);
    put_le(b, link.header + 4, link.length - 8, 8);
    const Error e = refused(b);
    EXPECT_EQ(e.part(), "section 'LINK'");
    EXPECT_TRUE(starts_with(e.reason(), "malformed: rest lengths has")) << e.what();
  }
  {
    std::string b = m_bytes;  // part 0's topology byte
    const Section part = section(b, "PART");
    const std::size_t topology = part.body + 4 + 4 + get_le(b, part.body + 4, 4);
    b[topology] = 9;
    const Error e = refused(b);
    EXPECT_EQ(e.reason(), "malformed: part 'body' has unknown topology 9");
  }
}

TEST_F(ModelFile, DeclaredSizesBeyondTheDataAreTruncatedNotAllocated) {
  // Valid CRCs, so only the framing checks stand between these sizes and an allocation.
  {
    std::string b = m_bytes;
    put_le(b, section(b, "META").header + 4, std::uint64_t(1) << 62, 8);
    refresh_header(b);
    const Error e = error_from([&] { (void)deserialize_model(b); });
    EXPECT_TRUE(starts_with(e.reason(), "truncated")) << e.what();
    EXPECT_EQ(e.part(), "section 'META'");
  }
  {
    std::string b = m_bytes;  // the name's length
    put_le(b, section(b, "META").body, 0xFFFFFFF0u, 4);
    refresh_header(b);
    const Error e = error_from([&] { (void)deserialize_model(b); });
    EXPECT_TRUE(starts_with(e.reason(), "truncated")) << e.what();
  }
  {
    std::string b = m_bytes;  // the positions' row count: 2^31 - 1 rows of 24 bytes
    put_le(b, section(b, "NODE").body, 0x7FFFFFFFu, 4);
    refresh_header(b);
    const Error e = error_from([&] { (void)deserialize_model(b); });
    EXPECT_TRUE(starts_with(e.reason(), "truncated")) << e.what();
    EXPECT_EQ(e.part(), "section 'NODE'");
  }
  {
    std::string b = m_bytes;  // the region count
    put_le(b, section(b, "REGN").body, 0xFFFFFFFFu, 4);
    refresh_header(b);
    const Error e = error_from([&] { (void)deserialize_model(b); });
    EXPECT_TRUE(starts_with(e.reason(), "truncated")) << e.what();
  }
}

TEST_F(ModelFile, MissingAndDuplicateSectionsAreMalformed) {
  {
    std::string b = m_bytes;
    const Section skin = section(b, "SKIN");
    b.erase(skin.header, 12 + skin.length);
    refresh_header(b);
    const Error e = error_from([&] { (void)deserialize_model(b); });
    EXPECT_EQ(e.part(), "section 'SKIN'");
    EXPECT_EQ(e.reason(), "malformed: the section is missing");
  }
  {
    std::string b = m_bytes;
    const Section meta = section(b, "META");
    b += b.substr(meta.header, 12 + meta.length);
    refresh_header(b);
    const Error e = error_from([&] { (void)deserialize_model(b); });
    EXPECT_EQ(e.reason(), "malformed: the section appears twice");
  }
}

/// The error validate() gives for `model`.
Error validation_error(const TissueModel<double>& model) {
  return error_from([&] { model.validate(); });
}

TEST_F(ModelFile, LinkToAMissingNodeIsRefusedWithTheValidatorsMessage) {
  const Index bad_node = m_model.spheres.num_nodes() + 7;
  std::string b = m_bytes;
  put_le(b, section(b, "LINK").body + 8 + 4, std::uint32_t(bad_node), 4);  // link 0, second node
  refresh_header(b);
  TissueModel<double> bad = m_model;
  bad.spheres.links()(0, 1) = bad_node;
  const Error want = validation_error(bad);
  ASSERT_FALSE(want.reason().empty());
  const Error e = error_from([&] { (void)deserialize_model(b, "bad.fsm"); });
  EXPECT_EQ(e.file(), "bad.fsm");
  EXPECT_EQ(e.part(), want.part());
  EXPECT_EQ(e.reason(), want.reason());
}

TEST_F(ModelFile, BadFixedFlagIsRefusedWithTheValidatorsMessage) {
  const std::size_t n = std::size_t(m_model.spheres.num_nodes());
  std::string b = m_bytes;
  // NODE: three |V| x 3 f64 arrays, two |V| x 1 f64, one |V| x 1 i32, then the u8 flags.
  const std::size_t flags =
      section(b, "NODE").body + 3 * (8 + 24 * n) + 2 * (8 + 8 * n) + (8 + 4 * n) + 8;
  b[flags + 5] = 2;
  refresh_header(b);
  TissueModel<double> bad = m_model;
  bad.spheres.fixed()[5] = 2;
  const Error want = validation_error(bad);
  const Error e = error_from([&] { (void)deserialize_model(b, "bad.fsm"); });
  EXPECT_EQ(e.part(), want.part());
  EXPECT_EQ(e.reason(), want.reason());
}

TEST_F(ModelFile, PartOutsideTheModelIsRefusedWithTheValidatorsMessage) {
  TissueModel<double> bad = m_model;
  bad.parts[1].num_nodes = 1000;
  const Error want = validation_error(bad);
  // The writer validates too, so write a good model and patch the part's node count.
  std::string b = m_bytes;
  const Section part = section(b, "PART");
  // PART: u32 count, then per part: u32 length + name, u8 topology, i32 region, f64 radius,
  // i32 first_node, i32 num_nodes, i32 first_link, i32 num_links, i32 surface, i32
  // first_tetrahedron, i32 num_tetrahedra.
  std::size_t at = part.body + 4;
  at += 4 + get_le(b, at, 4) + 1 + 4 + 8 + 7 * 4;  // past part 0
  at += 4 + get_le(b, at, 4) + 1 + 4 + 8 + 4;      // to num_nodes
  ASSERT_EQ(get_le(b, at, 4), std::uint64_t(m_model.parts[1].num_nodes));
  put_le(b, at, 1000, 4);
  refresh_header(b);
  const Error e = error_from([&] { (void)deserialize_model(b, "bad.fsm"); });
  EXPECT_EQ(e.part(), want.part());
  EXPECT_EQ(e.reason(), want.reason());
}

// The tetrahedra (version 2) are checked against the part that claims them: a crafted index
// outside the part, an inverted element or a count that disagrees with the parts is refused with
// the validator's words.
TEST_F(ModelFile, TetrahedraAreCheckedAgainstTheirPart) {
  const Section tets_section = section(m_bytes, "TETS");
  const std::size_t first = tets_section.body + 8;  // row 0, column 0
  const auto patched = [&](std::size_t at, std::uint64_t v) {
    std::string b = m_bytes;
    put_le(b, at, v, 4);
    refresh_header(b);
    return b;
  };
  const auto tets = m_model.spheres.tetrahedra();
  struct Case {
    const char* what;
    std::string bytes;
    std::string part, reason;  // the words the error must contain
  };
  std::vector<Case> cases;
  // A node of another part (the ovary's first): the tetrahedron's nodes then span two regions,
  // and the body part claims a node outside it.
  cases.push_back({"other part", patched(first, std::uint64_t(m_model.parts[1].first_node)),
                   "tetrahedron 0", "its nodes belong to different regions"});
  cases.push_back({"huge index", patched(first + 4, std::uint64_t(2147483646)), "tetrahedron 0",
                   "node index out of range"});
  cases.push_back({"negative index", patched(first + 4, std::uint64_t(0xFFFFFFFFu)),
                   "tetrahedron 0", "node index out of range"});
  {  // inverted: two vertices swapped
    std::string b = m_bytes;
    put_le(b, first + 8, std::uint64_t(tets(0, 3)), 4);
    put_le(b, first + 12, std::uint64_t(tets(0, 2)), 4);
    refresh_header(b);
    cases.push_back({"inverted", b, "tetrahedron 0", "is inverted or degenerate at rest"});
  }
  cases.push_back({"repeated", patched(first + 8, std::uint64_t(tets(0, 1))), "tetrahedron 0",
                   "repeats a node"});
  for (const Case& c : cases) {
    const Error e = error_from([&] { (void)deserialize_model(c.bytes, "tets.fsm"); });
    EXPECT_EQ(e.file(), "tets.fsm") << c.what;
    EXPECT_NE(e.part().find(c.part), std::string::npos) << c.what << ": " << e.what();
    EXPECT_NE(e.reason().find(c.reason), std::string::npos) << c.what << ": " << e.what();
  }
  // A part claiming more tetrahedra than the model has, even by a count near 2^31.
  for (const Index count :
       {Index(m_model.spheres.num_tetrahedra() + 1), std::numeric_limits<Index>::max()}) {
    TissueModel<double> bad = m_model;
    bad.parts[0].num_tetrahedra = count;
    const Error want = validation_error(bad);
    EXPECT_EQ(want.reason(), "tetrahedron range outside the model");
  }
}

/// The test model as an older writer wrote it: version 2 has no Poisson's ratio and force law in
/// REGN; version 1 neither, nor a TETS section or a tetrahedron range in PART.
std::string as_version(const std::string& v4, const TissueModel<double>& model, int version) {
  std::string b = v4.substr(0, k_header);
  put_le(b, 8, std::uint64_t(version), 4);
  for (const Section& s : sections(v4)) {
    if (s.tag == "TETS" && version < 2) continue;
    std::string body = v4.substr(s.body, s.length);
    if (s.tag == "REGN") {
      // Each region: name, five f64, then Poisson's ratio (f64, version 3), the tear strain
      // (f64, version 4) and the law (u8, version 3).
      std::string out = body.substr(0, 4);
      std::size_t at = 4;
      for (std::uint64_t k = 0; k < get_le(body, 0, 4); ++k) {
        const std::size_t len = 4 + get_le(body, at, 4) + 5 * 8;
        out += body.substr(at, len);
        if (version == 3) out += body.substr(at + len, 8) + body.substr(at + len + 16, 1);
        at += len + 8 + 8 + 1;
      }
      body = out;
    }
    if (s.tag == "LINK")  // drop the tear strain matrix (version 4) at the end
      body.resize(body.size() - 8 - 8 * std::size_t(model.spheres.num_links()));
    if (s.tag == "PART" && version < 2) {  // drop the two i32 at the end of each part
      std::string out = body.substr(0, 4);
      std::size_t at = 4;
      for (std::size_t k = 0; k < model.parts.size(); ++k) {
        const std::size_t len = 4 + get_le(body, at, 4) + 1 + 4 + 8 + 5 * 4;
        out += body.substr(at, len);
        at += len + 8;
      }
      body = out;
    }
    std::string header = s.tag + std::string(8, '\0');
    put_le(header, 4, body.size(), 8);
    b += header + body;
  }
  refresh_header(b);
  return b;
}

TEST_F(ModelFile, Version3FilesStillLoad) {
  // The test model with tear strains, written as version 3: everything but them comes back.
  TissueModel<double> model = m_model;
  Material<double> m = model.spheres.region(0).material;
  m.tear_strain = 0.4;
  model.spheres.set_region_material(0, m);
  model.spheres.tear_strain()[0] = 0.25;
  const std::string v4 = serialize_model(model);
  const TissueModel<double> back = deserialize_model(v4, "v4.fsm");
  EXPECT_EQ(back.spheres.region(0).material.tear_strain, 0.4);
  EXPECT_EQ(back.spheres.tear_strain()[0], 0.25);
  EXPECT_TRUE(std::isinf(back.spheres.tear_strain()[1]));
  const TissueModel<double> v3 = deserialize_model(as_version(v4, model, 3), "v3.fsm");
  expect_identical(m_model, v3, false);
  EXPECT_TRUE(std::isinf(v3.spheres.region(0).material.tear_strain));
  EXPECT_TRUE(std::isinf(v3.spheres.tear_strain()[0]));
  // A tear strain that is not positive is refused, naming the link.
  TissueModel<double> bad = model;
  std::string bytes = serialize_model(bad);
  const Section links = [&] {
    for (const Section& s : sections(bytes))
      if (s.tag == "LINK") return s;
    return Section{};
  }();
  const std::size_t first = links.body + links.length - 8 * std::size_t(model.spheres.num_links());
  put_le(bytes, first, 0x7ff8000000000000ull, 8);  // NaN
  refresh_header(bytes);
  const Error e = error_from([&] { (void)deserialize_model(bytes, "nan.fsm"); });
  EXPECT_EQ(e.file(), "nan.fsm");
  EXPECT_TRUE(starts_with(e.part(), "link 0 ")) << e.part();
  EXPECT_NE(e.reason().find("tear strain"), std::string::npos) << e.what();
}

TEST_F(ModelFile, Version2FilesStillLoad) {
  // The test model, written as version 2: everything comes back, every region with the link
  // law and the default Poisson's ratio.
  TissueModel<double> model = m_model;
  model.spheres.set_region_law(0, ForceLaw::continuum);
  const std::string v4 = serialize_model(model);
  const TissueModel<double> v2 = deserialize_model(as_version(v4, model, 2), "v2.fsm");
  EXPECT_EQ(v2.spheres.num_tetrahedra(), model.spheres.num_tetrahedra());
  TissueModel<double> want = model;
  want.spheres.set_region_law(0, ForceLaw::links);
  for (Index r = 0; r < want.spheres.num_regions(); ++r) {
    Material<double> m = want.spheres.region(r).material;
    m.poisson_ratio = Material<double>{}.poisson_ratio;
    want.spheres.set_region_material(r, m);
  }
  expect_identical(want, v2, false);
  for (Index r = 0; r < v2.spheres.num_regions(); ++r)
    EXPECT_EQ(v2.spheres.region(r).law, ForceLaw::links) << v2.spheres.region(r).name;
  // The fuzz seed written by the version 2 builder loads too.
  const std::string seed =
      std::string(FSM_TEST_DATA_DIR) + "/../fuzz/corpus/fuzz_model_file/block_v2.fsm";
  ASSERT_EQ(get_le(read_bytes(seed), 8, 4), 2u);
  EXPECT_GT(load_model(seed).spheres.num_tetrahedra(), 0);
}

TEST_F(ModelFile, Version1FilesStillLoad) {
  // The test model, written as version 1: everything but the tetrahedra comes back.
  const TissueModel<double> v1 = deserialize_model(as_version(m_bytes, m_model, 1), "v1.fsm");
  TissueModel<double> want = m_model;
  for (Part& p : want.parts) p.first_tetrahedron = p.num_tetrahedra = 0;
  expect_identical(want, v1, false);
  EXPECT_EQ(v1.spheres.num_tetrahedra(), 0);
  for (const Region<double>& r : v1.spheres.regions()) {
    EXPECT_EQ(r.law, ForceLaw::links) << r.name;
    EXPECT_EQ(r.material.poisson_ratio, Material<double>{}.poisson_ratio) << r.name;
  }
  // A file the version 1 builder wrote (tests/data: ovary_left + ligament_left of the bundled
  // uterus, fsm-build at commit d43657f): it loads, has no tetrahedra, and saves as version 4.
  const std::string path = std::string(FSM_TEST_DATA_DIR) + "/model_v1_ovary_ligament.fsm";
  const std::string old = read_bytes(path);
  ASSERT_GT(old.size(), k_header);
  ASSERT_EQ(get_le(old, 8, 4), 1u);
  const TissueModel<double> m = load_model(path);
  EXPECT_EQ(m.name, "ovary_ligament_v1");
  EXPECT_EQ(m.spheres.num_nodes(), 39);
  EXPECT_EQ(m.spheres.num_links(), 153);
  EXPECT_EQ(m.num_attachment_links, 24);
  EXPECT_EQ(m.spheres.num_fixed(), 5);
  ASSERT_EQ(m.parts.size(), 2u);
  EXPECT_EQ(m.parts[0].name, "ovary_left");
  EXPECT_EQ(m.parts[0].topology, Topology::tetrahedral);
  EXPECT_EQ(m.parts[1].topology, Topology::axis);
  EXPECT_EQ(m.spheres.num_tetrahedra(), 0);
  EXPECT_EQ(m.parts[0].num_tetrahedra, 0);
  const std::string again = serialize_model(m);
  EXPECT_EQ(get_le(again, 8, 4), model_file_version);
  expect_identical(m, deserialize_model(again));
}

TEST_F(ModelFile, WriterRefusesAnInvalidModel) {
  TissueModel<double> bad = m_model;
  bad.spheres.masses()[3] = -1.0;
  const Error want = validation_error(bad);
  const Error e = error_from([&] { (void)serialize_model(bad); });
  EXPECT_EQ(e.reason(), want.reason());
  const std::string path = temp_path("invalid");
  const Error saved = error_from([&] { save_model(path, bad); });
  EXPECT_EQ(saved.file(), path);
  EXPECT_EQ(saved.reason(), want.reason());
  EXPECT_FALSE(std::ifstream(path).good()) << "no file is written for an invalid model";
}

TEST_F(ModelFile, UnwritablePathNamesTheFile) {
  const std::string path = ::testing::TempDir() + "no_such_dir_fsm/out.fsm";
  const Error e = error_from([&] { save_model(path, m_model); });
  EXPECT_EQ(e.file(), path);
  EXPECT_EQ(e.part(), "");
  EXPECT_TRUE(starts_with(e.reason(), "cannot open for writing")) << e.what();
}

TEST_F(ModelFile, RandomEditsWithValidCrcsLoadValidOrThrowFsmError) {
  // Past the CRC, the parser itself must hold: random bytes and random 32-bit words (counts,
  // lengths, indices) at random places. Whatever loads must be a valid model that writes back.
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::size_t> pos(k_header, m_bytes.size() - 4);
  std::uniform_int_distribution<unsigned> byte(0, 255);
  int refused = 0, loaded = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::string b = m_bytes;
    const int edits = 1 + trial % 3;
    for (int k = 0; k < edits; ++k) {
      if (trial % 2 == 0) {
        b[pos(rng)] = static_cast<char>(byte(rng));
      } else {
        put_le(b, pos(rng), rng(), 4);
      }
    }
    refresh_header(b);
    try {
      const TissueModel<double> m = deserialize_model(b, "fuzz.fsm");
      ++loaded;
      EXPECT_NO_THROW(m.validate()) << "trial " << trial;
    } catch (const Error& e) {
      ++refused;
      EXPECT_EQ(e.file(), "fuzz.fsm") << "trial " << trial;
    }
  }
  EXPECT_GT(refused, 0);
  EXPECT_GT(loaded, 0);
}

}  // namespace
}  // namespace fsm
