#include "io/mesh_io.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>

#include <vtkCommand.h>
#include <vtkExecutive.h>
#include <vtkSmartPointer.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include "io/mesh_vtk.hpp"
#include "skel/transform.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace skel::io {
namespace {

static_assert(std::endian::native == std::endian::little, "the binary mesh writers assume a little-endian host");

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) {
    std::error_code ec;
    throw InputError(p.string() + (std::filesystem::exists(p, ec) ? ": cannot open the file for reading" : ": file not found"));
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}


// Appends `lead`, then the values separated by spaces, then a newline (no temporaries: GCC 12's
// -Wrestrict misfires on chains of string concatenation).
template <class T, size_t N>
void append_row(std::string& out, const char* lead, const std::array<T, N>& v, int64_t add = 0) {
  out += lead;
  char buf[32];
  for (size_t i = 0; i < N; ++i) {
    if (i) out += ' ';
    std::to_chars_result r;
    if constexpr (std::is_floating_point_v<T>) r = std::to_chars(buf, buf + sizeof buf, v[i]);
    else r = std::to_chars(buf, buf + sizeof buf, v[i] + add);
    out.append(buf, r.ptr);
  }
  out += '\n';
}

void check_writable(const Mesh& m) {
  const auto problems = m.check_invariants();
  if (!problems.empty()) throw InputError("input 'mesh': inconsistent mesh: " + problems.front());
}

template <class T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

// ---------------------------------------------------------------- text lines with numbers
// Cursor over a text file: whitespace-separated tokens with line numbers for messages.
struct TextCursor {
  const std::string& s;
  std::string file;
  size_t pos = 0;
  int64_t line = 1;
  [[nodiscard]] std::string where() const { return file + ":" + std::to_string(line); }
  // Skips spaces and tabs (not newlines).
  void skip_blank() {
    while (pos < s.size() && (s[pos] == ' ' || s[pos] == '\t' || s[pos] == '\r')) ++pos;
  }
  void skip_space() {
    while (pos < s.size() && std::isspace(static_cast<unsigned char>(s[pos]))) {
      if (s[pos] == '\n') ++line;
      ++pos;
    }
  }
  bool at_end() {
    skip_space();
    return pos >= s.size();
  }
  std::string_view token() {
    skip_space();
    const size_t b = pos;
    while (pos < s.size() && !std::isspace(static_cast<unsigned char>(s[pos]))) ++pos;
    return std::string_view(s).substr(b, pos - b);
  }
  template <class T>
  T number(const char* what) {
    const auto t = token();
    if (t.empty()) throw InputError(where() + ": expected " + what + ", found the end of the file");
    T v{};
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size())
      throw InputError(where() + ": expected " + what + ", found '" + std::string(t.substr(0, 40)) + "'");
    if constexpr (std::is_floating_point_v<T>)
      if (!std::isfinite(v)) throw InputError(where() + ": " + what + " is not finite");
    return v;
  }
  // Rest of the current line (without the newline), advancing past it.
  std::string_view rest_of_line() {
    const size_t b = pos;
    while (pos < s.size() && s[pos] != '\n') ++pos;
    std::string_view r = std::string_view(s).substr(b, pos - b);
    if (pos < s.size()) {
      ++pos;
      ++line;
    }
    if (!r.empty() && r.back() == '\r') r.remove_suffix(1);
    return r;
  }
};

int64_t checked_count(TextCursor& c, const char* what, size_t min_bytes_each) {
  const auto n = c.number<int64_t>(what);
  if (n < 0) throw InputError(c.where() + ": negative " + what);
  if (min_bytes_each > 0 && static_cast<uint64_t>(n) > (c.s.size() - c.pos) / min_bytes_each + 1)
    throw InputError(c.where() + ": " + what + " " + std::to_string(n) + " is more than the file holds");
  return n;
}

