#include "io/graph_io.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <functional>
#include <regex>
#include <set>
#include <sstream>

#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"
#include "skel/transform.hpp"
#include "io/vtk_xml_data.hpp"

#include <expat.h>

namespace skel::io {

namespace {

// ---------------------------------------------------------------- text helpers
void put_f(std::string& s, float v) { text::append_double(s, static_cast<double>(v), 9); }
void put_d(std::string& s, double v) { text::append_double(s, v, 17); }
void put_i(std::string& s, int64_t v) { s += std::to_string(v); }

std::string clean_name(const std::string& n) {
  std::string o = n;
  for (char& c : o)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.')) c = '_';
  return o.empty() ? "_" : o;
}

std::string xml_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}
// Whitespace-separated numbers of text[begin, end). Messages start with `where`; with `file` set they
// read "file:LINE: where: ..." where LINE counts from `first_line` at text[0] (the offending value's
// line; the block's first line when values run out).
class NumberReader {
public:
  NumberReader(const std::string& text, size_t begin, size_t end, std::string where, std::string file = {},
               int64_t first_line = 1)
      : text_(text.data()), begin_(text.data() + begin), p_(begin_), end_(text.data() + end), where_(std::move(where)),
        file_(std::move(file)), first_line_(first_line) {}
  double next() {
    skip();
    if (p_ >= end_) throw InputError(at(begin_) + ": fewer values than expected");
    last_ = p_;
    double v = 0.0;
    auto [ptr, ec] = std::from_chars(p_, end_, v);
    if (ec != std::errc() || (ptr < end_ && !separator(*ptr))) {
      // from_chars rejects "nan"/"inf" spellings of some writers and leading '+'.
      char* e = nullptr;
      std::string tok(p_, std::find_if(p_, end_, [](char c) { return separator(c); }));
      v = std::strtod(tok.c_str(), &e);
      if (e != tok.c_str() + tok.size()) throw InputError(at(p_) + ": expected a number, got '" + tok.substr(0, 20) + "'");
      p_ += tok.size();
      return v;
    }
    p_ = ptr;
    return v;
  }
  // A finite value: coordinates and radii (`what` names the value in the message).
  double next_finite(const char* what) {
    const double v = next();
    if (!std::isfinite(v)) throw InputError(where_last() + ": " + what + " is not a finite number");
    return v;
  }
  int64_t next_int() {
    const char* start = (skip(), p_);
    const double v = next();
    if (v != std::floor(v)) throw InputError(at(start) + ": expected an integer, got " + std::to_string(v));
    if (std::abs(v) > 9.0e15) throw InputError(at(start) + ": integer " + text::format_double(v, 6) + " is out of range");
    return static_cast<int64_t>(v);
  }
  bool at_end() {
    skip();
    return p_ >= end_;
  }
  // Message prefix at the value read last (for checks of its value by the caller).
  [[nodiscard]] std::string where_last() const { return at(last_); }

private:
  static bool separator(char c) { return std::isspace(static_cast<unsigned char>(c)) || c == ','; }
  void skip() {
    while (p_ < end_ && separator(*p_)) ++p_;
  }
  [[nodiscard]] std::string at(const char* p) const {
    if (file_.empty()) return where_;
    return file_ + ":" + std::to_string(first_line_ + std::count(text_, p, '\n')) + ": " + where_;
  }
  const char* text_;
  const char* begin_;
  const char* p_;
  const char* end_;
  const char* last_ = p_;
  std::string where_, file_;
  int64_t first_line_;
};

// A value stored as float: finite doubles beyond float's range would become infinite.
float finite_float(double v, const NumberReader& r, const char* what) {
  if (std::abs(v) > static_cast<double>(std::numeric_limits<float>::max()))
    throw InputError(r.where_last() + ": " + what + " is not a finite number");
  return static_cast<float>(v);
}

// A label (int32) from a number of the file: NaN and values outside int32 are refused (the cast
// would be undefined behaviour; libFuzzer found 1e11 in a GraphML <data> and -7.2e18 in VTP cell
// data). Fractions are cut towards zero, as before.
int32_t label_of(double v, const std::string& where) {
  if (!(v > static_cast<double>(std::numeric_limits<int32_t>::min()) - 1.0 &&
        v < static_cast<double>(std::numeric_limits<int32_t>::max()) + 1.0))
    throw InputError(where + ": label value " + text::format_double(v, 17) + " is not a 32-bit integer");
  return static_cast<int32_t>(v);
}

double to_num(const std::string& s, const std::string& where) {
  char* e = nullptr;
  const double v = std::strtod(s.c_str(), &e);
  if (e == s.c_str()) throw InputError(where + ": expected a number, got '" + s + "'");
  return v;
}

// A coordinate or radius: a number that is finite.
double finite_num(const std::string& s, const std::string& where, const char* what) {
  const double v = to_num(s, where);
  if (!std::isfinite(v)) throw InputError(where + ": " + what + " is not a finite number ('" + text::trim(s).substr(0, 24) + "')");
  return v;
}

// Sets polyline end points to their nodes' positions (files store them separately).
void snap_ends(SpatialGraph& g) {
  for (auto& e : g.edges) {
    e.points.front() = g.positions[e.node0];
    e.points.back() = g.positions[e.node1];
  }
}

void check_node_id(int64_t id, int64_t n, const std::string& where) {
  if (id < 0 || id >= n)
    throw InputError(where + ": node id " + std::to_string(id) + " out of range (" + std::to_string(n) + " nodes)");
}

// ---------------------------------------------------------------- XML (expat)
// The elements of an XML file, parsed by expat (a streaming parser: nesting depth costs heap, never
// stack). Elements live in one deque and link to their children by pointer, so neither building nor
// destroying the tree recurses, however deep the file nests.
struct Xml {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attrs;
  std::string text;
  int64_t line = 1;       // line of the start tag
  int64_t text_line = 1;  // line of the file where `text` starts (for messages)
  std::vector<const Xml*> children;
  [[nodiscard]] const std::string* attr(const std::string& k) const {
    for (const auto& [a, v] : attrs)
      if (a == k) return &v;
    return nullptr;
  }
  [[nodiscard]] std::string attr_or(const std::string& k, const std::string& d) const {
    const auto* v = attr(k);
    return v ? *v : d;
  }
  [[nodiscard]] const Xml* child(const std::string& n) const {
    for (const auto* c : children)
      if (c->name == n) return c;
    return nullptr;
  }
};

struct XmlDoc {
  std::deque<Xml> elements;  // elements[0]: the document (its one child is the root element)
  [[nodiscard]] const Xml& root() const { return elements.front(); }
};

XmlDoc parse_xml(const std::string& s, const std::string& source) {
  struct State {
    XmlDoc doc;
    std::vector<Xml*> stack;
    XML_Parser parser = nullptr;
  } st;
  st.doc.elements.emplace_back();
  st.stack.push_back(&st.doc.elements.front());
  std::unique_ptr<std::remove_pointer_t<XML_Parser>, void (*)(XML_Parser)> parser(XML_ParserCreate(nullptr),
                                                                                  XML_ParserFree);
  if (!parser) throw Error("XML parser: out of memory");
  st.parser = parser.get();
  XML_SetUserData(parser.get(), &st);
  XML_SetElementHandler(
      parser.get(),
      [](void* ud, const XML_Char* name, const XML_Char** atts) {
        auto& S = *static_cast<State*>(ud);
        Xml& el = S.doc.elements.emplace_back();
        el.name = name;
        for (const XML_Char** a = atts; *a; a += 2) el.attrs.emplace_back(a[0], a[1]);
        el.line = static_cast<int64_t>(XML_GetCurrentLineNumber(S.parser));
        el.text_line = el.line;
        S.stack.back()->children.push_back(&el);
        S.stack.push_back(&el);
      },
      [](void* ud, const XML_Char*) { static_cast<State*>(ud)->stack.pop_back(); });
  XML_SetCharacterDataHandler(parser.get(), [](void* ud, const XML_Char* text, int len) {
    auto& S = *static_cast<State*>(ud);
    Xml& el = *S.stack.back();
    if (el.text.empty()) el.text_line = static_cast<int64_t>(XML_GetCurrentLineNumber(S.parser));
    el.text.append(text, static_cast<size_t>(len));
  });
  // Fed in pieces: expat takes an int length.
  constexpr size_t piece = size_t{1} << 30;
  size_t off = 0;
  XML_Status status = XML_STATUS_OK;
  do {
    const size_t n = std::min(piece, s.size() - off);
    const bool last = off + n == s.size();
    status = XML_Parse(parser.get(), s.data() + off, static_cast<int>(n), last ? 1 : 0);
    off += n;
    if (last) break;
  } while (status == XML_STATUS_OK);
  if (status != XML_STATUS_OK) {
    const XML_Error code = XML_GetErrorCode(parser.get());
    const int64_t end_line = 1 + std::count(s.begin(), s.end(), '\n');
    const auto line = static_cast<int64_t>(XML_GetCurrentLineNumber(parser.get()));
    const bool at_end = XML_GetCurrentByteIndex(parser.get()) >= static_cast<XML_Index>(s.size());
    if (code == XML_ERROR_UNCLOSED_TOKEN || code == XML_ERROR_PARTIAL_CHAR)
      throw InputError(source + ":" + std::to_string(line) + ": unterminated XML tag");
    if (at_end && st.stack.size() > 1)
      throw InputError(source + ":" + std::to_string(st.stack.back()->line) + ": unclosed XML element <" +
                       st.stack.back()->name + "> (the file ends at line " + std::to_string(end_line) + ")");
    throw InputError(source + ":" + std::to_string(line) + ":" +
                     std::to_string(XML_GetCurrentColumnNumber(parser.get()) + 1) +
                     ": XML syntax error: " + XML_ErrorString(code));
  }
  return std::move(st.doc);
}

// Whether the graph knows where its source volume lies (origin, direction): then the files say so.
bool has_placement(const Grid& g) {
  return g.voxel_count() > 0 || g.origin != Vec3{0.0, 0.0, 0.0} || g.direction != kIdentityDirection;
}

// Graph files hold world coordinates, origin + D·(p − origin) with the source volume's direction D,
// so that a centerline overlays its image in Slicer or ParaView. In memory, positions stay in the
// volume's axis-aligned frame (origin + index·spacing), which every algorithm that maps graph points
// back to voxels assumes (label propagation, densities, skeleton distances); graph_to_text maps them
// out and graph_from_text maps a file that states a direction back in: this is the one place.
SpatialGraph with_direction_applied(const SpatialGraph& g, bool to_world) {
  const Direction& d = g.source_grid.direction;
  const Vec3& o = g.source_grid.origin;
  SpatialGraph out = g;
  if (to_world) {
    for (auto& p : out.positions) p = world_position(p, o, d);
    for (auto& e : out.edges)
      for (auto& p : e.points) p = world_position(p, o, d);
    return out;
  }
  const Matrix3 m{{{d[0], d[1], d[2]}, {d[3], d[4], d[5]}, {d[6], d[7], d[8]}}};
  Vec3 t{};
  for (size_t r = 0; r < 3; ++r) t[r] = o[r] - (m[r][0] * o[0] + m[r][1] * o[1] + m[r][2] * o[2]);
  const Transform back = Transform(m, t).inverse();
  for (auto& p : out.positions) p = back.apply(p);
  for (auto& e : out.edges)
    for (auto& p : e.points) p = back.apply(p);
  return out;
}

// ---------------------------------------------------------------- Amira
// A string inside Amira's double quotes (quotes and line breaks would end it).
std::string amira_string(const std::string& s) {
  std::string o;
  for (char c : s) o += (c == '"' || c == '\n' || c == '\r' || c == '\\') ? '_' : c;
  return o;
}

std::string amira_write(const SpatialGraph& g) {
  struct Block {
    std::string loc, type, name;
    int comps;
    std::function<void(std::string&)> data;
  };
  std::vector<Block> blocks;
  const int64_t nn = g.node_count(), ne = g.edge_count(), np = g.point_count();
  blocks.push_back({"VERTEX", "float", "VertexCoordinates", 3, [&](std::string& s) {
                      for (const auto& p : g.positions) {
                        put_f(s, float(p[0])); s += ' '; put_f(s, float(p[1])); s += ' '; put_f(s, float(p[2])); s += '\n';
                      }
                    }});
  blocks.push_back({"EDGE", "int", "EdgeConnectivity", 2, [&](std::string& s) {
                      for (const auto& e : g.edges) { put_i(s, e.node0); s += ' '; put_i(s, e.node1); s += '\n'; }
                    }});
  blocks.push_back({"EDGE", "int", "NumEdgePoints", 1, [&](std::string& s) {
                      for (const auto& e : g.edges) { put_i(s, static_cast<int64_t>(e.points.size())); s += '\n'; }
                    }});
  blocks.push_back({"POINT", "float", "EdgePointCoordinates", 3, [&](std::string& s) {
                      for (const auto& e : g.edges)
                        for (const auto& p : e.points) {
                          put_f(s, float(p[0])); s += ' '; put_f(s, float(p[1])); s += ' '; put_f(s, float(p[2])); s += '\n';
                        }
                    }});
  for (const auto& [name, v] : g.point_attributes) {
    const auto* vals = &v;
    blocks.push_back({"POINT", "float", name == "radius" ? "thickness" : clean_name(name), 1, [vals](std::string& s) {
                        for (const auto& e : *vals)
                          for (float x : e) { put_f(s, x); s += '\n'; }
                      }});
  }
  auto add_scalar = [&](const char* loc, const char* type, const std::string& name, auto* vals) {
    blocks.push_back({loc, type, clean_name(name), 1, [vals](std::string& s) {
                        for (auto x : *vals) {
                          if constexpr (std::is_same_v<std::decay_t<decltype(x)>, float>) put_f(s, x);
                          else put_i(s, x);
                          s += '\n';
                        }
                      }});
  };
  for (const auto& [name, v] : g.node_attributes) add_scalar("VERTEX", "float", name, &v);
  for (const auto& [name, v] : g.node_labels) add_scalar("VERTEX", "int", name, &v);
  for (const auto& [name, v] : g.edge_attributes) add_scalar("EDGE", "float", name, &v);
  for (const auto& [name, v] : g.edge_labels) add_scalar("EDGE", "int", name, &v);

  std::string s = "# AmiraMesh 3D ASCII 2.0\n\n\n";
  s += "define VERTEX " + std::to_string(nn) + "\n";
  s += "define EDGE " + std::to_string(ne) + "\n";
  s += "define POINT " + std::to_string(np) + "\n\n";
  // Amira's own layout of the coordinate unit (Edit > Units); the source volume's transform as
  // parameters of ours (Amira ignores unknown parameters).
  s += "Parameters {\n    Units {\n        Coordinates \"" + amira_string(g.unit) + "\"\n    }\n";
  if (has_placement(g.source_grid)) {
    s += "    SkelflowOrigin";
    for (double v : g.source_grid.origin) { s += ' '; put_d(s, v); }
    s += "\n    SkelflowDirection";
    for (double v : g.source_grid.direction) { s += ' '; put_d(s, v); }
    s += "\n";
  }
  s += "    ContentType \"HxSpatialGraph\"\n}\n\n";
  for (size_t k = 0; k < blocks.size(); ++k) {
    const auto& b = blocks[k];
    s += b.loc + " { " + b.type + (b.comps > 1 ? "[" + std::to_string(b.comps) + "]" : "") + " " + b.name +
         " } @" + std::to_string(k + 1) + "\n";
  }
  s += "\n# Data section follows\n";
  for (size_t k = 0; k < blocks.size(); ++k) {
    s += '@';  // (char, not "@" + std::to_string: GCC 12 warns falsely about that with -Wrestrict)
    s += std::to_string(k + 1);
    s += '\n';
    blocks[k].data(s);
    s += "\n";
  }
  return s;
}

SpatialGraph amira_read(const std::string& text, const std::string& src) {
  if (text.rfind("# AmiraMesh", 0) != 0 && text.rfind("# HyperSurface", 0) != 0)
    throw InputError(src + ": not an AmiraMesh file (first line must start with '# AmiraMesh')");
  const std::string first = text.substr(0, text.find('\n'));
  if (first.find("ASCII") == std::string::npos)
    throw InputError(src + ": only ASCII AmiraMesh is supported, header says '" + first + "'");
  std::map<std::string, int64_t> counts;
  std::map<std::string, int> count_line;
  // Header integers (counts, components, block numbers) without std::stoll's exceptions.
  auto header_int = [&](const std::string& digits, int line_no) {
    int64_t v = 0;
    if (!text::parse_int(digits, v) || v > std::numeric_limits<int32_t>::max() * int64_t{1024})
      throw InputError(src + ":" + std::to_string(line_no) + ": number " + digits.substr(0, 24) + " is too large");
    return v;
  };
  struct Decl {
    std::string loc, type, name;
    int comps = 1;
  };
  std::map<int, Decl> decls;
  static const std::regex def_re(R"(^\s*define\s+(\w+)\s+(\d+)\s*$)");
  static const std::regex decl_re(R"(^\s*(\w+)\s*\{\s*(\w+)\s*(\[\s*(\d+)\s*\])?\s+(\w+)\s*\}\s*@(\d+))");
  static const std::regex at_re(R"(^@(\d+)\s*$)");
  static const std::regex unit_re(R"re(^\s*Coordinates\s+"([^"]*)")re");
  static const std::regex vec_re(R"(^\s*Skelflow(Origin|Direction)\s+(.*)$)");
  std::string unit;
  std::vector<double> origin, direction;
  // Header: up to the first line that is only "@k".
  size_t pos = 0, data_start = std::string::npos;
  int line_no = 0;
  while (pos < text.size()) {
    size_t e = text.find('\n', pos);
    if (e == std::string::npos) e = text.size();
    std::string line = text.substr(pos, e - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    ++line_no;
    std::smatch m;
    if (std::regex_match(line, m, at_re)) {
      data_start = pos;
      break;
    }
    if (std::regex_match(line, m, def_re)) {
      const int64_t c = header_int(m[2], line_no);
      // Every element is at least one ASCII value of >= 2 bytes (digit and separator): a count the
      // file cannot hold is refused here, before anything is allocated for it.
      if (c > static_cast<int64_t>(text.size() / 2))
        throw InputError(src + ":" + std::to_string(line_no) + ": 'define " + m[1].str() + " " + m[2].str() +
                         "' declares more elements than a file of " + std::to_string(text.size()) + " bytes can hold");
      counts[m[1]] = c;
      count_line[m[1]] = line_no;
    } else if (std::regex_search(line, m, unit_re)) {
      unit = m[1];
    } else if (std::regex_match(line, m, vec_re)) {
      NumberReader r(line, static_cast<size_t>(m.position(2)), line.size(), "Skelflow" + m[1].str(), src, line_no);
      auto& v = m[1] == "Origin" ? origin : direction;
      v.clear();
      while (!r.at_end() && v.size() < 10) v.push_back(r.next_finite("a transform value"));
    } else if (std::regex_search(line, m, decl_re)) {
      const int64_t comps = m[4].matched ? header_int(m[4], line_no) : 1;
      decls[static_cast<int>(std::min<int64_t>(header_int(m[6], line_no), std::numeric_limits<int>::max()))] =
          Decl{m[1], m[2], m[5], static_cast<int>(std::min<int64_t>(comps, 1 << 20))};
    }
    pos = e + 1;
  }
  if (data_start == std::string::npos) throw InputError(src + ": no data section (no line '@1')");
  // Data blocks.
  std::map<int, std::pair<size_t, size_t>> ranges;
  {
    size_t p = data_start;
    int current = -1;
    size_t begin = 0;
    while (p < text.size()) {
      size_t e = text.find('\n', p);
      if (e == std::string::npos) e = text.size();
      if (text[p] == '@') {
        std::string line = text.substr(p, e - p);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::smatch m;
        if (std::regex_match(line, m, at_re)) {
          if (current >= 0) ranges[current] = {begin, p};
          int64_t k = 0;
          current = text::parse_int(m[1].str(), k) && k <= std::numeric_limits<int>::max() ? static_cast<int>(k) : -1;
          begin = e;
        }
      }
      p = e + 1;
    }
    if (current >= 0) ranges[current] = {begin, text.size()};
  }
  auto count_of = [&](const std::string& loc) {
    auto it = counts.find(loc);
    if (it == counts.end()) throw InputError(src + ": missing 'define " + loc + " n'");
    return it->second;
  };
  auto find_decl = [&](const std::string& loc, const std::string& name) -> int {
    for (const auto& [k, d] : decls)
      if (d.loc == loc && d.name == name) return k;
    throw InputError(src + ": missing '" + loc + " { ... " + name + " }' (is this an HxSpatialGraph?)");
  };
  auto reader = [&](int k) {
    auto it = ranges.find(k);
    if (it == ranges.end()) throw InputError(src + ": data block @" + std::to_string(k) + " is missing");
    auto d = decls.find(k);
    return NumberReader(text, it->second.first, it->second.second,
                        "block @" + std::to_string(k) + (d == decls.end() ? std::string() : " (" + d->second.name + ")"), src);
  };
  const int64_t nn = count_of("VERTEX"), ne = count_of("EDGE"), np = count_of("POINT");
  // Values per element of the structural blocks: 3 coordinates per vertex and point, 2 node ids and
  // a point count per edge, each >= 2 bytes.
  if (6 * nn + 6 * ne + 6 * np > static_cast<int64_t>(text.size()))
    throw InputError(src + ": 'define VERTEX " + std::to_string(nn) + "', 'define EDGE " + std::to_string(ne) +
                     "' and 'define POINT " + std::to_string(np) + "' need more values than a file of " +
                     std::to_string(text.size()) + " bytes can hold");
  SpatialGraph g;
  if (!unit.empty()) g.unit = unit;
  if (origin.size() == 3 && direction.size() == 9) {
    std::copy(origin.begin(), origin.end(), g.source_grid.origin.begin());
    std::copy(direction.begin(), direction.end(), g.source_grid.direction.begin());
  }
  g.source_grid.unit = g.unit;
  g.positions.resize(nn);
  {
    auto r = reader(find_decl("VERTEX", "VertexCoordinates"));
    for (auto& p : g.positions)
      for (int a = 0; a < 3; ++a) p[a] = finite_float(r.next_finite("a coordinate"), r, "a coordinate");
  }
  g.edges.resize(ne);
  {
    auto r = reader(find_decl("EDGE", "EdgeConnectivity"));
    for (auto& e : g.edges) {
      e.node0 = r.next_int();
      check_node_id(e.node0, nn, r.where_last());
      e.node1 = r.next_int();
      check_node_id(e.node1, nn, r.where_last());
    }
  }
  std::vector<int64_t> npts(ne);
  {
    auto r = reader(find_decl("EDGE", "NumEdgePoints"));
    int64_t sum = 0;
    for (auto& c : npts) {
      c = r.next_int();
      if (c < 2) throw InputError(r.where_last() + ": an edge has " + std::to_string(c) + " points, expected >= 2");
      if (c > np)
        throw InputError(r.where_last() + ": an edge has " + std::to_string(c) + " points, more than 'define POINT " +
                         std::to_string(np) + "'");
      sum += c;
    }
    if (sum != np)
      throw InputError(src + ": NumEdgePoints sum to " + std::to_string(sum) + " but 'define POINT' says " + std::to_string(np));
  }
  {
    auto r = reader(find_decl("POINT", "EdgePointCoordinates"));
    for (int64_t e = 0; e < ne; ++e) {
      g.edges[e].points.resize(npts[e]);
      for (auto& p : g.edges[e].points)
        for (int a = 0; a < 3; ++a) p[a] = finite_float(r.next_finite("a coordinate"), r, "a coordinate");
    }
  }
  snap_ends(g);
  static const std::set<std::string> structural = {"VertexCoordinates", "EdgeConnectivity", "NumEdgePoints",
                                                   "EdgePointCoordinates"};
  for (const auto& [k, d] : decls) {
    if (structural.count(d.name) || d.comps != 1) continue;
    auto r = reader(k);
    const bool is_int = d.type == "int" || d.type == "byte" || d.type == "short";
    if (d.loc == "POINT") {
      const bool radius = d.name == "thickness" || d.name == "radius";
      auto& v = g.point_attributes[d.name == "thickness" ? "radius" : d.name];
      v.resize(ne);
      for (int64_t e = 0; e < ne; ++e) {
        v[e].resize(npts[e]);
        for (auto& x : v[e]) x = radius ? finite_float(r.next_finite("a radius"), r, "a radius") : static_cast<float>(r.next());
      }
    } else if (d.loc == "VERTEX" || d.loc == "EDGE") {
      const int64_t cnt = d.loc == "VERTEX" ? nn : ne;
      if (is_int) {
        auto& v = (d.loc == "VERTEX" ? g.node_labels : g.edge_labels)[d.name];
        v.resize(cnt);
        for (auto& x : v) x = static_cast<int32_t>(r.next_int());
      } else {
        auto& v = (d.loc == "VERTEX" ? g.node_attributes : g.edge_attributes)[d.name];
        v.resize(cnt);
        const bool radius = d.loc == "VERTEX" && d.name == "radius";
        for (auto& x : v) x = radius ? finite_float(r.next_finite("a radius"), r, "a radius") : static_cast<float>(r.next());
      }
    }
  }
  return g;
}

// ---------------------------------------------------------------- VTK XML PolyData
// Writes DataArrays as ASCII text, or as appended raw data (zlib-compressed in blocks, UInt64
// headers: what VTK writes by default) collected in `appended` and written after the XML.
class VtpWriter {
public:
  explicit VtpWriter(bool binary) : binary_(binary) {}
  template <class T>
  void array(std::string& s, const char* type, const std::string& name, int comps, const std::vector<T>& values,
             bool field = false, int64_t tuples = -1) {
    s += field ? "      <DataArray type=\"" : "        <DataArray type=\"";
    s += type;
    s += "\" Name=\"" + xml_escape(name) + "\"";
    if (comps > 1) s += " NumberOfComponents=\"" + std::to_string(comps) + "\"";
    if (field)
      s += " NumberOfTuples=\"" +
           std::to_string(tuples >= 0 ? static_cast<size_t>(tuples) : values.size() / static_cast<size_t>(comps)) + "\"";
    if (binary_) {
      s += " format=\"appended\" offset=\"" + std::to_string(appended_.size()) + "\"/>\n";
      appended_ += vtk::encode_array(values.data(), values.size() * sizeof(T), true);
      return;
    }
    s += " format=\"ascii\">\n";
    size_t col = 0;
    for (const auto& x : values) {
      if constexpr (std::is_same_v<T, float>) put_f(s, x);
      else if constexpr (std::is_same_v<T, double>) put_d(s, x);
      else put_i(s, static_cast<int64_t>(x));
      s += (++col % 9 == 0) ? '\n' : ' ';
    }
    s += field ? "\n      </DataArray>\n" : "\n        </DataArray>\n";
  }
  // A field-data string array of one string (VTK: the characters, each string ended by 0).
  void string(std::string& s, const std::string& name, const std::string& value) {
    std::vector<uint8_t> chars(value.begin(), value.end());
    chars.push_back(0);
    // VTK names the type "String"; ASCII stores the character codes.
    std::string t;
    array(t, "String", name, 1, chars, true, 1);
    s += t;
  }
  [[nodiscard]] bool binary() const { return binary_; }
  [[nodiscard]] const std::string& appended() const { return appended_; }

private:
  bool binary_;
  std::string appended_;
};

std::string vtp_write(const SpatialGraph& g, bool binary) {
  const int64_t nn = g.node_count(), ne = g.edge_count();
  const int64_t np = nn + g.point_count();
  VtpWriter w(binary);
  std::string s = "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"";
  s += std::endian::native == std::endian::big ? "BigEndian" : "LittleEndian";
  s += "\" header_type=\"UInt64\"";
  if (binary) s += " compressor=\"vtkZLibDataCompressor\"";
  s += ">\n  <PolyData>\n";
  // Field data: the unit and, when known, the source volume's origin and direction.
  s += "    <FieldData>\n";
  w.string(s, "unit", g.unit);
  if (has_placement(g.source_grid)) {
    w.array(s, "Float64", "origin", 3, std::vector<double>(g.source_grid.origin.begin(), g.source_grid.origin.end()), true);
    w.array(s, "Float64", "direction", 9, std::vector<double>(g.source_grid.direction.begin(), g.source_grid.direction.end()), true);
  }
  s += "    </FieldData>\n";
  s += "    <Piece NumberOfPoints=\"" + std::to_string(np) + "\" NumberOfVerts=\"" + std::to_string(nn) +
       "\" NumberOfLines=\"" + std::to_string(ne) + "\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
  s += "      <PointData>\n";
  for (const auto& [name, v] : g.point_attributes) {
    std::vector<float> a(nn, 0.0f);
    for (const auto& e : v) a.insert(a.end(), e.begin(), e.end());
    w.array(s, "Float32", name, 1, a);
  }
  for (const auto& [name, v] : g.node_attributes) {
    std::vector<float> a(v.begin(), v.end());
    a.resize(np, 0.0f);
    w.array(s, "Float32", "node." + name, 1, a);
  }
  for (const auto& [name, v] : g.node_labels) {
    std::vector<int32_t> a(v.begin(), v.end());
    a.resize(np, 0);
    w.array(s, "Int32", "node." + name, 1, a);
  }
  s += "      </PointData>\n      <CellData>\n";
  // Cell data covers verts (nodes) then lines (edges).
  {
    std::vector<int64_t> n0(nn, -1), n1(nn, -1);
    for (const auto& e : g.edges) {
      n0.push_back(e.node0);
      n1.push_back(e.node1);
    }
    w.array(s, "Int64", "node0", 1, n0);
    w.array(s, "Int64", "node1", 1, n1);
  }
  for (const auto& [name, v] : g.edge_attributes) {
    std::vector<float> a(nn, 0.0f);
    a.insert(a.end(), v.begin(), v.end());
    w.array(s, "Float32", name, 1, a);
  }
  for (const auto& [name, v] : g.edge_labels) {
    std::vector<int32_t> a(nn, 0);
    a.insert(a.end(), v.begin(), v.end());
    w.array(s, "Int32", name, 1, a);
  }
  s += "      </CellData>\n      <Points>\n";
  {
    std::vector<double> xyz;
    xyz.reserve(static_cast<size_t>(3 * np));
    for (const auto& p : g.positions) xyz.insert(xyz.end(), p.begin(), p.end());
    for (const auto& e : g.edges)
      for (const auto& p : e.points) xyz.insert(xyz.end(), p.begin(), p.end());
    w.array(s, "Float64", "Points", 3, xyz);
  }
  s += "      </Points>\n      <Verts>\n";
  {
    std::vector<int64_t> conn(nn), offs(nn);
    for (int64_t i = 0; i < nn; ++i) {
      conn[i] = i;
      offs[i] = i + 1;
    }
    w.array(s, "Int64", "connectivity", 1, conn);
    w.array(s, "Int64", "offsets", 1, offs);
  }
  s += "      </Verts>\n      <Lines>\n";
  {
    std::vector<int64_t> conn, offs;
    int64_t next = nn;
    for (const auto& e : g.edges) {
      for (size_t i = 0; i < e.points.size(); ++i) conn.push_back(next++);
      offs.push_back(static_cast<int64_t>(conn.size()));
    }
    w.array(s, "Int64", "connectivity", 1, conn);
    w.array(s, "Int64", "offsets", 1, offs);
  }
  s += "      </Lines>\n    </Piece>\n  </PolyData>\n";
  if (binary) {
    s += "  <AppendedData encoding=\"raw\">\n   _";
    s += w.appended();
    s += "\n  </AppendedData>\n";
  }
  s += "</VTKFile>\n";
  return s;
}

// The DataArrays of one VTK XML file in any of its encodings (skel::io::vtk).
struct VtpData {
  vtk::Encoding enc;
  std::string appended;
  bool appended_base64 = false;
  std::vector<uint64_t> offsets;  // sorted offsets of the appended arrays: each ends at the next
  std::string src;

  // Payload bytes of a binary or appended array.
  [[nodiscard]] std::string bytes(const Xml& a) const {
    const std::string what = src + ": DataArray '" + a.attr_or("Name", "") + "'";
    const std::string format = a.attr_or("format", "ascii");
    if (format == "binary") return vtk::decode_inline(a.text, enc, what);
    if (format != "appended") throw InputError(what + ": unknown format '" + format + "'");
    int64_t off = 0;
    if (!text::parse_int(text::trim(a.attr_or("offset", "")), off) || off < 0)
      throw InputError(what + ": appended data needs an offset, got '" + a.attr_or("offset", "").substr(0, 24) + "'");
    if (appended.empty() && offsets.empty()) throw InputError(what + ": format 'appended' but the file has no <AppendedData>");
    const auto next = std::upper_bound(offsets.begin(), offsets.end(), static_cast<uint64_t>(off));
    return vtk::decode_appended(appended, appended_base64, static_cast<uint64_t>(off),
                                next == offsets.end() ? appended.size() : *next, enc, what);
  }
  // The numbers of a DataArray; with `finite_what` set ("a coordinate", "a radius"), non-finite
  // values are refused (at their line in ASCII files).
  [[nodiscard]] std::vector<double> numbers(const Xml& a, const char* finite_what = nullptr) const {
    std::vector<double> v;
    const std::string name = a.attr_or("Name", "");
    if (a.attr_or("format", "ascii") == "ascii") {
      NumberReader r(a.text, 0, a.text.size(), "DataArray '" + name + "'", src, a.text_line);
      while (!r.at_end()) v.push_back(finite_what ? r.next_finite(finite_what) : r.next());
      return v;
    }
    std::string type = a.attr_or("type", "");
    if (type == "String") type = "UInt8";
    v = vtk::to_doubles(bytes(a), type, enc, src + ": DataArray '" + name + "'");
    if (finite_what)
      for (size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i]))
          throw InputError(src + ": DataArray '" + name + "': value " + std::to_string(i) + ": " + finite_what +
                           " is not a finite number");
    return v;
  }
  // The first string of a String array.
  [[nodiscard]] std::string string(const Xml& a) const {
    std::string s;
    for (double ch : numbers(a)) {
      if (ch == 0) break;
      if (!(ch > 0 && ch < 256))
        throw InputError(src + ": DataArray '" + a.attr_or("Name", "") + "' holds a character code " + text::format_double(ch, 6));
      s += static_cast<char>(static_cast<unsigned char>(ch));
    }
    return s;
  }
};

// A stored index (offset, point or node id) as an integer; garbage (fractions, huge or negative
// values) is refused with `what`.
int64_t vtp_index(double v, const std::string& what) {
  if (!(v >= 0.0 && v < 9.0e15) || v != std::floor(v))
    throw InputError(what + " " + text::format_double(v, 17) + " is not a valid index");
  return static_cast<int64_t>(v);
}

SpatialGraph vtp_read(const std::string& text, const std::string& src) {
  vtk::SplitFile split = vtk::split_appended(text, src);
  const XmlDoc doc = parse_xml(split.xml, src);
  const Xml* vtk = doc.root().child("VTKFile");
  if (!vtk || vtk->attr_or("type", "") != "PolyData") throw InputError(src + ": not a VTK XML PolyData file");
  VtpData data;
  data.src = src;
  data.enc = vtk::parse_encoding(vtk->attr_or("header_type", ""), vtk->attr_or("byte_order", ""),
                                 vtk->attr_or("compressor", ""), src);
  if (const Xml* ad = vtk->child("AppendedData")) {
    const std::string e = ad->attr_or("encoding", "raw");
    if (e != "raw" && e != "base64") throw InputError(src + ": <AppendedData> encoding '" + e + "' is not raw or base64");
    data.appended_base64 = e == "base64";
    data.appended = std::move(split.appended);
  }
  for (const auto& el : doc.elements)
    if (el.name == "DataArray" && el.attr_or("format", "") == "appended") {
      int64_t off = 0;
      if (text::parse_int(text::trim(el.attr_or("offset", "")), off) && off >= 0) data.offsets.push_back(static_cast<uint64_t>(off));
    }
  std::sort(data.offsets.begin(), data.offsets.end());
  const Xml* pd = vtk->child("PolyData");
  const Xml* piece = pd ? pd->child("Piece") : nullptr;
  if (!piece) throw InputError(src + ": no <Piece>");
  std::string unit;
  Vec3 origin{0.0, 0.0, 0.0};
  Direction direction = kIdentityDirection;
  if (const Xml* fd = pd->child("FieldData"))
    for (const auto* c : fd->children) {
      if (c->name != "DataArray") continue;
      const std::string name = c->attr_or("Name", "");
      if (name == "unit" && c->attr_or("type", "") == "String") {
        unit = data.string(*c);
      } else if (name == "origin" || name == "direction") {
        const auto v = data.numbers(*c, "a transform value");
        if (name == "origin" && v.size() == 3) std::copy(v.begin(), v.end(), origin.begin());
        if (name == "direction" && v.size() == 9) std::copy(v.begin(), v.end(), direction.begin());
      }
    }
  auto section_array = [&](const char* sec, const std::string& name) -> const Xml* {
    const Xml* s = piece->child(sec);
    if (!s) return nullptr;
    for (const auto* c : s->children)
      if (c->name == "DataArray" && c->attr_or("Name", "") == name) return c;
    return nullptr;
  };
  const Xml* pts_sec = piece->child("Points");
  if (!pts_sec || pts_sec->children.empty()) throw InputError(src + ": no <Points>");
  const auto xyz = data.numbers(*pts_sec->children.front(), "a coordinate");
  const int64_t np = static_cast<int64_t>(xyz.size() / 3);
  // The declared sizes must match what the file holds (nothing is allocated from them).
  for (const char* attr : {"NumberOfPoints", "NumberOfVerts", "NumberOfLines"}) {
    const std::string* declared = piece->attr(attr);
    if (!declared) continue;
    int64_t d = 0;
    const Xml* sec = std::string(attr) == "NumberOfVerts" ? piece->child("Verts") : piece->child("Lines");
    const Xml* offs = nullptr;
    if (sec)
      for (const auto* c : sec->children)
        if (c->name == "DataArray" && c->attr_or("Name", "") == "offsets") offs = c;
    int64_t actual = np;
    if (std::string(attr) != "NumberOfPoints") {
      if (!offs) continue;
      actual = static_cast<int64_t>(data.numbers(*offs).size());
    }
    if (!text::parse_int(*declared, d) || d != actual)
      throw InputError(src + ":" + std::to_string(piece->line) + ": <Piece> declares " + attr + "=\"" +
                       declared->substr(0, 24) + "\" but the file holds " + std::to_string(actual));
  }
  auto cells = [&](const char* sec) {
    std::pair<std::vector<double>, std::vector<double>> co;
    if (const Xml* c = section_array(sec, "connectivity")) co.first = data.numbers(*c);
    if (const Xml* o = section_array(sec, "offsets")) co.second = data.numbers(*o);
    return co;
  };
  const auto verts = cells("Verts");
  const auto lines = cells("Lines");
  SpatialGraph g;
  if (!unit.empty()) g.unit = unit;
  g.source_grid.unit = g.unit;
  g.source_grid.origin = origin;
  g.source_grid.direction = direction;
  const int64_t nn = static_cast<int64_t>(verts.second.size());
  std::vector<int64_t> node_point(nn);
  for (int64_t i = 0; i < nn; ++i) {
    const int64_t b = i == 0 ? 0 : vtp_index(verts.second[i - 1], src + ": vertex cell " + std::to_string(i) + ": offset");
    if (b >= static_cast<int64_t>(verts.first.size()))
      throw InputError(src + ": vertex cell " + std::to_string(i) + ": offset " + std::to_string(b) +
                       " is past the end of the connectivity (" + std::to_string(verts.first.size()) + " values)");
    const int64_t pid = vtp_index(verts.first[b], src + ": vertex cell " + std::to_string(i) + ": point");
    if (pid >= np) throw InputError(src + ": vertex cell refers to point " + std::to_string(pid));
    node_point[i] = pid;
    g.add_node({xyz[3 * pid], xyz[3 * pid + 1], xyz[3 * pid + 2]});
  }
  const int64_t ne = static_cast<int64_t>(lines.second.size());
  const Xml* n0a = section_array("CellData", "node0");
  const Xml* n1a = section_array("CellData", "node1");
  std::vector<double> n0, n1;
  if (n0a && n1a) {
    n0 = data.numbers(*n0a);
    n1 = data.numbers(*n1a);
  }
  // Without node0/node1 arrays (files from other tools), nodes are matched by point id.
  std::map<int64_t, int64_t> node_of_point;
  for (int64_t i = 0; i < nn; ++i) node_of_point.emplace(node_point[i], i);
  std::vector<std::pair<int64_t, int64_t>> line_range(ne);
  for (int64_t e = 0; e < ne; ++e) {
    const std::string cell = src + ": line cell " + std::to_string(e);
    const int64_t b = e == 0 ? 0 : vtp_index(lines.second[e - 1], cell + ": offset");
    const int64_t en = vtp_index(lines.second[e], cell + ": offset");
    if (en - b < 2 || en > static_cast<int64_t>(lines.first.size()))
      throw InputError(src + ": line cell " + std::to_string(e) + " has fewer than 2 points or bad offsets");
    line_range[e] = {b, en};
    std::vector<Vec3> pts;
    for (int64_t k = b; k < en; ++k) {
      const int64_t pid = vtp_index(lines.first[k], cell + ": point");
      if (pid >= np) throw InputError(src + ": line cell refers to point " + std::to_string(pid));
      pts.push_back({xyz[3 * pid], xyz[3 * pid + 1], xyz[3 * pid + 2]});
    }
    int64_t a = -1, z = -1;
    if (!n0.empty()) {
      if (static_cast<int64_t>(std::min(n0.size(), n1.size())) < nn + ne)
        throw InputError(src + ": cell data 'node0'/'node1' have " + std::to_string(std::min(n0.size(), n1.size())) +
                         " values for " + std::to_string(nn + ne) + " cells");
      a = vtp_index(n0[static_cast<size_t>(nn + e)], cell + ": node0");
      z = vtp_index(n1[static_cast<size_t>(nn + e)], cell + ": node1");
    } else {
      // A line end becomes a node; lines that share the end's point id share the node.
      const auto node_at = [&](int64_t pid, const Vec3& p) {
        auto [it, fresh] = node_of_point.try_emplace(pid, -1);
        if (fresh) it->second = g.add_node(p);
        return it->second;
      };
      a = node_at(vtp_index(lines.first[b], cell + ": point"), pts.front());
      z = node_at(vtp_index(lines.first[en - 1], cell + ": point"), pts.back());
    }
    check_node_id(a, g.node_count(), src + ": node0");
    check_node_id(z, g.node_count(), src + ": node1");
    g.edges.push_back(GraphEdge{a, z, std::move(pts)});
  }
  snap_ends(g);
  if (const Xml* sec = piece->child("PointData"))
    for (const auto* cp : sec->children) {
      const Xml& c = *cp;
      if (c.name != "DataArray" || c.attr_or("NumberOfComponents", "1") != "1") continue;
      const std::string name = c.attr_or("Name", "");
      const auto v = data.numbers(c, name == "radius" || name == "node.radius" ? "a radius" : nullptr);
      if (static_cast<int64_t>(v.size()) != np) throw InputError(src + ": point data '" + name + "' has the wrong length");
      const bool is_int = c.attr_or("type", "").find("Int") != std::string::npos;
      if (name.rfind("node.", 0) == 0) {
        const std::string n = name.substr(5);
        if (is_int) {
          auto& a = g.node_labels[n];
          for (int64_t i = 0; i < nn; ++i) a.push_back(label_of(v[node_point[i]], src + ": point data '" + name + "'"));
        } else {
          auto& a = g.node_attributes[n];
          for (int64_t i = 0; i < nn; ++i) a.push_back(static_cast<float>(v[node_point[i]]));
        }
      } else {
        auto& a = g.point_attributes[name];
        a.resize(ne);
        for (int64_t e = 0; e < ne; ++e)
          for (int64_t k = line_range[e].first; k < line_range[e].second; ++k)
            a[e].push_back(static_cast<float>(v[static_cast<int64_t>(lines.first[k])]));
      }
    }
  if (const Xml* sec = piece->child("CellData"))
    for (const auto* cp : sec->children) {
      const Xml& c = *cp;
      const std::string name = c.attr_or("Name", "");
      if (c.name != "DataArray" || name == "node0" || name == "node1" || c.attr_or("NumberOfComponents", "1") != "1")
        continue;
      const auto v = data.numbers(c);
      if (static_cast<int64_t>(v.size()) != nn + ne) throw InputError(src + ": cell data '" + name + "' has the wrong length");
      if (c.attr_or("type", "").find("Int") != std::string::npos) {
        auto& a = g.edge_labels[name];
        for (int64_t e = 0; e < ne; ++e) a.push_back(label_of(v[nn + e], src + ": cell data '" + name + "'"));
      } else {
        auto& a = g.edge_attributes[name];
        for (int64_t e = 0; e < ne; ++e) a.push_back(static_cast<float>(v[nn + e]));
      }
    }
  // Attributes must cover every node, also those added for unmatched line ends.
  for (auto& [n, a] : g.node_attributes) a.resize(g.positions.size(), 0.0f);
  for (auto& [n, a] : g.node_labels) a.resize(g.positions.size(), 0);
  return g;
}

// ---------------------------------------------------------------- SWC
std::string swc_write(const SpatialGraph& g) {
  if (g.cyclomatic_number() != 0)
    throw InputError("SWC stores trees: the graph has " + std::to_string(g.cyclomatic_number()) +
                     " independent loop(s); use .am, .vtp, .graphml or .csv");
  const auto adj = g.adjacency();
  const auto* pr = g.point_attributes.count("radius") ? &g.point_attributes.at("radius") : nullptr;
  const auto* nr = g.node_attributes.count("radius") ? &g.node_attributes.at("radius") : nullptr;
  const auto* nt = g.node_labels.count("swc_type") ? &g.node_labels.at("swc_type") : nullptr;
  const auto* et = g.edge_labels.count("swc_type") ? &g.edge_labels.at("swc_type") : nullptr;
  std::string s = "# SWC written by skelflow: id type x y z radius parent\n# unit: ";
  for (char c : g.unit) s += (c == '\n' || c == '\r') ? '_' : c;
  s += '\n';
  std::vector<int64_t> sample(g.positions.size(), -1);
  int64_t next = 1;
  auto line = [&](int64_t id, int64_t type, const Vec3& p, double r, int64_t parent) {
    put_i(s, id); s += ' '; put_i(s, type); s += ' ';
    put_d(s, p[0]); s += ' '; put_d(s, p[1]); s += ' '; put_d(s, p[2]); s += ' ';
    put_d(s, r); s += ' '; put_i(s, parent); s += '\n';
  };
  auto node_radius = [&](int64_t n, int64_t via_edge, bool at_end) -> double {
    if (nr) return (*nr)[n];
    if (pr && via_edge >= 0) return at_end ? (*pr)[via_edge].back() : (*pr)[via_edge].front();
    return 0.0;
  };
  for (int64_t root = 0; root < g.node_count(); ++root) {
    if (sample[root] >= 0) continue;
    const int64_t first_edge = adj.degree(root) > 0 ? adj.edge_ids[adj.offsets[root]] : -1;
    sample[root] = next++;
    line(sample[root], nt ? (*nt)[root] : 0, g.positions[root],
         node_radius(root, first_edge, first_edge >= 0 && g.edges[first_edge].node1 == root), -1);
    std::deque<int64_t> q{root};
    while (!q.empty()) {
      const int64_t u = q.front();
      q.pop_front();
      for (int64_t a = adj.offsets[u]; a < adj.offsets[u + 1]; ++a) {
        const int64_t e = adj.edge_ids[a];
        const auto& ed = g.edges[e];
        const bool fwd = ed.node0 == u;
        const int64_t v = fwd ? ed.node1 : ed.node0;
        if (sample[v] >= 0) continue;
        const int64_t n = static_cast<int64_t>(ed.points.size());
        int64_t parent = sample[u];
        for (int64_t k = 1; k + 1 < n; ++k) {
          const int64_t i = fwd ? k : n - 1 - k;
          line(next, et ? (*et)[e] : 0, ed.points[i], pr ? (*pr)[e][i] : 0.0, parent);
          parent = next++;
        }
        sample[v] = next++;
        line(sample[v], nt ? (*nt)[v] : 0, g.positions[v], node_radius(v, e, fwd), parent);
        q.push_back(v);
      }
    }
  }
  return s;
}

SpatialGraph swc_read(const std::string& text, const std::string& src) {
  struct Sample {
    int64_t id, type, parent;
    Vec3 p;
    double r;
    int line;  // for messages
  };
  std::vector<Sample> smp;
  std::map<int64_t, int64_t> index;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  std::string unit;
  while (std::getline(in, line)) {
    ++line_no;
    const size_t h = line.find('#');
    if (h != std::string::npos) {
      // "# unit: mm" (skelflow's header comment) names the coordinate unit.
      const std::string c = text::trim(std::string_view(line).substr(h + 1));
      if (text::to_lower(c.substr(0, 5)) == "unit:") unit = text::trim(c.substr(5));
      line.resize(h);
    }
    NumberReader r(line, 0, line.size(), src + ":" + std::to_string(line_no));
    if (r.at_end()) continue;
    Sample s{};
    s.id = r.next_int();
    s.type = r.next_int();
    for (int a = 0; a < 3; ++a) s.p[a] = r.next_finite("a coordinate");
    s.r = r.next_finite("the radius");
    s.parent = r.next_int();
    s.line = line_no;
    if (!index.emplace(s.id, static_cast<int64_t>(smp.size())).second)
      throw InputError(src + ":" + std::to_string(line_no) + ": duplicate sample id " + std::to_string(s.id));
    smp.push_back(s);
  }
  const int64_t n = static_cast<int64_t>(smp.size());
  std::vector<int64_t> parent(n, -1), children(n, 0);
  for (int64_t i = 0; i < n; ++i) {
    if (smp[i].parent < 0) continue;
    auto it = index.find(smp[i].parent);
    if (it == index.end())
      throw InputError(src + ":" + std::to_string(smp[i].line) + ": sample " + std::to_string(smp[i].id) +
                       " has unknown parent " + std::to_string(smp[i].parent));
    parent[i] = it->second;
    ++children[it->second];
  }
  // Parent links must form trees: walk up from every sample (iteratively), marking the path; a walk
  // that meets its own path has found a cycle.
  {
    std::vector<uint8_t> state(n, 0);  // 0: unseen, 1: on the current walk, 2: leads to a root
    std::vector<int64_t> path;
    for (int64_t i = 0; i < n; ++i) {
      int64_t v = i;
      path.clear();
      while (v >= 0 && state[v] == 0) {
        state[v] = 1;
        path.push_back(v);
        v = parent[v];
      }
      if (v >= 0 && state[v] == 1) {
        // v is on the cycle; name it and the cycle's length.
        int64_t len = 1;
        for (int64_t u = parent[v]; u != v; u = parent[u]) ++len;
        throw InputError(src + ":" + std::to_string(smp[v].line) + ": sample " + std::to_string(smp[v].id) +
                         ": parent links form a cycle of " + std::to_string(len) + " sample(s) (parent " +
                         std::to_string(smp[v].parent) + "); SWC samples must form trees");
      }
      for (int64_t u : path) state[u] = 2;
    }
  }
  SpatialGraph g;
  if (!unit.empty()) g.unit = unit;
  g.source_grid.unit = g.unit;
  std::vector<int64_t> node(n, -1);
  g.ensure_node_attribute("radius");
  for (int64_t i = 0; i < n; ++i)
    if (parent[i] < 0 || children[i] != 1) {
      node[i] = g.add_node(smp[i].p);
      g.node_attributes["radius"][node[i]] = static_cast<float>(smp[i].r);
      g.ensure_node_label("swc_type")[node[i]] = static_cast<int32_t>(smp[i].type);
    }
  std::vector<std::vector<float>> rad;
  std::vector<int32_t> etype;
  for (int64_t i = 0; i < n; ++i) {
    if (node[i] < 0 || parent[i] < 0) continue;
    // Walk up from node sample i to the next node sample.
    std::vector<Vec3> pts{smp[i].p};
    std::vector<float> rr{static_cast<float>(smp[i].r)};
    int64_t cur = parent[i];
    int32_t type = static_cast<int32_t>(smp[i].type);
    int64_t guard = 0;
    while (node[cur] < 0) {
      pts.push_back(smp[cur].p);
      rr.push_back(static_cast<float>(smp[cur].r));
      type = static_cast<int32_t>(smp[cur].type);
      cur = parent[cur];
      if (++guard > n) throw Error(src + ": parent links form a cycle (not found by the cycle check)");
    }
    pts.push_back(smp[cur].p);
    rr.push_back(static_cast<float>(smp[cur].r));
    std::reverse(pts.begin(), pts.end());
    std::reverse(rr.begin(), rr.end());
    g.edges.push_back(GraphEdge{node[cur], node[i], std::move(pts)});
    rad.push_back(std::move(rr));
    etype.push_back(type);
  }
  g.point_attributes["radius"] = std::move(rad);
  g.edge_labels["swc_type"] = std::move(etype);
  return g;
}

// ---------------------------------------------------------------- GraphML
std::string graphml_write(const SpatialGraph& g) {
  std::string s = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                  "<graphml xmlns=\"http://graphml.graphdrawing.org/xmlns\">\n";
  int key = 0;
  std::map<std::string, std::string> nkey, ekey;  // name -> key id
  auto add_key = [&](const char* for_, const std::string& name, const char* type, std::map<std::string, std::string>& m) {
    const std::string id = "d" + std::to_string(key++);
    m[name] = id;
    s += "  <key id=\"" + id + "\" for=\"" + for_ + "\" attr.name=\"" + xml_escape(name) + "\" attr.type=\"" + type + "\"/>\n";
  };
  std::map<std::string, std::string> gkey;
  add_key("graph", "unit", "string", gkey);
  add_key("node", "x", "double", nkey);
  add_key("node", "y", "double", nkey);
  add_key("node", "z", "double", nkey);
  for (const auto& [n, v] : g.node_attributes) add_key("node", n, "double", nkey);
  for (const auto& [n, v] : g.node_labels) add_key("node", n, "int", nkey);
  // Edge geometry as numbers: p<i>_x, p<i>_y, p<i>_z for point i of the polyline and p<i>_<name>
  // for its point attributes (keys up to the longest polyline; shorter edges leave the rest out).
  add_key("edge", "num_points", "int", ekey);
  for (const auto& [n, v] : g.edge_attributes) add_key("edge", n, "double", ekey);
  for (const auto& [n, v] : g.edge_labels) add_key("edge", n, "int", ekey);
  size_t max_points = 0;
  for (const auto& e : g.edges) max_points = std::max(max_points, e.points.size());
  std::vector<std::string> pkey;  // key ids: point i, field f at i * fields + f
  const size_t fields = 3 + g.point_attributes.size();
  for (size_t i = 0; i < max_points; ++i) {
    const std::string pre = "p" + std::to_string(i) + "_";
    std::map<std::string, std::string> m;
    for (const char* a : {"x", "y", "z"}) {
      add_key("edge", pre + a, "double", m);
      pkey.push_back(m[pre + a]);
    }
    for (const auto& [n, v] : g.point_attributes) {
      add_key("edge", pre + n, "double", m);
      pkey.push_back(m[pre + n]);
    }
  }
  s += "  <graph id=\"G\" edgedefault=\"undirected\">\n";
  s += "    <data key=\"" + gkey["unit"] + "\">" + xml_escape(g.unit) + "</data>\n";
  for (int64_t i = 0; i < g.node_count(); ++i) {
    s += "    <node id=\"n" + std::to_string(i) + "\">";
    for (int a = 0; a < 3; ++a) {
      s += "<data key=\"" + nkey[a == 0 ? "x" : a == 1 ? "y" : "z"] + "\">";
      put_d(s, g.positions[i][a]);
      s += "</data>";
    }
    for (const auto& [n, v] : g.node_attributes) {
      s += "<data key=\"" + nkey[n] + "\">";
      put_f(s, v[i]);
      s += "</data>";
    }
    for (const auto& [n, v] : g.node_labels) s += "<data key=\"" + nkey[n] + "\">" + std::to_string(v[i]) + "</data>";
    s += "</node>\n";
  }
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    const auto& ed = g.edges[e];
    s += "    <edge id=\"e" + std::to_string(e) + "\" source=\"n" + std::to_string(ed.node0) + "\" target=\"n" +
         std::to_string(ed.node1) + "\"><data key=\"" + ekey["num_points"] + "\">" + std::to_string(ed.points.size()) +
         "</data>";
    for (const auto& [n, v] : g.edge_attributes) {
      s += "<data key=\"" + ekey[n] + "\">";
      put_f(s, v[e]);
      s += "</data>";
    }
    for (const auto& [n, v] : g.edge_labels) s += "<data key=\"" + ekey[n] + "\">" + std::to_string(v[e]) + "</data>";
    for (size_t i = 0; i < ed.points.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        s += "<data key=\"" + pkey[i * fields + static_cast<size_t>(a)] + "\">";
        put_d(s, ed.points[i][a]);
        s += "</data>";
      }
      size_t f = 3;
      for (const auto& [n, v] : g.point_attributes) {
        s += "<data key=\"" + pkey[i * fields + f++] + "\">";
        put_f(s, v[e][i]);
        s += "</data>";
      }
    }
    s += "</edge>\n";
  }
  s += "  </graph>\n</graphml>\n";
  return s;
}

