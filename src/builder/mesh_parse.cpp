// Strict parsers of the four mesh formats (OBJ, OFF, STL, PLY) for untrusted files: every count a
// header declares is checked against the bytes that remain before anything is allocated for it,
// and every error names the line (text) or byte offset (binary) and what is wrong there. CGAL-free
// (the fuzzers build it alone); read_mesh() welds and triangulates the result (mesh_io.cpp).

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fsm/builder/mesh_io.hpp"
#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using Soup = PolygonSoup;

std::string quoted(std::string_view s) {
  constexpr std::size_t k_show = 24;
  std::string out = "'";
  for (const char c : s.substr(0, k_show))
    out +=
        (static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7F) ? c : '?';
  if (s.size() > k_show) out += "...";
  return out + "'";
}

// --- Text: lines and tokens -----------------------------------------------------------------

class TextReader {
 public:
  TextReader(std::string_view bytes, const std::string& file) : m_bytes(bytes), m_file(file) {}

  /// The next line without its end (\n, \r\n or \r) and without a '#' comment when `comments`;
  /// false at the end of the file.
  bool next_line(std::string_view& line, bool comments = true) {
    if (m_pos >= m_bytes.size()) return false;
    const std::size_t end = m_bytes.find_first_of("\r\n", m_pos);
    const std::size_t stop = end == std::string_view::npos ? m_bytes.size() : end;
    line = m_bytes.substr(m_pos, stop - m_pos);
    m_pos = stop;
    if (m_pos < m_bytes.size() && m_bytes[m_pos] == '\r') ++m_pos;
    if (m_pos < m_bytes.size() && m_bytes[m_pos] == '\n') ++m_pos;
    ++m_line;
    if (comments) {
      const std::size_t hash = line.find('#');
      if (hash != std::string_view::npos) line = line.substr(0, hash);
    }
    return true;
  }

  [[nodiscard]] std::size_t line_number() const noexcept { return m_line; }
  [[nodiscard]] std::size_t remaining() const noexcept { return m_bytes.size() - m_pos; }

  [[noreturn]] void fail(const std::string& why) const {
    throw Error(m_file, "", "line " + std::to_string(m_line) + ": " + why);
  }

 private:
  std::string_view m_bytes;
  const std::string& m_file;
  std::size_t m_pos{0};
  std::size_t m_line{0};
};

/// Splits at blanks (space, tab, vertical tab, form feed).
class Tokens {
 public:
  explicit Tokens(std::string_view s) : m_s(s) {}
  bool next(std::string_view& t) {
    while (m_pos < m_s.size() && is_blank(m_s[m_pos])) ++m_pos;
    if (m_pos >= m_s.size()) return false;
    const std::size_t start = m_pos;
    while (m_pos < m_s.size() && !is_blank(m_s[m_pos])) ++m_pos;
    t = m_s.substr(start, m_pos - start);
    return true;
  }
  /// The tokens not yet taken.
  std::size_t count() const {
    Tokens copy = *this;
    std::string_view t;
    std::size_t n = 0;
    while (copy.next(t)) ++n;
    return n;
  }

 private:
  static bool is_blank(char c) noexcept { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }
  std::string_view m_s;
  std::size_t m_pos{0};
};

bool parse_double(std::string_view t, double& out) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);  // from_chars refuses a leading '+'
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), out);
  if (ec == std::errc::result_out_of_range) {
    out = std::numeric_limits<double>::infinity();  // reported as not finite by the caller
    return end == t.data() + t.size();
  }
  return ec == std::errc() && end == t.data() + t.size();
}

bool parse_integer(std::string_view t, long long& out) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), out);
  return ec == std::errc() && end == t.data() + t.size();
}

/// A coordinate token: a finite number; otherwise the line and what it holds.
double coordinate(const TextReader& r, std::string_view t, const char* what) {
  double v = 0;
  if (!parse_double(t, v)) r.fail(std::string(what) + " " + quoted(t) + " is not a number");
  if (!std::isfinite(v))
    r.fail(std::string(what) + " " + quoted(t) + " is not finite (NaN, infinite or too large)");
  return v;
}