// ---------------------------------------------------------------- OBJ
std::string obj_write(const Mesh& m) {
  std::string out = "# skelflow mesh\n# unit " + m.unit + "\n";
  out.reserve(out.size() + m.points.size() * 40 + m.triangles.size() * 30);
  for (const auto& p : m.points) append_row(out, "v ", p);
  for (const auto& t : m.triangles) append_row(out, "f ", t, 1);
  for (int64_t l = 0; l < m.line_count(); ++l) {
    out += "l";
    char buf[24];
    for (int64_t i = m.line_offsets[l]; i < m.line_offsets[l + 1]; ++i) {
      out += ' ';
      out.append(buf, std::to_chars(buf, buf + sizeof buf, m.line_vertices[i] + 1).ptr);
    }
    out += '\n';
  }
  return out;
}

Mesh obj_read(const std::string& s, const std::string& file) {
  Mesh m;
  TextCursor c{s, file};
  int64_t line_no = 0;
  auto where = [&] { return file + ":" + std::to_string(line_no); };
  auto index = [&](std::string_view tok) {
    const std::string_view head = tok.substr(0, tok.find('/'));
    int64_t v = 0;
    const auto r = std::from_chars(head.data(), head.data() + head.size(), v);
    if (r.ec != std::errc() || r.ptr != head.data() + head.size() || v == 0)
      throw InputError(where() + ": bad vertex index '" + std::string(tok.substr(0, 40)) + "'");
    const int64_t id = v > 0 ? v - 1 : m.vertex_count() + v;
    if (id < 0 || id >= m.vertex_count())
      throw InputError(where() + ": vertex index " + std::to_string(v) + " out of range (" +
                       std::to_string(m.vertex_count()) + " vertices so far)");
    return id;
  };
  while (c.pos < s.size()) {
    line_no = c.line;
    const std::string text(c.rest_of_line());
    TextCursor t{text, file};
    t.line = line_no;
    const auto key = t.token();
    if (key.empty() || key[0] == '#') {
      if (key == "#" && t.token() == "unit") {
        const auto u = t.token();
        if (!u.empty()) m.unit = std::string(u);
      }
      continue;
    }
    if (key == "v") {
      Mesh::Point p{t.number<float>("x"), t.number<float>("y"), t.number<float>("z")};
      m.points.push_back(p);
    } else if (key == "f" || key == "l") {
      std::vector<int64_t> ids;
      for (auto tok = t.token(); !tok.empty(); tok = t.token()) ids.push_back(index(tok));
      if (key == "f") {
        if (ids.size() < 3) throw InputError(where() + ": a face needs 3 vertices");
        for (size_t i = 2; i < ids.size(); ++i) m.add_triangle(ids[0], ids[i - 1], ids[i]);
      } else {
        if (ids.size() < 2) throw InputError(where() + ": a line needs 2 vertices");
        m.add_line(ids);
      }
    }
    // vn, vt, g, o, s, usemtl, mtllib, p: not part of a Mesh.
  }
  return m;
}

// ---------------------------------------------------------------- Amira HxSurface (ASCII)
std::string surf_write(const Mesh& m) {
  std::string out =
      "# HyperSurface 0.1 ASCII\n\n"
      "Parameters {\n"
      "    Materials {\n"
      "        Exterior {\n"
      "            Id 1\n"
      "        }\n"
      "        Inside {\n"
      "            Id 2\n"
      "        }\n"
      "    }\n"
      "    Unit \"" + m.unit + "\"\n"
      "}\n\n";
  out += "Vertices " + std::to_string(m.vertex_count()) + "\n";
  for (const auto& p : m.points) append_row(out, "    ", p);
  out += "NBranchingPoints 0\nNVerticesOnCurves 0\nBoundaryCurves 0\nPatches 1\n{\n";
  out += "InnerRegion Inside\nOuterRegion Exterior\nBoundaryID 0\nBranchingPoints 0\n\n";
  out += "Triangles " + std::to_string(m.triangle_count()) + "\n";
  for (const auto& t : m.triangles) append_row(out, "    ", t, 1);
  out += "}\n";
  return out;
}