SpatialGraph graphml_read(const std::string& text, const std::string& src) {
  const XmlDoc doc = parse_xml(text, src);
  const Xml* gm = doc.root().child("graphml");
  if (!gm) throw InputError(src + ": no <graphml> element");
  struct Key {
    std::string for_, name, type;
    int64_t point = -1;  // p<i>_<field>: polyline point i (numeric edge geometry)
    std::string field;   // x, y, z or a point attribute
  };
  std::map<std::string, Key> keys;
  for (const auto* cp : gm->children)
    if (cp->name == "key")
      keys[cp->attr_or("id", "")] = {cp->attr_or("for", ""), cp->attr_or("attr.name", ""), cp->attr_or("attr.type", ""), -1, {}};
  // Point keys: every point needs its own keys, so an index is below the number of keys.
  for (auto& [id, k] : keys) {
    if (k.name.size() < 4 || k.name[0] != 'p') continue;
    const size_t us = k.name.find('_');
    int64_t i = 0;
    if (us == std::string::npos || us + 1 == k.name.size() || !text::parse_int(std::string_view(k.name).substr(1, us - 1), i) ||
        i < 0 || i >= static_cast<int64_t>(keys.size()) || !std::isdigit(static_cast<unsigned char>(k.name[1])))
      continue;
    k.point = i;
    k.field = k.name.substr(us + 1);
  }
  const Xml* graph = gm->child("graph");
  if (!graph) throw InputError(src + ": no <graph> element");
  SpatialGraph g;
  for (const auto* cp : graph->children)
    if (cp->name == "data") {
      const auto k = keys.find(cp->attr_or("key", ""));
      if (k != keys.end() && k->second.name == "unit" && !text::trim(cp->text).empty()) g.unit = text::trim(cp->text);
    }
  g.source_grid.unit = g.unit;
  std::map<std::string, int64_t> ids;
  std::map<std::string, std::vector<float>> nf;
  std::map<std::string, std::vector<int32_t>> nl;
  for (const auto* cp : graph->children) {
    const Xml& c = *cp;
    if (c.name != "node") continue;
    Vec3 p{0, 0, 0};
    const int64_t i = g.node_count();
    for (const auto* dp : c.children) {
      const Xml& d = *dp;
      if (d.name != "data") continue;
      const Key& k = keys[d.attr_or("key", "")];
      const std::string where = src + ": node " + c.attr_or("id", "") + " '" + k.name + "'";
      const std::string at = src + ":" + std::to_string(d.line) + ": node '" + c.attr_or("id", "") + "' '" + k.name + "'";
      if (k.name == "x" || k.name == "y" || k.name == "z") p[k.name[0] - 'x'] = finite_num(d.text, at, "a coordinate");
      else if (k.name == "radius" && (k.type == "float" || k.type == "double"))
        nf[k.name].resize(i + 1), nf[k.name][i] = static_cast<float>(finite_num(d.text, at, "the radius"));
      else if (k.type == "int" || k.type == "long") nl[k.name].resize(i + 1), nl[k.name][i] = label_of(to_num(d.text, where), at);
      else if (k.type == "float" || k.type == "double") nf[k.name].resize(i + 1), nf[k.name][i] = static_cast<float>(to_num(d.text, where));
    }
    ids[c.attr_or("id", "")] = g.add_node(p);
  }
  for (auto& [n, v] : nf) v.resize(g.positions.size(), 0.0f), g.node_attributes[n] = std::move(v);
  for (auto& [n, v] : nl) v.resize(g.positions.size(), 0), g.node_labels[n] = std::move(v);
  for (const auto* cp : graph->children) {
    const Xml& c = *cp;
    if (c.name != "edge") continue;
    auto a = ids.find(c.attr_or("source", "")), b = ids.find(c.attr_or("target", ""));
    if (a == ids.end() || b == ids.end()) {
      const std::string id = c.attr_or("id", ""), missing = c.attr_or(a == ids.end() ? "source" : "target", "");
      throw InputError(src + ": edge " + (id.empty() ? std::string() : "'" + id + "' ") + "refers to unknown node '" +
                       missing + "'");
    }
    const std::string edge_name = c.attr("id") ? "'" + c.attr_or("id", "") + "'" : std::string("#") + std::to_string(g.edge_count());
    std::vector<Vec3> pts;
    std::vector<std::array<bool, 3>> have;  // numeric geometry: which coordinates were given
    int64_t num_points = -1;
    std::map<std::string, float> ef;
    std::map<std::string, int32_t> el;
    std::map<std::string, std::vector<float>> pa;
    for (const auto* dp : c.children) {
      const Xml& d = *dp;
      if (d.name != "data") continue;
      const Key& k = keys[d.attr_or("key", "")];
      const std::string where = src + ": edge " + c.attr_or("id", "") + " '" + k.name + "'";
      const std::string what = "edge " + edge_name + " '" + k.name + "'";
      if (k.point >= 0) {
        const auto i = static_cast<size_t>(k.point);
        const std::string at = src + ":" + std::to_string(d.line) + ": " + what;
        if (k.field == "x" || k.field == "y" || k.field == "z") {
          if (pts.size() <= i) pts.resize(i + 1, Vec3{0, 0, 0}), have.resize(i + 1, {false, false, false});
          pts[i][k.field[0] - 'x'] = finite_num(d.text, at, "a coordinate");
          have[i][k.field[0] - 'x'] = true;
        } else {
          auto& v = pa[k.field];
          if (v.size() <= i) v.resize(i + 1, std::numeric_limits<float>::quiet_NaN());
          v[i] = static_cast<float>(k.field == "radius" ? finite_num(d.text, at, "a radius") : to_num(d.text, at));
        }
      } else if (k.name == "num_points") {
        num_points = static_cast<int64_t>(to_num(d.text, where));
      } else if (k.name == "points") {
        std::string t = d.text;
        std::replace(t.begin(), t.end(), ';', ' ');
        NumberReader rr(t, 0, t.size(), what, src, d.text_line);
        while (!rr.at_end()) {
          Vec3 p{};
          for (int q = 0; q < 3; ++q) p[q] = rr.next_finite("a coordinate");
          pts.push_back(p);
        }
      } else if (k.name.rfind("point.", 0) == 0) {
        NumberReader r(d.text, 0, d.text.size(), what, src, d.text_line);
        auto& v = pa[k.name.substr(6)];
        const bool radius = k.name == "point.radius";
        while (!r.at_end()) v.push_back(static_cast<float>(radius ? r.next_finite("a radius") : r.next()));
      } else if (k.type == "int" || k.type == "long") {
        el[k.name] = label_of(to_num(d.text, where), src + ":" + std::to_string(d.line) + ": " + what);
      } else if (k.type == "float" || k.type == "double") {
        ef[k.name] = static_cast<float>(to_num(d.text, where));
      }
    }
    for (size_t i = 0; i < have.size(); ++i)
      if (!(have[i][0] && have[i][1] && have[i][2]))
        throw InputError(src + ":" + std::to_string(c.line) + ": edge " + edge_name + ": point " + std::to_string(i) +
                         " lacks a coordinate (keys p" + std::to_string(i) + "_x, _y, _z)");
    if (num_points >= 0 && num_points != static_cast<int64_t>(pts.size()))
      throw InputError(src + ":" + std::to_string(c.line) + ": edge " + edge_name + ": num_points says " +
                       std::to_string(num_points) + " but " + std::to_string(pts.size()) + " points are given");
    // No 'points' data: a straight edge between its nodes; otherwise a polyline of >= 2 points.
    if (pts.size() == 1)
      throw InputError(src + ":" + std::to_string(c.line) + ": edge " + edge_name +
                       " has 1 point in 'points', expected >= 2 (its end nodes at least)");
    const int64_t e = g.add_edge(a->second, b->second, std::move(pts));
    for (const auto& [n, v] : ef) g.ensure_edge_attribute(n)[e] = v;
    for (const auto& [n, v] : el) g.ensure_edge_label(n)[e] = v;
    for (auto& [n, v] : pa) {
      auto& dst = g.ensure_point_attribute(n);
      if (v.size() != g.edges[e].points.size())
        throw InputError(src + ": edge " + c.attr_or("id", "") + " point." + n + " has " + std::to_string(v.size()) +
                         " values for " + std::to_string(g.edges[e].points.size()) + " points");
      dst[e] = std::move(v);
    }
  }
  for (const auto& [n, v] : g.edge_attributes) g.ensure_edge_attribute(n);
  for (const auto& [n, v] : g.edge_labels) g.ensure_edge_label(n);
  for (const auto& [n, v] : g.point_attributes) g.ensure_point_attribute(n);
  snap_ends(g);
  return g;
}