const char* const k_axes[3] = {"x coordinate", "y coordinate", "z coordinate"};

// --- OBJ --------------------------------------------------------------------------------------

// OBJ: "v x y z [w | r g b]", "f i[/t][/n] ..." with 1-based or negative (relative) indices.
// Every other statement (vt, vn, g, o, s, usemtl, mtllib, l, p, ...) is ignored, as the format
// allows.
Soup parse_obj(std::string_view bytes, const std::string& file) {
  Soup soup;
  TextReader r(bytes, file);
  std::string_view line;
  std::vector<std::size_t> face_lines;  // for an index past the last vertex, found at the end
  while (r.next_line(line)) {
    Tokens tok(line);
    std::string_view key;
    if (!tok.next(key)) continue;
    if (key == "v") {
      std::array<double, 3> p{};
      std::string_view t;
      for (int c = 0; c < 3; ++c) {
        if (!tok.next(t))
          r.fail("vertex " + std::to_string(soup.points.size() + 1) + " has " + std::to_string(c) +
                 " coordinates, needs 3");
        p[std::size_t(c)] = coordinate(r, t, k_axes[c]);
      }
      soup.points.push_back(p);
    } else if (key == "f") {
      const std::size_t n = tok.count();
      if (n < 3) r.fail("face with " + std::to_string(n) + " vertices (a face needs at least 3)");
      std::vector<std::size_t> face;
      face.reserve(n);  // bounded by the line's length
      std::string_view t;
      while (tok.next(t)) {
        const std::string_view index = t.substr(0, t.find('/'));
        long long k = 0;
        if (!parse_integer(index, k) || k == 0)
          r.fail("face vertex " + quoted(t) +
                 " is not a vertex index (1-based, or negative counting back)");
        if (k < 0) {
          const long long from_end = static_cast<long long>(soup.points.size()) + k;
          if (from_end < 0)
            r.fail("face vertex " + quoted(t) + " counts back past the first vertex (only " +
                   std::to_string(soup.points.size()) + " so far)");
          face.push_back(std::size_t(from_end));
        } else {
          face.push_back(std::size_t(k - 1));
        }
      }
      soup.polygons.push_back(std::move(face));
      face_lines.push_back(r.line_number());
    }
  }
  // Positive indices may refer to vertices defined later in the file: checked at the end.
  for (std::size_t f = 0; f < soup.polygons.size(); ++f)
    for (const std::size_t v : soup.polygons[f])
      if (v >= soup.points.size())
        throw Error(file, "",
                    "line " + std::to_string(face_lines[f]) + ": face refers to vertex " +
                        std::to_string(v + 1) + ", but the file has " +
                        std::to_string(soup.points.size()) + " vertices");
  return soup;
}

// --- OFF --------------------------------------------------------------------------------------

