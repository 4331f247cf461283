// NRRD volumes (teem.sourceforge.net/nrrd/format.html): `.nrrd` (header and data in one file) and
// `.nhdr` (header; the data in the file named by `data file`, raw or gzip). Read: types int8..float64,
// both byte orders, encodings raw, gzip and ascii; `sizes`, `spacings` or `space directions` (->
// spacing and direction), `space origin`, `space units` (or per-axis `units`) -> unit. Coordinates
// are kept in the file's space as stored (no RAS/LPS flip; `skelflow info` shows the space).
// Write: `.nrrd` only, little endian, gzip (compression > 0) or raw, with space directions, space
// origin and space units.
#include <algorithm>
#include <bit>
#include <charconv>
#include <limits>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>

#include "io/volume_bytes.hpp"
#include "io/volume_format.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace skel::io {

namespace {

namespace fs = std::filesystem;

struct Field {
  std::string value;
  int line = 0;
};

struct NrrdHeader {
  std::string file;                 // for messages
  std::map<std::string, Field> fields;  // lower-case key -> value
  uint64_t data_offset = 0;         // attached data: first byte after the blank line
  bool attached = false;
  // Derived:
  VolumeHeader header;
  std::string encoding;             // raw, gzip, ascii
  bool big_endian = false;
  fs::path data_path;
  int64_t byte_skip = 0;            // -1: data at the end of the (raw) file
  int64_t line_skip = 0;

  [[nodiscard]] const Field* get(const std::string& k) const {
    auto it = fields.find(k);
    return it == fields.end() ? nullptr : &it->second;
  }
  [[nodiscard]] std::string at(const Field& f) const { return file + ":" + std::to_string(f.line); }
};

constexpr uint64_t kMaxHeader = 1 << 20;

std::string nrrd_type(const std::string& raw) {
  std::string t = text::to_lower(text::trim(raw));
  static const std::map<std::string, std::string> names{
      {"signed char", "int8"}, {"int8", "int8"}, {"int8_t", "int8"},
      {"uchar", "uint8"}, {"unsigned char", "uint8"}, {"uint8", "uint8"}, {"uint8_t", "uint8"},
      {"short", "int16"}, {"short int", "int16"}, {"signed short", "int16"}, {"signed short int", "int16"},
      {"int16", "int16"}, {"int16_t", "int16"},
      {"ushort", "uint16"}, {"unsigned short", "uint16"}, {"unsigned short int", "uint16"}, {"uint16", "uint16"},
      {"uint16_t", "uint16"},
      {"int", "int32"}, {"signed int", "int32"}, {"int32", "int32"}, {"int32_t", "int32"},
      {"uint", "uint32"}, {"unsigned int", "uint32"}, {"uint32", "uint32"}, {"uint32_t", "uint32"},
      {"longlong", "int64"}, {"long long", "int64"}, {"long long int", "int64"}, {"signed long long", "int64"},
      {"signed long long int", "int64"}, {"int64", "int64"}, {"int64_t", "int64"},
      {"ulonglong", "uint64"}, {"unsigned long long", "uint64"}, {"unsigned long long int", "uint64"},
      {"uint64", "uint64"}, {"uint64_t", "uint64"},
      {"float", "float32"}, {"double", "float64"}};
  auto it = names.find(t);
  return it == names.end() ? std::string() : it->second;
}

std::string nrrd_type_name(const std::string& dtype) {
  static const std::map<std::string, std::string> names{
      {"uint8", "uint8"}, {"uint16", "uint16"}, {"uint32", "uint32"}, {"uint64", "uint64"},
      {"int32", "int32"}, {"float32", "float"}, {"float64", "double"}};
  return names.at(dtype);
}

// Whitespace-separated words of a value, with "quoted strings" as one word (quotes removed).
std::vector<std::string> words(const std::string& v) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < v.size()) {
    while (i < v.size() && std::isspace(static_cast<unsigned char>(v[i]))) ++i;
    if (i >= v.size()) break;
    if (v[i] == '"') {
      const size_t e = v.find('"', i + 1);
      out.push_back(v.substr(i + 1, e == std::string::npos ? std::string::npos : e - i - 1));
      i = e == std::string::npos ? v.size() : e + 1;
    } else {
      size_t e = i;
      while (e < v.size() && !std::isspace(static_cast<unsigned char>(v[e]))) ++e;
      out.push_back(v.substr(i, e - i));
      i = e;
    }
  }
  return out;
}

