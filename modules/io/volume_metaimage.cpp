// MetaImage volumes (ITK/VTK MetaIO): `.mha` (header and data in one file, ElementDataFile = LOCAL)
// and `.mhd` (header; the data in the file ElementDataFile names, raw or zlib-compressed). Read:
// ElementType MET_CHAR..MET_DOUBLE, DimSize, ElementSpacing, Offset (or Origin / Position),
// TransformMatrix (or Rotation / Orientation), BinaryDataByteOrderMSB (or ElementByteOrderMSB),
// CompressedData (zlib), HeaderSize for detached data. MetaIO has no unit field: Skelflow writes and
// reads `ElementSpacingUnit = mm` (other MetaIO readers skip a field they do not know); without it
// the unit is the default (µm).
// TransformMatrix is stored as MetaIO stores it: its row k is the direction of voxel axis k (the
// transpose of the row-major direction cosines of Grid::direction).
// Write: `.mha` only, little endian, zlib-compressed when compression > 0.
#include <algorithm>
#include <cmath>
#include <cstring>
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
  std::string key;  // as written
  std::string value;
  int line = 0;
};

struct MetaHeader {
  std::string file;
  std::map<std::string, Field> fields;  // lower-case key
  VolumeHeader header;
  bool big_endian = false;
  bool compressed = false;
  int64_t compressed_size = -1;  // CompressedDataSize, -1 when absent
  int64_t header_size = 0;       // HeaderSize of detached data; -1: data at the end
  fs::path data_path;
  uint64_t data_offset = 0;      // LOCAL data: first byte after the ElementDataFile line
  bool local = false;

  [[nodiscard]] const Field* get(const std::string& k) const {
    auto it = fields.find(k);
    return it == fields.end() ? nullptr : &it->second;
  }
  [[nodiscard]] std::string at(const Field& f) const { return file + ":" + std::to_string(f.line); }
};

constexpr uint64_t kMaxHeader = 1 << 20;

std::string met_type(const std::string& t) {
  static const std::map<std::string, std::string> names{
      {"MET_CHAR", "int8"},       {"MET_UCHAR", "uint8"},      {"MET_SHORT", "int16"},
      {"MET_USHORT", "uint16"},   {"MET_INT", "int32"},        {"MET_UINT", "uint32"},
      {"MET_LONG", "int32"},      {"MET_ULONG", "uint32"},     {"MET_LONG_LONG", "int64"},
      {"MET_ULONG_LONG", "uint64"}, {"MET_FLOAT", "float32"},  {"MET_DOUBLE", "float64"}};
  auto it = names.find(t);
  return it == names.end() ? std::string() : it->second;
}

std::string met_name(const std::string& dtype) {
  static const std::map<std::string, std::string> names{
      {"uint8", "MET_UCHAR"}, {"uint16", "MET_USHORT"}, {"uint32", "MET_UINT"}, {"uint64", "MET_ULONG_LONG"},
      {"int32", "MET_INT"},   {"float32", "MET_FLOAT"}, {"float64", "MET_DOUBLE"}};
  return names.at(dtype);
}

std::vector<double> numbers(const MetaHeader& h, const Field& f, size_t count) {
  std::vector<double> out;
  std::string v = f.value;
  std::replace(v.begin(), v.end(), '\t', ' ');
  for (const auto& w : text::split(v, ' ')) {
    const std::string t = text::trim(w);
    if (t.empty()) continue;
    double v = 0;
    if (!text::parse_double(t, v) || !std::isfinite(v))
      throw InputError(h.at(f) + ": '" + f.key + "': expected numbers, got '" + t.substr(0, 30) + "'");
    out.push_back(v);
  }
  if (out.size() != count)
    throw InputError(h.at(f) + ": '" + f.key + "' has " + std::to_string(out.size()) + " values; expected " +
                     std::to_string(count));
  return out;
}

bool boolean(const MetaHeader& h, const Field& f) {
  const std::string v = text::to_lower(f.value);
  if (v == "true" || v == "1") return true;
  if (v == "false" || v == "0") return false;
  throw InputError(h.at(f) + ": '" + f.key + "' is '" + f.value + "' (True or False)");
}