// ---------------------------------------------------------------- CSV
std::string csv_name(const std::string& n) {
  std::string o = n;
  for (char& c : o)
    if (c == ',' || c == '"' || c == '\n' || c == '\r') c = '_';
  return o;
}

std::string csv_edges_write(const SpatialGraph& g) {
  const std::string u = " [" + csv_name(g.unit) + "]";
  std::string s = "edge,node0,node1,point,x" + u + ",y" + u + ",z" + u;
  for (const auto& [n, v] : g.point_attributes) s += ",point:" + csv_name(n);
  for (const auto& [n, v] : g.edge_attributes) s += ",edge:" + csv_name(n);
  for (const auto& [n, v] : g.edge_labels) s += ",edge_label:" + csv_name(n);
  s += '\n';
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    const auto& ed = g.edges[e];
    for (size_t i = 0; i < ed.points.size(); ++i) {
      put_i(s, e); s += ','; put_i(s, ed.node0); s += ','; put_i(s, ed.node1); s += ','; put_i(s, static_cast<int64_t>(i));
      for (int a = 0; a < 3; ++a) { s += ','; put_d(s, ed.points[i][a]); }
      for (const auto& [n, v] : g.point_attributes) { s += ','; put_f(s, v[e][i]); }
      for (const auto& [n, v] : g.edge_attributes) { s += ','; put_f(s, v[e]); }
      for (const auto& [n, v] : g.edge_labels) { s += ','; put_i(s, v[e]); }
      s += '\n';
    }
  }
  return s;
}