double number(const NrrdHeader& h, const Field& f, const std::string& s, const std::string& key) {
  double v = 0;
  if (!text::parse_double(text::trim(s), v))
    throw InputError(h.at(f) + ": '" + key + "': expected a number, got '" + s.substr(0, 30) + "'");
  return v;
}

// "(a,b,c)" -> a vector; "none" -> false.
bool vector3(const NrrdHeader& h, const Field& f, const std::string& s, const std::string& key, Vec3& out) {
  const std::string t = text::trim(s);
  if (t == "none") return false;
  if (t.size() < 2 || t.front() != '(' || t.back() != ')')
    throw InputError(h.at(f) + ": '" + key + "': expected a vector like (1,0,0), got '" + t.substr(0, 40) + "'");
  const auto parts = text::split(t.substr(1, t.size() - 2), ',');
  if (parts.size() != 3)
    throw InputError(h.at(f) + ": '" + key + "': expected 3 components, got " + std::to_string(parts.size()) + " in '" +
                     t.substr(0, 40) + "'");
  for (size_t i = 0; i < 3; ++i) out[i] = number(h, f, parts[i], key);
  return true;
}

// Vectors of a "space directions"/"space origin" value: "(..) (..) none".
std::vector<std::string> vector_words(const std::string& v) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i < v.size()) {
    while (i < v.size() && std::isspace(static_cast<unsigned char>(v[i]))) ++i;
    if (i >= v.size()) break;
    size_t e = i;
    if (v[i] == '(') {
      e = v.find(')', i);
      e = e == std::string::npos ? v.size() : e + 1;
    } else {
      while (e < v.size() && !std::isspace(static_cast<unsigned char>(v[e]))) ++e;
    }
    out.push_back(v.substr(i, e - i));
    i = e;
  }
  return out;
}