Mesh surf_read(const std::string& s, const std::string& file) {
  Mesh m;
  TextCursor c{s, file};
  const auto head = c.rest_of_line();
  if (head.rfind("# HyperSurface", 0) != 0)
    throw InputError(file + ":1: not an Amira HxSurface file (expected '# HyperSurface 0.1 ASCII')");
  if (head.find("ASCII") == std::string_view::npos)
    throw InputError(file + ":1: only ASCII HxSurface files are read (this one is '" + std::string(head) + "')");
  bool have_vertices = false;
  int depth = 0;
  while (!c.at_end()) {
    const auto tok = c.token();
    if (tok == "{") {
      ++depth;
    } else if (tok == "}") {
      --depth;
    } else if (tok == "Unit" && depth == 1) {
      auto u = c.token();
      if (u.size() >= 2 && u.front() == '"' && u.back() == '"') u = u.substr(1, u.size() - 2);
      m.unit = std::string(u);
    } else if (tok == "Vertices" && depth == 0) {
      const int64_t n = checked_count(c, "vertex count", 6);
      m.points.resize(n);
      for (auto& p : m.points) p = {c.number<float>("x"), c.number<float>("y"), c.number<float>("z")};
      have_vertices = true;
    } else if (tok == "Triangles") {
      const int64_t n = checked_count(c, "triangle count", 6);
      m.triangles.reserve(m.triangles.size() + n);
      for (int64_t t = 0; t < n; ++t) {
        Mesh::Triangle tri{};
        for (auto& id : tri) {
          id = c.number<int64_t>("vertex index") - 1;
          if (id < 0 || id >= m.vertex_count())
            throw InputError(c.where() + ": vertex index " + std::to_string(id + 1) + " out of range 1.." +
                             std::to_string(m.vertex_count()));
        }
        m.triangles.push_back(tri);
      }
    } else if (tok == "Parameters" && depth == 0) {
      // Skip to the block; the Unit inside it is read above (depth 1), all else ignored.
    } else if (depth == 0 && (tok == "NBranchingPoints" || tok == "NVerticesOnCurves" || tok == "BoundaryCurves" ||
                              tok == "Patches")) {
      (void)checked_count(c, "count", 0);
    } else if (depth == 0 && !tok.empty() && tok[0] == '#') {
      (void)c.rest_of_line();
    }
    // Everything else (patch headers, materials) is skipped token by token.
    if (depth < 0) throw InputError(c.where() + ": unbalanced '}'");
  }
  if (!have_vertices) throw InputError(file + ": no 'Vertices' section");
  return m;
}

// ---------------------------------------------------------------- STL
std::string stl_write(const Mesh& m) {
  if (m.triangle_count() > UINT32_MAX) throw Error("STL holds at most 2^32-1 triangles");
  std::string out;
  out.reserve(84 + 50 * m.triangles.size());
  std::string header = "skelflow mesh, unit " + m.unit;
  header.resize(80, ' ');
  out += header;
  put<uint32_t>(out, static_cast<uint32_t>(m.triangle_count()));
  for (const auto& t : m.triangles) {
    const auto& a = m.points[t[0]];
    const auto& b = m.points[t[1]];
    const auto& c = m.points[t[2]];
    const double u[3] = {double(b[0]) - a[0], double(b[1]) - a[1], double(b[2]) - a[2]};
    const double v[3] = {double(c[0]) - a[0], double(c[1]) - a[1], double(c[2]) - a[2]};
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& x : n) x = len > 0 ? x / len : 0.0;
    for (double x : n) put<float>(out, static_cast<float>(x));
    for (int k = 0; k < 3; ++k)
      for (int a2 = 0; a2 < 3; ++a2) put<float>(out, m.points[t[k]][a2]);
    put<uint16_t>(out, 0);
  }
  return out;
}

