// The read side of HDF5 volumes (hdf5_read.hpp): in the reader's process for trusted files and in the
// probe helper for users' files.
#include "io/hdf5_read.hpp"

#include <sys/mman.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iomanip>
#include <new>
#include <sstream>

#include "io/hdf5_chunks.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"

namespace fs = std::filesystem;

namespace skel::io::h5 {

namespace {

herr_t innermost(unsigned n, const H5E_error2_t* e, void* data) {
  auto* s = static_cast<std::string*>(data);
  if (n == 0 && e && e->desc) *s = e->desc;  // the innermost problem
  return 0;
}

AttributeSource g_attribute_source = nullptr;

}  // namespace

std::string hdf5_reason() {
  std::string s;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, innermost, &s);
  H5Eclear2(H5E_DEFAULT);
  return s.empty() ? std::string() : " (HDF5: " + s + ")";
}

void fail(const fs::path& file, const std::string& what) {
  throw InputError(display_path(file).string() + ": " + what + hdf5_reason());
}

Handle open_file(const fs::path& file, bool write, hid_t fapl) {
  std::error_code ec;
  if (!fs::exists(file, ec)) throw InputError(file.string() + ": file not found");
  if (fs::is_directory(file, ec)) throw InputError(file.string() + ": is a folder, not an HDF5 file");
  const htri_t is = H5Fis_hdf5(file.c_str());
  if (is <= 0) fail(file, "not an HDF5 file, or the file is truncated or corrupt");
  Handle own_fapl;
  if (fapl < 0) {
    own_fapl = Handle(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    fapl = own_fapl.id;
  }
  Handle f(H5Fopen(file.c_str(), write ? H5F_ACC_RDWR : H5F_ACC_RDONLY, fapl), H5Fclose);
  if (!f) fail(file, "cannot open as HDF5: the file is truncated or corrupt");
  return f;
}

namespace {
herr_t collect_dataset(hid_t, const char* name, const H5O_info_t* info, void* data) {
  if (info->type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(std::string("/") + name);
  return 0;
}
}  // namespace

std::vector<std::string> list_datasets(hid_t file) {
  std::vector<std::string> names;
  H5Ovisit2(file, H5_INDEX_NAME, H5_ITER_NATIVE, collect_dataset, &names, H5O_INFO_BASIC);
  H5Eclear2(H5E_DEFAULT);
  return names;
}

Handle open_dataset(hid_t f, const fs::path& file, const std::string& dataset) {
  // Check each path component so that a missing group is a clear message, not an HDF5 stack.
  if (dataset.empty() || dataset[0] != '/') throw InputError(file.string() + ": dataset name '" + dataset + "' must start with '/'");
  std::string partial;
  std::stringstream ss(dataset.substr(1));
  std::string part;
  bool exists = true;
  while (std::getline(ss, part, '/')) {
    partial += "/" + part;
    if (H5Lexists(f, partial.c_str(), H5P_DEFAULT) <= 0) {
      exists = false;
      break;
    }
  }
  H5Eclear2(H5E_DEFAULT);
  if (!exists) {
    std::string names;
    for (const auto& n : list_datasets(f)) {
      if (!names.empty()) names += ", ";
      names += n;
    }
    throw InputError(file.string() + ": no dataset '" + dataset + "' (datasets: " + (names.empty() ? "none" : names) + ")");
  }
  Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  H5Pset_chunk_cache(dapl.id, 12421, 256u << 20, 1.0);  // 256 MiB chunk cache: whole chunk rows stay cached
  Handle d(H5Dopen2(f, dataset.c_str(), dapl.id), H5Dclose);
  if (!d) fail(file, "'" + dataset + "' is not a dataset");
  return d;
}

namespace {

std::string dtype_name(hid_t type) {
  const H5T_class_t cls = H5Tget_class(type);
  const size_t size = H5Tget_size(type);
  if (cls == H5T_FLOAT) return size == 4 ? "float32" : size == 8 ? "float64" : "float" + std::to_string(size * 8);
  if (cls == H5T_INTEGER) {
    const bool sign = H5Tget_sign(type) == H5T_SGN_2;
    return std::string(sign ? "int" : "uint") + std::to_string(size * 8);
  }
  return "unsupported";
}

// "" when the bit fields of `type` (an integer or float of 1-8 bytes) lie inside its bytes: precision
// at least 1 bit, offset + precision within 8 × size, and for floats the sign, exponent and mantissa
// within the precision; else what is wrong. libhdf5 1.10.8's conversions trust these fields: a
// mutated integer type of precision 0 at bit offset 256 in 8 bytes made H5Dread's integer-to-double
// conversion (H5T__bit_copy) fault with SIGBUS in the reader's process (libFuzzer, session 9).
// Types with fewer bits than their bytes hold (the n-bit filter's) are valid and read.
std::string invalid_type_fields(hid_t type) {
  const H5T_class_t cls = H5Tget_class(type);
  const size_t bits = 8 * H5Tget_size(type);
  const size_t precision = H5Tget_precision(type);
  const int offset = H5Tget_offset(type);
  H5Eclear2(H5E_DEFAULT);
  if (precision < 1 || offset < 0 || static_cast<size_t>(offset) + precision > bits)
    return std::to_string(precision) + " bits of precision at bit offset " + std::to_string(offset) + " in " +
           std::to_string(bits / 8) + " bytes";
  if (cls == H5T_FLOAT) {
    size_t spos = 0, epos = 0, esize = 0, mpos = 0, msize = 0;
    const bool fields = H5Tget_fields(type, &spos, &epos, &esize, &mpos, &msize) >= 0;
    H5Eclear2(H5E_DEFAULT);
    const size_t top = static_cast<size_t>(offset) + precision;
    if (!fields || esize < 1 || spos >= top || epos + esize > top || mpos + msize > top || mpos < static_cast<size_t>(offset))
      return "sign, exponent or mantissa outside the float's bits";
  }
  return "";
}

}  // namespace

Opened open_volume(const fs::path& file, const std::string& dataset, bool write, hid_t fapl) {
  Opened o;
  o.file = open_file(file, write, fapl);
  o.dset = open_dataset(o.file.id, file, dataset);
  o.space = Handle(H5Dget_space(o.dset.id), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(o.space.id);
  if (rank != 3)
    throw InputError(file.string() + ": dataset '" + dataset + "' has rank " + std::to_string(rank) +
                     ", expected 3 (shape [z][y][x])");
  hsize_t d[3];
  H5Sget_simple_extent_dims(o.space.id, d, nullptr);
  o.dims = {static_cast<int64_t>(d[2]), static_cast<int64_t>(d[1]), static_cast<int64_t>(d[0])};
  Handle t(H5Dget_type(o.dset.id), H5Tclose);
  o.dtype = dtype_name(t.id);
  static const std::vector<std::string> ok{"uint8", "uint16", "uint32", "uint64", "int8", "int16",
                                           "int32", "int64", "float32", "float64"};
  if (std::find(ok.begin(), ok.end(), o.dtype) == ok.end())
    throw InputError(file.string() + ": dataset '" + dataset + "' has an unsupported data type (" + o.dtype +
                     "); integer and float datasets are supported");
  if (const std::string bad = invalid_type_fields(t.id); !bad.empty())
    throw InputError(file.string() + ": dataset '" + dataset + "' has a damaged " + o.dtype + " type (" + bad +
                     "): the file is damaged");
  return o;
}

void set_attribute_source(AttributeSource source) { g_attribute_source = source; }

namespace {

// The attribute probe::kAttributeNames[index] of `object` (open as `obj`): from the attribute source
// when one is set and has it, else libhdf5's reading in this process.
probe::Attribute attribute(hid_t obj, const std::string& object, size_t index, const fs::path& file) {
  probe::Attribute a;
  if (!g_attribute_source || !g_attribute_source(file, object, index, a)) a = probe::read_attribute(obj, index);
  H5Eclear2(H5E_DEFAULT);
  const std::string name = probe::kAttributeNames[index];
  using Kind = probe::Attribute::Kind;
  switch (a.kind) {
    case Kind::wrong_count: throw InputError(file.string() + ": attribute '" + name + "' must hold 3 numbers (x, y, z)");
    case Kind::not_string: throw InputError(file.string() + ": attribute '" + name + "' must be a string");
    case Kind::unreadable: throw InputError(file.string() + ": cannot read attribute '" + name + "' of '" + object + "'");
    case Kind::too_long:
      throw InputError(file.string() + ": attribute '" + name + "' of '" + object + "' is longer than " +
                       std::to_string(probe::kMaxStringBytes) + " bytes");
    default: break;
  }
  if (probe::is_string_attribute(index) ? a.kind == Kind::numbers : a.kind == Kind::text)  // not from this walk
    throw InputError(file.string() + ": cannot read attribute '" + name + "' of '" + object + "'");
  return a;
}

// Attribute indices in probe::kAttributeNames.
constexpr size_t kSpacing = 0, kOrigin = 1, kElementSize = 2, kUnit = 3;

bool read_vec3_attr(hid_t obj, const std::string& object, size_t index, Vec3& out, const fs::path& file) {
  const probe::Attribute a = attribute(obj, object, index, file);
  if (a.kind != probe::Attribute::Kind::numbers) return false;
  out = {a.numbers[0], a.numbers[1], a.numbers[2]};
  return true;
}

// A string attribute (fixed or variable length); false when absent.
bool read_string_attr(hid_t obj, const std::string& object, size_t index, std::string& out, const fs::path& file) {
  const probe::Attribute a = attribute(obj, object, index, file);
  if (a.kind != probe::Attribute::Kind::text) return false;
  out = a.text;
  return true;
}

// The unit of files written by Fiji, BigDataViewer and ilastik: `element_size_um` is in micrometres
// by its name.
constexpr const char* kElementSizeUnit = "\u00b5m";

// Spacing, origin and unit of a dataset: attributes `spacing`, `origin` (x, y, z) and `unit` on the
// dataset; without `spacing`, `element_size_um` ([z][y][x], µm; Fiji, BigDataViewer, ilastik) on the
// dataset or its group.
void read_geometry(hid_t file_id, hid_t dset, const std::string& dataset, const fs::path& file, VolumeInfo& g) {
  g.has_spacing = read_vec3_attr(dset, dataset, kSpacing, g.spacing, file);
  g.has_origin = read_vec3_attr(dset, dataset, kOrigin, g.origin, file);
  g.has_unit = read_string_attr(dset, dataset, kUnit, g.unit, file);
  if (!g.has_spacing) {
    Vec3 zyx{1, 1, 1};
    bool found = read_vec3_attr(dset, dataset, kElementSize, zyx, file);
    if (!found) {
      std::string group = dataset.substr(0, dataset.rfind('/'));
      if (group.empty()) group = "/";
      probe::Attribute a;
      if (g_attribute_source && g_attribute_source(file, group, kElementSize, a)) {
        // The probe's value: the group is not opened in this process.
        found = read_vec3_attr(-1, group, kElementSize, zyx, file);
      } else {
        Handle grp(H5Oopen(file_id, group.c_str(), H5P_DEFAULT), H5Oclose);
        H5Eclear2(H5E_DEFAULT);
        if (grp) found = read_vec3_attr(grp.id, group, kElementSize, zyx, file);
      }
    }
    if (found) {
      g.spacing = {zyx[2], zyx[1], zyx[0]};
      g.has_spacing = true;
      if (!g.has_unit) {
        g.unit = kElementSizeUnit;
        g.has_unit = true;
      }
    }
  }
  for (int k = 0; k < 3; ++k)
    if (!(g.spacing[k] > 0) || !std::isfinite(g.spacing[k]))
      throw InputError(file.string() + ": dataset '" + dataset + "': the spacing must be > 0 on every axis");
  if (g.unit.empty()) throw InputError(file.string() + ": dataset '" + dataset + "': attribute 'unit' is empty");
}

// The data a dataset holds lies in its file (external raw files, H5Pset_external, are left out), so
// a stored size beyond the file's is a corrupt chunk index or layout message, refused before H5Dread
// allocates a buffer of that size for one chunk (libFuzzer: a 5 KB file claiming a 4 GB chunk).
void check_stored_size(const Opened& o, const fs::path& file, const std::string& dataset) {
  Handle plist(H5Dget_create_plist(o.dset.id), H5Pclose);
  const double held = static_cast<double>(H5Dget_storage_size(o.dset.id));
  hsize_t file_size = 0;
  const bool external = H5Pget_external_count(plist.id) > 0;
  const bool sized = H5Fget_filesize(o.file.id, &file_size) >= 0;
  H5Eclear2(H5E_DEFAULT);
  if (!external && sized && held > static_cast<double>(file_size)) {
    std::ostringstream s;
    s << file.string() << ": dataset '" << dataset << "' claims " << std::fixed << std::setprecision(0) << held
      << " bytes of stored data but the file is only " << file_size << " bytes: the file is truncated or corrupt";
    throw InputError(s.str());
  }
}

}  // namespace

VolumeInfo volume_info(const Opened& o, const fs::path& file, const std::string& dataset) {
  VolumeInfo info;
  info.dims = o.dims;
  info.dtype = o.dtype;
  read_geometry(o.file.id, o.dset.id, dataset, file, info);
  Handle plist(H5Dget_create_plist(o.dset.id), H5Pclose);
  if (H5Pget_layout(plist.id) == H5D_CHUNKED) {
    hsize_t c[3];
    H5Pget_chunk(plist.id, 3, c);
    info.chunks = {static_cast<int64_t>(c[2]), static_cast<int64_t>(c[1]), static_cast<int64_t>(c[0])};
  }
  const int nf = H5Pget_nfilters(plist.id);
  for (int i = 0; i < nf; ++i) {
    unsigned flags = 0;
    size_t nelem = 0;
    char name[64] = {0};
    unsigned config = 0;
    const H5Z_filter_t f = H5Pget_filter2(plist.id, static_cast<unsigned>(i), &flags, &nelem, nullptr, sizeof name, name, &config);
    info.filters.push_back(f == H5Z_FILTER_DEFLATE ? "deflate" : f == H5Z_FILTER_SHUFFLE ? "shuffle" : name);
  }
  H5Eclear2(H5E_DEFAULT);
  return info;
}

// The dims a file declares are checked against the data it holds before the volume is allocated, so
// a corrupt or hostile 4 KB file cannot make Skelflow allocate terabytes. Unfiltered data must be
// all there; deflate cannot compress better than 1032:1 (shuffle and fletcher32 add nothing), so a
// compressed dataset may declare at most ~1100 times what it stores. Filters this HDF5 cannot decode
// are refused here too, instead of after the allocation.
void check_whole_read(const Opened& o, const fs::path& file, const std::string& dataset) {
  if (o.dims[0] == 0 || o.dims[1] == 0 || o.dims[2] == 0)
    throw InputError(file.string() + ": dataset '" + dataset + "' is empty (" + std::to_string(o.dims[0]) + "x" +
                     std::to_string(o.dims[1]) + "x" + std::to_string(o.dims[2]) +
                     " voxels as x,y,z); a volume needs at least one voxel on every axis");
  Handle t(H5Dget_type(o.dset.id), H5Tclose);
  const double voxels = static_cast<double>(o.dims[0]) * static_cast<double>(o.dims[1]) * static_cast<double>(o.dims[2]);
  const double declared = voxels * static_cast<double>(H5Tget_size(t.id));
  const double held = static_cast<double>(H5Dget_storage_size(o.dset.id));
  Handle plist(H5Dget_create_plist(o.dset.id), H5Pclose);
  const int nf = H5Pget_nfilters(plist.id);
  for (int i = 0; i < nf; ++i) {
    unsigned flags = 0, config = 0;
    size_t nelem = 0;
    char name[64] = {0};
    const H5Z_filter_t f = H5Pget_filter2(plist.id, static_cast<unsigned>(i), &flags, &nelem, nullptr, sizeof name, name, &config);
    if (f < 0 || H5Zfilter_avail(f) <= 0) {
      H5Eclear2(H5E_DEFAULT);
      throw InputError(file.string() + ": dataset '" + dataset + "' is compressed with HDF5 filter " +
                       std::to_string(f) + (name[0] ? std::string(" (") + name + ")" : std::string()) +
                       ", which this HDF5 library cannot decode; rewrite it with gzip/deflate or without compression");
    }
  }
  check_stored_size(o, file, dataset);
  const double max_ratio = nf > 0 ? 1100.0 : 1.0;
  if (declared > held * max_ratio) {
    std::ostringstream s;
    s << file.string() << ": dataset '" << dataset << "' declares " << o.dims[0] << "x" << o.dims[1] << "x" << o.dims[2]
      << " voxels (x,y,z) of " << o.dtype << " (" << declared << " bytes) but the file holds only " << held
      << " bytes of data for it" << (nf > 0 ? " (more than deflate can compress)" : "")
      << ": the file is truncated or corrupt";
    throw InputError(s.str());
  }
}

template <class T>
void read_voxels(const Opened& o, const fs::path& file, const std::string& dataset, const Dims& begin, const Dims& size,
                 T* out, int threads) {
  if (size[0] <= 0 || size[1] <= 0 || size[2] <= 0) return;
  // Chunked datasets with shuffle / deflate / Fletcher32: our own decoding (hdf5_chunks.hpp), which
  // refuses a damaged chunk instead of letting libhdf5 overrun a buffer; anything else: H5Dread.
  if (detail::read_chunked_box<T>(o.dset.id, file, dataset, o.dims, begin, size, out, threads)) return;
  hsize_t start[3] = {static_cast<hsize_t>(begin[2]), static_cast<hsize_t>(begin[1]), static_cast<hsize_t>(begin[0])};
  hsize_t count[3] = {static_cast<hsize_t>(size[2]), static_cast<hsize_t>(size[1]), static_cast<hsize_t>(size[0])};
  if (H5Sselect_hyperslab(o.space.id, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    fail(file, "invalid box for dataset '" + dataset + "'");
  Handle mem(H5Screate_simple(3, count, nullptr), H5Sclose);
  if (H5Dread(o.dset.id, detail::native_type<T>(), mem.id, o.space.id, H5P_DEFAULT, out) < 0)
    fail(file, "cannot read dataset '" + dataset + "': the file is truncated or corrupt");
}
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, uint8_t*, int);
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, uint16_t*, int);
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, uint32_t*, int);
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, uint64_t*, int);
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, int32_t*, int);
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, float*, int);
template void read_voxels(const Opened&, const fs::path&, const std::string&, const Dims&, const Dims&, double*, int);

