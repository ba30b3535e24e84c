// VTK XML writer for ParaView time series (docs/python.md and docs/demo.md: "ParaView").

#include "fsm/vtk_export.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "fsm/error.hpp"

namespace fsm {

namespace {

constexpr std::uint8_t k_vtk_line = 3, k_vtk_triangle = 5, k_vtk_tetra = 10;

// RFC 4648 base64 with padding.
void base64(const unsigned char* data, std::size_t n, std::string& out) {
  static constexpr char k_alphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::size_t i = 0;
  for (; i + 3 <= n; i += 3) {
    const std::uint32_t v = (std::uint32_t(data[i]) << 16) | (std::uint32_t(data[i + 1]) << 8) |
                            std::uint32_t(data[i + 2]);
    out += k_alphabet[(v >> 18) & 63];
    out += k_alphabet[(v >> 12) & 63];
    out += k_alphabet[(v >> 6) & 63];
    out += k_alphabet[v & 63];
  }
  if (i < n) {
    std::uint32_t v = std::uint32_t(data[i]) << 16;
    if (i + 1 < n) v |= std::uint32_t(data[i + 1]) << 8;
    out += k_alphabet[(v >> 18) & 63];
    out += k_alphabet[(v >> 12) & 63];
    out += i + 1 < n ? k_alphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
}

// Little-endian bytes of arithmetic values, whatever the host.
template <typename T>
void append_le(std::vector<unsigned char>& bytes, T value) {
  unsigned char raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  std::uint16_t probe = 1;
  unsigned char first = 0;
  std::memcpy(&first, &probe, 1);
  if (first == 1) {
    bytes.insert(bytes.end(), raw, raw + sizeof(T));
  } else {
    for (std::size_t k = sizeof(T); k-- > 0;) bytes.push_back(raw[k]);
  }
}

// One <DataArray> in VTK's inline binary form: a UInt64 byte count, then the data, each base64
// encoded on its own (as VTK writes it).
template <typename T>
std::string data_array(const char* vtk_type, const std::string& name, int components,
                       const std::vector<T>& values) {
  std::vector<unsigned char> header, body;
  append_le<std::uint64_t>(header, std::uint64_t(values.size() * sizeof(T)));
  body.reserve(values.size() * sizeof(T));
  for (const T& v : values) append_le<T>(body, v);
  std::string s = "        <DataArray type=\"";
  s += vtk_type;
  s += "\"";
  if (!name.empty()) s += " Name=\"" + name + "\"";
  if (components > 1) s += " NumberOfComponents=\"" + std::to_string(components) + "\"";
  s += " format=\"binary\">\n          ";
  base64(header.data(), header.size(), s);
  base64(body.data(), body.size(), s);
  s += "\n        </DataArray>\n";
  return s;
}

std::vector<double> flatten(const Eigen::Ref<const Positions<double>>& a) {
  std::vector<double> v(std::size_t(a.rows()) * 3);
  for (Index i = 0; i < a.rows(); ++i)
    for (int c = 0; c < 3; ++c) v[std::size_t(i) * 3 + std::size_t(c)] = a(i, c);
  return v;
}

struct Cells {
  std::vector<std::int32_t> connectivity, offsets;
  std::vector<std::uint8_t> types;
  void add(std::uint8_t type, const Index* nodes, int count) {
    if (connectivity.size() > std::size_t(INT32_MAX - count))
      throw Error("", "VTK export", "more than 2^31 - 1 cell nodes (Int32 offsets)");
    for (int k = 0; k < count; ++k) connectivity.push_back(nodes[k]);
    offsets.push_back(std::int32_t(connectivity.size()));
    types.push_back(type);
  }
};

std::string piece(const std::vector<double>& points, const Cells& cells,
                  const std::string& point_data, const std::string& cell_data) {
  std::ostringstream o;
  o << "<?xml version=\"1.0\"?>\n"
    << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
       "header_type=\"UInt64\">\n"
    << "  <UnstructuredGrid>\n"
    << "    <Piece NumberOfPoints=\"" << points.size() / 3 << "\" NumberOfCells=\""
    << cells.types.size() << "\">\n"
    << "      <PointData>\n"
    << point_data << "      </PointData>\n"
    << "      <CellData>\n"
    << cell_data << "      </CellData>\n"
    << "      <Points>\n"
    << data_array("Float64", "Points", 3, points) << "      </Points>\n"
    << "      <Cells>\n"
    << data_array("Int32", "connectivity", 1, cells.connectivity)
    << data_array("Int32", "offsets", 1, cells.offsets)
    << data_array("UInt8", "types", 1, cells.types) << "      </Cells>\n"
    << "    </Piece>\n"
    << "  </UnstructuredGrid>\n"
    << "</VTKFile>\n";
  return o.str();
}

void write_file(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw Error(path, "VTK export", "cannot open for writing");
  f.write(text.data(), std::streamsize(text.size()));
  f.flush();
  if (!f) throw Error(path, "VTK export", "cannot write (disk full?)");
}

std::string numbered(const std::string& name, const char* piece_name, std::size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06zu", k);
  return name + "_" + piece_name + "_" + buf + ".vtu";
}

}  // namespace

VtkSeriesWriter::VtkSeriesWriter(const std::string& directory, const SphereModel<double>& model,
                                 const Skin<double>* skin, const std::string& name)
    : m_directory(directory), m_name(name), m_model(model), m_skin(skin) {
  if (name.empty() || name.find_first_of("/\\") != std::string::npos)
    throw Error(directory, "VTK export", "the series name '" + name + "' is empty or a path");
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec || !std::filesystem::is_directory(directory))
    throw Error(directory, "VTK export", "cannot create the folder: " + ec.message());
}

std::string VtkSeriesWriter::series_path() const {
  return (std::filesystem::path(m_directory) / (m_name + ".pvd")).string();
}

void VtkSeriesWriter::write(double time, const Eigen::Ref<const Positions<double>>& positions,
                            const Eigen::Ref<const Positions<double>>& velocities,
                            const Eigen::Ref<const Positions<double>>& forces,
                            const Positions<double>* surface) {
  const std::size_t k = m_times.size();
  const std::string spheres_file = numbered(m_name, "spheres", k);
  const std::string spheres_path = (std::filesystem::path(m_directory) / spheres_file).string();
  const Index n = m_model.num_nodes();
  if (positions.rows() != n || velocities.rows() != n || forces.rows() != n)
    throw Error(spheres_path, "VTK export",
                "positions, velocities and forces need " + std::to_string(n) + " rows (got " +
                    std::to_string(positions.rows()) + ", " + std::to_string(velocities.rows()) +
                    ", " + std::to_string(forces.rows()) + ")");
  if (!std::isfinite(time) || (!m_times.empty() && !(time > m_times.back())))
    throw Error(spheres_path, "VTK export", "the time must be finite and after the last state's");

  // Spheres: points, links and tetrahedra.
  Cells cells;
  std::vector<std::int32_t> kind;
  const auto links = m_model.links();
  for (Index l = 0; l < links.rows(); ++l) {
    const Index pair[2] = {links(l, 0), links(l, 1)};
    cells.add(k_vtk_line, pair, 2);
    kind.push_back(0);
  }
  const auto tets = m_model.tetrahedra();
  for (Index t = 0; t < tets.rows(); ++t) {
    const Index quad[4] = {tets(t, 0), tets(t, 1), tets(t, 2), tets(t, 3)};
    cells.add(k_vtk_tetra, quad, 4);
    kind.push_back(1);
  }
  std::vector<double> radius(std::size_t(n), 0.0);
  std::vector<std::int32_t> fixed(std::size_t(n), 0), region(std::size_t(n), 0);
  for (Index i = 0; i < n; ++i) {
    radius[std::size_t(i)] = m_model.radii()[i];
    fixed[std::size_t(i)] = m_model.fixed()[i] ? 1 : 0;
    region[std::size_t(i)] = m_model.node_regions()[i];
  }
  const std::string point_data = data_array("Float64", "radius", 1, radius) +
                                 data_array("Float64", "velocity", 3, flatten(velocities)) +
                                 data_array("Float64", "force", 3, flatten(forces)) +
                                 data_array("Int32", "fixed", 1, fixed) +
                                 data_array("Int32", "region", 1, region);
  write_file(spheres_path,
             piece(flatten(positions), cells, point_data, data_array("Int32", "kind", 1, kind)));

  // The render surface.
  if (m_skin != nullptr) {
    const Positions<double>& v = surface != nullptr ? *surface : m_skin->rest.vertices;
    const std::string surface_path =
        (std::filesystem::path(m_directory) / numbered(m_name, "surface", k)).string();
    if (v.rows() != m_skin->rest.num_vertices())
      throw Error(surface_path, "VTK export",
                  "the surface needs " + std::to_string(m_skin->rest.num_vertices()) + " rows");
    Cells triangles;
    std::vector<std::int32_t> which(std::size_t(m_skin->rest.num_faces()), -1);
    for (Index f = 0; f < m_skin->rest.num_faces(); ++f) {
      const Index tri[3] = {m_skin->rest.faces(f, 0), m_skin->rest.faces(f, 1),
                            m_skin->rest.faces(f, 2)};
      triangles.add(k_vtk_triangle, tri, 3);
    }
    for (std::size_t s = 0; s < m_skin->surfaces.size(); ++s) {
      const auto& part = m_skin->surfaces[s];
      for (Index f = part.first_face; f < part.first_face + part.num_faces; ++f)
        if (f >= 0 && f < Index(which.size())) which[std::size_t(f)] = std::int32_t(s);
    }
    write_file(surface_path,
               piece(flatten(v), triangles, "", data_array("Int32", "surface", 1, which)));
  }
  m_times.push_back(time);
  write_index();
}

void VtkSeriesWriter::write_index() const {
  std::ostringstream o;
  o << "<?xml version=\"1.0\"?>\n"
    << "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    << "  <Collection>\n";
  char t[32];
  for (std::size_t k = 0; k < m_times.size(); ++k) {
    std::snprintf(t, sizeof t, "%.17g", m_times[k]);
    o << "    <DataSet timestep=\"" << t << "\" part=\"0\" file=\""
      << numbered(m_name, "spheres", k) << "\"/>\n";
    if (m_skin != nullptr)
      o << "    <DataSet timestep=\"" << t << "\" part=\"1\" file=\""
        << numbered(m_name, "surface", k) << "\"/>\n";
  }
  o << "  </Collection>\n</VTKFile>\n";
  write_file(series_path(), o.str());
}

}  // namespace fsm