std::string csv_nodes_write(const SpatialGraph& g) {
  const std::string u = " [" + csv_name(g.unit) + "]";
  std::string s = "node,x" + u + ",y" + u + ",z" + u;
  for (const auto& [n, v] : g.node_attributes) s += ",node:" + csv_name(n);
  for (const auto& [n, v] : g.node_labels) s += ",node_label:" + csv_name(n);
  s += '\n';
  for (int64_t i = 0; i < g.node_count(); ++i) {
    put_i(s, i);
    for (int a = 0; a < 3; ++a) { s += ','; put_d(s, g.positions[i][a]); }
    for (const auto& [n, v] : g.node_attributes) { s += ','; put_f(s, v[i]); }
    for (const auto& [n, v] : g.node_labels) { s += ','; put_i(s, v[i]); }
    s += '\n';
  }
  return s;
}

struct CsvTable {
  std::vector<std::string> header;  // names without their unit
  std::string unit;                 // the first unit of a header "x [mm]"
  std::vector<std::vector<double>> rows;
  std::vector<int> lines;  // file line of each row
  std::string src;
  // Refuses a non-finite value in column `col` (a coordinate or radius), naming the file and line.
  void check_finite(size_t col, const char* what) const {
    for (size_t i = 0; i < rows.size(); ++i)
      if (!std::isfinite(rows[i][col]))
        throw InputError(src + ":" + std::to_string(lines[i]) + ": column '" + header[col] + "': " + what +
                         " is not a finite number");
  }
};
CsvTable csv_parse(const std::string& text, const std::string& src) {
  CsvTable t;
  t.src = src;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    auto f = text::split(line, ',');
    for (auto& field : f) std::erase(field, '\r');  // stray CRs inside a line are dropped
    if (t.header.empty()) {
      for (auto& h : f)
        if (const size_t b = h.rfind(" ["); b != std::string::npos && h.size() > b + 2 && h.back() == ']') {
          if (t.unit.empty()) t.unit = h.substr(b + 2, h.size() - b - 3);
          h.resize(b);
        }
      t.header = f;
      continue;
    }
    if (f.size() != t.header.size())
      throw InputError(src + ":" + std::to_string(line_no) + ": " + std::to_string(f.size()) + " fields, header has " +
                       std::to_string(t.header.size()));
    std::vector<double> row(f.size());
    for (size_t k = 0; k < f.size(); ++k) row[k] = to_num(f[k], src + ":" + std::to_string(line_no));
    t.rows.push_back(std::move(row));
    t.lines.push_back(line_no);
  }
  return t;
}

