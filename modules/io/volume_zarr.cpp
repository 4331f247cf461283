// Zarr v2 arrays and OME-Zarr (NGFF 0.1-0.4) images: a directory store (`.zarr`, `.ome.zarr`).
// Read: the array at the path itself (`.zarray`), the array VolumeReadOptions::dataset names, or
// the multiscale level VolumeReadOptions::level of the group's `.zattrs` (0 = full resolution);
// dtypes |u1 <u2 <u4 <u8 |i1 <i2 <i4 <i8 <f4 <f8 |b1 (either byte order), order "C", no filters,
// compressors null, blosc (any cname, shuffle), zlib, gzip, zstd; chunk keys with "." or "/";
// missing chunks read as fill_value. Arrays of more than 3 dimensions are read when the leading
// (t, c) dimensions have size 1; the last three are z, y, x. Spacing, origin and unit come from the
// multiscale's axes (unit of the spatial axes) and coordinateTransformations (scale, translation;
// the dataset's, then the multiscale's). read_box reads only the chunks the box touches.
// Write: an OME-Zarr 0.4 group with one level "0" (axes z, y, x with the unit, scale and translation),
// chunks of about 1 MiB (as HDF5's), "/" keys, blosc lz4 with byte shuffle at level = compression
// (null when 0), chunks that are all 0 not stored (they read as fill_value 0). The directory is
// written under a temporary name and renamed into place. Block-wise writing for out-of-core stages:
// create_zarr_volume / write_zarr_box (zarr_volume.hpp). A volume with a direction cannot be stored
// (OME-Zarr 0.4 has no rotation).
#include <blosc.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>

#include "io/hdf5_volume.hpp"
#include "io/volume_bytes.hpp"
#include "io/volume_format.hpp"
#include "io/zarr_volume.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/parallel.hpp"
#include "skel/text.hpp"

namespace skel::io {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

enum class Codec { none, blosc, zlib, zstd };

struct ZArray {
  std::string file;               // the array folder, for messages
  fs::path dir;
  std::vector<int64_t> shape, chunks;  // all dimensions, C order
  std::string dtype;              // Skelflow stored type
  bool big_endian = false;
  size_t itemsize = 1;
  Codec codec = Codec::none;
  std::string codec_name;         // for describe
  int clevel = 5;                 // compression level for writing (blosc clevel, zlib/gzip/zstd level)
  std::string cname = "lz4";      // blosc compressor name
  int shuffle = 1;                // blosc shuffle (0 none, 1 byte, 2 bit)
  std::string sep = ".";
  std::string fill_bytes;         // one voxel of fill_value, in the file's byte order
  VolumeHeader header;
  std::string array_path;         // relative to the store root ("" = the root)
  int levels = 0;                 // multiscale levels, 0 when none
  [[nodiscard]] int nd() const { return static_cast<int>(shape.size()); }
};

json read_json(const fs::path& p, const std::string& what) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw InputError(p.string() + ": cannot read " + what);
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  json j = json::parse(s, nullptr, false);
  if (j.is_discarded()) throw InputError(p.string() + ": not valid JSON");
  if (!j.is_object()) throw InputError(p.string() + ": " + what + " is not a JSON object");
  return j;
}

std::vector<int64_t> int_list(const json& j, const std::string& where, const char* key) {
  if (!j.contains(key) || !j[key].is_array()) throw InputError(where + ": '" + key + "' is missing or not a list");
  std::vector<int64_t> out;
  for (const auto& v : j[key]) {
    if (!v.is_number_integer() || v.get<int64_t>() < 0)
      throw InputError(where + ": '" + key + "' holds '" + v.dump().substr(0, 30) + "', not a non-negative integer");
    out.push_back(v.get<int64_t>());
  }
  return out;
}

std::vector<double> num_list(const json& j, const std::string& where, const char* key, size_t n) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != n)
    throw InputError(where + ": '" + key + "' must be a list of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (const auto& v : j[key]) {
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      throw InputError(where + ": '" + key + "' holds '" + v.dump().substr(0, 30) + "', not a finite number");
    out.push_back(v.get<double>());
  }
  return out;
}

std::string numpy_dtype(const std::string& d, bool& big_endian) {
  if (d.size() < 3 || (d[0] != '<' && d[0] != '>' && d[0] != '|')) return {};
  big_endian = d[0] == '>';
  const std::string k = d.substr(1);
  if (k == "u1" || k == "b1") return "uint8";
  if (k == "u2") return "uint16";
  if (k == "u4") return "uint32";
  if (k == "u8") return "uint64";
  if (k == "i1") return "int8";
  if (k == "i2") return "int16";
  if (k == "i4") return "int32";
  if (k == "i8") return "int64";
  if (k == "f4") return "float32";
  if (k == "f8") return "float64";
  return {};
}

std::string numpy_name(const std::string& dtype) {
  if (dtype == "uint8") return "|u1";
  if (dtype == "uint16") return "<u2";
  if (dtype == "uint32") return "<u4";
  if (dtype == "uint64") return "<u8";
  if (dtype == "int32") return "<i4";
  if (dtype == "float32") return "<f4";
  return "<f8";
}