struct PointKey {
  size_t operator()(const Mesh::Point& p) const {
    uint32_t b[3];
    std::memcpy(b, p.data(), 12);
    return (size_t(b[0]) * 73856093u) ^ (size_t(b[1]) * 19349663u) ^ (size_t(b[2]) * 83492791u);
  }
};

Mesh stl_read(const std::string& s, const std::string& file) {
  Mesh m;
  std::unordered_map<Mesh::Point, int64_t, PointKey> ids;
  auto vertex = [&](const Mesh::Point& p) {
    Mesh::Point q = p;
    for (float& x : q)
      if (x == 0.0f) x = 0.0f;  // -0 and +0 are one vertex
    const auto [it, fresh] = ids.emplace(q, m.vertex_count());
    if (fresh) m.points.push_back(p);
    return it->second;
  };
  const bool sized_binary = s.size() >= 84 && [&] {
    uint32_t n = 0;
    std::memcpy(&n, s.data() + 80, 4);
    return s.size() == 84 + 50 * uint64_t(n);
  }();
  if (!sized_binary && s.rfind("solid", 0) == 0) {
    TextCursor c{s, file};
    (void)c.rest_of_line();
    std::vector<int64_t> corner;
    while (!c.at_end()) {
      const auto tok = c.token();
      if (tok == "vertex") {
        corner.push_back(vertex({c.number<float>("x"), c.number<float>("y"), c.number<float>("z")}));
      } else if (tok == "endloop") {
        if (corner.size() < 3) throw InputError(c.where() + ": a facet with fewer than 3 vertices");
        for (size_t i = 2; i < corner.size(); ++i) m.add_triangle(corner[0], corner[i - 1], corner[i]);
        corner.clear();
      }
    }
    return m;
  }
  if (s.size() < 84) throw InputError(file + ": not an STL file (" + std::to_string(s.size()) + " bytes, binary STL needs 84)");
  uint32_t n = 0;
  std::memcpy(&n, s.data() + 80, 4);
  if (!sized_binary)
    throw InputError(file + ": binary STL of " + std::to_string(n) + " triangles needs " +
                     std::to_string(84 + 50 * uint64_t(n)) + " bytes, the file has " + std::to_string(s.size()));
  m.triangles.reserve(n);
  for (uint32_t t = 0; t < n; ++t) {
    const char* rec = s.data() + 84 + 50 * uint64_t(t) + 12;
    Mesh::Triangle tri{};
    for (int k = 0; k < 3; ++k) {
      Mesh::Point p;
      std::memcpy(p.data(), rec + 12 * k, 12);
      for (float x : p)
        if (!std::isfinite(x)) throw InputError(file + ": triangle " + std::to_string(t) + " has a non-finite vertex");
      tri[k] = vertex(p);
    }
    m.triangles.push_back(tri);
  }
  return m;
}

// ---------------------------------------------------------------- PLY
void check_name(const std::string& name) {
  if (name.empty() || std::any_of(name.begin(), name.end(), [](unsigned char ch) { return std::isspace(ch); }))
    throw InputError("input 'mesh': attribute name '" + name + "' cannot be a PLY property (empty or with spaces)");
}