MetaHeader parse_header(const fs::path& path) {
  MetaHeader h;
  h.file = path.string();
  const uint64_t size = volbytes::file_size(path);
  std::string head(static_cast<size_t>(std::min(size, kMaxHeader)), '\0');
  volbytes::read_exact(path, 0, head.data(), head.size(), "header");
  size_t pos = 0;
  int line = 0;
  bool ended = false;
  while (pos < head.size()) {
    size_t e = head.find('\n', pos);
    if (e == std::string::npos) e = head.size();
    ++line;
    std::string l = head.substr(pos, e - pos);
    pos = std::min(e + 1, head.size());
    if (!l.empty() && l.back() == '\r') l.pop_back();
    if (text::trim(l).empty()) continue;
    const size_t eq = l.find('=');
    if (eq == std::string::npos) {
      if (line == 1) throw InputError(h.file + ": not a MetaImage file (its first line is not 'Key = Value')");
      throw InputError(h.file + ":" + std::to_string(line) + ": expected 'Key = Value', got '" + l.substr(0, 60) + "'");
    }
    const std::string key = text::trim(l.substr(0, eq));
    std::string lk = text::to_lower(key);
    if (lk == "origin" || lk == "position") lk = "offset";
    if (lk == "rotation" || lk == "orientation") lk = "transformmatrix";
    if (lk == "elementbyteordermsb") lk = "binarydatabyteordermsb";
    if (h.fields.count(lk))
      throw InputError(h.file + ":" + std::to_string(line) + ": '" + key + "' appears twice");
    h.fields[lk] = Field{key, text::trim(l.substr(eq + 1)), line};
    if (lk == "elementdatafile") {
      ended = true;
      h.data_offset = pos;
      break;
    }
  }
  if (h.fields.empty() || (!h.get("ndims") && !h.get("dimsize")))
    throw InputError(h.file + ": not a MetaImage file (no NDims or DimSize)");
  if (!ended)
    throw InputError(h.file + ": the MetaImage header has no 'ElementDataFile' line (truncated, or longer than 1 MiB)");

  auto need = [&](const std::string& k, const char* shown) -> const Field& {
    const Field* f = h.get(k);
    if (!f) throw InputError(h.file + ": the MetaImage header has no '" + std::string(shown) + "'");
    return *f;
  };
  if (const Field* f = h.get("objecttype"); f && text::to_lower(f->value) != "image")
    throw InputError(h.at(*f) + ": ObjectType is '" + f->value + "'; Skelflow reads images");
  const Field& nf = need("ndims", "NDims");
  int64_t nd = 0;
  if (!text::parse_int(nf.value, nd) || nd < 1 || nd > 3)
    throw InputError(h.at(nf) + ": NDims is " + nf.value + "; Skelflow reads volumes of 1 to 3 axes");
  const auto n = static_cast<size_t>(nd);
  const Field& df = need("dimsize", "DimSize");
  Dims dims{1, 1, 1};
  {
    const auto d = numbers(h, df, n);
    for (size_t i = 0; i < n; ++i) {
      if (d[i] < 1 || d[i] != std::floor(d[i]) || d[i] > 9e15)
        throw InputError(h.at(df) + ": DimSize value " + text::format_double(d[i], 17) + " is not a positive integer");
      dims[i] = static_cast<int64_t>(d[i]);
    }
  }
  const Field& tf = need("elementtype", "ElementType");
  h.header.dtype = met_type(tf.value);
  if (h.header.dtype.empty())
    throw InputError(h.at(tf) + ": unsupported ElementType '" + tf.value + "' (MET_CHAR, MET_UCHAR, MET_SHORT, MET_USHORT, "
                     "MET_INT, MET_UINT, MET_LONG, MET_ULONG, MET_LONG_LONG, MET_ULONG_LONG, MET_FLOAT, MET_DOUBLE)");
  if (const Field* f = h.get("elementnumberofchannels"); f && text::trim(f->value) != "1")
    throw InputError(h.at(*f) + ": ElementNumberOfChannels is " + f->value + "; Skelflow reads one channel");
  if (const Field* f = h.get("binarydata"); f && !boolean(h, *f))
    throw InputError(h.at(*f) + ": ASCII MetaImage data (BinaryData = False) is not supported");
  if (const Field* f = h.get("binarydatabyteordermsb")) h.big_endian = boolean(h, *f);
  if (const Field* f = h.get("compresseddata")) h.compressed = boolean(h, *f);
  if (const Field* f = h.get("compresseddatasize"))
    if (!text::parse_int(f->value, h.compressed_size) || h.compressed_size < 0)
      throw InputError(h.at(*f) + ": CompressedDataSize is '" + f->value + "' (a byte count)");
  if (const Field* f = h.get("headersize"))
    if (!text::parse_int(f->value, h.header_size) || h.header_size < -1)
      throw InputError(h.at(*f) + ": HeaderSize is '" + f->value + "' (a byte count, or -1)");

  Grid& g = h.header.grid;
  g.dims = dims;
  if (const Field* f = h.get("elementspacing")) {
    const auto s = numbers(h, *f, n);
    for (size_t i = 0; i < n; ++i) {
      if (!(s[i] > 0)) throw InputError(h.at(*f) + ": ElementSpacing of axis " + std::to_string(i) + " is " +
                                        text::format_double(s[i], 17) + " (must be > 0)");
      g.spacing[i] = s[i];
    }
    h.header.has_spacing = true;
  } else if (const Field* f2 = h.get("elementsize")) {
    const auto s = numbers(h, *f2, n);
    for (size_t i = 0; i < n; ++i)
      if (s[i] > 0) g.spacing[i] = s[i];
    h.header.has_spacing = true;
  }
  if (const Field* f = h.get("offset")) {
    const auto o = numbers(h, *f, n);
    for (size_t i = 0; i < n; ++i) g.origin[i] = o[i];
    h.header.has_origin = true;
  }
  if (const Field* f = h.get("transformmatrix")) {
    const auto m = numbers(h, *f, n * n);
    Direction d = kIdentityDirection;
    for (size_t k = 0; k < n; ++k)      // voxel axis k = row k of the file's matrix
      for (size_t r = 0; r < n; ++r) d[r * 3 + k] = m[k * n + r];
    g.direction = d;
  }
  if (const Field* f = h.get("elementspacingunit")) {
    g.unit = volbytes::normalize_unit(f->value);
    if (g.unit.empty()) throw InputError(h.at(*f) + ": ElementSpacingUnit is empty");
    h.header.has_unit = true;
  }

  const Field& ef = *h.get("elementdatafile");
  const std::string ed = ef.value;
  if (ed == "LOCAL") {
    h.local = true;
    h.data_path = path;
  } else if (ed.rfind("LIST", 0) == 0 || ed.find('%') != std::string::npos) {
    throw InputError(h.at(ef) + ": ElementDataFile '" + ed.substr(0, 40) + "' lists several files; Skelflow reads one data file");
  } else {
    h.data_path = fs::path(ed).is_absolute() ? fs::path(ed) : path.parent_path() / ed;
  }
  h.header.details.push_back(std::string("data: ") + (h.compressed ? "zlib-compressed" : "raw") +
                             (volbytes::dtype_bytes(h.header.dtype) > 1 ? (h.big_endian ? ", big endian" : ", little endian") : "") +
                             (h.local ? "" : ", in " + h.data_path.string()));
  return h;
}