// One voxel of `v` as stored bytes of `dtype` in the given byte order.
std::string fill_value_bytes(const std::string& dtype, double v, bool big_endian) {
  std::string b(volbytes::dtype_bytes(dtype), '\0');
  auto put = [&](auto x) { std::memcpy(b.data(), &x, sizeof x); };
  if (dtype == "uint8") put(static_cast<uint8_t>(v));
  else if (dtype == "int8") put(static_cast<int8_t>(v));
  else if (dtype == "uint16") put(static_cast<uint16_t>(v));
  else if (dtype == "int16") put(static_cast<int16_t>(v));
  else if (dtype == "uint32") put(static_cast<uint32_t>(v));
  else if (dtype == "int32") put(static_cast<int32_t>(v));
  else if (dtype == "uint64") put(static_cast<uint64_t>(v));
  else if (dtype == "int64") put(static_cast<int64_t>(v));
  else if (dtype == "float32") put(static_cast<float>(v));
  else put(v);
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b.begin(), b.end());
  return b;
}

void parse_zarray(ZArray& a, const fs::path& dir) {
  a.dir = dir;
  a.file = dir.string();
  const fs::path zp = dir / ".zarray";
  const json j = read_json(zp, ".zarray");
  const std::string where = zp.string();
  if (!j.contains("zarr_format") || j["zarr_format"] != 2)
    throw InputError(where + ": zarr_format is " + (j.contains("zarr_format") ? j["zarr_format"].dump() : "missing") +
                     "; Skelflow reads Zarr v2");
  a.shape = int_list(j, where, "shape");
  a.chunks = int_list(j, where, "chunks");
  if (a.shape.empty() || a.shape.size() > 5)
    throw InputError(where + ": an array of " + std::to_string(a.shape.size()) + " dimensions; Skelflow reads 1 to 5 (t, c, z, y, x)");
  if (a.chunks.size() != a.shape.size())
    throw InputError(where + ": 'chunks' has " + std::to_string(a.chunks.size()) + " values but 'shape' " +
                     std::to_string(a.shape.size()));
  for (size_t i = 0; i < a.chunks.size(); ++i)
    if (a.chunks[i] < 1) throw InputError(where + ": chunk size " + std::to_string(a.chunks[i]) + " of dimension " + std::to_string(i) + " is not positive");
  if (!j.contains("dtype") || !j["dtype"].is_string()) throw InputError(where + ": 'dtype' is missing or not a string");
  a.dtype = numpy_dtype(j["dtype"].get<std::string>(), a.big_endian);
  if (a.dtype.empty())
    throw InputError(where + ": unsupported dtype '" + j["dtype"].get<std::string>() +
                     "' (|u1 <u2 <u4 <u8 |i1 <i2 <i4 <i8 <f4 <f8 |b1, either byte order)");
  a.itemsize = volbytes::dtype_bytes(a.dtype);
  if (j.contains("order") && j["order"] != "C")
    throw InputError(where + ": order " + j["order"].dump() + "; Skelflow reads C-order arrays");
  if (j.contains("filters") && !j["filters"].is_null() && !(j["filters"].is_array() && j["filters"].empty()))
    throw InputError(where + ": filters " + j["filters"].dump().substr(0, 60) + " are not supported");
  if (j.contains("dimension_separator")) {
    if (j["dimension_separator"] != "." && j["dimension_separator"] != "/")
      throw InputError(where + ": dimension_separator " + j["dimension_separator"].dump() + " (\".\" or \"/\")");
    a.sep = j["dimension_separator"].get<std::string>();
  }
  const json c = j.contains("compressor") ? j["compressor"] : json();
  if (c.is_null()) {
    a.codec = Codec::none;
    a.codec_name = "none";
  } else {
    const std::string id = c.is_object() && c.contains("id") && c["id"].is_string() ? c["id"].get<std::string>() : "";
    if (id == "blosc") a.codec = Codec::blosc;
    else if (id == "zlib" || id == "gzip") a.codec = Codec::zlib;
    else if (id == "zstd") a.codec = Codec::zstd;
    else
      throw InputError(where + ": unsupported compressor " + (id.empty() ? c.dump().substr(0, 60) : "'" + id + "'") +
                       " (blosc, zlib, gzip, zstd or null)");
    a.codec_name = id;
    if (c.contains("cname") && c["cname"].is_string()) a.cname = c["cname"].get<std::string>(), a.codec_name += " " + a.cname;
    if (c.contains("clevel") && c["clevel"].is_number_integer()) a.clevel = c["clevel"].get<int>();
    if (c.contains("level") && c["level"].is_number_integer()) a.clevel = c["level"].get<int>();
    if (c.contains("shuffle") && c["shuffle"].is_number_integer()) a.shuffle = c["shuffle"].get<int>();
  }
  double fill = 0;
  if (j.contains("fill_value") && !j["fill_value"].is_null()) {
    const json& f = j["fill_value"];
    if (f.is_number()) fill = f.get<double>();
    else if (f.is_boolean()) fill = f.get<bool>() ? 1 : 0;
    else if (f == "NaN") fill = std::numeric_limits<double>::quiet_NaN();
    else if (f == "Infinity") fill = std::numeric_limits<double>::infinity();
    else if (f == "-Infinity") fill = -std::numeric_limits<double>::infinity();
    else throw InputError(where + ": fill_value " + f.dump().substr(0, 30) + " is not a number");
  }
  a.fill_bytes = fill_value_bytes(a.dtype, fill, a.big_endian);
  // Spatial dims: the last three (x fastest); leading ones must be 1.
  const int nd = a.nd();
  for (int i = 0; i + 3 < nd; ++i)
    if (a.shape[static_cast<size_t>(i)] != 1)
      throw InputError(where + ": dimension " + std::to_string(i) + " of shape " + j["shape"].dump() +
                       " is not 1: a series of volumes or channels; Skelflow reads one 3D volume");
  Dims dims{1, 1, 1};
  for (int k = 0; k < 3 && k < nd; ++k) dims[static_cast<size_t>(k)] = a.shape[static_cast<size_t>(nd - 1 - k)];
  a.header.grid.dims = dims;
  volbytes::checked_bytes(a.file, dims, a.itemsize);
  uint64_t chunk_bytes = a.itemsize;
  for (auto c2 : a.chunks) {
    if (chunk_bytes > (uint64_t{1} << 31) / static_cast<uint64_t>(c2))
      throw InputError(where + ": chunks " + j["chunks"].dump() + " are larger than 2 GiB");
    chunk_bytes *= static_cast<uint64_t>(c2);
  }
  a.header.dtype = a.dtype;
}