std::string ply_write(const Mesh& m) {
  if (m.vertex_count() > INT32_MAX) throw Error("PLY vertex indices are 32-bit: at most 2^31-1 vertices");
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment skelflow mesh\ncomment unit " + m.unit + "\n";
  auto props = [&](const MeshAttributes& a) {
    for (const auto& [name, arr] : a) {
      check_name(name);
      h += std::string("property ") + (std::holds_alternative<std::vector<int32_t>>(arr) ? "int " : "float ") + name + "\n";
    }
  };
  h += "element vertex " + std::to_string(m.vertex_count()) + "\nproperty float x\nproperty float y\nproperty float z\n";
  props(m.vertex_attributes);
  h += "element face " + std::to_string(m.triangle_count()) + "\nproperty list uchar int vertex_indices\n";
  props(m.triangle_attributes);
  if (m.line_count() > 0) {
    h += "element line " + std::to_string(m.line_count()) + "\nproperty list int int vertex_indices\n";
    props(m.line_attributes);
  }
  h += "end_header\n";
  std::string out = std::move(h);
  auto values = [&](const MeshAttributes& a, int64_t i) {
    for (const auto& [name, arr] : a)
      std::visit([&](const auto& v) { put(out, v[i]); }, arr);
  };
  for (int64_t v = 0; v < m.vertex_count(); ++v) {
    for (float x : m.points[v]) put<float>(out, x);
    values(m.vertex_attributes, v);
  }
  for (int64_t t = 0; t < m.triangle_count(); ++t) {
    put<uint8_t>(out, 3);
    for (int64_t id : m.triangles[t]) put<int32_t>(out, static_cast<int32_t>(id));
    values(m.triangle_attributes, t);
  }
  for (int64_t l = 0; l < m.line_count(); ++l) {
    const int64_t b = m.line_offsets[l], e = m.line_offsets[l + 1];
    if (e - b > INT32_MAX) throw Error("PLY list lengths are 32-bit");
    put<int32_t>(out, static_cast<int32_t>(e - b));
    for (int64_t i = b; i < e; ++i) put<int32_t>(out, static_cast<int32_t>(m.line_vertices[i]));
    values(m.line_attributes, l);
  }
  return out;
}

enum class PlyType { i8, u8, i16, u16, i32, u32, f32, f64, none };
int ply_size(PlyType t) {
  switch (t) {
    case PlyType::i8: case PlyType::u8: return 1;
    case PlyType::i16: case PlyType::u16: return 2;
    case PlyType::i32: case PlyType::u32: case PlyType::f32: return 4;
    case PlyType::f64: return 8;
    case PlyType::none: break;
  }
  return 0;
}
PlyType ply_type(std::string_view n) {
  if (n == "char" || n == "int8") return PlyType::i8;
  if (n == "uchar" || n == "uint8") return PlyType::u8;
  if (n == "short" || n == "int16") return PlyType::i16;
  if (n == "ushort" || n == "uint16") return PlyType::u16;
  if (n == "int" || n == "int32") return PlyType::i32;
  if (n == "uint" || n == "uint32") return PlyType::u32;
  if (n == "float" || n == "float32") return PlyType::f32;
  if (n == "double" || n == "float64") return PlyType::f64;
  return PlyType::none;
}
bool ply_integer(PlyType t) { return t != PlyType::f32 && t != PlyType::f64; }

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::none;       // value type (list items for lists)
  PlyType count_type = PlyType::none;  // list length type; none for scalars
};
struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> props;
};