// The first voxel byte of uncompressed data, its size checked against the file's.
uint64_t raw_data_start(const MetaHeader& h) {
  const std::string data_file = h.data_path.string();
  const uint64_t need = volbytes::checked_bytes(h.file, h.header.grid.dims, volbytes::dtype_bytes(h.header.dtype));
  const uint64_t size = volbytes::file_size(h.data_path);
  uint64_t start = h.local ? h.data_offset : 0;
  if (!h.local && h.header_size > 0) start = static_cast<uint64_t>(h.header_size);
  if (!h.local && h.header_size == -1) {
    volbytes::check_available(data_file, size, need, "the voxel data");
    start = size - need;
  }
  volbytes::check_available(data_file, size > start ? size - start : 0, need, "the voxel data");
  return start;
}

DataPtr read_metaimage(const fs::path& path, const VolumeReadOptions&);

// A box of uncompressed data read in place; compressed data is inflated whole and cut.
DataPtr read_metaimage_box(const fs::path& path, const VolumeReadOptions& o, Dims begin, Dims size) {
  const MetaHeader h = parse_header(path);
  if (!h.compressed)
    return read_raw_voxel_box(h.data_path, raw_data_start(h), h.header.grid, h.header.dtype, h.big_endian, begin, size);
  return crop_volume_box(*read_metaimage(path, o), begin, size);
}

