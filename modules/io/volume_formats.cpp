// The volume format registry: the list of formats and the lookups by extension and magic bytes.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

#include "io/volume_format.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/out_of_core.hpp"

namespace skel::io {

// Each format file defines one of these.
VolumeFormat hdf5_volume_format();
VolumeFormat tiff_volume_format();
VolumeFormat raw_volume_format();
VolumeFormat nrrd_volume_format();
VolumeFormat nhdr_volume_format();
VolumeFormat metaimage_volume_format();
VolumeFormat mhd_volume_format();
VolumeFormat nifti_volume_format();
VolumeFormat vti_volume_format();
VolumeFormat amira_volume_format();
VolumeFormat zarr_volume_format();

const std::vector<VolumeFormat>& volume_formats() {
  static const std::vector<VolumeFormat> formats = [] {
    std::vector<VolumeFormat> f;
    f.push_back(hdf5_volume_format());
    f.push_back(tiff_volume_format());
    f.push_back(raw_volume_format());
    f.push_back(nrrd_volume_format());
    f.push_back(nhdr_volume_format());
    f.push_back(metaimage_volume_format());
    f.push_back(mhd_volume_format());
    f.push_back(nifti_volume_format());
    f.push_back(vti_volume_format());
    f.push_back(amira_volume_format());
    f.push_back(zarr_volume_format());
    return f;
  }();
  return formats;
}

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The format whose extension is the longest suffix of the file name, or null.
const VolumeFormat* by_extension(const std::filesystem::path& path, bool writable) {
  const std::string name = lower(path.filename().string());
  const VolumeFormat* best = nullptr;
  size_t best_len = 0;
  for (const auto& f : volume_formats()) {
    if (writable && !f.write) continue;
    for (const auto& e : f.extensions)
      if (e.size() > best_len && ends_with(name, e)) {
        best = &f;
        best_len = e.size();
      }
  }
  return best;
}

bool fs_is_directory(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::is_directory(p, ec);
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + v[i];
  return s;
}

}  // namespace

std::vector<std::string> readable_volume_extensions() {
  std::vector<std::string> out;
  for (const auto& f : volume_formats()) out.insert(out.end(), f.extensions.begin(), f.extensions.end());
  return out;
}

std::vector<std::string> writable_volume_extensions() {
  std::vector<std::string> out;
  for (const auto& f : volume_formats())
    if (f.write) out.insert(out.end(), f.extensions.begin(), f.extensions.end());
  return out;
}

const VolumeFormat& volume_format_for_read(const std::filesystem::path& path) {
  if (const auto* f = by_extension(path, false)) {
    // "slices/z*.tif": a pattern of a slice-folder format.
    if (path.filename().string().find_first_of("*?[") == std::string::npos || f->slice_folders) return *f;
  }
  std::error_code ec;
  if (fs_is_directory(path) || path.filename().string().find_first_of("*?[") != std::string::npos) {
    // A folder of slices: the format of its files.
    if (fs_is_directory(path))
      for (const auto& e : std::filesystem::directory_iterator(path, ec))
        if (const auto* f = by_extension(e.path(), false); f && f->slice_folders) return *f;
    std::vector<std::string> exts;
    for (const auto& f : volume_formats())
      if (f.slice_folders) exts.insert(exts.end(), f.extensions.begin(), f.extensions.end());
    throw InputError(path.string() + ": " + (fs_is_directory(path) ? "folder holds no slice files" : "pattern names no slice files") +
                     " Skelflow reads (extensions: " + join(exts) + ")");
  }
  std::string head;
  if (std::ifstream in(path, std::ios::binary); in) {
    head.resize(512);
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<size_t>(in.gcount()));
  }
  for (const auto& f : volume_formats())
    if (!head.empty() && f.sniff && f.sniff(head)) return f;
  throw InputError(path.string() + ": not a volume file Skelflow reads (known extensions: " +
                   join(readable_volume_extensions()) + ")");
}