// Reads PLY values in ASCII or either binary byte order.
struct PlyReader {
  const std::string& s;
  const std::string& file;
  size_t pos;
  int mode;  // 0 ascii, 1 binary little endian, 2 binary big endian
  TextCursor text{s, file};
  double value(PlyType t) {
    if (mode == 0) {
      text.pos = pos;
      const double v = text.number<double>("a number");
      pos = text.pos;
      return v;
    }
    const int n = ply_size(t);
    if (pos + n > s.size()) throw InputError(file + ": the data ends early (at byte " + std::to_string(pos) + ")");
    unsigned char b[8];
    std::memcpy(b, s.data() + pos, n);
    if (mode == 2) std::reverse(b, b + n);
    pos += n;
    switch (t) {
      case PlyType::i8: { int8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::u8: return b[0];
      case PlyType::i16: { int16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::u16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::i32: { int32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::u32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::f32: { float v; std::memcpy(&v, b, 4); return v; }
      case PlyType::f64: { double v; std::memcpy(&v, b, 8); return v; }
      case PlyType::none: break;
    }
    return 0.0;
  }
};

Mesh ply_read(const std::string& s, const std::string& file) {
  Mesh m;
  TextCursor c{s, file};
  if (c.rest_of_line() != "ply") throw InputError(file + ":1: not a PLY file (expected 'ply')");
  int mode = -1;
  std::vector<PlyElement> elements;
  for (;;) {
    if (c.pos >= s.size()) throw InputError(c.where() + ": the header has no 'end_header'");
    const std::string where = c.where();
    const std::string text(c.rest_of_line());
    TextCursor t{text, file};
    const auto key = t.token();
    if (key == "end_header") break;
    if (key == "format") {
      const auto f = t.token();
      if (f == "ascii") mode = 0;
      else if (f == "binary_little_endian") mode = 1;
      else if (f == "binary_big_endian") mode = 2;
      else throw InputError(where + ": unknown PLY format '" + std::string(f) + "'");
    } else if (key == "comment") {
      if (t.token() == "unit") {
        const auto u = t.token();
        if (!u.empty()) m.unit = std::string(u);
      }
    } else if (key == "element") {
      PlyElement e;
      e.name = std::string(t.token());
      t.line = c.line - 1;
      e.count = t.number<int64_t>("an element count");
      if (e.count < 0) throw InputError(where + ": negative element count");
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) throw InputError(where + ": a property before any element");
      PlyProperty p;
      const auto ty = t.token();
      if (ty == "list") {
        p.count_type = ply_type(t.token());
        p.type = ply_type(t.token());
        if (p.count_type == PlyType::none || p.type == PlyType::none || !ply_integer(p.count_type))
          throw InputError(where + ": bad list property types");
      } else {
        p.type = ply_type(ty);
        if (p.type == PlyType::none) throw InputError(where + ": unknown property type '" + std::string(ty) + "'");
      }
      p.name = std::string(t.token());
      elements.back().props.push_back(p);
    } else if (key != "obj_info" && !key.empty()) {
      throw InputError(where + ": unexpected header line '" + text.substr(0, 60) + "'");
    }
  }
  if (mode < 0) throw InputError(file + ": the PLY header has no 'format' line");
  PlyReader r{s, file, c.pos, mode};
  r.text.line = c.line;
  for (const auto& e : elements) {
    // Smallest possible size of one element, to refuse impossible counts before allocating.
    uint64_t least = 0;
    for (const auto& p : e.props) least += mode == 0 ? 2 : static_cast<uint64_t>(ply_size(p.count_type == PlyType::none ? p.type : p.count_type));
    if (least > 0 && static_cast<uint64_t>(e.count) > (s.size() - r.pos) / least + 1)
      throw InputError(file + ": element '" + e.name + "' count " + std::to_string(e.count) + " is more than the file holds");
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face", is_line = e.name == "line";
    int ix = -1, iy = -1, iz = -1, ilist = -1;
    for (size_t k = 0; k < e.props.size(); ++k) {
      const auto& p = e.props[k];
      if (p.name == "x") ix = int(k);
      if (p.name == "y") iy = int(k);
      if (p.name == "z") iz = int(k);
      if (p.count_type != PlyType::none && (p.name == "vertex_indices" || p.name == "vertex_index")) ilist = int(k);
    }
    if (is_vertex && (ix < 0 || iy < 0 || iz < 0)) throw InputError(file + ": element 'vertex' lacks x, y or z");
    if ((is_face || is_line) && ilist < 0) throw InputError(file + ": element '" + e.name + "' lacks vertex_indices");
    MeshAttributes* attrs = is_vertex ? &m.vertex_attributes : is_face ? &m.triangle_attributes : is_line ? &m.line_attributes : nullptr;
    std::vector<std::pair<size_t, MeshAttribute*>> targets;
    if (attrs)
      for (size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        if (p.count_type != PlyType::none || int(k) == ix || int(k) == iy || int(k) == iz) continue;
        auto& a = (*attrs)[p.name];
        if (ply_integer(p.type)) a = std::vector<int32_t>{};
        else a = std::vector<float>{};
        targets.emplace_back(k, &a);
      }
    if (is_vertex) m.points.reserve(e.count);
    std::vector<int64_t> list;
    for (int64_t i = 0; i < e.count; ++i) {
      Mesh::Point pt{};
      int64_t copies = 1;  // triangles made from this face (fan), for its attribute values
      for (size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        if (p.count_type != PlyType::none) {
          const double nd = r.value(p.count_type);
          if (nd < 0 || nd > double(s.size())) throw InputError(file + ": element '" + e.name + "' " + std::to_string(i) + ": bad list length");
          const auto n = static_cast<int64_t>(nd);
          list.resize(n);
          for (auto& v : list) v = static_cast<int64_t>(r.value(p.type));
          if (int(k) != ilist) continue;
          for (int64_t v : list)
            if (v < 0) throw InputError(file + ": element '" + e.name + "' " + std::to_string(i) + ": negative vertex index");
          if (is_face) {
            if (n < 3) throw InputError(file + ": face " + std::to_string(i) + " has " + std::to_string(n) + " vertices");
            for (int64_t j = 2; j < n; ++j) m.add_triangle(list[0], list[j - 1], list[j]);
            copies = n - 2;
          } else if (is_line) {
            if (n < 2) throw InputError(file + ": line " + std::to_string(i) + " has " + std::to_string(n) + " vertices");
            m.add_line(list);
          }
          continue;
        }
        const double v = r.value(p.type);
        if (int(k) == ix || int(k) == iy || int(k) == iz) {
          if (!std::isfinite(v)) throw InputError(file + ": vertex " + std::to_string(i) + " is not finite");
          pt[int(k) == ix ? 0 : int(k) == iy ? 1 : 2] = static_cast<float>(v);
          continue;
        }
        for (auto& [tk, a] : targets)
          if (tk == k)
            std::visit([&](auto& vec) {
              for (int64_t cpy = 0; cpy < copies; ++cpy) vec.push_back(static_cast<typename std::decay_t<decltype(vec)>::value_type>(v));
            }, *a);
      }
      if (is_vertex) m.points.push_back(pt);
    }
  }
  for (const auto& t : m.triangles)
    for (int64_t id : t)
      if (id >= m.vertex_count())
        throw InputError(file + ": a face names vertex " + std::to_string(id) + " of " + std::to_string(m.vertex_count()));
  for (int64_t id : m.line_vertices)
    if (id >= m.vertex_count())
      throw InputError(file + ": a line names vertex " + std::to_string(id) + " of " + std::to_string(m.vertex_count()));
  return m;
}

// ---------------------------------------------------------------- VTP (through VTK)
// Collects VTK's error and warning messages of one reader or writer instead of printing them.
class VtkMessages : public vtkCommand {
public:
  static VtkMessages* New() { return new VtkMessages; }
  void Execute(vtkObject*, unsigned long event, void* data) override {
    if (event == vtkCommand::ErrorEvent && data && first.empty()) first = static_cast<const char*>(data);
    if (event == vtkCommand::ErrorEvent) failed = true;
  }
  std::string first;
  bool failed = false;
};

// VTK's message without its "ERROR: In FILE, line N" line and "vtkClass (0x...): " prefix.
std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  if (const auto nl = s.rfind('\n'); nl != std::string::npos) s = s.substr(nl + 1);
  if (const auto p = s.find("): "); p != std::string::npos && p < 80) s = s.substr(p + 3);
  return s.size() > 200 ? s.substr(0, 200) : s;
}

void vtp_write(const Mesh& m, const std::filesystem::path& path) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    auto poly = mesh_to_vtk(m);
    auto w = vtkSmartPointer<vtkXMLPolyDataWriter>::New();
    auto msg = vtkSmartPointer<VtkMessages>::New();
    w->AddObserver(vtkCommand::ErrorEvent, msg);
    w->AddObserver(vtkCommand::WarningEvent, msg);
    w->GetExecutive()->AddObserver(vtkCommand::ErrorEvent, msg);
    w->SetInputData(poly);
    w->SetFileName(tmp.string().c_str());
    w->SetDataModeToAppended();
    w->EncodeAppendedDataOff();
    w->SetCompressorTypeToZLib();
    w->SetHeaderTypeToUInt64();
    if (!w->Write() || msg->failed) {
      // VTK's message names the temporary; users see the file they asked for.
      std::string why = msg->first.empty() ? "VTK's writer failed" : trim(msg->first);
      const std::string t = tmp.string(), shown = display_path(tmp).string();
      for (auto at = why.find(t); at != std::string::npos; at = why.find(t, at + shown.size())) why.replace(at, t.size(), shown);
      throw Error("cannot write " + shown + ": " + why);
    }
  });
}

