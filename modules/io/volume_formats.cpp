// The volume format registry: the list of formats and the lookups by extension and magic bytes.
#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>

#include "io/volume_format.hpp"
#include "skel/error.hpp"

namespace skel::io {

// Each format file defines one of these.
VolumeFormat hdf5_volume_format();
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
  if (const auto* f = by_extension(path, false)) return *f;
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
  if (const auto* f = by_extension(path, true)) return *f;
  throw InputError(path.string() + ": cannot write a volume of this type (extensions that can be written: " +
                   join(writable_volume_extensions()) + ")");
}

VolumeHeader read_volume_header(const std::filesystem::path& path, const VolumeReadOptions& options) {
  return volume_format_for_read(path).read_header(path, options);
}

DataPtr read_any_volume(const std::filesystem::path& path, const VolumeReadOptions& options) {
  return volume_format_for_read(path).read(path, options);
}

void write_any_volume(const std::filesystem::path& path, const DataObject& volume, const VolumeWriteOptions& options) {
  volume_format_for_write(path).write(path, volume, options);
}

std::string describe_volume_file(const std::filesystem::path& path) {
  const VolumeFormat& f = volume_format_for_read(path);
  if (f.describe) return f.describe(path);
  const VolumeHeader h = f.read_header(path, {});
  const Grid& g = h.grid;
  std::string s = "  format: " + f.name + "\n";
  s += "  voxels: " + h.dtype + " " + std::to_string(g.dims[0]) + "x" + std::to_string(g.dims[1]) + "x" +
       std::to_string(g.dims[2]) + " (x,y,z)\n";
  auto vec = [](const Vec3& v) {
    std::ostringstream o;
    o << v[0] << " " << v[1] << " " << v[2];
    return o.str();
  };
  s += "  spacing: " + vec(g.spacing) + " " + g.unit + (h.has_spacing ? "" : " (default)") + "\n";
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