const VolumeFormat& volume_format_for_write(const std::filesystem::path& path) {
  // The engine's temporary (".v.h5.skelflow-tmp-...") is written in the format of its final name.
  const std::filesystem::path final_path = display_path(path);
  if (const auto* f = by_extension(final_path, true)) return *f;
  throw InputError(final_path.string() + ": cannot write a volume of this type (extensions that can be written: " +
                   join(writable_volume_extensions()) + ")");
}

namespace {

// The spacing and unit overrides of `o`, checked (the module checks them too; this names the file).
void check_overrides(const std::filesystem::path& path, const VolumeReadOptions& o) {
  if (!o.spacing.empty()) {
    if (o.spacing.size() != 3)
      throw InputError(path.string() + ": the spacing override needs 3 values (x, y, z), got " +
                       std::to_string(o.spacing.size()));
    for (double v : o.spacing)
      if (!(v > 0) || !std::isfinite(v)) throw InputError(path.string() + ": the spacing override must be > 0 on every axis");
  }
}

void override_grid(Grid& g, const VolumeReadOptions& o) {
  if (!o.spacing.empty()) {
    // The origin of a box stays at the same physical place in voxels: scale it with the spacing.
    for (size_t k = 0; k < 3; ++k) {
      g.origin[k] = g.spacing[k] > 0 ? g.origin[k] / g.spacing[k] * o.spacing[k] : g.origin[k];
      g.spacing[k] = o.spacing[k];
    }
  }
  if (!o.unit.empty()) g.unit = o.unit;
}

// Applies the overrides to a volume the reader has just made (not shared with anyone yet).
DataPtr with_overrides(DataPtr v, const VolumeReadOptions& o) {
  if (o.spacing.empty() && o.unit.empty()) return v;
  visit_volume(*v, "volume", [&](const auto& vol) {
    using V = std::decay_t<decltype(vol)>;
    auto& mine = const_cast<V&>(vol);  // the reader's fresh object: safe to change before it is shared
    Grid g = mine.grid();
    override_grid(g, o);
    mine.copy_geometry(g);
  });
  return v;
}

}  // namespace

VolumeHeader read_volume_header(const std::filesystem::path& path, const VolumeReadOptions& options) {
  check_overrides(path, options);
  VolumeHeader h = volume_format_for_read(path).read_header(path, options);
  override_grid(h.grid, options);
  if (!options.spacing.empty()) h.has_spacing = true;
  if (!options.unit.empty()) h.has_unit = true;
  return h;
}

DataPtr read_any_volume(const std::filesystem::path& path, const VolumeReadOptions& options) {
  check_overrides(path, options);
  return with_overrides(volume_format_for_read(path).read(path, options), options);
}

DataPtr read_any_volume_box(const std::filesystem::path& path, const VolumeReadOptions& options, Dims begin, Dims size) {
  check_overrides(path, options);
  const VolumeFormat& f = volume_format_for_read(path);
  if (f.read_box) {
    const VolumeHeader h = f.read_header(path, options);
    for (int k = 0; k < 3; ++k)
      if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > h.grid.dims[k])
        throw InputError(path.string() + ": box at (" + std::to_string(begin[0]) + ", " + std::to_string(begin[1]) + ", " +
                         std::to_string(begin[2]) + ") of size " + std::to_string(size[0]) + "x" +
                         std::to_string(size[1]) + "x" + std::to_string(size[2]) + " is outside the volume (" +
                         std::to_string(h.grid.dims[0]) + "x" + std::to_string(h.grid.dims[1]) + "x" +
                         std::to_string(h.grid.dims[2]) + ")");
    return with_overrides(f.read_box(path, options, begin, size), options);
  }
  DataPtr whole = f.read(path, options);
  const Dims& d = any_volume_grid(*whole, path.string()).dims;
  for (int k = 0; k < 3; ++k)
    if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > d[k]) throw InputError(path.string() + ": box outside the volume");
  return with_overrides(crop_volume_box(*whole, begin, size), options);
}