NrrdHeader parse_header(const fs::path& path) {
  NrrdHeader h;
  h.file = path.string();
  const uint64_t size = volbytes::file_size(path);
  std::string head(static_cast<size_t>(std::min(size, kMaxHeader)), '\0');
  volbytes::read_exact(path, 0, head.data(), head.size(), "header");
  if (head.compare(0, 7, "NRRD000") != 0 || head.size() < 8 || !std::isdigit(static_cast<unsigned char>(head[7])))
    throw InputError(h.file + ": not a NRRD file (it does not start with 'NRRD000x')");
  size_t pos = head.find('\n');
  if (pos == std::string::npos) throw InputError(h.file + ": the NRRD header ends after its first line (truncated)");
  ++pos;
  int line = 1;
  bool blank = false;
  while (pos < head.size()) {
    size_t e = head.find('\n', pos);
    if (e == std::string::npos) {
      if (size > head.size()) throw InputError(h.file + ": the NRRD header is longer than 1 MiB or has no blank line before the data");
      e = head.size();
    }
    ++line;
    std::string l = head.substr(pos, e - pos);
    pos = e + 1;
    if (!l.empty() && l.back() == '\r') l.pop_back();
    if (l.empty()) {
      blank = true;
      break;
    }
    if (l[0] == '#') continue;
    if (l.find(":=") != std::string::npos) continue;  // key/value pairs: not used
    const size_t c = l.find(": ");
    if (c == std::string::npos)
      throw InputError(h.file + ":" + std::to_string(line) + ": expected 'field: value', got '" + l.substr(0, 60) + "'");
    std::string key = text::to_lower(text::trim(l.substr(0, c)));
    if (key == "datafile") key = "data file";
    if (key == "lineskip") key = "line skip";
    if (key == "byteskip") key = "byte skip";
    if (key == "spacedirections") key = "space directions";
    if (key == "spaceorigin") key = "space origin";
    if (key == "spaceunits") key = "space units";
    if (h.fields.count(key))
      throw InputError(h.file + ":" + std::to_string(line) + ": field '" + key + "' appears twice");
    h.fields[key] = Field{text::trim(l.substr(c + 2)), line};
  }
  h.attached = !h.get("data file");
  if (h.attached) {
    if (!blank) throw InputError(h.file + ": the NRRD header has no blank line before the data (truncated?)");
    h.data_offset = pos;
  }

  auto need = [&](const std::string& k) -> const Field& {
    const Field* f = h.get(k);
    if (!f) throw InputError(h.file + ": the NRRD header has no '" + k + "' field");
    return *f;
  };
  const Field& tf = need("type");
  const std::string dtype = nrrd_type(tf.value);
  if (dtype.empty())
    throw InputError(h.at(tf) + ": unsupported NRRD type '" + tf.value +
                     "' (int8, uint8, int16, uint16, int32, uint32, int64, uint64, float, double)");
  const Field& df = need("dimension");
  int64_t dim = 0;
  if (!text::parse_int(df.value, dim) || dim < 1 || dim > 3)
    throw InputError(h.at(df) + ": 'dimension' is " + df.value + "; Skelflow reads volumes of 1 to 3 axes");
  const Field& sf = need("sizes");
  const auto sw = words(sf.value);
  if (static_cast<int64_t>(sw.size()) != dim)
    throw InputError(h.at(sf) + ": 'sizes' has " + std::to_string(sw.size()) + " values but 'dimension' is " +
                     std::to_string(dim));
  Dims dims{1, 1, 1};
  for (size_t i = 0; i < sw.size(); ++i)
    if (!text::parse_int(sw[i], dims[i]) || dims[i] < 1)
      throw InputError(h.at(sf) + ": 'sizes': '" + sw[i] + "' is not a positive integer");

  const Field& ef = need("encoding");
  const std::string enc = text::to_lower(ef.value);
  if (enc == "raw") h.encoding = "raw";
  else if (enc == "gzip" || enc == "gz") h.encoding = "gzip";
  else if (enc == "ascii" || enc == "text" || enc == "txt") h.encoding = "ascii";
  else
    throw InputError(h.at(ef) + ": unsupported NRRD encoding '" + ef.value + "' (raw, gzip, ascii)");
  if (const Field* f = h.get("endian")) {
    const std::string e = text::to_lower(f->value);
    if (e != "little" && e != "big") throw InputError(h.at(*f) + ": 'endian' is '" + f->value + "' (little or big)");
    h.big_endian = e == "big";
  } else if (volbytes::dtype_bytes(dtype) > 1 && h.encoding != "ascii") {
    throw InputError(h.file + ": the NRRD header has no 'endian' field (needed for " + dtype + " data)");
  }
  if (const Field* f = h.get("byte skip")) {
    if (!text::parse_int(f->value, h.byte_skip) || h.byte_skip < -1)
      throw InputError(h.at(*f) + ": 'byte skip' is '" + f->value + "' (an integer >= -1)");
    if (h.byte_skip != 0 && h.encoding != "raw")
      throw InputError(h.at(*f) + ": 'byte skip' with encoding " + h.encoding + " is not supported");
  }
  if (const Field* f = h.get("line skip"))
    if (!text::parse_int(f->value, h.line_skip) || h.line_skip < 0)
      throw InputError(h.at(*f) + ": 'line skip' is '" + f->value + "' (an integer >= 0)");
  if (const Field* f = h.get("data file")) {
    const auto w = words(f->value);
    if (w.size() != 1 || w[0] == "LIST")
      throw InputError(h.at(*f) + ": 'data file' lists several files ('" + f->value.substr(0, 40) +
                       "'); Skelflow reads one data file");
    h.data_path = fs::path(w[0]).is_absolute() ? fs::path(w[0]) : path.parent_path() / w[0];
  } else {
    h.data_path = path;
  }

  // Geometry.
  Grid& g = h.header.grid;
  g.dims = dims;
  const Field* dirf = h.get("space directions");
  if (dirf) {
    const auto vw = vector_words(dirf->value);
    if (static_cast<int64_t>(vw.size()) != dim)
      throw InputError(h.at(*dirf) + ": 'space directions' has " + std::to_string(vw.size()) + " entries but 'dimension' is " +
                       std::to_string(dim));
    std::array<Vec3, 3> axes{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    for (size_t k = 0; k < vw.size(); ++k)
      if (!vector3(h, *dirf, vw[k], "space directions", axes[k]))
        throw InputError(h.at(*dirf) + ": 'space directions': axis " + std::to_string(k) + " is 'none'; Skelflow reads spatial axes only");
    if (dim < 3) {
      // Complete the frame: the missing axes are orthogonal unit vectors.
      const Vec3& a = axes[0];
      if (dim == 1) {  // a unit vector orthogonal to axis 0 (Gram-Schmidt on the least parallel axis)
        const double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        Vec3 b = la > 0 && std::abs(a[0]) / la < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
        const double p = la > 0 ? (b[0] * a[0] + b[1] * a[1] + b[2] * a[2]) / (la * la) : 0.0;
        for (size_t i = 0; i < 3; ++i) b[i] -= p * a[i];
        const double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        axes[1] = {b[0] / lb, b[1] / lb, b[2] / lb};
      }
      const Vec3& u = axes[0];
      const Vec3& v = axes[1];
      Vec3 w{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
      const double n = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
      if (n > 0) axes[2] = {w[0] / n, w[1] / n, w[2] / n};
    }
    if (!volbytes::split_axes(axes, g.spacing, g.direction))
      throw InputError(h.at(*dirf) + ": 'space directions' has an axis of length 0");
    h.header.has_spacing = true;
  } else if (const Field* f = h.get("spacings")) {
    const auto w = words(f->value);
    if (static_cast<int64_t>(w.size()) != dim)
      throw InputError(h.at(*f) + ": 'spacings' has " + std::to_string(w.size()) + " values but 'dimension' is " +
                       std::to_string(dim));
    for (size_t k = 0; k < w.size(); ++k) {
      const double s = text::to_lower(w[k]) == "nan" ? 1.0 : number(h, *f, w[k], "spacings");
      if (!(s > 0) || !std::isfinite(s))
        throw InputError(h.at(*f) + ": 'spacings': axis " + std::to_string(k) + " has spacing " + w[k] + " (must be > 0)");
      g.spacing[k] = s;
    }
    h.header.has_spacing = true;
  }
  if (const Field* f = h.get("space origin")) {
    if (!vector3(h, *f, f->value, "space origin", g.origin))
      throw InputError(h.at(*f) + ": 'space origin' is 'none'");
    for (double o : g.origin)
      if (!std::isfinite(o)) throw InputError(h.at(*f) + ": 'space origin' is not finite");
    h.header.has_origin = true;
  }
  const Field* uf = h.get("space units");
  if (!uf) uf = h.get("units");
  if (uf) {
    const auto w = words(uf->value);
    std::string unit;
    for (const auto& u : w) {
      if (u.empty() || u == "none" || u == "???") continue;
      const std::string n = volbytes::normalize_unit(u);
      if (!unit.empty() && n != unit)
        throw InputError(h.at(*uf) + ": the axes have different units ('" + uf->value + "'); Skelflow needs one unit");
      unit = n;
    }
    if (!unit.empty()) {
      g.unit = unit;
      h.header.has_unit = true;
    }
  }
  h.header.dtype = dtype;
  h.header.details.push_back("encoding: " + h.encoding + (volbytes::dtype_bytes(dtype) > 1 && h.encoding != "ascii"
                                                              ? std::string(h.big_endian ? ", big endian" : ", little endian")
                                                              : std::string()));
  if (const Field* f = h.get("space")) h.header.details.push_back("space: " + f->value + " (coordinates as stored)");
  if (!h.attached) h.header.details.push_back("data file: " + h.data_path.string());
  return h;
}

// The first data byte of a raw/ascii data file after `line skip` lines.
uint64_t skip_lines(const NrrdHeader& h, uint64_t start) {
  if (h.line_skip == 0) return start;
  std::ifstream in(h.data_path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(start));
  std::string l;
  for (int64_t i = 0; i < h.line_skip; ++i)
    if (!std::getline(in, l))
      throw InputError(h.data_path.string() + ": 'line skip' " + std::to_string(h.line_skip) + " skips past the end of the file");
  return static_cast<uint64_t>(in.tellg());
}

// The first voxel byte of raw-encoded data, its size checked against the file's.
uint64_t raw_data_start(const NrrdHeader& h) {
  const std::string data_file = h.data_path.string();
  const uint64_t need = volbytes::checked_bytes(h.file, h.header.grid.dims, volbytes::dtype_bytes(h.header.dtype));
  const uint64_t size = volbytes::file_size(h.data_path);
  if (h.byte_skip == -1) {
    volbytes::check_available(data_file, size, need, "the voxel data");
    return size - need;
  }
  const uint64_t start = skip_lines(h, h.attached ? h.data_offset : 0) + static_cast<uint64_t>(h.byte_skip);
  volbytes::check_available(data_file, size > start ? size - start : 0, need, "the voxel data");
  return start;
}

DataPtr read_nrrd(const fs::path& path, const VolumeReadOptions&);

// A box of raw-encoded data read in place; gzip and ascii data are decoded whole and cut.
DataPtr read_nrrd_box(const fs::path& path, const VolumeReadOptions& o, Dims begin, Dims size) {
  const NrrdHeader h = parse_header(path);
  if (h.encoding == "raw")
    return read_raw_voxel_box(h.data_path, raw_data_start(h), h.header.grid, h.header.dtype, h.big_endian, begin, size);
  return crop_volume_box(*read_nrrd(path, o), begin, size);
}

DataPtr read_nrrd(const fs::path& path, const VolumeReadOptions&) {
  const NrrdHeader h = parse_header(path);
  const std::string data_file = h.data_path.string();
  const uint64_t need = volbytes::checked_bytes(h.file, h.header.grid.dims, volbytes::dtype_bytes(h.header.dtype));
  const uint64_t size = volbytes::file_size(h.data_path);
  uint64_t start = h.attached ? h.data_offset : 0;
  if (h.encoding == "raw") {
    start = raw_data_start(h);
    return volbytes::decode(h.header.grid, h.header.dtype, h.big_endian, [&](char* dst, uint64_t n) {
      volbytes::read_exact(h.data_path, start, dst, n, "voxel data");
    });
  }
  start = skip_lines(h, start);
  const uint64_t avail = size > start ? size - start : 0;
  if (h.encoding == "gzip") {
    volbytes::check_compressed(data_file, avail, need, "the gzip voxel data");
    std::string comp(static_cast<size_t>(avail), '\0');
    volbytes::read_exact(h.data_path, start, comp.data(), avail, "voxel data");
    return volbytes::decode(h.header.grid, h.header.dtype, h.big_endian, [&](char* dst, uint64_t n) {
      volbytes::inflate_into(data_file, "gzip voxel data", comp.data(), comp.size(), dst, n);
    });
  }
  // ascii: every value takes at least one digit and one separator.
  const uint64_t count = static_cast<uint64_t>(h.header.grid.voxel_count());
  volbytes::check_available(data_file, avail + 1, 2 * count, "the ascii voxel data");
  std::string txt(static_cast<size_t>(avail), '\0');
  volbytes::read_exact(h.data_path, start, txt.data(), avail, "voxel data");
  const bool native_big = std::endian::native == std::endian::big;
  return volbytes::decode(h.header.grid, h.header.dtype, native_big, [&](char* dst, uint64_t) {
    const size_t w = volbytes::dtype_bytes(h.header.dtype);
    const char* p = txt.data();
    const char* end = p + txt.size();
    auto sep = [](char c) { return std::isspace(static_cast<unsigned char>(c)) || c == ','; };
    for (uint64_t i = 0; i < count; ++i) {
      while (p < end && sep(*p)) ++p;
      if (p >= end)
        throw InputError(data_file + ": ascii data ends after " + std::to_string(i) + " of " + std::to_string(count) + " values");
      const char* q = p;
      while (q < end && !sep(*q)) ++q;
      const std::string_view tok(p, static_cast<size_t>(q - p));
      if (!volbytes::store_text_value(tok, h.header.dtype, dst + i * w))
        throw InputError(data_file + ": ascii data value " + std::to_string(i) + " '" + std::string(tok.substr(0, 30)) +
                         "' is not a " + h.header.dtype + " value");
      p = q;
    }
  });
}

void write_nrrd(const fs::path& path, const DataObject& volume, const VolumeWriteOptions& o) {
  const Grid& g = volume_grid(volume, display_path(path).string());
  const std::string dtype = volbytes::volume_dtype(volume);
  std::string s = "NRRD0004\n# Complete NRRD file format specification at:\n# http://teem.sourceforge.net/nrrd/format.html\n";
  s += "type: " + nrrd_type_name(dtype) + "\n";
  s += "dimension: 3\nspace dimension: 3\n";
  s += "sizes: " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " + std::to_string(g.dims[2]) + "\n";
  s += "space directions:";
  for (size_t k = 0; k < 3; ++k) {
    double a[3];
    for (size_t r = 0; r < 3; ++r) a[r] = g.direction[r * 3 + k] * g.spacing[k];
    s += " (" + volbytes::join_numbers(a, 3, ",") + ")";
  }
  s += "\n";
  s += "kinds: domain domain domain\n";
  s += "space units: \"" + g.unit + "\" \"" + g.unit + "\" \"" + g.unit + "\"\n";
  s += "space origin: (" + volbytes::join_numbers(g.origin.data(), 3, ",") + ")\n";
  s += "endian: little\n";
  s += std::string("encoding: ") + (o.compression > 0 ? "gzip" : "raw") + "\n\n";
  const std::string data = volbytes::encode(volume, false);
  if (o.compression > 0) s += volbytes::deflate(data.data(), data.size(), o.compression, true);
  else s += data;
  write_file_atomically(path, s);
}

VolumeFormat make(bool attached) {
  VolumeFormat f;
  f.name = attached ? "NRRD" : "NRRD (detached header)";
  f.extensions = {attached ? ".nrrd" : ".nhdr"};
  f.sniff = [](std::string_view head) { return head.substr(0, 7) == "NRRD000"; };
  f.read_header = [](const fs::path& p, const VolumeReadOptions&) { return parse_header(p).header; };
  f.read = read_nrrd;
  f.read_box = read_nrrd_box;
  f.boxes_are_cheap = [](const fs::path& p, const VolumeReadOptions&) { return parse_header(p).encoding == "raw"; };
  if (attached) f.write = write_nrrd;
  return f;
}

}  // namespace

VolumeFormat nrrd_volume_format() { return make(true); }
VolumeFormat nhdr_volume_format() { return make(false); }

}  // namespace skel::io