// Spacing, origin and unit of the multiscale dataset `path` (x, y, z from the last three axes).
void apply_multiscale(ZArray& a, const json& ms, const std::string& where, const std::string& path) {
  const int nd = a.nd();
  Grid& g = a.header.grid;
  // Axes: v0.4 objects {name, type, unit}; v0.3 strings.
  if (ms.contains("axes") && ms["axes"].is_array()) {
    const json& axes = ms["axes"];
    if (static_cast<int>(axes.size()) != nd)
      throw InputError(where + ": the multiscale has " + std::to_string(axes.size()) + " axes but the array " + std::to_string(nd) +
                       " dimensions");
    std::string unit;
    for (int k = std::max(0, nd - 3); k < nd; ++k) {
      const json& ax = axes[static_cast<size_t>(k)];
      if (!ax.is_object() || !ax.contains("unit") || !ax["unit"].is_string()) continue;
      const std::string u = volbytes::normalize_unit(ax["unit"].get<std::string>());
      if (!unit.empty() && u != unit)
        throw InputError(where + ": the spatial axes have different units ('" + unit + "', '" + u + "'); Skelflow needs one unit");
      unit = u;
    }
    if (!unit.empty()) g.unit = unit, a.header.has_unit = true;
  }
  std::vector<double> scale(static_cast<size_t>(nd), 1.0), trans(static_cast<size_t>(nd), 0.0);
  bool has_scale = false, has_trans = false;
  auto apply = [&](const json& transforms) {
    if (!transforms.is_array()) return;
    std::vector<double> s(static_cast<size_t>(nd), 1.0), t(static_cast<size_t>(nd), 0.0);
    for (const auto& tr : transforms) {
      if (!tr.is_object() || !tr.contains("type")) continue;
      if (tr["type"] == "scale") {
        s = num_list(tr, where, "scale", static_cast<size_t>(nd));
        has_scale = true;
      } else if (tr["type"] == "translation") {
        t = num_list(tr, where, "translation", static_cast<size_t>(nd));
        has_trans = true;
      } else if (tr["type"] != "identity") {
        throw InputError(where + ": coordinate transformation " + tr["type"].dump() + " is not supported (scale, translation)");
      }
    }
    for (size_t i = 0; i < static_cast<size_t>(nd); ++i) {
      scale[i] *= s[i];
      trans[i] = trans[i] * s[i] + t[i];
    }
  };
  for (const auto& ds : ms["datasets"])
    if (ds.is_object() && ds.contains("path") && ds["path"] == path && ds.contains("coordinateTransformations"))
      apply(ds["coordinateTransformations"]);
  if (ms.contains("coordinateTransformations")) apply(ms["coordinateTransformations"]);
  for (int k = 0; k < 3 && k < nd; ++k) {
    const auto i = static_cast<size_t>(nd - 1 - k);
    if (!(scale[i] > 0)) throw InputError(where + ": the scale of axis " + std::to_string(i) + " is not positive");
    g.spacing[static_cast<size_t>(k)] = scale[i];
    g.origin[static_cast<size_t>(k)] = trans[i];
  }
  a.header.has_spacing = has_scale;
  a.header.has_origin = has_trans;
}