SpatialGraph csv_read(const std::string& text, const std::string& nodes_text, const std::string& src) {
  const CsvTable nodes = csv_parse(nodes_text, src + " (nodes)");
  const CsvTable edges = csv_parse(text, src);
  auto col = [&](const CsvTable& t, const std::string& n, const std::string& which) -> size_t {
    auto it = std::find(t.header.begin(), t.header.end(), n);
    if (it == t.header.end()) throw InputError(src + " (" + which + "): missing column '" + n + "'");
    return static_cast<size_t>(it - t.header.begin());
  };
  SpatialGraph g;
  if (!nodes.unit.empty() && !edges.unit.empty() && nodes.unit != edges.unit)
    throw InputError(src + ": the edges file says unit '" + edges.unit + "' and the nodes file '" + nodes.unit + "'");
  if (!nodes.unit.empty() || !edges.unit.empty()) g.unit = nodes.unit.empty() ? edges.unit : nodes.unit;
  g.source_grid.unit = g.unit;
  const size_t cx = col(nodes, "x", "nodes"), cy = col(nodes, "y", "nodes"), cz = col(nodes, "z", "nodes");
  for (size_t c : {cx, cy, cz}) nodes.check_finite(c, "a coordinate");
  for (size_t k = 0; k < nodes.header.size(); ++k)
    if (nodes.header[k] == "node:radius") nodes.check_finite(k, "a radius");
  for (const auto& r : nodes.rows) g.add_node({r[cx], r[cy], r[cz]});
  for (size_t k = 0; k < nodes.header.size(); ++k) {
    const auto& h = nodes.header[k];
    if (h.rfind("node:", 0) == 0) {
      auto& v = g.ensure_node_attribute(h.substr(5));
      for (size_t i = 0; i < nodes.rows.size(); ++i) v[i] = static_cast<float>(nodes.rows[i][k]);
    } else if (h.rfind("node_label:", 0) == 0) {
      auto& v = g.ensure_node_label(h.substr(11));
      for (size_t i = 0; i < nodes.rows.size(); ++i)
        v[i] = label_of(nodes.rows[i][k], nodes.src + ":" + std::to_string(nodes.lines[i]) + ": column '" + h + "'");
    }
  }
  const size_t ce = col(edges, "edge", "edges"), c0 = col(edges, "node0", "edges"), c1 = col(edges, "node1", "edges");
  const size_t ex = col(edges, "x", "edges"), ey = col(edges, "y", "edges"), ez = col(edges, "z", "edges");
  for (size_t c : {ex, ey, ez}) edges.check_finite(c, "a coordinate");
  for (size_t k = 0; k < edges.header.size(); ++k)
    if (edges.header[k] == "point:radius") edges.check_finite(k, "a radius");
  auto node_id = [&](size_t row, size_t col) {
    const double v = edges.rows[row][col];
    if (!(v >= 0.0 && v < static_cast<double>(g.node_count())) || v != std::floor(v))
      throw InputError(src + ":" + std::to_string(edges.lines[row]) + ": " + edges.header[col] + ": node id " +
                       text::format_double(v, 17) + " out of range (" + std::to_string(g.node_count()) + " nodes)");
    return static_cast<int64_t>(v);
  };
  std::vector<std::pair<size_t, size_t>> ranges;  // rows of each edge
  for (size_t i = 0; i < edges.rows.size();) {
    size_t j = i;
    while (j < edges.rows.size() && edges.rows[j][ce] == edges.rows[i][ce]) ++j;
    const auto& r = edges.rows[i];
    const int64_t a = node_id(i, c0), b = node_id(i, c1);
    std::vector<Vec3> pts;
    for (size_t k = i; k < j; ++k) pts.push_back({edges.rows[k][ex], edges.rows[k][ey], edges.rows[k][ez]});
    if (pts.size() < 2)
      throw InputError(src + ":" + std::to_string(edges.lines[i]) + ": edge " + text::format_double(r[ce], 17) +
                       " has fewer than 2 points");
    g.edges.push_back(GraphEdge{a, b, std::move(pts)});
    ranges.emplace_back(i, j);
    i = j;
  }
  for (size_t k = 0; k < edges.header.size(); ++k) {
    const auto& h = edges.header[k];
    if (h.rfind("point:", 0) == 0) {
      auto& v = g.point_attributes[h.substr(6)];
      v.resize(ranges.size());
      for (size_t e = 0; e < ranges.size(); ++e)
        for (size_t r = ranges[e].first; r < ranges[e].second; ++r) v[e].push_back(static_cast<float>(edges.rows[r][k]));
    } else if (h.rfind("edge:", 0) == 0) {
      auto& v = g.edge_attributes[h.substr(5)];
      for (const auto& rg : ranges) v.push_back(static_cast<float>(edges.rows[rg.first][k]));
    } else if (h.rfind("edge_label:", 0) == 0) {
      auto& v = g.edge_labels[h.substr(11)];
      for (const auto& rg : ranges)
        v.push_back(label_of(edges.rows[rg.first][k], edges.src + ":" + std::to_string(edges.lines[rg.first]) + ": column '" + h + "'"));
    }
  }
  snap_ends(g);
  return g;
}

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

}  // namespace