// OFF: "[ST][C][N]OFF" header, "nv nf ne", nv vertex lines "x y z [extra]", nf face lines
// "n i_0 ... i_{n-1} [colour]". '#' starts a comment. Binary OFF and other dimensions are
// refused by name.
Soup parse_off(std::string_view bytes, const std::string& file) {
  Soup soup;
  TextReader r(bytes, file);
  std::string_view line, t;
  // Header keyword (it may share its line with the counts).
  while (r.next_line(line) && Tokens(line).count() == 0) {
  }
  Tokens head(line);
  if (!head.next(t)) r.fail("empty file: no OFF header");
  const std::string keyword(t);
  const bool known = keyword == "OFF" || keyword == "COFF" || keyword == "NOFF" ||
                     keyword == "CNOFF" || keyword == "STOFF" || keyword == "STCOFF" ||
                     keyword == "STNOFF" || keyword == "STCNOFF";
  if (!known) {
    if (keyword.size() > 3 && keyword.compare(keyword.size() - 3, 3, "OFF") == 0)
      r.fail("the OFF variant " + quoted(keyword) + " is not supported (only 3-D OFF, COFF, NOFF)");
    r.fail("the file does not start with 'OFF' (it starts with " + quoted(keyword) + ")");
  }
  if (head.next(t) && t == "BINARY") r.fail("binary OFF is not supported; write it as text");
  // Counts: on the header line after the keyword, or on the next line with content.
  std::vector<std::string_view> counts;
  {
    Tokens rest(line);
    rest.next(t);  // the keyword
    while (rest.next(t)) counts.push_back(t);
    while (counts.empty() && r.next_line(line)) {
      Tokens c(line);
      while (c.next(t)) counts.push_back(t);
    }
  }
  if (counts.size() < 2)
    r.fail("the counts line needs 'vertices faces [edges]', found " +
           std::to_string(counts.size()) + " numbers");
  long long nv = 0, nf = 0;
  if (!parse_integer(counts[0], nv) || nv < 0)
    r.fail("the vertex count " + quoted(counts[0]) + " is not a non-negative integer");
  if (!parse_integer(counts[1], nf) || nf < 0)
    r.fail("the face count " + quoted(counts[1]) + " is not a non-negative integer");
  // Every line takes at least 2 bytes (a character and its newline): a header that declares more
  // than the file could hold is refused before anything is allocated, and what is reserved is
  // bounded by the file's size (a well-formed vertex line takes 6 bytes, a face line 8). A count
  // that is wrong but possible shows up as a truncated file at the line where it ends.
  const long double lines = static_cast<long double>(nv) + static_cast<long double>(nf);
  if (2 * lines - 1 > static_cast<long double>(r.remaining()))
    r.fail("the header declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
           " faces, more than the remaining " + std::to_string(r.remaining()) +
           " bytes can hold (the file is truncated or the counts are wrong)");
  soup.points.reserve(std::min(std::size_t(nv), r.remaining() / 6 + 1));
  soup.polygons.reserve(std::min(std::size_t(nf), r.remaining() / 8 + 1));
  auto content_line = [&](const char* what, long long k) {
    while (r.next_line(line))
      if (Tokens(line).count() > 0) return;
    throw Error(file, "",
                "line " + std::to_string(r.line_number()) + ": the file ends before " + what + " " +
                    std::to_string(k) + " (truncated, or the header's counts are wrong)");
  };
  for (long long v = 0; v < nv; ++v) {
    content_line("vertex", v);
    Tokens tok(line);
    std::array<double, 3> p{};
    for (int c = 0; c < 3; ++c) {
      if (!tok.next(t))
        r.fail("vertex " + std::to_string(v) + " has " + std::to_string(c) +
               " coordinates, needs 3");
      p[std::size_t(c)] = coordinate(r, t, k_axes[c]);
    }
    soup.points.push_back(p);
  }
  for (long long f = 0; f < nf; ++f) {
    content_line("face", f);
    Tokens tok(line);
    long long n = 0;
    tok.next(t);
    if (!parse_integer(t, n) || n < 3)
      r.fail("face " + std::to_string(f) + " starts with " + quoted(t) +
             ", not a vertex count of at least 3");
    const std::size_t have = tok.count();
    if (std::uint64_t(n) > have)
      r.fail("face " + std::to_string(f) + " declares " + std::to_string(n) +
             " vertices, the line has " + std::to_string(have) + " numbers");
    std::vector<std::size_t> face;
    face.reserve(std::size_t(n));  // n <= the numbers on this line
    for (long long k = 0; k < n; ++k) {
      tok.next(t);
      long long i = 0;
      if (!parse_integer(t, i))
        r.fail("face " + std::to_string(f) + " vertex " + quoted(t) + " is not an integer");
      if (i < 0 || i >= nv)
        r.fail("face " + std::to_string(f) + " refers to vertex " + std::to_string(i) +
               ", the file has " + std::to_string(nv) + " (0-based)");
      face.push_back(std::size_t(i));
    }
    soup.polygons.push_back(std::move(face));
  }
  return soup;
}

// --- STL --------------------------------------------------------------------------------------