ZArray open_array(const fs::path& root, const VolumeReadOptions& o) {
  ZArray a;
  if (!fs::is_directory(root)) throw InputError(root.string() + ": not a Zarr folder (no such directory)");
  json ms;  // the multiscale, when the root is an OME-Zarr group
  std::string ms_where;
  if (fs::exists(root / ".zattrs")) {
    const json attrs = read_json(root / ".zattrs", ".zattrs");
    if (attrs.contains("multiscales") && attrs["multiscales"].is_array() && !attrs["multiscales"].empty()) {
      ms = attrs["multiscales"][0];
      ms_where = (root / ".zattrs").string();
      if (!ms.is_object() || !ms.contains("datasets") || !ms["datasets"].is_array() || ms["datasets"].empty())
        throw InputError(ms_where + ": the multiscale has no datasets");
    }
  }
  std::string path = o.dataset;
  while (!path.empty() && path.front() == '/') path.erase(0, 1);
  if (path.empty() && !fs::exists(root / ".zarray")) {
    if (ms.is_null())
      throw InputError(root.string() + ": not a Zarr array or OME-Zarr image (no .zarray, and no multiscales in .zattrs)");
    const auto& ds = ms["datasets"];
    if (o.level < 0 || o.level >= static_cast<int>(ds.size()))
      throw InputError(root.string() + ": level " + std::to_string(o.level) + " does not exist (the image has " +
                       std::to_string(ds.size()) + " levels, 0 to " + std::to_string(ds.size() - 1) + ")");
    const json& d = ds[static_cast<size_t>(o.level)];
    if (!d.is_object() || !d.contains("path") || !d["path"].is_string())
      throw InputError(ms_where + ": dataset " + std::to_string(o.level) + " has no path");
    path = d["path"].get<std::string>();
  }
  const fs::path dir = path.empty() ? root : root / path;
  if (!fs::exists(dir / ".zarray"))
    throw InputError(dir.string() + ": not a Zarr array (no .zarray)" + (o.dataset.empty() ? "" : " (dataset '" + o.dataset + "')"));
  parse_zarray(a, dir);
  a.array_path = path;
  if (!ms.is_null()) {
    a.levels = static_cast<int>(ms["datasets"].size());
    apply_multiscale(a, ms, ms_where, path);
  }
  a.header.details.push_back("array: " + (path.empty() ? std::string("(root)") : path) +
                             (a.levels ? " (level " + std::to_string(o.level) + " of " + std::to_string(a.levels) + ")" : ""));
  std::string ch;
  for (int k = 0; k < 3 && k < a.nd(); ++k) ch += (k ? "x" : "") + std::to_string(a.chunks[static_cast<size_t>(a.nd() - 1 - k)]);
  a.header.details.push_back("chunks: " + ch + " (x,y,z), compressor: " + a.codec_name);
  return a;
}