GraphFormat graph_format_from_path(const std::filesystem::path& path, const std::string& what) {
  const std::string ext = text::to_lower(path.extension().string());
  if (ext == ".am") return GraphFormat::amira;
  if (ext == ".vtp") return GraphFormat::vtp;
  if (ext == ".swc") return GraphFormat::swc;
  if (ext == ".graphml") return GraphFormat::graphml;
  if (ext == ".csv") return GraphFormat::csv;
  throw InputError(what + ": unknown graph file extension '" + ext + "' of '" + path.string() +
                   "'; expected .am, .vtp, .swc, .graphml or .csv");
}

std::string graph_to_text(const SpatialGraph& in, GraphFormat f, std::string* nodes_text, const GraphWriteOptions& o) {
  const auto problems = in.check_invariants();
  if (!problems.empty()) throw InputError("input 'graph': inconsistent graph: " + problems.front());
  SpatialGraph world;
  if (in.source_grid.direction != kIdentityDirection) world = with_direction_applied(in, true);
  const SpatialGraph& g = in.source_grid.direction != kIdentityDirection ? world : in;
  switch (f) {
    case GraphFormat::amira: return amira_write(g);
    case GraphFormat::vtp: return vtp_write(g, o.encoding == VtpEncoding::binary);
    case GraphFormat::swc: return swc_write(g);
    case GraphFormat::graphml: return graphml_write(g);
    case GraphFormat::csv:
      if (nodes_text) *nodes_text = csv_nodes_write(g);
      return csv_edges_write(g);
  }
  throw Error("graph_to_text: unknown format");
}

