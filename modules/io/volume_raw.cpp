// Raw volumes as a VolumeFormat: voxels without a header (or after one of `header_bytes`), x fastest,
// with dims, type, byte order and spacing given as parameters (VolumeReadOptions::raw and spacing).
// The file's size must equal header + voxels: a wrong dims or type is caught before allocating.
#include <algorithm>
#include <bit>
#include <cstring>
#include <fstream>

#include "io/volume_format.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"

namespace fs = std::filesystem;

namespace skel::io {
namespace {

int64_t type_bytes(const std::string& t) {
  if (t == "uint8" || t == "int8") return 1;
  if (t == "uint16" || t == "int16") return 2;
  if (t == "uint32" || t == "int32" || t == "float32") return 4;
  if (t == "uint64" || t == "int64" || t == "float64") return 8;
  return 0;
}

struct RawLayout {
  VolumeHeader header;
  int64_t bytes = 0;  // per voxel
};

RawLayout raw_layout(const fs::path& file, const VolumeReadOptions& o) {
  const auto& r = o.raw;
  const std::string name = file.string();
  if (r.dims.size() != 3)
    throw InputError(name + ": a raw file states no dims: set `raw_dims` to (x, y, z)");
  if (r.type.empty())
    throw InputError(name + ": a raw file states no voxel type: set `raw_type` (uint8, uint16, ..., float32)");
  const int64_t b = type_bytes(r.type);
  if (b == 0) throw InputError(name + ": unknown raw voxel type '" + r.type + "'");
  if (o.spacing.empty())
    throw InputError(name + ": a raw file states no spacing: set `spacing` (x, y, z) and `unit`");
  if (r.header_bytes < 0) throw InputError(name + ": `raw_header_bytes` must be >= 0");
  for (int64_t d : r.dims)
    if (d <= 0) throw InputError(name + ": `raw_dims` must be > 0 on every axis");
  std::error_code ec;
  if (!fs::exists(file, ec)) throw InputError(name + ": file not found");
  if (!fs::is_regular_file(file, ec)) throw InputError(name + ": not a regular file");
  const auto size = static_cast<int64_t>(fs::file_size(file, ec));
  // Overflow-checked: absurd dims are a size mismatch, not a huge allocation.
  int64_t need = b;
  bool overflow = false;
  for (int64_t d : r.dims) overflow = overflow || __builtin_mul_overflow(need, d, &need);
  overflow = overflow || __builtin_add_overflow(need, r.header_bytes, &need);
  if (overflow || need != size) {
    const std::string dims = std::to_string(r.dims[0]) + "x" + std::to_string(r.dims[1]) + "x" + std::to_string(r.dims[2]);
    throw InputError(name + ": holds " + std::to_string(size) + " bytes, but " + dims + " voxels of " + r.type +
                     (r.header_bytes ? " after a header of " + std::to_string(r.header_bytes) + " bytes" : std::string()) +
                     " need " + (overflow ? std::string("more than 2^63") : std::to_string(need)) +
                     ": check `raw_dims`, `raw_type` and `raw_header_bytes`");
  }
  RawLayout l;
  l.bytes = b;
  l.header.grid.dims = {r.dims[0], r.dims[1], r.dims[2]};
  l.header.dtype = r.type;
  l.header.details.push_back("raw: " + std::string(r.big_endian ? "big" : "little") + "-endian, header " +
                             std::to_string(r.header_bytes) + " bytes");
  return l;
}

template <class T, class S>
Volume<T> read_raw_box_as(const fs::path& file, uint64_t offset, const Grid& grid, bool big_endian, Dims begin, Dims size) {
  Grid g = grid;
  g.dims = size;
  for (size_t k = 0; k < 3; ++k) g.origin[k] += static_cast<double>(begin[k]) * g.spacing[k];
  Volume<T> v = Volume<T>::uninitialized(g);
  if (v.size() == 0) return v;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot open");
  const Dims& d = grid.dims;
  // Whole rows of a slice are one contiguous run of the file: read them with one call.
  const int64_t rows_per_read = size[0] == d[0] ? size[1] : 1;
  std::vector<S> run(static_cast<size_t>(size[0] * rows_per_read));
  const bool swap = big_endian != (std::endian::native == std::endian::big);
  for (int64_t z = 0; z < size[2]; ++z)
    for (int64_t y = 0; y < size[1]; y += rows_per_read) {
      const int64_t index = begin[0] + d[0] * ((begin[1] + y) + d[1] * (begin[2] + z));
      in.seekg(static_cast<std::streamoff>(offset + static_cast<uint64_t>(index) * sizeof(S)));
      in.read(reinterpret_cast<char*>(run.data()), static_cast<std::streamsize>(run.size() * sizeof(S)));
      if (!in) throw InputError(file.string() + ": cannot read row " + std::to_string(begin[1] + y) + " of slice " +
                                std::to_string(begin[2] + z) + ": the file is truncated, changed or unreadable");
      T* out = &v(0, y, z);
      for (size_t i = 0; i < run.size(); ++i) {
        S s = run[i];
        if (swap && sizeof(S) > 1) {
          unsigned char bytes[sizeof(S)];
          std::memcpy(bytes, &s, sizeof(S));
          std::reverse(bytes, bytes + sizeof(S));
          std::memcpy(&s, bytes, sizeof(S));
        }
        out[i] = static_cast<T>(s);
      }
    }
  return v;
}

DataPtr read_raw(const fs::path& file, const VolumeReadOptions& o, Dims begin, Dims size, const RawLayout& l) {
  return read_raw_voxel_box(file, static_cast<uint64_t>(o.raw.header_bytes), l.header.grid, l.header.dtype,
                            o.raw.big_endian, begin, size);
}

}  // namespace

DataPtr read_raw_voxel_box(const fs::path& file, uint64_t offset, const Grid& grid, const std::string& t,
                           bool big_endian, Dims begin, Dims size) {
  const bool e = big_endian;
  if (t == "uint8") return std::make_shared<VolumeU8>(read_raw_box_as<uint8_t, uint8_t>(file, offset, grid, e, begin, size));
  if (t == "uint16") return std::make_shared<VolumeU16>(read_raw_box_as<uint16_t, uint16_t>(file, offset, grid, e, begin, size));
  if (t == "uint32") return std::make_shared<VolumeU32>(read_raw_box_as<uint32_t, uint32_t>(file, offset, grid, e, begin, size));
  if (t == "uint64") return std::make_shared<VolumeU64>(read_raw_box_as<uint64_t, uint64_t>(file, offset, grid, e, begin, size));
  if (t == "int8") return std::make_shared<VolumeI32>(read_raw_box_as<int32_t, int8_t>(file, offset, grid, e, begin, size));
  if (t == "int16") return std::make_shared<VolumeI32>(read_raw_box_as<int32_t, int16_t>(file, offset, grid, e, begin, size));
  if (t == "int32") return std::make_shared<VolumeI32>(read_raw_box_as<int32_t, int32_t>(file, offset, grid, e, begin, size));
  if (t == "int64") return std::make_shared<VolumeF64>(read_raw_box_as<double, int64_t>(file, offset, grid, e, begin, size));
  if (t == "float32") return std::make_shared<VolumeF32>(read_raw_box_as<float, float>(file, offset, grid, e, begin, size));
  if (t == "float64") return std::make_shared<VolumeF64>(read_raw_box_as<double, double>(file, offset, grid, e, begin, size));
  throw InputError(file.string() + ": unknown voxel type '" + t + "'");
}

VolumeFormat raw_volume_format() {
  VolumeFormat f;
  f.name = "raw";
  f.extensions = {".raw"};
  f.read_header = [](const fs::path& p, const VolumeReadOptions& o) { return raw_layout(p, o).header; };
  f.read = [](const fs::path& p, const VolumeReadOptions& o) {
    const RawLayout l = raw_layout(p, o);
    return read_raw(p, o, Dims{0, 0, 0}, l.header.grid.dims, l);
  };
  f.read_box = [](const fs::path& p, const VolumeReadOptions& o, Dims begin, Dims size) {
    return read_raw(p, o, begin, size, raw_layout(p, o));
  };
  return f;
}

}  // namespace skel::io