std::string string_attribute(const Opened& o, const fs::path& file, const std::string& dataset, const std::string& name) {
  const auto* names = std::begin(probe::kAttributeNames);
  const auto at = std::find_if(names, std::end(probe::kAttributeNames), [&](const char* n) { return name == n; });
  if (at == std::end(probe::kAttributeNames) || !probe::is_string_attribute(static_cast<size_t>(at - names)))
    throw Error("read_string_attribute: '" + name + "' is not one of the string attributes the readers read");
  std::string out;
  read_string_attr(o.dset.id, dataset, static_cast<size_t>(at - names), out, file);
  return out;
}

std::string describe(const fs::path& file, const std::function<void(const std::string&)>& before_open) {
  std::vector<std::string> names;
  {
    Handle f = open_file(file, false);
    names = list_datasets(f.id);
  }
  std::ostringstream s;
  if (names.empty()) s << "  (no datasets)\n";
  for (const auto& n : names) {
    try {
      if (before_open) before_open(n);
      const Opened o = open_volume(file, n);
      const VolumeInfo i = volume_info(o, file, n);
      s << "  " << n << ": " << i.dtype << " " << i.dims[0] << "x" << i.dims[1] << "x" << i.dims[2] << " (x,y,z)";
      if (i.chunks[0]) s << ", chunks " << i.chunks[0] << "x" << i.chunks[1] << "x" << i.chunks[2];
      for (const auto& fl : i.filters) s << ", " << fl;
      s << ", spacing " << i.spacing[0] << " " << i.spacing[1] << " " << i.spacing[2] << " " << i.unit
        << (i.has_spacing ? "" : " (default)");
      s << ", origin " << i.origin[0] << " " << i.origin[1] << " " << i.origin[2] << " " << i.unit
        << (i.has_unit ? "" : " (unit: default)") << "\n";
      const std::string enc = string_attribute(o, file, n, "encoding");
      if (!enc.empty()) s << "    encoding: " << enc << "\n";
    } catch (const InputError& e) {
      s << "  " << n << ": " << e.what() << "\n";
    }
  }
  return s.str();
}