// The stored bytes of one chunk (all its voxels, full chunk size), or false when the chunk file is
// missing (fill_value).
bool load_chunk(const ZArray& a, const std::vector<int64_t>& idx, std::string& out, uint64_t chunk_bytes) {
  std::string key;
  for (size_t i = 0; i < idx.size(); ++i) key += (i ? a.sep : "") + std::to_string(idx[i]);
  const fs::path p = a.dir / key;
  std::ifstream in(p, std::ios::binary);
  if (!in) return false;
  const std::string comp((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string file = p.string();
  out.resize(static_cast<size_t>(chunk_bytes));
  switch (a.codec) {
    case Codec::none:
      if (comp.size() != chunk_bytes)
        throw InputError(file + ": chunk holds " + std::to_string(comp.size()) + " bytes; the chunk shape needs " +
                         std::to_string(chunk_bytes) + " (truncated?)");
      out = comp;
      return true;
    case Codec::zlib:
      volbytes::check_compressed(file, comp.size(), chunk_bytes, "the chunk");
      volbytes::inflate_into(file, "chunk", comp.data(), comp.size(), out.data(), chunk_bytes);
      return true;
    case Codec::blosc: {
      size_t nbytes = 0;
      if (comp.size() < 16 || blosc_cbuffer_validate(comp.data(), comp.size(), &nbytes) < 0)
        throw InputError(file + ": corrupt blosc chunk (bad header; truncated?)");
      if (nbytes != chunk_bytes)
        throw InputError(file + ": blosc chunk holds " + std::to_string(nbytes) + " bytes; the chunk shape needs " +
                         std::to_string(chunk_bytes));
      const int n = blosc_decompress_ctx(comp.data(), out.data(), out.size(), 1);
      if (n < 0 || static_cast<uint64_t>(n) != chunk_bytes) throw InputError(file + ": corrupt blosc chunk");
      return true;
    }
    case Codec::zstd: {
      const unsigned long long fs_ = ZSTD_getFrameContentSize(comp.data(), comp.size());
      if (fs_ == ZSTD_CONTENTSIZE_ERROR) throw InputError(file + ": corrupt zstd chunk (not a zstd frame)");
      if (fs_ != ZSTD_CONTENTSIZE_UNKNOWN && fs_ != chunk_bytes)
        throw InputError(file + ": zstd chunk holds " + std::to_string(fs_) + " bytes; the chunk shape needs " + std::to_string(chunk_bytes));
      const size_t n = ZSTD_decompress(out.data(), out.size(), comp.data(), comp.size());
      if (ZSTD_isError(n)) throw InputError(file + ": corrupt zstd chunk (" + ZSTD_getErrorName(n) + ")");
      if (n != chunk_bytes)
        throw InputError(file + ": zstd chunk holds " + std::to_string(n) + " bytes; the chunk shape needs " + std::to_string(chunk_bytes));
      return true;
    }
  }
  return false;
}

// Fills dst (stored bytes of the box [begin, begin + size), x fastest) from the chunks it touches.
void assemble(const ZArray& a, Dims begin, Dims size, char* dst, int threads) {
  const int nd = a.nd();
  const size_t w = a.itemsize;
  // Chunk extents in x, y, z (the last three dims); leading dims: chunk 0.
  auto cdim = [&](int k) { return k < nd ? a.chunks[static_cast<size_t>(nd - 1 - k)] : int64_t{1}; };
  const int64_t cx = cdim(0), cy = cdim(1), cz = cdim(2);
  uint64_t chunk_bytes = w;
  for (auto c : a.chunks) chunk_bytes *= static_cast<uint64_t>(c);
  const int64_t x0 = begin[0] / cx, x1 = (begin[0] + size[0] - 1) / cx;
  const int64_t y0 = begin[1] / cy, y1 = (begin[1] + size[1] - 1) / cy;
  const int64_t z0 = begin[2] / cz, z1 = (begin[2] + size[2] - 1) / cz;
  if (size[0] <= 0 || size[1] <= 0 || size[2] <= 0) return;
  const int64_t nx = x1 - x0 + 1, ny = y1 - y0 + 1, nz = z1 - z0 + 1;
  parallel_for(0, nx * ny * nz, threads, [&](int64_t lo, int64_t hi) {
    std::string buf;
    for (int64_t c = lo; c < hi; ++c) {
      const int64_t ix = x0 + c % nx, iy = y0 + (c / nx) % ny, iz = z0 + c / (nx * ny);
      std::vector<int64_t> idx(static_cast<size_t>(nd), 0);
      if (nd >= 1) idx[static_cast<size_t>(nd - 1)] = ix;
      if (nd >= 2) idx[static_cast<size_t>(nd - 2)] = iy;
      if (nd >= 3) idx[static_cast<size_t>(nd - 3)] = iz;
      const bool present = load_chunk(a, idx, buf, chunk_bytes);
      // The part of this chunk inside the box.
      const int64_t bx = std::max(begin[0], ix * cx), ex = std::min(begin[0] + size[0], (ix + 1) * cx);
      const int64_t by = std::max(begin[1], iy * cy), ey = std::min(begin[1] + size[1], (iy + 1) * cy);
      const int64_t bz = std::max(begin[2], iz * cz), ez = std::min(begin[2] + size[2], (iz + 1) * cz);
      const auto row = static_cast<size_t>(ex - bx) * w;
      for (int64_t z = bz; z < ez; ++z)
        for (int64_t y = by; y < ey; ++y) {
          char* d = dst + ((bx - begin[0]) + size[0] * ((y - begin[1]) + size[1] * (z - begin[2]))) * static_cast<int64_t>(w);
          if (present) {
            const char* s = buf.data() + ((bx - ix * cx) + cx * ((y - iy * cy) + cy * (z - iz * cz))) * static_cast<int64_t>(w);
            std::memcpy(d, s, row);
          } else {
            for (size_t i = 0; i < row; i += w) std::memcpy(d + i, a.fill_bytes.data(), w);
          }
        }
    }
  });
}

void check_memory(const std::string& file, uint64_t bytes) {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages > 0 && page > 0 && bytes > static_cast<uint64_t>(pages) * static_cast<uint64_t>(page))
    throw InputError(file + ": the array holds " + std::to_string(bytes) + " bytes, more than this machine's memory (" +
                     std::to_string(static_cast<uint64_t>(pages) * static_cast<uint64_t>(page)) +
                     " bytes); read it by boxes (block-wise stages) or choose a smaller level");
}

DataPtr read_zarr(const fs::path& path, const VolumeReadOptions& o) {
  const ZArray a = open_array(path, o);
  const Grid& g = a.header.grid;
  check_memory(a.file, volbytes::checked_bytes(a.file, g.dims, a.itemsize));
  return volbytes::decode(g, a.dtype, a.big_endian,
                          [&](char* dst, uint64_t) { assemble(a, Dims{0, 0, 0}, g.dims, dst, o.threads); });
}

DataPtr read_zarr_box(const fs::path& path, const VolumeReadOptions& o, Dims begin, Dims size) {
  const ZArray a = open_array(path, o);
  const Grid& g = a.header.grid;
  for (size_t i = 0; i < 3; ++i)
    if (begin[i] < 0 || size[i] < 0 || begin[i] + size[i] > g.dims[i])
      throw InputError(a.file + ": box " + std::to_string(begin[0]) + "," + std::to_string(begin[1]) + "," + std::to_string(begin[2]) +
                       " + " + std::to_string(size[0]) + "x" + std::to_string(size[1]) + "x" + std::to_string(size[2]) +
                       " is outside the array (" + std::to_string(g.dims[0]) + "x" + std::to_string(g.dims[1]) + "x" +
                       std::to_string(g.dims[2]) + ")");
  Grid box = g;
  box.dims = size;
  for (size_t i = 0; i < 3; ++i) box.origin[i] = g.origin[i] + static_cast<double>(begin[i]) * g.spacing[i];
  check_memory(a.file, volbytes::checked_bytes(a.file, size, a.itemsize));
  return volbytes::decode(box, a.dtype, a.big_endian, [&](char* dst, uint64_t) { assemble(a, begin, size, dst, o.threads); });
}

// OME-NGFF unit names.
std::string ome_unit(const std::string& u) {
  if (u == kDefaultUnit) return "micrometer";
  if (u == "mm") return "millimeter";
  if (u == "nm") return "nanometer";
  if (u == "m") return "meter";
  if (u == "cm") return "centimeter";
  return u;
}

void write_file(const fs::path& p, const char* data, size_t n, const std::string& shown) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(data, static_cast<std::streamsize>(n));
  out.close();
  if (!out) throw Error("cannot write " + shown + ": " + std::strerror(errno ? errno : EIO) + " (" + p.filename().string() + ")");
}