DataPtr read_metaimage(const fs::path& path, const VolumeReadOptions&) {
  const MetaHeader h = parse_header(path);
  const std::string data_file = h.data_path.string();
  const uint64_t need = volbytes::checked_bytes(h.file, h.header.grid.dims, volbytes::dtype_bytes(h.header.dtype));
  const uint64_t size = volbytes::file_size(h.data_path);
  uint64_t start = h.local ? h.data_offset : 0;
  if (!h.local && h.header_size > 0) start = static_cast<uint64_t>(h.header_size);
  if (!h.compressed) {
    start = raw_data_start(h);
    return volbytes::decode(h.header.grid, h.header.dtype, h.big_endian, [&](char* dst, uint64_t bytes) {
      volbytes::read_exact(h.data_path, start, dst, bytes, "voxel data");
    });
  }
  uint64_t avail = size > start ? size - start : 0;
  if (h.compressed_size >= 0) {
    volbytes::check_available(data_file, avail, static_cast<uint64_t>(h.compressed_size), "CompressedDataSize");
    avail = static_cast<uint64_t>(h.compressed_size);
  }
  volbytes::check_compressed(data_file, avail, need, "the compressed voxel data");
  std::string comp(static_cast<size_t>(avail), '\0');
  volbytes::read_exact(h.data_path, start, comp.data(), avail, "voxel data");
  return volbytes::decode(h.header.grid, h.header.dtype, h.big_endian, [&](char* dst, uint64_t bytes) {
    volbytes::inflate_into(data_file, "compressed voxel data", comp.data(), comp.size(), dst, bytes);
  });
}

void write_metaimage(const fs::path& path, const DataObject& volume, const VolumeWriteOptions& o) {
  const Grid& g = volume_grid(volume, display_path(path).string());
  const std::string dtype = volbytes::volume_dtype(volume);
  const std::string raw = volbytes::encode(volume, false);
  std::string data = o.compression > 0 ? volbytes::deflate(raw.data(), raw.size(), o.compression, false) : std::string();
  double tm[9];
  for (size_t k = 0; k < 3; ++k)
    for (size_t r = 0; r < 3; ++r) tm[k * 3 + r] = g.direction[r * 3 + k];
  std::string s = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n";
  s += std::string("CompressedData = ") + (o.compression > 0 ? "True" : "False") + "\n";
  if (o.compression > 0) s += "CompressedDataSize = " + std::to_string(data.size()) + "\n";
  s += "TransformMatrix = " + volbytes::join_numbers(tm, 9) + "\n";
  s += "Offset = " + volbytes::join_numbers(g.origin.data(), 3) + "\n";
  s += "CenterOfRotation = 0 0 0\n";
  s += "ElementSpacing = " + volbytes::join_numbers(g.spacing.data(), 3) + "\n";
  s += "ElementSpacingUnit = " + g.unit + "\n";
  s += "DimSize = " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " + std::to_string(g.dims[2]) + "\n";
  s += "ElementType = " + met_name(dtype) + "\n";
  s += "ElementDataFile = LOCAL\n";
  s += o.compression > 0 ? data : raw;
  write_file_atomically(path, s);
}

VolumeFormat make(bool local) {
  VolumeFormat f;
  f.name = local ? "MetaImage" : "MetaImage (detached header)";
  f.extensions = {local ? ".mha" : ".mhd"};
  f.sniff = [](std::string_view head) {
    const std::string h(head.substr(0, 64));
    return h.rfind("ObjectType = Image", 0) == 0 || h.rfind("NDims = ", 0) == 0;
  };
  f.read_header = [](const fs::path& p, const VolumeReadOptions&) { return parse_header(p).header; };
  f.read = read_metaimage;
  f.read_box = read_metaimage_box;
  f.boxes_are_cheap = [](const fs::path& p, const VolumeReadOptions&) { return !parse_header(p).compressed; };
  if (local) f.write = write_metaimage;
  return f;
}

}  // namespace

VolumeFormat metaimage_volume_format() { return make(true); }
VolumeFormat mhd_volume_format() { return make(false); }

}  // namespace skel::io