// ------------------------------------------------------------------ requests to the probe helper

size_t memory_type_bytes(MemoryType t) {
  switch (t) {
    case MemoryType::u8: return 1;
    case MemoryType::u16: return 2;
    case MemoryType::u32: case MemoryType::i32: case MemoryType::f32: return 4;
    case MemoryType::u64: case MemoryType::f64: return 8;
  }
  return 0;
}

namespace {

void put(std::string& out, const void* p, size_t n) { out.append(static_cast<const char*>(p), n); }
template <class V> void put_value(std::string& out, V v) { put(out, &v, sizeof v); }
void put_string(std::string& out, const std::string& s) {
  put_value<uint32_t>(out, static_cast<uint32_t>(s.size()));
  out += s;
}
bool get(const std::string& in, size_t& at, void* p, size_t n) {
  if (n > in.size() - at) return false;
  std::memcpy(p, in.data() + at, n);
  at += n;
  return true;
}
bool get_string(const std::string& in, size_t& at, std::string& s) {
  uint32_t n = 0;
  if (!get(in, at, &n, sizeof n) || n > in.size() - at) return false;
  s.assign(in, at, n);
  at += n;
  return true;
}

}  // namespace

std::string encode_info(const VolumeInfo& i) {
  std::string out;
  put(out, i.dims.data(), sizeof i.dims);
  put_string(out, i.dtype);
  put(out, i.chunks.data(), sizeof i.chunks);
  put_value<uint32_t>(out, static_cast<uint32_t>(i.filters.size()));
  for (const auto& f : i.filters) put_string(out, f);
  put(out, i.spacing.data(), sizeof i.spacing);
  put(out, i.origin.data(), sizeof i.origin);
  put_string(out, i.unit);
  const uint8_t flags = static_cast<uint8_t>((i.has_spacing ? 1 : 0) | (i.has_origin ? 2 : 0) | (i.has_unit ? 4 : 0));
  put_value(out, flags);
  return out;
}