// Writes a directory through `write(dir)` under a temporary sibling name, then renames it into
// place (replacing an old one); the engine's temporaries are written directly.
void write_dir_atomically(const fs::path& final_path, const std::function<void(const fs::path&)>& write) {
  TempName t;
  std::error_code ec;
  if (parse_temp_name(final_path, t) && !t.backup) {
    fs::remove_all(final_path, ec);
    fs::create_directories(final_path);
    write(final_path);
    return;
  }
  if (final_path.has_parent_path()) fs::create_directories(final_path.parent_path(), ec);
  const fs::path tmp = temp_sibling(final_path);
  try {
    fs::remove_all(tmp, ec);
    fs::create_directories(tmp);
    write(tmp);
    if (fs::exists(final_path)) {
      const fs::path old = backup_sibling(final_path, make_run_id());
      fs::rename(final_path, old);
      fs::rename(tmp, final_path);
      fs::remove_all(old, ec);
    } else {
      fs::rename(tmp, final_path);
    }
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(tmp, ec);
    throw Error("cannot write " + final_path.string() + ": " + e.code().message());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

// The stored bytes of one chunk, compressed with the array's codec.
std::string compress_chunk(const ZArray& a, const char* data, size_t n) {
  switch (a.codec) {
    case Codec::none: return std::string(data, n);
    case Codec::zlib: return volbytes::deflate(data, n, std::clamp(a.clevel, 1, 9), a.codec_name == "gzip");
    case Codec::zstd: {
      std::string out(ZSTD_compressBound(n), '\0');
      const size_t r = ZSTD_compress(out.data(), out.size(), data, n, a.clevel);
      if (ZSTD_isError(r)) throw Error(std::string("zstd: compression failed: ") + ZSTD_getErrorName(r));
      out.resize(r);
      return out;
    }
    case Codec::blosc: {
      std::string out(n + BLOSC_MAX_OVERHEAD, '\0');
      const int r = blosc_compress_ctx(std::clamp(a.clevel, 0, 9), a.shuffle, a.itemsize, n, data, out.data(), out.size(),
                                       a.cname.c_str(), 0, 1);
      if (r <= 0) throw Error("blosc: compression with '" + a.cname + "' failed");
      out.resize(static_cast<size_t>(r));
      return out;
    }
  }
  return {};
}

std::string chunk_key(const ZArray& a, int64_t ix, int64_t iy, int64_t iz) {
  const int nd = a.nd();
  std::vector<int64_t> idx(static_cast<size_t>(nd), 0);
  if (nd >= 1) idx[static_cast<size_t>(nd - 1)] = ix;
  if (nd >= 2) idx[static_cast<size_t>(nd - 2)] = iy;
  if (nd >= 3) idx[static_cast<size_t>(nd - 3)] = iz;
  std::string key;
  for (size_t i = 0; i < idx.size(); ++i) key += (i ? a.sep : "") + std::to_string(idx[i]);
  return key;
}

// Writes the stored bytes of a block (x fastest, native little endian) whose voxel (0,0,0) is array
// voxel `begin`: every chunk it touches is (re)written, partly covered ones read first; chunks that
// end up all fill_value are removed.
void write_chunks(const ZArray& a, const char* block, Dims bdims, Dims begin, int threads, const std::string& shown) {
  const int nd = a.nd();
  const size_t w = a.itemsize;
  auto cdim = [&](int k) { return k < nd ? a.chunks[static_cast<size_t>(nd - 1 - k)] : int64_t{1}; };
  const int64_t cx = cdim(0), cy = cdim(1), cz = cdim(2);
  const Dims& dims = a.header.grid.dims;
  uint64_t chunk_bytes = w;
  for (auto c : a.chunks) chunk_bytes *= static_cast<uint64_t>(c);
  if (bdims[0] <= 0 || bdims[1] <= 0 || bdims[2] <= 0) return;
  const int64_t x0 = begin[0] / cx, x1 = (begin[0] + bdims[0] - 1) / cx;
  const int64_t y0 = begin[1] / cy, y1 = (begin[1] + bdims[1] - 1) / cy;
  const int64_t z0 = begin[2] / cz, z1 = (begin[2] + bdims[2] - 1) / cz;
  const int64_t nx = x1 - x0 + 1, ny = y1 - y0 + 1, nz = z1 - z0 + 1;
  std::mutex dir_mutex;
  parallel_for(0, nx * ny * nz, threads, [&](int64_t lo, int64_t hi) {
    std::string buf;
    for (int64_t c = lo; c < hi; ++c) {
      const int64_t ix = x0 + c % nx, iy = y0 + (c / nx) % ny, iz = z0 + c / (nx * ny);
      // The part of the chunk inside the array, and inside the block.
      const int64_t ax1 = std::min(dims[0], (ix + 1) * cx), ay1 = std::min(dims[1], (iy + 1) * cy),
                    az1 = std::min(dims[2], (iz + 1) * cz);
      const int64_t bx = std::max(begin[0], ix * cx), ex = std::min(begin[0] + bdims[0], ax1);
      const int64_t by = std::max(begin[1], iy * cy), ey = std::min(begin[1] + bdims[1], ay1);
      const int64_t bz = std::max(begin[2], iz * cz), ez = std::min(begin[2] + bdims[2], az1);
      const bool whole = bx == ix * cx && ex == ax1 && by == iy * cy && ey == ay1 && bz == iz * cz && ez == az1;
      std::vector<int64_t> idx(static_cast<size_t>(nd), 0);
      if (nd >= 1) idx[static_cast<size_t>(nd - 1)] = ix;
      if (nd >= 2) idx[static_cast<size_t>(nd - 2)] = iy;
      if (nd >= 3) idx[static_cast<size_t>(nd - 3)] = iz;
      if (whole || !load_chunk(a, idx, buf, chunk_bytes)) {
        buf.resize(static_cast<size_t>(chunk_bytes));
        for (size_t i = 0; i < buf.size(); i += w) std::memcpy(buf.data() + i, a.fill_bytes.data(), w);
      }
      const auto row = static_cast<size_t>(ex - bx) * w;
      for (int64_t z = bz; z < ez; ++z)
        for (int64_t y = by; y < ey; ++y) {
          const char* src = block + ((bx - begin[0]) + bdims[0] * ((y - begin[1]) + bdims[1] * (z - begin[2]))) * static_cast<int64_t>(w);
          char* dst = buf.data() + ((bx - ix * cx) + cx * ((y - iy * cy) + cy * (z - iz * cz))) * static_cast<int64_t>(w);
          std::memcpy(dst, src, row);
        }
      const fs::path file = a.dir / chunk_key(a, ix, iy, iz);
      bool all_fill = true;
      for (size_t i = 0; i < buf.size() && all_fill; i += w) all_fill = std::memcmp(buf.data() + i, a.fill_bytes.data(), w) == 0;
      if (all_fill) {  // not stored: reads as fill_value
        std::error_code ec;
        fs::remove(file, ec);
        continue;
      }
      const std::string out = compress_chunk(a, buf.data(), buf.size());
      if (file.parent_path() != a.dir) {
        std::lock_guard<std::mutex> lock(dir_mutex);
        fs::create_directories(file.parent_path());
      }
      write_file(file, out.data(), out.size(), shown);
    }
  });
}

// .zgroup, .zattrs (OME-Zarr 0.4 multiscales, one level) and the array's .zarray in `dir`.
void write_metadata(const fs::path& dir, const std::string& dtype, const Grid& g, std::array<int64_t, 3> c, int level,
                    const std::string& array_path, const std::string& shown) {
  if (g.direction != kIdentityDirection)
    throw InputError(shown + ": OME-Zarr 0.4 stores no rotation and this volume has a direction (write NRRD, MetaImage, "
                     "NIfTI or VTK image data to keep it)");
  const size_t w = volbytes::dtype_bytes(dtype);
  json zarray = {{"zarr_format", 2},
                 {"shape", {g.dims[2], g.dims[1], g.dims[0]}},
                 {"chunks", {c[2], c[1], c[0]}},
                 {"dtype", numpy_name(dtype)},
                 {"fill_value", 0},
                 {"order", "C"},
                 {"filters", nullptr},
                 {"dimension_separator", "/"}};
  if (level > 0)
    zarray["compressor"] = {{"id", "blosc"}, {"cname", "lz4"}, {"clevel", level}, {"shuffle", w > 1 ? 1 : 0}, {"blocksize", 0}};
  else
    zarray["compressor"] = nullptr;
  json axes = json::array();
  for (const char* n : {"z", "y", "x"}) axes.push_back({{"name", n}, {"type", "space"}, {"unit", ome_unit(g.unit)}});
  json attrs = {{"multiscales",
                 {{{"version", "0.4"},
                   {"name", fs::path(shown).stem().string()},
                   {"axes", axes},
                   {"datasets",
                    {{{"path", array_path},
                      {"coordinateTransformations",
                       {{{"type", "scale"}, {"scale", {g.spacing[2], g.spacing[1], g.spacing[0]}}},
                        {{"type", "translation"}, {"translation", {g.origin[2], g.origin[1], g.origin[0]}}}}}}}}}}}};
  fs::create_directories(dir / array_path);
  const std::string zgroup = "{\n    \"zarr_format\": 2\n}\n";
  write_file(dir / ".zgroup", zgroup.data(), zgroup.size(), shown);
  const std::string za = attrs.dump(4) + "\n";
  write_file(dir / ".zattrs", za.data(), za.size(), shown);
  const std::string zr = zarray.dump(4) + "\n";
  write_file(dir / array_path / ".zarray", zr.data(), zr.size(), shown);
}

std::string array_path_of(const VolumeWriteOptions& o) {
  std::string p = o.dataset.empty() ? "0" : o.dataset;
  while (!p.empty() && p.front() == '/') p.erase(0, 1);
  return p.empty() ? "0" : p;
}

void write_zarr(const fs::path& path, const DataObject& volume, const VolumeWriteOptions& o) {
  const std::string shown = display_path(path).string();
  const Grid& g = volume_grid(volume, shown);
  const std::string dtype = volbytes::volume_dtype(volume);
  if (g.direction != kIdentityDirection) write_metadata(path, dtype, g, {1, 1, 1}, 0, "0", shown);  // throws, writes nothing
  if (std::endian::native == std::endian::big) throw Error("Zarr writer: big-endian hosts are not supported");
  const auto c = automatic_chunks(g.dims, static_cast<int64_t>(volbytes::dtype_bytes(dtype)));  // (x, y, z)
  const std::string array_path = array_path_of(o);
  write_dir_atomically(path, [&](const fs::path& dir) {
    write_metadata(dir, dtype, g, c, std::clamp(o.compression, 0, 9), array_path, shown);
    VolumeReadOptions ro;
    ro.dataset = array_path;
    const ZArray a = open_array(dir, ro);
    visit_volume(volume, shown, [&](const auto& v) {
      write_chunks(a, reinterpret_cast<const char*>(v.data()), g.dims, Dims{0, 0, 0}, o.threads, shown);
    });
  });
}

// write_zarr of a volume given box by box: bands of whole x-rows of chunks (as many chunk rows as
// the source's max_box_bytes holds), each chunk written once, whole.
void write_zarr_boxes(const fs::path& path, const VolumeBoxSource& source, const VolumeWriteOptions& o) {
  const std::string shown = display_path(path).string();
  const Grid& g = source.grid;
  const std::string dtype = visit_voxel_type(source.type_id, shown, [](auto t) { return std::string(VoxelTraits<decltype(t)>::name); });
  if (g.direction != kIdentityDirection) write_metadata(path, dtype, g, {1, 1, 1}, 0, "0", shown);  // throws, writes nothing
  if (std::endian::native == std::endian::big) throw Error("Zarr writer: big-endian hosts are not supported");
  const size_t w = volbytes::dtype_bytes(dtype);
  const auto c = automatic_chunks(g.dims, static_cast<int64_t>(w));  // (x, y, z)
  const std::string array_path = array_path_of(o);
  write_dir_atomically(path, [&](const fs::path& dir) {
    write_metadata(dir, dtype, g, c, std::clamp(o.compression, 0, 9), array_path, shown);
    VolumeReadOptions ro;
    ro.dataset = array_path;
    const ZArray a = open_array(dir, ro);
    const Dims& n = g.dims;
    const int64_t rows = units_per_box(source, static_cast<uint64_t>(n[0] * c[1] * c[2]) * w, (n[1] + c[1] - 1) / c[1]);
    for (int64_t z0 = 0; z0 < n[2]; z0 += c[2])
      for (int64_t y0 = 0; y0 < n[1]; y0 += rows * c[1]) {
        const Dims begin{0, y0, z0}, size{n[0], std::min(rows * c[1], n[1] - y0), std::min(c[2], n[2] - z0)};
        const DataPtr box = source.read(begin, size);
        visit_volume(*box, shown, [&](const auto& v) {
          if (v.dims() != size || volbytes::volume_dtype(v) != dtype) throw Error(shown + ": the volume's box reader gave a wrong box");
          write_chunks(a, reinterpret_cast<const char*>(v.data()), size, begin, o.threads, shown);
        });
      }
  });
}

}  // namespace

VolumeFormat zarr_volume_format() {
  VolumeFormat f;
  f.name = "Zarr / OME-Zarr";
  f.extensions = {".zarr", ".ome.zarr"};
  f.read_header = [](const fs::path& p, const VolumeReadOptions& o) { return open_array(p, o).header; };
  f.read = read_zarr;
  f.read_box = read_zarr_box;
  f.write = write_zarr;
  f.write_boxes = write_zarr_boxes;
  return f;
}

void create_zarr_volume(const std::filesystem::path& dir, const std::string& dtype, const Grid& grid,
                        const VolumeWriteOptions& options, std::array<int64_t, 3> chunks) {
  const std::string shown = display_path(dir).string();
  if (volbytes::dtype_bytes(dtype) == 0 || dtype == "int8" || dtype == "int16" || dtype == "int64")
    throw InputError(shown + ": cannot create a Zarr array of voxel type '" + dtype +
                     "' (uint8, uint16, uint32, uint64, int32, float32, float64)");
  grid.validate();
  const auto automatic = automatic_chunks(grid.dims, static_cast<int64_t>(volbytes::dtype_bytes(dtype)));
  for (size_t i = 0; i < 3; ++i)
    if (chunks[i] <= 0) chunks[i] = automatic[i];
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir);
  write_metadata(dir, dtype, grid, chunks, std::clamp(options.compression, 0, 9), array_path_of(options), shown);
}