SpatialGraph graph_from_text(const std::string& text, GraphFormat f, const std::string& nodes_text, const std::string& src) {
  SpatialGraph g;
  switch (f) {
    case GraphFormat::amira: g = amira_read(text, src); break;
    case GraphFormat::vtp: g = vtp_read(text, src); break;
    case GraphFormat::swc: g = swc_read(text, src); break;
    case GraphFormat::graphml: g = graphml_read(text, src); break;
    case GraphFormat::csv: g = csv_read(text, nodes_text, src); break;
  }
  if (g.source_grid.direction != kIdentityDirection) g = with_direction_applied(g, false);
  const auto problems = g.check_invariants();
  if (!problems.empty()) throw InputError(src + ": inconsistent graph: " + problems.front());
  return g;
}

void write_graph(const SpatialGraph& g, const std::filesystem::path& path, GraphFormat f,
                 const std::filesystem::path& nodes_path, const GraphWriteOptions& o) {
  if (f == GraphFormat::csv && nodes_path.empty())
    throw InputError("parameter 'nodes_path': required for CSV graphs (the nodes table goes there)");
  std::string nodes;
  const std::string text = graph_to_text(g, f, &nodes, o);
  auto put = [](const std::filesystem::path& p, const std::string& t) { write_file_atomically(p, t); };
  put(path, text);
  if (f == GraphFormat::csv) put(nodes_path, nodes);
}

void apply_read_options(SpatialGraph& g, const ReadGraphOptions& o) {
  if (!(o.scale > 0.0) || !std::isfinite(o.scale))
    throw InputError("parameter 'scale': expected a finite number > 0, got " + text::format_double(o.scale, 17));
  if (o.scale != 1.0) scale_graph(g, o.scale);
  if (!o.unit.empty()) g.unit = o.unit;
  g.source_grid.unit = g.unit;
}

SpatialGraph read_graph(const std::filesystem::path& path, GraphFormat f, const std::filesystem::path& nodes_path) {
  std::string nodes;
  if (f == GraphFormat::csv) {
    std::filesystem::path np = nodes_path;
    if (np.empty()) np = path.parent_path() / (path.stem().string() + "_nodes.csv");
    nodes = read_text(np);
  }
  return graph_from_text(read_text(path), f, nodes, path.string());
}

}  // namespace skel::io