float get_f32(const char* p) {
  std::uint32_t bits = 0;
  for (int k = 3; k >= 0; --k) bits = (bits << 8) | static_cast<unsigned char>(p[k]);
  float v = 0;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

std::uint32_t get_u32(const char* p) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(p[k]);
  return v;
}

Soup parse_stl_binary(std::string_view bytes, const std::string& file) {
  Soup soup;
  const std::uint64_t n = get_u32(bytes.data() + 80);
  const std::uint64_t want = 84 + 50 * n;
  if (want != bytes.size())
    throw Error(
        file, "",
        "binary STL: the header declares " + std::to_string(n) + " facets (" +
            std::to_string(want) + " bytes), the file has " + std::to_string(bytes.size()) +
            (want > bytes.size() ? " bytes (truncated)" : " bytes (extra bytes at the end)"));
  soup.points.reserve(std::size_t(3 * n));
  soup.polygons.reserve(std::size_t(n));
  for (std::uint64_t f = 0; f < n; ++f) {
    const char* p = bytes.data() + 84 + 50 * f + 12;  // skip the normal
    std::vector<std::size_t> face;
    for (int k = 0; k < 3; ++k) {
      std::array<double, 3> q{};
      for (int c = 0; c < 3; ++c) {
        q[std::size_t(c)] = double(get_f32(p + 12 * k + 4 * c));
        if (!std::isfinite(q[std::size_t(c)]))
          throw Error(file, "",
                      "byte " + std::to_string(84 + 50 * f + 12 + 12 * k + 4 * c) + ": facet " +
                          std::to_string(f) + " vertex " + std::to_string(k) +
                          " has a non-finite " + k_axes[c]);
      }
      face.push_back(soup.points.size());
      soup.points.push_back(q);
    }
    soup.polygons.push_back(std::move(face));
  }
  return soup;
}

Soup parse_stl_ascii(std::string_view bytes, const std::string& file) {
  Soup soup;
  TextReader r(bytes, file);
  std::string_view line, t;
  // Outside a solid: "solid [name]"; inside: facets, then "endsolid". Several solids may follow
  // one another.
  enum class State { outside, solid, loop, vertices, endloop, endfacet } state = State::outside;
  std::vector<std::size_t> face;
  while (r.next_line(line, false)) {
    Tokens tok(line);
    if (!tok.next(t)) continue;
    switch (state) {
      case State::outside:
        if (t != "solid") r.fail("expected 'solid', found " + quoted(t));
        state = State::solid;
        break;
      case State::solid:
        if (t == "endsolid") {
          state = State::outside;
        } else if (t == "facet") {
          state = State::loop;
        } else {
          r.fail("expected 'facet' or 'endsolid', found " + quoted(t));
        }
        break;
      case State::loop:
        if (t != "outer") r.fail("expected 'outer loop', found " + quoted(t));
        state = State::vertices;
        face.clear();
        break;
      case State::vertices: {
        if (t != "vertex") r.fail("expected 'vertex' (3 per facet), found " + quoted(t));
        std::array<double, 3> q{};
        for (int c = 0; c < 3; ++c) {
          if (!tok.next(t)) r.fail("a vertex has " + std::to_string(c) + " coordinates, needs 3");
          q[std::size_t(c)] = coordinate(r, t, k_axes[c]);
        }
        face.push_back(soup.points.size());
        soup.points.push_back(q);
        if (face.size() == 3) state = State::endloop;
        break;
      }
      case State::endloop:
        if (t != "endloop") r.fail("expected 'endloop' after 3 vertices, found " + quoted(t));
        state = State::endfacet;
        break;
      case State::endfacet:
        if (t != "endfacet") r.fail("expected 'endfacet', found " + quoted(t));
        soup.polygons.push_back(face);
        state = State::solid;
        break;
    }
  }
  if (state == State::solid)
    throw Error(file, "",
                "line " + std::to_string(r.line_number()) +
                    ": the file ends without 'endsolid' (truncated)");
  if (state != State::outside)
    throw Error(
        file, "",
        "line " + std::to_string(r.line_number()) + ": the file ends inside a facet (truncated)");
  return soup;
}