template <class T>
void write_zarr_box(const std::filesystem::path& dir, const Volume<T>& block, Dims begin, const VolumeWriteOptions& options) {
  VolumeReadOptions ro;
  ro.dataset = array_path_of(options);
  const ZArray a = open_array(dir, ro);
  const std::string shown = display_path(dir).string();
  if (a.dtype != VoxelTraits<T>::name || a.big_endian)
    throw InputError(shown + ": the Zarr array holds " + a.dtype + (a.big_endian ? " (big endian)" : "") +
                     " voxels; cannot write a block of " + VoxelTraits<T>::name);
  const Dims& d = a.header.grid.dims;
  for (size_t i = 0; i < 3; ++i)
    if (begin[i] < 0 || begin[i] + block.dims()[i] > d[i])
      throw InputError(shown + ": a block of " + std::to_string(block.nx()) + "x" + std::to_string(block.ny()) + "x" +
                       std::to_string(block.nz()) + " at " + std::to_string(begin[0]) + "," + std::to_string(begin[1]) + "," +
                       std::to_string(begin[2]) + " does not fit the array (" + std::to_string(d[0]) + "x" +
                       std::to_string(d[1]) + "x" + std::to_string(d[2]) + ")");
  write_chunks(a, reinterpret_cast<const char*>(block.data()), block.dims(), begin, options.threads, shown);
}

template void write_zarr_box(const fs::path&, const Volume<uint8_t>&, Dims, const VolumeWriteOptions&);
template void write_zarr_box(const fs::path&, const Volume<uint16_t>&, Dims, const VolumeWriteOptions&);
template void write_zarr_box(const fs::path&, const Volume<uint32_t>&, Dims, const VolumeWriteOptions&);
template void write_zarr_box(const fs::path&, const Volume<uint64_t>&, Dims, const VolumeWriteOptions&);
template void write_zarr_box(const fs::path&, const Volume<int32_t>&, Dims, const VolumeWriteOptions&);
template void write_zarr_box(const fs::path&, const Volume<float>&, Dims, const VolumeWriteOptions&);
template void write_zarr_box(const fs::path&, const Volume<double>&, Dims, const VolumeWriteOptions&);

}  // namespace skel::io