Mesh vtp_read(const std::filesystem::path& path) {
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      std::error_code ec;
      throw InputError(path.string() + (std::filesystem::exists(path, ec) ? ": cannot open the file for reading" : ": file not found"));
    }
  }
  auto r = vtkSmartPointer<vtkXMLPolyDataReader>::New();
  auto msg = vtkSmartPointer<VtkMessages>::New();
  r->AddObserver(vtkCommand::ErrorEvent, msg);
  r->AddObserver(vtkCommand::WarningEvent, msg);
  r->SetReaderErrorObserver(msg);
  r->SetParserErrorObserver(msg);
  r->GetExecutive()->AddObserver(vtkCommand::ErrorEvent, msg);
  r->SetFileName(path.string().c_str());
  r->Update();
  if (msg->failed || r->GetErrorCode() != 0 || !r->GetOutput())
    throw InputError(path.string() + ": not a readable VTK XML PolyData file" +
                     (msg->first.empty() ? std::string() : " (" + trim(msg->first) + ")"));
  return mesh_from_vtk(*r->GetOutput(), path.string());
}

}  // namespace

MeshFormat mesh_format_from_path(const std::filesystem::path& path, const std::string& what) {
  const std::string ext = text::to_lower(path.extension().string());
  if (ext == ".vtp") return MeshFormat::vtp;
  if (ext == ".ply") return MeshFormat::ply;
  if (ext == ".stl") return MeshFormat::stl;
  if (ext == ".obj") return MeshFormat::obj;
  if (ext == ".surf") return MeshFormat::surf;
  throw InputError(what + ": unknown mesh file extension '" + ext + "' of '" + path.string() +
                   "'; expected .vtp, .ply, .stl, .obj or .surf");
}