Soup parse_stl(std::string_view bytes, const std::string& file) {
  if (bytes.size() >= 84 && 84 + 50 * std::uint64_t(get_u32(bytes.data() + 80)) == bytes.size())
    return parse_stl_binary(bytes, file);
  // ASCII when it reads as text from the start.
  std::size_t start = 0;
  while (start < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[start]))) ++start;
  if (bytes.substr(start, 5) == "solid") {
    bool text = true;
    for (const char c : bytes.substr(0, std::min<std::size_t>(bytes.size(), 4096)))
      text =
          text && (c == '\n' || c == '\r' || c == '\t' ||
                   (static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7F));
    if (text) return parse_stl_ascii(bytes, file);
  }
  if (bytes.size() < 84)
    throw Error(file, "",
                "not an STL file: " + std::to_string(bytes.size()) +
                    " bytes, neither ASCII ('solid ...') nor a binary STL (84 bytes at least)");
  return parse_stl_binary(bytes, file);  // reports the size mismatch
}

// --- PLY --------------------------------------------------------------------------------------

enum class PlyType : std::uint8_t { i8, u8, i16, u16, i32, u32, f32, f64 };

bool ply_type(std::string_view name, PlyType& t) {
  static const std::pair<std::string_view, PlyType> names[] = {
      {"char", PlyType::i8},    {"int8", PlyType::i8},     {"uchar", PlyType::u8},
      {"uint8", PlyType::u8},   {"short", PlyType::i16},   {"int16", PlyType::i16},
      {"ushort", PlyType::u16}, {"uint16", PlyType::u16},  {"int", PlyType::i32},
      {"int32", PlyType::i32},  {"uint", PlyType::u32},    {"uint32", PlyType::u32},
      {"float", PlyType::f32},  {"float32", PlyType::f32}, {"double", PlyType::f64},
      {"float64", PlyType::f64}};
  for (const auto& [n, v] : names)
    if (n == name) {
      t = v;
      return true;
    }
  return false;
}

std::size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::i8:
    case PlyType::u8:
      return 1;
    case PlyType::i16:
    case PlyType::u16:
      return 2;
    case PlyType::i32:
    case PlyType::u32:
    case PlyType::f32:
      return 4;
    case PlyType::f64:
      return 8;
  }
  return 1;
}

struct PlyProperty {
  std::string name;
  PlyType type{PlyType::f32};
  bool list{false};
  PlyType count_type{PlyType::u8};
};

struct PlyElement {
  std::string name;
  std::uint64_t count{0};
  std::vector<PlyProperty> properties;
};

/// Reads PLY values from binary data (either byte order) or ASCII tokens.
class PlyData {
 public:
  /// `offset`: where the data starts in the file; `first_line`: the header's last line number.
  PlyData(std::string_view body, std::size_t offset, std::size_t first_line, int format,
          const std::string& file)
      : m_body(body), m_offset(offset), m_format(format), m_file(file), m_line(first_line) {}

  [[nodiscard]] bool ascii() const noexcept { return m_format == 0; }
  [[nodiscard]] std::size_t remaining() const noexcept { return m_body.size() - m_pos; }