DataPtr crop_volume_box(const DataObject& whole, Dims begin, Dims size) {
  return visit_volume(whole, "volume", [&](const auto& v) -> DataPtr {
    using T = typename std::decay_t<decltype(v)>::value_type;
    for (int k = 0; k < 3; ++k)
      if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > v.dims()[k]) throw InputError("box outside the volume");
    Grid g = v.grid();
    g.dims = size;
    for (int k = 0; k < 3; ++k) g.origin[k] += static_cast<double>(begin[k]) * g.spacing[k];
    auto out = std::make_shared<Volume<T>>(Volume<T>::uninitialized(g));
    for (int64_t z = 0; z < size[2]; ++z)
      for (int64_t y = 0; y < size[1]; ++y)
        std::copy_n(&v(begin[0], begin[1] + y, begin[2] + z), size[0], &(*out)(0, y, z));
    return out;
  });
}

bool reads_boxes_cheaply(const std::filesystem::path& path, const VolumeReadOptions& options) {
  const VolumeFormat& f = volume_format_for_read(path);
  return f.read_box && (!f.boxes_are_cheap || f.boxes_are_cheap(path, options));
}

std::string volume_type_for_dtype(const std::string& dtype) {
  if (dtype == "uint8") return type_ids::volume_u8;
  if (dtype == "uint16") return type_ids::volume_u16;
  if (dtype == "uint32") return type_ids::volume_u32;
  if (dtype == "uint64") return type_ids::volume_u64;
  if (dtype == "int8" || dtype == "int16" || dtype == "int32") return type_ids::volume_i32;
  if (dtype == "float32") return type_ids::volume_f32;
  if (dtype == "float64" || dtype == "int64") return type_ids::volume_f64;
  throw InputError("unknown voxel type '" + dtype + "'");
}

void write_any_volume(const std::filesystem::path& path, const DataObject& volume, const VolumeWriteOptions& options) {
  volume_format_for_write(path).write(path, volume, options);
}

void write_any_volume_boxes(const std::filesystem::path& path, const VolumeBoxSource& volume, const VolumeWriteOptions& options) {
  const VolumeFormat& f = volume_format_for_write(path);
  if (!f.write_boxes)
    throw InputError(display_path(path).string() + ": " + f.name + " files are written from a whole volume in memory, not box by box");
  f.write_boxes(path, volume, options);
}

int64_t units_per_box(const VolumeBoxSource& source, uint64_t unit_bytes, int64_t count) {
  if (source.max_box_bytes == 0 || unit_bytes == 0) return std::max<int64_t>(count, 1);
  return std::clamp<int64_t>(static_cast<int64_t>(source.max_box_bytes / unit_bytes), 1, std::max<int64_t>(count, 1));
}

std::string describe_volume_file(const std::filesystem::path& path) {
  const VolumeFormat& f = volume_format_for_read(path);
  std::string s = "  format: " + f.name + "\n";
  if (f.describe) return s + f.describe(path);
  VolumeReadOptions first_channel;  // a multi-channel file is described by its first channel (details name the count)
  first_channel.channel = 0;
  const VolumeHeader h = f.read_header(path, first_channel);
  const Grid& g = h.grid;
  s += "  voxels: " + h.dtype + " " + std::to_string(g.dims[0]) + "x" + std::to_string(g.dims[1]) + "x" +
       std::to_string(g.dims[2]) + " (x,y,z)\n";
  auto vec = [](const Vec3& v) {
    std::ostringstream o;
    o << v[0] << " " << v[1] << " " << v[2];
    return o.str();
  };
  s += "  spacing: " + vec(g.spacing) + " " + g.unit + (h.has_spacing ? "" : " (default)") +
       (h.has_unit ? "" : " (unit: default)") + "\n";
  s += "  origin: " + vec(g.origin) + " " + g.unit + (h.has_origin ? "" : " (default)") + "\n";
  if (g.direction != kIdentityDirection) {
    std::ostringstream o;
    for (int i = 0; i < 9; ++i) o << (i ? " " : "") << g.direction[static_cast<size_t>(i)];
    s += "  direction: " + o.str() + "\n";
  }
  for (const auto& d : h.details) s += "  " + d + "\n";
  return s;
}

}  // namespace skel::io