bool decode_info(const std::string& in, VolumeInfo& i, std::string* whole_read_refusal) {
  i = VolumeInfo{};
  size_t at = 0;
  uint32_t nf = 0;
  if (!get(in, at, i.dims.data(), sizeof i.dims) || !get_string(in, at, i.dtype) || !get(in, at, i.chunks.data(), sizeof i.chunks) ||
      !get(in, at, &nf, sizeof nf) || nf > in.size())
    return false;
  i.filters.resize(nf);
  for (auto& f : i.filters)
    if (!get_string(in, at, f)) return false;
  uint8_t flags = 0;
  if (!get(in, at, i.spacing.data(), sizeof i.spacing) || !get(in, at, i.origin.data(), sizeof i.origin) ||
      !get_string(in, at, i.unit) || !get(in, at, &flags, sizeof flags))
    return false;
  if (whole_read_refusal && !get_string(in, at, *whole_read_refusal)) return false;
  if (at != in.size() && whole_read_refusal) return false;
  i.has_spacing = flags & 1;
  i.has_origin = flags & 2;
  i.has_unit = flags & 4;
  return true;
}

namespace {

// A read request in the helper: the box into the window.
std::string serve_read(const std::string& path, const std::string& dataset, const ReadRequest& r, int window_fd) {
  const auto t = static_cast<MemoryType>(r.memory_type);
  const size_t elem = memory_type_bytes(t);
  if (elem == 0) throw Error("read request: unknown memory type " + std::to_string(r.memory_type));
  const Dims begin{r.begin[0], r.begin[1], r.begin[2]}, size{r.size[0], r.size[1], r.size[2]};
  for (int k = 0; k < 3; ++k)
    if (size[k] < 0 || begin[k] < 0) throw Error("read request: negative box");
  const double bytes = static_cast<double>(size[0]) * static_cast<double>(size[1]) * static_cast<double>(size[2]) * double(elem);
  struct stat st {};
  if (::fstat(window_fd, &st) != 0 || double(st.st_size) < bytes)
    throw Error("read request: the box does not fit the shared window");
  const fs::path file(path);
  const Opened o = open_volume(file, dataset);
  for (int k = 0; k < 3; ++k)
    if (begin[k] + size[k] > o.dims[k]) throw InputError(file.string() + ": box outside dataset '" + dataset + "'");
  if (bytes == 0) return {};
  if (r.own_chunks) unsetenv("SKEL_HDF5_OWN_CHUNKS");
  else setenv("SKEL_HDF5_OWN_CHUNKS", "0", 1);
  // The window stays mapped between requests (populated once): mapping it anew for each read cost a
  // page fault per 4 KiB, a box's worth each time, more than the decoding on this kind of virtual
  // machine. The parent only grows the window; a new size is mapped anew.
  static void* mapped = nullptr;
  static size_t mapped_bytes = 0;
  static int mapped_fd = -1;
  if (mapped == nullptr || mapped_fd != window_fd || mapped_bytes != static_cast<size_t>(st.st_size)) {
    if (mapped) ::munmap(mapped, mapped_bytes);
    mapped = nullptr;
    void* m = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE, window_fd, 0);
    if (m == MAP_FAILED) throw std::bad_alloc();
    mapped = m;
    mapped_bytes = static_cast<size_t>(st.st_size);
    mapped_fd = window_fd;
  }
  void* map = mapped;
  // Threads for the decoding only where they pay: a box under 8 MiB is decoded on this thread (a thread
  // pool's start and its idle spinning after each request cost the helper more than such a box's
  // decoding; the fuzz target's boxes made the helper retire its walkers when a new pool's stacks
  // reached the walk's memory limit).
  const int threads = bytes >= double(8 << 20) ? r.threads : 1;
  const int64_t decoded = detail::own_chunks_decoded(), declined = detail::own_chunk_reads_declined();
  switch (t) {
    case MemoryType::u8: read_voxels(o, file, dataset, begin, size, static_cast<uint8_t*>(map), threads); break;
    case MemoryType::u16: read_voxels(o, file, dataset, begin, size, static_cast<uint16_t*>(map), threads); break;
    case MemoryType::u32: read_voxels(o, file, dataset, begin, size, static_cast<uint32_t*>(map), threads); break;
    case MemoryType::u64: read_voxels(o, file, dataset, begin, size, static_cast<uint64_t*>(map), threads); break;
    case MemoryType::i32: read_voxels(o, file, dataset, begin, size, static_cast<int32_t*>(map), threads); break;
    case MemoryType::f32: read_voxels(o, file, dataset, begin, size, static_cast<float*>(map), threads); break;
    case MemoryType::f64: read_voxels(o, file, dataset, begin, size, static_cast<double*>(map), threads); break;
  }
  const ReadAnswer a{detail::own_chunks_decoded() - decoded, detail::own_chunk_reads_declined() - declined};
  std::string out;
  put_value(out, a);
  return out;
}

}  // namespace