void write_mesh(const Mesh& in, const std::filesystem::path& path, MeshFormat format) {
  check_writable(in);
  // Files hold world coordinates (Mesh::frame_direction): the one place where the direction of the
  // source volume is applied to mesh points.
  Mesh world;
  const bool rotated = in.frame_direction != kIdentityDirection;
  if (rotated) {
    world = in;
    for (auto& p : world.points) {
      const Vec3 w = world_position({p[0], p[1], p[2]}, in.frame_origin, in.frame_direction);
      p = {static_cast<float>(w[0]), static_cast<float>(w[1]), static_cast<float>(w[2])};
    }
    world.frame_direction = kIdentityDirection;
  }
  const Mesh& mesh = rotated ? world : in;
  switch (format) {
    case MeshFormat::vtp: vtp_write(mesh, path); return;
    case MeshFormat::ply: write_file_atomically(path, ply_write(mesh)); return;
    case MeshFormat::stl: write_file_atomically(path, stl_write(mesh)); return;
    case MeshFormat::obj: write_file_atomically(path, obj_write(mesh)); return;
    case MeshFormat::surf: write_file_atomically(path, surf_write(mesh)); return;
  }
}

Mesh read_mesh(const std::filesystem::path& path, MeshFormat format) {
  if (format == MeshFormat::vtp) return vtp_read(path);
  const std::string s = read_text(path);
  const std::string file = path.string();
  switch (format) {
    case MeshFormat::ply: return ply_read(s, file);
    case MeshFormat::stl: return stl_read(s, file);
    case MeshFormat::obj: return obj_read(s, file);
    case MeshFormat::surf: return surf_read(s, file);
    case MeshFormat::vtp: break;
  }
  return {};
}

}  // namespace skel::io
