// Amira/Avizo lattice volumes (`.am` with `define Lattice nx ny nz`; AmiraMesh spatial graphs live
// in graph_io.cpp). Read: `# AmiraMesh BINARY-LITTLE-ENDIAN 2.1`, `# AmiraMesh 3D BINARY 2.0` (big
// endian), `# AmiraMesh 3D ASCII 2.0` (and `# Avizo ...`); data types byte, short, ushort, int,
// float, double (one component); blocks raw, HxByteRLE or HxZip (zlib) as `@1(HxZip,size)` says;
// `CoordType "uniform"` with `BoundingBox xmin xmax ymin ymax zmin zmax` of the voxel centres:
// spacing = (max - min) / (n - 1) (1 for an axis of one voxel), origin = min;
// `Units { Coordinates "mm" }` -> unit. Amira lattices carry no direction (identity).
// Write: binary little endian, HxZip when compression > 0; byte, ushort, int, float and double
// (uint32/uint64 volumes, and volumes with a direction, cannot be stored: InputError).
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <regex>

#include "io/volume_bytes.hpp"
#include "io/volume_format.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace skel::io {

namespace {

namespace fs = std::filesystem;

constexpr uint64_t kMaxHeader = 1 << 20;

struct Block {
  int index = 0;
  std::string type;     // Amira type name
  std::string dtype;    // Skelflow stored type
  int components = 1;
  std::string name;
  std::string encoding;  // "", "HxByteRLE", "HxZip"
  int64_t encoded_size = -1;
  int line = 0;
};

struct AmiraHeader {
  std::string file;
  VolumeHeader header;
  bool ascii = false, big_endian = false;
  std::vector<Block> blocks;  // every Lattice declaration, in header order
  size_t chosen = 0;          // the voxels: the first one-component Lattice block
  uint64_t data_begin = 0;    // first byte after the header (the data section)
};

std::string amira_dtype(const std::string& t) {
  static const std::map<std::string, std::string> names{{"byte", "uint8"},  {"short", "int16"}, {"ushort", "uint16"},
                                                        {"int", "int32"},   {"float", "float32"}, {"double", "float64"}};
  auto it = names.find(t);
  return it == names.end() ? std::string() : it->second;
}

AmiraHeader parse_header(const fs::path& path) {
  AmiraHeader a;
  a.file = path.string();
  const uint64_t size = volbytes::file_size(path);
  std::string head(static_cast<size_t>(std::min(size, kMaxHeader)), '\0');
  volbytes::read_exact(path, 0, head.data(), head.size(), "header");
  const size_t nl = head.find('\n');
  const std::string first = head.substr(0, nl);
  if (first.rfind("# AmiraMesh", 0) != 0 && first.rfind("# Avizo", 0) != 0)
    throw InputError(a.file + ": not an AmiraMesh file (the first line does not start with '# AmiraMesh')");
  if (first.find("BINARY-LITTLE-ENDIAN") != std::string::npos) a.big_endian = false;
  else if (first.find("BINARY") != std::string::npos) a.big_endian = true;
  else if (first.find("ASCII") != std::string::npos) a.ascii = true;
  else throw InputError(a.file + ":1: unknown AmiraMesh encoding in '" + first.substr(0, 60) + "' (BINARY-LITTLE-ENDIAN, BINARY, ASCII)");
  // The header: up to the first line that is only "@k".
  static const std::regex at_re(R"(^@(\d+)\s*$)");
  static const std::regex def_re(R"(^\s*define\s+Lattice\s+(\d+)(\s+(\d+))?(\s+(\d+))?\s*$)");
  static const std::regex decl_re(
      R"(^\s*Lattice\s*\{\s*(\w+)\s*(\[\s*(\d+)\s*\])?\s+(\w+)\s*\}\s*@(\d+)\s*(\(\s*(\w+)\s*,\s*(\d+)\s*\))?)");
  size_t pos = nl == std::string::npos ? head.size() : nl + 1;
  int line = 1;
  bool found_at = false, has_define = false;
  Dims dims{1, 1, 1};
  std::string params;
  while (pos < head.size()) {
    size_t e = head.find('\n', pos);
    if (e == std::string::npos) e = head.size();
    std::string l = head.substr(pos, e - pos);
    if (!l.empty() && l.back() == '\r') l.pop_back();
    ++line;
    std::smatch m;
    if (std::regex_match(l, m, at_re)) {
      a.data_begin = pos;
      found_at = true;
      break;
    }
    if (std::regex_match(l, m, def_re)) {
      has_define = true;
      for (size_t i = 0; i < 3; ++i) {
        const std::string v = m[1 + 2 * i].str();
        if (v.empty()) continue;
        if (!text::parse_int(v, dims[i]) || dims[i] < 1)
          throw InputError(a.file + ":" + std::to_string(line) + ": 'define Lattice': size '" + v.substr(0, 24) + "' is not a positive integer");
      }
    } else if (std::regex_search(l, m, decl_re)) {
      Block b;
      b.type = m[1].str();
      int64_t c = 1, k = 0, n = -1;
      if (m[3].matched && (!text::parse_int(m[3].str(), c) || c < 1 || c > 1 << 20))
        throw InputError(a.file + ":" + std::to_string(line) + ": bad component count '" + m[3].str() + "'");
      if (!text::parse_int(m[5].str(), k) || k > 1 << 20) throw InputError(a.file + ":" + std::to_string(line) + ": bad block number");
      if (m[6].matched) {
        b.encoding = m[7].str();
        if (!text::parse_int(m[8].str(), n)) throw InputError(a.file + ":" + std::to_string(line) + ": bad encoded size");
        if (b.encoding != "HxByteRLE" && b.encoding != "HxZip")
          throw InputError(a.file + ":" + std::to_string(line) + ": unsupported AmiraMesh encoding '" + b.encoding +
                           "' (HxByteRLE, HxZip)");
      }
      b.components = static_cast<int>(c);
      b.index = static_cast<int>(k);
      b.name = m[4].str();
      b.encoded_size = n;
      b.line = line;
      b.dtype = amira_dtype(b.type);
      a.blocks.push_back(b);
    } else if (text::trim(l).rfind("define ", 0) != 0) {
      params += l + "\n";
    }
    pos = e + 1;
  }
  if (!has_define)
    throw InputError(a.file + ": no 'define Lattice nx ny nz' (an AmiraMesh file that is not a volume: a spatial graph?)");
  if (a.blocks.empty()) throw InputError(a.file + ": no 'Lattice { type Data } @1' declaration");
  if (!found_at) throw InputError(a.file + ": the AmiraMesh header has no data section ('@1' line; truncated, or a header over 1 MiB)");
  a.chosen = a.blocks.size();
  for (size_t i = 0; i < a.blocks.size(); ++i)
    if (a.blocks[i].components == 1) {
      a.chosen = i;
      break;
    }
  if (a.chosen == a.blocks.size())
    throw InputError(a.file + ":" + std::to_string(a.blocks[0].line) + ": the lattice has " +
                     std::to_string(a.blocks[0].components) + " components per voxel; Skelflow reads one");
  const Block& b = a.blocks[a.chosen];
  if (b.dtype.empty())
    throw InputError(a.file + ":" + std::to_string(b.line) + ": unsupported lattice type '" + b.type +
                     "' (byte, short, ushort, int, float, double)");
  if (a.ascii && !b.encoding.empty())
    throw InputError(a.file + ":" + std::to_string(b.line) + ": an ASCII file with " + b.encoding + " data");

  VolumeHeader& h = a.header;
  Grid& g = h.grid;
  g.dims = dims;
  std::smatch m;
  static const std::regex coord_re(R"(CoordType\s+\"(\w+)\")");
  if (std::regex_search(params, m, coord_re) && m[1].str() != "uniform")
    throw InputError(a.file + ": CoordType \"" + m[1].str() + "\"; Skelflow reads uniform lattices");
  static const std::regex bbox_re(R"(BoundingBox\s+([^,\n}]*))");
  if (std::regex_search(params, m, bbox_re)) {
    std::vector<double> v;
    std::string box = text::trim(m[1].str());
    std::replace(box.begin(), box.end(), '\t', ' ');
    for (const auto& w : text::split(box, ' ')) {
      if (text::trim(w).empty()) continue;
      double x = 0;
      if (!text::parse_double(text::trim(w), x) || !std::isfinite(x))
        throw InputError(a.file + ": BoundingBox value '" + w.substr(0, 24) + "' is not a finite number");
      v.push_back(x);
    }
    if (v.size() != 6) throw InputError(a.file + ": BoundingBox has " + std::to_string(v.size()) + " values; expected 6");
    for (size_t i = 0; i < 3; ++i) {
      g.origin[i] = v[2 * i];
      if (dims[i] > 1) {
        g.spacing[i] = (v[2 * i + 1] - v[2 * i]) / static_cast<double>(dims[i] - 1);
        if (!(g.spacing[i] > 0))
          throw InputError(a.file + ": BoundingBox axis " + std::string(1, "xyz"[i]) + " (" + text::format_double(v[2 * i], 17) +
                           " to " + text::format_double(v[2 * i + 1], 17) + ") gives no positive spacing");
      }
    }
    h.has_spacing = h.has_origin = true;
  }
  static const std::regex unit_re(R"(Units\s*\{[^}]*Coordinates\s+\"([^\"]*)\")");
  if (std::regex_search(params, m, unit_re) && !text::trim(m[1].str()).empty()) {
    g.unit = volbytes::normalize_unit(m[1].str());
    h.has_unit = true;
  }
  h.dtype = b.dtype;
  h.details.push_back(std::string("encoding: ") + (a.ascii ? "ASCII" : a.big_endian ? "binary, big endian" : "binary, little endian") +
                      (b.encoding.empty() ? "" : ", " + b.encoding));
  return a;
}

// HxByteRLE: a control byte c; c & 0x80: (c & 0x7f) literal bytes follow; else the next byte c times.
void unrle(const std::string& file, const char* src, uint64_t n, char* dst, uint64_t expected) {
  uint64_t i = 0, o = 0;
  while (o < expected) {
    if (i >= n) throw InputError(file + ": HxByteRLE data ends after " + std::to_string(o) + " of " + std::to_string(expected) + " bytes (truncated)");
    const auto c = static_cast<unsigned char>(src[i++]);
    const uint64_t count = c & 0x7f;
    if (count == 0) continue;
    if (o + count > expected) throw InputError(file + ": HxByteRLE data holds more than " + std::to_string(expected) + " bytes");
    if (c & 0x80) {
      if (i + count > n) throw InputError(file + ": HxByteRLE data ends inside a literal run (truncated)");
      std::memcpy(dst + o, src + i, count);
      i += count;
    } else {
      if (i >= n) throw InputError(file + ": HxByteRLE data ends inside a run (truncated)");
      std::memset(dst + o, src[i++], count);
    }
    o += count;
  }
}

// Bytes a binary block occupies in the data section.
uint64_t block_bytes(const AmiraHeader& a, const Block& b, const Dims& dims) {
  if (b.encoded_size >= 0) return static_cast<uint64_t>(b.encoded_size);
  const size_t w = volbytes::dtype_bytes(amira_dtype(b.type));
  if (w == 0) throw InputError(a.file + ":" + std::to_string(b.line) + ": cannot skip a block of type '" + b.type + "'");
  return volbytes::checked_bytes(a.file, dims, w * static_cast<size_t>(b.components));
}

DataPtr read_amira(const fs::path& path, const VolumeReadOptions&) {
  const AmiraHeader a = parse_header(path);
  const Block& b = a.blocks[a.chosen];
  const Grid& g = a.header.grid;
  const uint64_t need = volbytes::checked_bytes(a.file, g.dims, volbytes::dtype_bytes(b.dtype));
  const uint64_t size = volbytes::file_size(path);
  const std::string marker = "@" + std::to_string(b.index);
  if (a.ascii) {
    // Find the line "@k" of our block; values follow until the next "@" line.
    std::string txt(static_cast<size_t>(size - a.data_begin), '\0');
    volbytes::read_exact(path, a.data_begin, txt.data(), txt.size(), "data section");
    size_t p = 0, begin = std::string::npos;
    while (p < txt.size()) {
      size_t e = txt.find('\n', p);
      if (e == std::string::npos) e = txt.size();
      if (text::trim(std::string_view(txt).substr(p, e - p)) == marker) {
        begin = e;
        break;
      }
      p = e + 1;
    }
    if (begin == std::string::npos) throw InputError(a.file + ": data block " + marker + " is missing");
    size_t end = txt.find("\n@", begin);
    if (end == std::string::npos) end = txt.size();
    const uint64_t count = static_cast<uint64_t>(g.voxel_count());
    volbytes::check_available(a.file, end - begin + 1, 2 * count, "the ASCII lattice data");
    const bool native_big = std::endian::native == std::endian::big;
    return volbytes::decode(g, b.dtype, native_big, [&](char* dst, uint64_t) {
      const char* q = txt.data() + begin;
      const char* stop = txt.data() + end;
      const size_t w = volbytes::dtype_bytes(b.dtype);
      for (uint64_t i = 0; i < count; ++i) {
        while (q < stop && std::isspace(static_cast<unsigned char>(*q))) ++q;
        const char* r = q;
        while (r < stop && !std::isspace(static_cast<unsigned char>(*r))) ++r;
        if (q == r || !volbytes::store_text_value(std::string_view(q, static_cast<size_t>(r - q)), b.dtype, dst + i * w))
          throw InputError(a.file + ": ASCII lattice value " + std::to_string(i) + " is missing or not a " + b.type + " value");
        q = r;
      }
    });
  }
  // Binary: blocks follow each other as "@k\n" + bytes + "\n", in the order of the file.
  uint64_t p = a.data_begin;
  std::string lbuf;
  auto read_line = [&](uint64_t at) {
    lbuf.assign(static_cast<size_t>(std::min<uint64_t>(64, size - std::min(size, at))), '\0');
    volbytes::read_exact(path, at, lbuf.data(), lbuf.size(), "data section");
    const size_t e = lbuf.find('\n');
    return std::make_pair(lbuf.substr(0, e), e == std::string::npos ? lbuf.size() : e + 1);
  };
  while (true) {
    if (p >= size) throw InputError(a.file + ": data block " + marker + " is missing (the file ends first)");
    auto [l, len] = read_line(p);
    while (!l.empty() && (l.back() == '\r' || l.back() == ' ')) l.pop_back();
    if (l.empty()) {  // the newline after the previous block
      p += len;
      continue;
    }
    int64_t k = 0;
    if (l[0] != '@' || !text::parse_int(l.substr(1), k))
      throw InputError(a.file + ": expected a data block marker '@k' at byte " + std::to_string(p) + ", found '" +
                       l.substr(0, 20) + "'");
    p += len;
    const Block* blk = nullptr;
    for (const auto& x : a.blocks)
      if (x.index == k) blk = &x;
    if (!blk) throw InputError(a.file + ": data block @" + std::to_string(k) + " is not declared in the header");
    if (blk == &b) break;
    p += block_bytes(a, *blk, g.dims);
  }
  const uint64_t avail = size > p ? size - p : 0;
  if (b.encoding.empty()) {
    volbytes::check_available(a.file, avail, need, "the lattice data");
    return volbytes::decode(g, b.dtype, a.big_endian,
                            [&](char* dst, uint64_t n) { volbytes::read_exact(path, p, dst, n, "lattice data"); });
  }
  const auto enc = static_cast<uint64_t>(b.encoded_size);
  volbytes::check_available(a.file, avail, enc, "the " + b.encoding + " lattice data");
  if (b.encoding == "HxZip") volbytes::check_compressed(a.file, enc, need, "the HxZip lattice data");
  else if (need / 128 > enc + 1) // one control byte codes at most 127 bytes
    throw InputError(a.file + ": the HxByteRLE lattice data claims " + std::to_string(need) + " bytes from only " +
                     std::to_string(enc) + " encoded bytes (truncated, or the lattice size is wrong)");
  std::string comp(static_cast<size_t>(enc), '\0');
  volbytes::read_exact(path, p, comp.data(), enc, "lattice data");
  return volbytes::decode(g, b.dtype, a.big_endian, [&](char* dst, uint64_t n) {
    if (b.encoding == "HxZip") volbytes::inflate_into(a.file, "HxZip lattice data", comp.data(), comp.size(), dst, n);
    else unrle(a.file, comp.data(), comp.size(), dst, n);
  });
}

void write_amira(const fs::path& path, const DataObject& volume, const VolumeWriteOptions& o) {
  const std::string shown = display_path(path).string();
  const Grid& g = volume_grid(volume, shown);
  const std::string dtype = volbytes::volume_dtype(volume);
  static const std::map<std::string, std::string> names{
      {"uint8", "byte"}, {"uint16", "ushort"}, {"int32", "int"}, {"float32", "float"}, {"float64", "double"}};
  auto it = names.find(dtype);
  if (it == names.end())
    throw InputError(shown + ": Amira lattices store byte, short, ushort, int, float and double voxels, not " + dtype +
                     " (convert the volume first, e.g. volume.convert to int32 or float64)");
  if (g.direction != kIdentityDirection)
    throw InputError(shown + ": an Amira lattice stores no direction and this volume is rotated (write NRRD, MetaImage, "
                     "NIfTI or VTK image data to keep it)");
  double bbox[6];
  for (size_t i = 0; i < 3; ++i) {
    bbox[2 * i] = g.origin[i];
    bbox[2 * i + 1] = g.origin[i] + g.spacing[i] * static_cast<double>(std::max<int64_t>(g.dims[i] - 1, 0));
  }
  const std::string raw = volbytes::encode(volume, false);
  const bool zip = o.compression > 0;
  const std::string data = zip ? volbytes::deflate(raw.data(), raw.size(), o.compression, false) : std::string();
  const std::string d = std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " + std::to_string(g.dims[2]);
  std::string s = "# AmiraMesh BINARY-LITTLE-ENDIAN 2.1\n\n\ndefine Lattice " + d + "\n\nParameters {\n";
  s += "    Units {\n        Coordinates \"" + g.unit + "\"\n    }\n";
  s += "    Content \"" + std::to_string(g.dims[0]) + "x" + std::to_string(g.dims[1]) + "x" + std::to_string(g.dims[2]) + " " +
       it->second + ", uniform coordinates\",\n";
  s += "    BoundingBox " + volbytes::join_numbers(bbox, 6) + ",\n    CoordType \"uniform\"\n}\n\n";
  s += "Lattice { " + it->second + " Data } @1";
  if (zip) s += "(HxZip," + std::to_string(data.size()) + ")";
  s += "\n\n# Data section follows\n@1\n";
  s += zip ? data : raw;
  s += "\n";
  write_file_atomically(path, s);
}

}  // namespace

VolumeFormat amira_volume_format() {
  VolumeFormat f;
  f.name = "Amira lattice";
  f.extensions = {".am"};
  f.sniff = [](std::string_view head) {
    return (head.substr(0, 11) == "# AmiraMesh" || head.substr(0, 7) == "# Avizo") &&
           head.find("define Lattice") != std::string_view::npos;
  };
  f.read_header = [](const fs::path& p, const VolumeReadOptions&) { return parse_header(p).header; };
  f.read = read_amira;
  f.write = write_amira;
  return f;
}

}  // namespace skel::io