int serve_request(Request kind, const std::string& path, const std::string& dataset, const std::string& extra, int window_fd,
                  std::string& payload) {
  payload.clear();
  try {
    const fs::path file(path);
    switch (kind) {
      case Request::info: {  // the info, then why a whole read would be refused ("" when it would not)
        const Opened o = open_volume(file, dataset);
        payload = encode_info(volume_info(o, file, dataset));
        std::string refusal;
        try {
          check_whole_read(o, file, dataset);
        } catch (const InputError& e) {
          refusal = e.what();
        }
        put_string(payload, refusal);
        return probe::kWalkOk;
      }
      case Request::read: {
        ReadRequest r;
        if (extra.size() != sizeof r) throw Error("read request: malformed");
        std::memcpy(&r, extra.data(), sizeof r);
        payload = serve_read(path, dataset, r, window_fd);
        return probe::kWalkOk;
      }
      case Request::describe: payload = describe(file, nullptr); return probe::kWalkOk;
      case Request::string_attribute: {
        const Opened o = open_volume(file, dataset);
        payload = string_attribute(o, file, dataset, extra);
        return probe::kWalkOk;
      }
      case Request::walk: break;
    }
    throw Error("unknown request " + std::to_string(static_cast<uint32_t>(kind)));
  } catch (const InputError& e) {
    payload = e.what();
    return kRefused;
  } catch (const std::bad_alloc&) {
    payload.clear();
    return probe::kWalkOutOfMemory;
  } catch (const std::exception& e) {
    payload = e.what();
    return kFailed;
  }
}

}  // namespace skel::io::h5