  double value(PlyType t, const std::string& what) {
    if (ascii()) return ascii_value(t, what);
    const std::size_t n = ply_size(t);
    if (n > remaining()) fail("the file ends inside " + what + " (truncated)");
    std::uint64_t bits = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t at = m_format == 1 ? n - 1 - k : k;  // 1: little endian
      bits = (bits << 8) | static_cast<unsigned char>(m_body[m_pos + at]);
    }
    m_pos += n;
    switch (t) {
      case PlyType::i8:
        return double(static_cast<std::int8_t>(bits));
      case PlyType::u8:
        return double(static_cast<std::uint8_t>(bits));
      case PlyType::i16:
        return double(static_cast<std::int16_t>(bits));
      case PlyType::u16:
        return double(static_cast<std::uint16_t>(bits));
      case PlyType::i32:
        return double(static_cast<std::int32_t>(bits));
      case PlyType::u32:
        return double(static_cast<std::uint32_t>(bits));
      case PlyType::f32: {
        const auto b = static_cast<std::uint32_t>(bits);
        float f = 0;
        std::memcpy(&f, &b, sizeof f);
        return double(f);
      }
      case PlyType::f64: {
        double d = 0;
        std::memcpy(&d, &bits, sizeof d);
        return d;
      }
    }
    return 0;
  }

  /// Whether a list of `n` items of `type` can fit in what is left (binary: the bytes; ASCII: the
  /// numbers left on the instance's line).
  [[nodiscard]] bool list_fits(double n, PlyType type) const {
    if (!(n >= 0)) return false;
    if (!ascii()) return n * double(ply_size(type)) <= double(remaining());
    return n <= double(m_tokens.count());
  }
  [[nodiscard]] std::string left() const {
    return ascii() ? std::to_string(m_tokens.count()) + " numbers left on its line"
                   : std::to_string(remaining()) + " bytes left in the file";
  }

  /// Ends an element instance (ASCII: the rest of its line must be empty).
  void end_instance(const std::string& what) {
    if (!ascii()) return;
    std::string_view t;
    if (m_tokens.next(t)) fail(what + " has more values than its properties: " + quoted(t));
    m_line_open = false;
  }

  [[noreturn]] void fail(const std::string& why) const {
    if (ascii()) throw Error(m_file, "", "line " + std::to_string(m_line) + ": " + why);
    throw Error(m_file, "", "byte " + std::to_string(m_offset + m_pos) + ": " + why);
  }

  [[nodiscard]] std::size_t line() const noexcept { return m_line; }

 private:
  double ascii_value(PlyType t, const std::string& what) {
    std::string_view tok;
    while (!m_line_open || !m_tokens.next(tok)) {
      if (m_line_open) fail(what + " is missing: the line ends early");
      // An element instance starts on a new line; blank lines between instances are skipped.
      do {
        if (m_pos >= m_body.size()) fail("the file ends before " + what + " (truncated)");
        const std::size_t end = m_body.find('\n', m_pos);
        const std::size_t stop = end == std::string_view::npos ? m_body.size() : end;
        m_current = m_body.substr(m_pos, stop - m_pos);
        if (!m_current.empty() && m_current.back() == '\r') m_current.remove_suffix(1);
        m_pos = end == std::string_view::npos ? m_body.size() : end + 1;
        ++m_line;
      } while (Tokens(m_current).count() == 0);
      m_tokens = Tokens(m_current);
      m_line_open = true;
    }
    double v = 0;
    if (t == PlyType::f32 || t == PlyType::f64) {
      if (!parse_double(tok, v)) fail(what + " " + quoted(tok) + " is not a number");
    } else {
      long long i = 0;
      if (!parse_integer(tok, i)) fail(what + " " + quoted(tok) + " is not an integer");
      v = double(i);
    }
    return v;
  }

  std::string_view m_body;
  std::size_t m_offset;
  int m_format;  // 0 ascii, 1 binary little endian, 2 binary big endian
  const std::string& m_file;
  std::size_t m_pos{0};
  // ASCII state
  std::size_t m_line;
  std::string_view m_current;
  Tokens m_tokens{std::string_view()};
  bool m_line_open{false};
};

Soup parse_ply(std::string_view bytes, const std::string& file) {
  // Header: text lines up to "end_header".
  TextReader r(bytes, file);
  std::string_view line, t;
  if (!r.next_line(line, false) || line != "ply")
    throw Error(file, "", "line 1: the file does not start with 'ply'");
  int format = -1;
  std::vector<PlyElement> elements;
  bool ended = false;
  while (r.next_line(line, false)) {
    Tokens tok(line);
    if (!tok.next(t)) continue;
    if (t == "end_header") {
      ended = true;
      break;
    }
    if (t == "comment" || t == "obj_info") continue;
    if (t == "format") {
      std::string_view f, version;
      tok.next(f);
      tok.next(version);
      if (f == "ascii")
        format = 0;
      else if (f == "binary_little_endian")
        format = 1;
      else if (f == "binary_big_endian")
        format = 2;
      else
        r.fail("unknown PLY format " + quoted(f));
      if (version != "1.0") r.fail("PLY version " + quoted(version) + " is not 1.0");
    } else if (t == "element") {
      PlyElement e;
      std::string_view name, count;
      if (!tok.next(name) || !tok.next(count)) r.fail("'element' needs a name and a count");
      long long n = 0;
      if (!parse_integer(count, n) || n < 0)
        r.fail("element " + quoted(name) + " has count " + quoted(count) +
               ", not a non-negative integer");
      std::string_view extra;
      if (tok.next(extra))
        r.fail("'element " + std::string(name) + " " + std::string(count) + "' is followed by " +
               quoted(extra) + " (an element line is 'element NAME COUNT')");
      e.name = std::string(name);
      e.count = std::uint64_t(n);
      elements.push_back(std::move(e));
    } else if (t == "property") {
      if (elements.empty()) r.fail("'property' before any 'element'");
      PlyProperty p;
      std::string_view type;
      tok.next(type);
      if (type == "list") {
        std::string_view count_type, item_type;
        tok.next(count_type);
        tok.next(item_type);
        p.list = true;
        if (!ply_type(count_type, p.count_type) || !ply_type(item_type, p.type))
          r.fail("unknown list types " + quoted(count_type) + " " + quoted(item_type));
        if (p.count_type == PlyType::f32 || p.count_type == PlyType::f64)
          r.fail("a list count must be an integer type, not " + quoted(count_type));
      } else if (!ply_type(type, p.type)) {
        r.fail("unknown property type " + quoted(type));
      }
      std::string_view name;
      if (!tok.next(name)) r.fail("a property needs a name");
      p.name = std::string(name);
      elements.back().properties.push_back(std::move(p));
    } else {
      r.fail("unknown header line " + quoted(t) + " (is 'end_header' missing before the data?)");
    }
  }
  if (!ended) r.fail("the header has no 'end_header' (truncated)");
  if (format < 0) throw Error(file, "", "the PLY header has no 'format' line");
  // An instance without properties occupies no bytes, so the size check below cannot bound its
  // count: such an element (as a fuzzer found, 5e12 of them) is refused outright.
  for (const PlyElement& e : elements)
    if (e.count > 0 && e.properties.empty())
      throw Error(file, "",
                  "element " + quoted(e.name) + " declares " + std::to_string(e.count) +
                      " instances but no properties");

  // Where the data starts: right after the end_header line.
  const std::size_t data_at = bytes.size() - r.remaining();
  PlyData d(bytes.substr(data_at), data_at, r.line_number(), format, file);

  // Each element's instances need at least this many bytes: a header that declares more than the
  // file holds is refused before anything is allocated.
  long double need = 0;
  for (const PlyElement& e : elements) {
    std::size_t per = 0;
    for (const PlyProperty& p : e.properties)
      per += format == 0 ? 2 : (p.list ? ply_size(p.count_type) : ply_size(p.type));
    need += static_cast<long double>(e.count) * static_cast<long double>(per);
  }
  if (format == 0) need -= 1;  // the last value may lack its separator
  if (need > static_cast<long double>(d.remaining())) {
    // The need can exceed any integer type (counts up to 2^64 times several bytes).
    char needed[64];
    std::snprintf(needed, sizeof needed, "%.0Lf", need);
    throw Error(file, "",
                std::string("the header declares elements needing at least ") + needed +
                    " bytes, the data has " + std::to_string(d.remaining()) +
                    " (truncated, or the counts are wrong)");
  }

  Soup soup;
  bool have_vertices = false, have_faces = false;
  for (const PlyElement& e : elements) {
    const bool vertex = e.name == "vertex", face = e.name == "face";
    int xyz[3] = {-1, -1, -1};
    int indices = -1;
    for (std::size_t k = 0; k < e.properties.size(); ++k) {
      const PlyProperty& p = e.properties[k];
      if (vertex && !p.list)
        for (int c = 0; c < 3; ++c)
          if (p.name == std::string(1, char('x' + c))) xyz[c] = int(k);
      if (face && p.list && (p.name == "vertex_indices" || p.name == "vertex_index"))
        indices = int(k);
    }
    if (vertex) {
      if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
        throw Error(file, "", "the vertex element has no x, y and z properties");
      soup.points.reserve(std::size_t(e.count));
      have_vertices = true;
    }
    if (face) {
      if (indices < 0) throw Error(file, "", "the face element has no 'vertex_indices' list");
      soup.polygons.reserve(std::size_t(e.count));
      have_faces = true;
    }
    for (std::uint64_t i = 0; i < e.count; ++i) {
      const std::string what = e.name + " " + std::to_string(i);
      std::array<double, 3> q{};
      std::vector<std::size_t> polygon;
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const PlyProperty& p = e.properties[k];
        if (!p.list) {
          const double v = d.value(p.type, what + " " + p.name);
          for (int c = 0; c < 3; ++c)
            if (vertex && int(k) == xyz[c]) {
              if (!std::isfinite(v)) d.fail(what + " has a non-finite " + k_axes[c]);
              q[std::size_t(c)] = v;
            }
          continue;
        }
        const double n = d.value(p.count_type, what + " " + p.name + " count");
        if (!d.list_fits(n, p.type))
          d.fail(what + " declares a list of " + std::to_string(static_cast<long long>(n)) +
                 " values, more than the " + d.left() + " (truncated, or the count is wrong)");
        const bool mine = face && int(k) == indices;
        if (mine) {
          if (n < 3)
            d.fail(what + " has " + std::to_string(static_cast<long long>(n)) +
                   " vertices (a face needs at least 3)");
          polygon.reserve(std::size_t(n));
        }
        for (std::size_t j = 0; j < std::size_t(n); ++j) {
          const double v = d.value(p.type, what + " " + p.name + " value");
          if (!mine) continue;
          if (!(v >= 0) || v != std::floor(v) ||
              v >= double(std::numeric_limits<std::int64_t>::max()))
            d.fail(what + " has vertex index " + std::to_string(v) +
                   ", not a non-negative integer");
          polygon.push_back(std::size_t(v));
        }
      }
      d.end_instance(what);
      if (vertex) soup.points.push_back(q);
      if (face) soup.polygons.push_back(std::move(polygon));
    }
  }
  if (!have_vertices) throw Error(file, "", "the PLY file has no 'vertex' element");
  if (!have_faces) throw Error(file, "", "the PLY file has no 'face' element");
  for (std::size_t f = 0; f < soup.polygons.size(); ++f)
    for (const std::size_t v : soup.polygons[f])
      if (v >= soup.points.size())
        throw Error(file, "",
                    "face " + std::to_string(f) + " refers to vertex " + std::to_string(v) +
                        ", the file has " + std::to_string(soup.points.size()) + " (0-based)");
  return soup;
}

}  // namespace

std::optional<MeshFormat> mesh_format(const std::string& path) {
  std::string ext;
  const std::size_t dot = path.find_last_of('.');
  const std::size_t slash = path.find_last_of('/');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash))
    ext = path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == "obj") return MeshFormat::obj;
  if (ext == "off") return MeshFormat::off;
  if (ext == "stl") return MeshFormat::stl;
  if (ext == "ply") return MeshFormat::ply;
  return std::nullopt;
}

PolygonSoup parse_mesh(std::string_view bytes, MeshFormat format, const std::string& file) {
  switch (format) {
    case MeshFormat::obj:
      return parse_obj(bytes, file);
    case MeshFormat::off:
      return parse_off(bytes, file);
    case MeshFormat::stl:
      return parse_stl(bytes, file);
    case MeshFormat::ply:
      return parse_ply(bytes, file);
  }
  throw Error(file, "", "unknown mesh format");
}

}  // namespace fsm::build
