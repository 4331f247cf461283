#include "io/hdf5_volume.hpp"
#include "io/volume_format.hpp"

#include <hdf5.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <mutex>
#include <sstream>

#include "io/hdf5_chunks.hpp"
#include "io/hdf5_probe.hpp"
#include "io/hdf5_write_driver.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/out_of_core.hpp"
#include "skel/resume_io.hpp"
#include "skel/parallel.hpp"

namespace fs = std::filesystem;

namespace skel::io {

namespace {

std::mutex& hdf5_mutex() {
  static std::mutex m;
  return m;
}

// Turns off HDF5's own error printing once; we collect the stack ourselves.
// libhdf5's error printing off for the calling thread (Debian's libhdf5 is built thread-safe: its
// error settings are per thread, so a once-per-process call left other threads printing stacks).
void quiet() { detail::quiet_hdf5_errors_on_this_thread(); }

herr_t walk(unsigned n, const H5E_error2_t* e, void* data) {
  auto* s = static_cast<std::string*>(data);
  if (n == 0 && e && e->desc) *s = e->desc;  // the innermost problem
  return 0;
}

std::string hdf5_reason() {
  std::string s;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, walk, &s);
  H5Eclear2(H5E_DEFAULT);
  return s.empty() ? std::string() : " (HDF5: " + s + ")";
}

// RAII handle.
struct Handle {
  hid_t id = -1;
  herr_t (*close)(hid_t) = nullptr;
  Handle() = default;
  Handle(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) {}
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& o) noexcept : id(o.id), close(o.close) { o.id = -1; }
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      if (id >= 0 && close) close(id);
      id = o.id;
      close = o.close;
      o.id = -1;
    }
    return *this;
  }
  ~Handle() {
    if (id >= 0 && close) close(id);
  }
  explicit operator bool() const { return id >= 0; }
  // Closes now and reports whether that worked (the destructor cannot).
  bool close_now() {
    const hid_t i = id;
    id = -1;
    return i < 0 || !close || close(i) >= 0;
  }
};

[[noreturn]] void fail(const fs::path& file, const std::string& what) {
  throw InputError(display_path(file).string() + ": " + what + hdf5_reason());
}

// A failed write: a failure while running (Error), naming the file the user asked for (not the
// temporary it is written under) and the OS's reason when the driver saw one.
[[noreturn]] void fail_write(const fs::path& file, const std::string& what) {
  const int err = detail::first_write_errno();
  const std::string hdf5 = hdf5_reason();
  throw Error("cannot write " + display_path(file).string() + ": " + what + ": " +
              (err != 0 ? std::string(std::strerror(err)) : hdf5.empty() ? std::string("HDF5 error") : hdf5.substr(2, hdf5.size() - 3)));
}

// Opens `file`. A user's file opened for reading is first walked by the structure probe
// (hdf5_probe.hpp: libhdf5 crashes on some corrupt files) together with the lookup of `dataset`;
// files opened for writing are Skelflow's own outputs and are not probed. Caller holds the mutex.
Handle open_file(const fs::path& file, bool write = false, const std::string& dataset = {}) {
  std::error_code ec;
  if (!fs::exists(file, ec)) throw InputError(file.string() + ": file not found");
  if (fs::is_directory(file, ec)) throw InputError(file.string() + ": is a folder, not an HDF5 file");
  if (!write) probe_hdf5_file(file, dataset);
  const htri_t is = H5Fis_hdf5(file.c_str());
  if (is <= 0) fail(file, "not an HDF5 file, or the file is truncated or corrupt");
  Handle fapl(write ? detail::safe_write_fapl() : H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  Handle f(H5Fopen(file.c_str(), write ? H5F_ACC_RDWR : H5F_ACC_RDONLY, fapl.id), H5Fclose);
  if (!f) fail(file, "cannot open as HDF5: the file is truncated or corrupt");
  return f;
}

herr_t collect_dataset(hid_t, const char* name, const H5O_info_t* info, void* data) {
  if (info->type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(std::string("/") + name);
  return 0;
}

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

struct Opened {
  Handle file, dset, space;
  Dims dims{0, 0, 0};
  std::string dtype;
};

Opened open_volume(const fs::path& file, const std::string& dataset, bool write = false) {
  Opened o;
  o.file = open_file(file, write, dataset);
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

// The attribute probe::kAttributeNames[index] of `object` (open as `obj`): the structure probe's
// reading when it is on (hdf5_probe.hpp: libhdf5 1.10.8 can read out of bounds while it decodes a
// damaged attribute message, so that decoding happens in the probe's process, not here), else
// libhdf5's in this process. Caller holds the mutex.
probe::Attribute attribute(hid_t obj, const std::string& object, size_t index, const fs::path& file) {
  probe::Attribute a;
  if (!probed_attribute(file, object, index, a)) a = probe::read_attribute(obj, index);
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
struct Geometry {
  Vec3 spacing{1, 1, 1}, origin{0, 0, 0};
  std::string unit = kDefaultUnit;
  bool has_spacing = false, has_origin = false, has_unit = false;
};

Geometry read_geometry(hid_t file_id, hid_t dset, const std::string& dataset, const fs::path& file) {
  Geometry g;
  g.has_spacing = read_vec3_attr(dset, dataset, kSpacing, g.spacing, file);
  g.has_origin = read_vec3_attr(dset, dataset, kOrigin, g.origin, file);
  g.has_unit = read_string_attr(dset, dataset, kUnit, g.unit, file);
  if (!g.has_spacing) {
    Vec3 zyx{1, 1, 1};
    bool found = read_vec3_attr(dset, dataset, kElementSize, zyx, file);
    if (!found) {
      std::string group = dataset.substr(0, dataset.rfind('/'));
      if (group.empty()) group = "/";
      Handle grp(H5Oopen(file_id, group.c_str(), H5P_DEFAULT), H5Oclose);
      H5Eclear2(H5E_DEFAULT);
      if (grp) found = read_vec3_attr(grp.id, group, kElementSize, zyx, file);
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
  return g;
}

template <class T> hid_t native();
template <> hid_t native<uint8_t>() { return H5T_NATIVE_UINT8; }
template <> hid_t native<uint16_t>() { return H5T_NATIVE_UINT16; }
template <> hid_t native<uint32_t>() { return H5T_NATIVE_UINT32; }
template <> hid_t native<uint64_t>() { return H5T_NATIVE_UINT64; }
template <> hid_t native<int32_t>() { return H5T_NATIVE_INT32; }
template <> hid_t native<float>() { return H5T_NATIVE_FLOAT; }
template <> hid_t native<double>() { return H5T_NATIVE_DOUBLE; }

template <class T>
Volume<T> read_into(Opened& o, const fs::path& file, const std::string& dataset, Dims begin, Dims size, int threads = 0) {
  Grid g(size);
  const Geometry geo = read_geometry(o.file.id, o.dset.id, dataset, file);
  const Vec3& sp = geo.spacing;
  const Vec3& org = geo.origin;
  g.spacing = sp;
  g.unit = geo.unit;
  g.origin = {org[0] + static_cast<double>(begin[0]) * sp[0], org[1] + static_cast<double>(begin[1]) * sp[1],
              org[2] + static_cast<double>(begin[2]) * sp[2]};
  Volume<T> v = Volume<T>::uninitialized(g);
  if (v.size() == 0) return v;
  // Chunked datasets with shuffle / deflate / Fletcher32: our own decoding (hdf5_chunks.hpp), which
  // refuses a damaged chunk instead of letting libhdf5 overrun a buffer; anything else: H5Dread.
  if (detail::read_chunked_box<T>(o.dset.id, file, dataset, o.dims, begin, size, v.data(), threads)) return v;
  hsize_t start[3] = {static_cast<hsize_t>(begin[2]), static_cast<hsize_t>(begin[1]), static_cast<hsize_t>(begin[0])};
  hsize_t count[3] = {static_cast<hsize_t>(size[2]), static_cast<hsize_t>(size[1]), static_cast<hsize_t>(size[0])};
  if (H5Sselect_hyperslab(o.space.id, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    fail(file, "invalid box for dataset '" + dataset + "'");
  Handle mem(H5Screate_simple(3, count, nullptr), H5Sclose);
  if (H5Dread(o.dset.id, native<T>(), mem.id, o.space.id, H5P_DEFAULT, v.data()) < 0)
    fail(file, "cannot read dataset '" + dataset + "': the file is truncated or corrupt");
  return v;
}

}  // namespace

VolumeInfo read_volume_info(const fs::path& file, const std::string& dataset) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  VolumeInfo info;
  info.dims = o.dims;
  info.dtype = o.dtype;
  const Geometry geo = read_geometry(o.file.id, o.dset.id, dataset, file);
  info.spacing = geo.spacing;
  info.origin = geo.origin;
  info.unit = geo.unit;
  info.has_spacing = geo.has_spacing;
  info.has_origin = geo.has_origin;
  info.has_unit = geo.has_unit;
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
  return info;
}

namespace {

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

// The dims a file declares are checked against the data it holds before the volume is allocated, so
// a corrupt or hostile 4 KB file cannot make Skelflow allocate terabytes. Unfiltered data must be
// all there; deflate cannot compress better than 1032:1 (shuffle and fletcher32 add nothing), so a
// compressed dataset may declare at most ~1100 times what it stores. Filters this HDF5 cannot decode
// are refused here too, instead of after the allocation.
void check_declared_size(const Opened& o, const fs::path& file, const std::string& dataset) {
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

}  // namespace

DataPtr read_volume(const fs::path& file, const std::string& dataset, int threads) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  if (o.dims[0] == 0 || o.dims[1] == 0 || o.dims[2] == 0)
    throw InputError(file.string() + ": dataset '" + dataset + "' is empty (" + std::to_string(o.dims[0]) + "x" +
                     std::to_string(o.dims[1]) + "x" + std::to_string(o.dims[2]) +
                     " voxels as x,y,z); a volume needs at least one voxel on every axis");
  check_declared_size(o, file, dataset);
  const Dims z{0, 0, 0};
  const std::string& t = o.dtype;
  if (t == "uint8") return std::make_shared<VolumeU8>(read_into<uint8_t>(o, file, dataset, z, o.dims, threads));
  if (t == "uint16") return std::make_shared<VolumeU16>(read_into<uint16_t>(o, file, dataset, z, o.dims, threads));
  if (t == "uint32") return std::make_shared<VolumeU32>(read_into<uint32_t>(o, file, dataset, z, o.dims, threads));
  if (t == "uint64") return std::make_shared<VolumeU64>(read_into<uint64_t>(o, file, dataset, z, o.dims, threads));
  if (t == "int8" || t == "int16" || t == "int32")
    return std::make_shared<VolumeI32>(read_into<int32_t>(o, file, dataset, z, o.dims, threads));
  if (t == "float32") return std::make_shared<VolumeF32>(read_into<float>(o, file, dataset, z, o.dims, threads));
  return std::make_shared<VolumeF64>(read_into<double>(o, file, dataset, z, o.dims, threads));  // float64, int64
}

template <class T>
Volume<T> read_box(const fs::path& file, const std::string& dataset, Dims begin, Dims size) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  for (int k = 0; k < 3; ++k)
    if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > o.dims[k])
      throw InputError(file.string() + ": box outside dataset '" + dataset + "'");
  return read_into<T>(o, file, dataset, begin, size);
}
template Volume<uint8_t> read_box(const fs::path&, const std::string&, Dims, Dims);
template Volume<uint16_t> read_box(const fs::path&, const std::string&, Dims, Dims);
template Volume<uint32_t> read_box(const fs::path&, const std::string&, Dims, Dims);
template Volume<uint64_t> read_box(const fs::path&, const std::string&, Dims, Dims);
template Volume<int32_t> read_box(const fs::path&, const std::string&, Dims, Dims);
template Volume<float> read_box(const fs::path&, const std::string&, Dims, Dims);
template Volume<double> read_box(const fs::path&, const std::string&, Dims, Dims);

std::array<int64_t, 3> automatic_chunks(Dims dims, int64_t bytes_per_voxel) {
  // About 1 MiB per chunk, as close to a cube as the dims allow, with power-of-two edges
  // (uint8: 128x128x64, uint16: 128x128x32, float32: 64x64x64, float64: 64x64x32). Large chunks keep
  // whole-volume reads fast (HDF5's small automatic chunks read at ~300 MB/s), cube-like ones keep
  // block reads of the out-of-core algorithms cheap: an aligned 64³ box touches one or two chunks
  // instead of 64 whole-slice chunks.
  const int64_t nx = std::max<int64_t>(dims[0], 1), ny = std::max<int64_t>(dims[1], 1), nz = std::max<int64_t>(dims[2], 1);
  const int64_t target = std::max<int64_t>((int64_t{1} << 20) / std::max<int64_t>(bytes_per_voxel, 1), 1);
  const auto side = static_cast<int64_t>(std::bit_ceil(static_cast<uint64_t>(std::max(1.0, std::floor(std::cbrt(static_cast<double>(target)) + 1e-9)))));
  const int64_t cx = std::min(nx, side);
  const int64_t cy = std::clamp<int64_t>(target / cx, 1, std::min(ny, side));
  const int64_t cz = std::clamp<int64_t>(target / (cx * cy), 1, nz);
  return {cx, cy, cz};
}

namespace {

hid_t native_of(const std::string& dtype) {
  if (dtype == "uint8") return H5T_NATIVE_UINT8;
  if (dtype == "uint16") return H5T_NATIVE_UINT16;
  if (dtype == "uint32") return H5T_NATIVE_UINT32;
  if (dtype == "uint64") return H5T_NATIVE_UINT64;
  if (dtype == "int32") return H5T_NATIVE_INT32;
  if (dtype == "float32") return H5T_NATIVE_FLOAT;
  if (dtype == "float64") return H5T_NATIVE_DOUBLE;
  throw InputError("unsupported voxel type '" + dtype + "' (uint8, uint16, uint32, uint64, int32, float32, float64)");
}

void check_write_args(const std::string& dataset, const WriteOptions& opt) {
  if (opt.compression < 0 || opt.compression > 9)
    throw InputError("compression must be 0..9, got " + std::to_string(opt.compression));
  if (dataset.empty() || dataset[0] != '/') throw InputError("dataset name '" + dataset + "' must start with '/'");
  for (int k = 0; k < 3; ++k)
    if (opt.chunks[k] < 0) throw InputError("chunk sizes must be >= 0 (0 = automatic)");
}

// Creates `file` (truncating) holding an empty chunked dataset with spacing/origin attributes.
// Caller holds the mutex.
std::pair<Handle, Handle> create_dataset(const fs::path& file, const std::string& dataset, hid_t type, const Grid& g,
                                         const WriteOptions& opt) {
  Handle fapl(detail::safe_write_fapl(), H5Pclose);
  Handle f(H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id), H5Fclose);
  if (!f) fail_write(file, "cannot create the file");
  const Dims& n = g.dims;
  const hsize_t dims[3] = {static_cast<hsize_t>(n[2]), static_cast<hsize_t>(n[1]), static_cast<hsize_t>(n[0])};
  Handle space(H5Screate_simple(3, dims, nullptr), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_obj_track_times(dcpl.id, 0);  // no modification times: the same volume gives the same bytes
  const size_t elem = H5Tget_size(type);
  if (g.voxel_count() > 0) {
    std::array<int64_t, 3> c = automatic_chunks(n, static_cast<int64_t>(elem));
    if (opt.chunks[0] > 0 && opt.chunks[1] > 0 && opt.chunks[2] > 0)
      for (int k = 0; k < 3; ++k) c[k] = std::min(opt.chunks[k], n[k]);
    const hsize_t hc[3] = {static_cast<hsize_t>(c[2]), static_cast<hsize_t>(c[1]), static_cast<hsize_t>(c[0])};
    H5Pset_chunk(dcpl.id, 3, hc);
    H5Pset_fill_time(dcpl.id, H5D_FILL_TIME_IFSET);  // no fill pass before our own writes
    if (opt.compression > 0) {
      if (elem > 1) H5Pset_shuffle(dcpl.id);
      H5Pset_deflate(dcpl.id, static_cast<unsigned>(opt.compression));
    }
  }
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  H5Pset_create_intermediate_group(lcpl.id, 1);
  Handle d(H5Dcreate2(f.id, dataset.c_str(), type, space.id, lcpl.id, dcpl.id, H5P_DEFAULT), H5Dclose);
  if (!d) fail_write(file, "cannot create dataset '" + dataset + "'");
  for (const auto& [name, val] : {std::pair{"spacing", g.spacing}, std::pair{"origin", g.origin}}) {
    const hsize_t three = 3;
    Handle as(H5Screate_simple(1, &three, nullptr), H5Sclose);
    Handle a(H5Acreate2(d.id, name, H5T_IEEE_F64LE, as.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!a || H5Awrite(a.id, H5T_NATIVE_DOUBLE, val.data()) < 0) fail_write(file, std::string("cannot write attribute ") + name);
  }
  {
    Handle st(H5Tcopy(H5T_C_S1), H5Tclose);
    H5Tset_size(st.id, std::max<size_t>(g.unit.size(), 1));
    H5Tset_cset(st.id, H5T_CSET_UTF8);
    Handle as(H5Screate(H5S_SCALAR), H5Sclose);
    Handle a(H5Acreate2(d.id, "unit", st.id, as.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    std::string u = g.unit;
    u.resize(std::max<size_t>(u.size(), 1));
    if (!a || H5Awrite(a.id, st.id, u.data()) < 0) fail_write(file, "cannot write attribute unit");
  }
  return {std::move(f), std::move(d)};
}

// HDF5's shuffle filter (H5Z_filter_shuffle): byte j of element i goes to position j * n + i.
template <size_t S>
void shuffle_bytes(const unsigned char* src, unsigned char* dst, size_t n) {
  for (size_t j = 0; j < S; ++j) {
    unsigned char* d = dst + j * n;
    const unsigned char* p = src + j;
    for (size_t i = 0; i < n; ++i) d[i] = p[i * S];
  }
}

// Writes `v` into the chunked, deflate-filtered dataset `d` by compressing the chunks ourselves on
// `threads` threads and storing them with H5Dwrite_chunk (filter mask 0: every filter applied). The
// chunk bytes are what HDF5's pipeline produces: the chunk in dataset order ([z][y][x], x fastest),
// full-size with the part outside the dataset zero (HDF5 stores edge chunks full-size), shuffled
// for multi-byte types, then zlib compress2 at the dataset's level, exactly as H5Z_filter_deflate.
// Chunks are compressed in batches and written in chunk order by the calling thread (which holds
// the HDF5 mutex; the workers call no HDF5 function). Caller holds the mutex.
// `v` may be a band of the dataset starting at `at` (on chunk boundaries, ending on chunk boundaries
// or at the dataset's end): only its chunks are written.
template <class T>
void write_compressed_chunks(hid_t d, const Volume<T>& v, int level, int threads, const fs::path& file,
                             const std::string& dataset, const Dims& at = Dims{0, 0, 0}) {
  Handle dcpl(H5Dget_create_plist(d), H5Pclose);
  hsize_t hc[3];
  if (H5Pget_chunk(dcpl.id, 3, hc) != 3) fail(file, "cannot read the chunk shape of dataset '" + dataset + "'");
  const int64_t cx = static_cast<int64_t>(hc[2]), cy = static_cast<int64_t>(hc[1]), cz = static_cast<int64_t>(hc[0]);
  const int64_t nx = v.nx(), ny = v.ny(), nz = v.nz();
  const int64_t gx = (nx + cx - 1) / cx, gy = (ny + cy - 1) / cy, gz = (nz + cz - 1) / cz;
  const int64_t total = gx * gy * gz;
  const size_t elems = static_cast<size_t>(cx * cy * cz), bytes = elems * sizeof(T);
  const uLong bound = compressBound(static_cast<uLong>(bytes));
  threads = effective_threads(threads);
  const int64_t batch = std::min<int64_t>(total, int64_t{8} * threads);
  std::vector<std::vector<unsigned char>> out(static_cast<size_t>(batch));
  std::vector<uLongf> out_size(static_cast<size_t>(batch));
  for (int64_t first = 0; first < total; first += batch) {
    const int64_t count = std::min(batch, total - first);
    parallel_for(0, count, threads, [&](int64_t b, int64_t e) {
      std::vector<T> raw(elems);
      std::vector<unsigned char> shuffled(sizeof(T) > 1 ? bytes : 0);
      for (int64_t k = b; k < e; ++k) {
        const int64_t c = first + k;
        const int64_t x0 = (c % gx) * cx, y0 = (c / gx % gy) * cy, z0 = (c / (gx * gy)) * cz;
        const int64_t wx = std::min(cx, nx - x0), wy = std::min(cy, ny - y0), wz = std::min(cz, nz - z0);
        if (wx < cx || wy < cy || wz < cz) std::fill(raw.begin(), raw.end(), T{});
        for (int64_t z = 0; z < wz; ++z)
          for (int64_t y = 0; y < wy; ++y)
            std::memcpy(raw.data() + (z * cy + y) * cx, v.data() + v.index(x0, y0 + y, z0 + z),
                        static_cast<size_t>(wx) * sizeof(T));
        const auto* src = reinterpret_cast<const unsigned char*>(raw.data());
        if constexpr (sizeof(T) > 1) {
          shuffle_bytes<sizeof(T)>(src, shuffled.data(), elems);
          src = shuffled.data();
        }
        auto& o = out[static_cast<size_t>(k)];
        o.resize(bound);
        uLongf n = bound;
        if (compress2(o.data(), &n, src, static_cast<uLong>(bytes), level) != Z_OK)
          throw InputError(file.string() + ": cannot compress a chunk of dataset '" + dataset + "' (out of memory?)");
        out_size[static_cast<size_t>(k)] = n;
      }
    });
    for (int64_t k = 0; k < count; ++k) {
      const int64_t c = first + k;
      const hsize_t offset[3] = {static_cast<hsize_t>(at[2] + (c / (gx * gy)) * cz),
                                 static_cast<hsize_t>(at[1] + (c / gx % gy) * cy),
                                 static_cast<hsize_t>(at[0] + (c % gx) * cx)};
      if (H5Dwrite_chunk(d, H5P_DEFAULT, 0, offset, out_size[static_cast<size_t>(k)], out[static_cast<size_t>(k)].data()) < 0)
        fail_write(file, "dataset '" + dataset + "'");
    }
  }
}

}  // namespace

void write_volume(const fs::path& file, const DataObject& volume, const std::string& dataset, const WriteOptions& opt) {
  check_write_args(dataset, opt);
  visit_volume(volume, "volume", [&](const auto& v) {
    using T = typename std::decay_t<decltype(v)>::value_type;
    write_atomically(file, [&](const fs::path& tmp) {
      std::lock_guard lock(hdf5_mutex());
      quiet();
      auto [f, d] = create_dataset(tmp, dataset, native<T>(), v.grid(), opt);
      if (v.size() > 0 && opt.compression > 0)
        write_compressed_chunks(d.id, v, opt.compression, opt.threads, file, dataset);
      else if (v.size() > 0 && H5Dwrite(d.id, native<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
        fail_write(file, "dataset '" + dataset + "'");
      if (H5Fflush(f.id, H5F_SCOPE_GLOBAL) < 0) fail_write(file, "dataset '" + dataset + "'");
      // Closed here so that a failure is reported; the flush above leaves close little to write.
      if (!d.close_now() || !f.close_now() || detail::first_write_errno() != 0) fail_write(file, "dataset '" + dataset + "'");
    });
  });
}

void write_volume_boxes(const fs::path& file, const VolumeBoxSource& source, const std::string& dataset,
                        const WriteOptions& opt) {
  check_write_args(dataset, opt);
  source.grid.validate();
  visit_voxel_type(source.type_id, "volume", [&](auto t) {
    using T = decltype(t);
    const Dims n = source.grid.dims;
    write_atomically(file, [&](const fs::path& tmp) {
      std::unique_lock lock(hdf5_mutex());  // destroyed after the handles: they close under the lock
      quiet();
      auto [f, d] = create_dataset(tmp, dataset, native<T>(), source.grid, opt);
      if (source.grid.voxel_count() > 0) {
        Handle dcpl(H5Dget_create_plist(d.id), H5Pclose);
        hsize_t hc[3];
        if (H5Pget_chunk(dcpl.id, 3, hc) != 3) fail(file, "cannot read the chunk shape of dataset '" + dataset + "'");
        const int64_t cy = static_cast<int64_t>(hc[1]), cz = static_cast<int64_t>(hc[0]);
        // Bands of whole x-rows of chunks, in the dataset's chunk order (the file write_volume makes).
        const int64_t rows = units_per_box(source, static_cast<uint64_t>(n[0] * cy * cz) * sizeof(T), (n[1] + cy - 1) / cy);
        for (int64_t z0 = 0; z0 < n[2]; z0 += cz)
          for (int64_t y0 = 0; y0 < n[1]; y0 += rows * cy) {
            const Dims begin{0, y0, z0}, size{n[0], std::min(rows * cy, n[1] - y0), std::min(cz, n[2] - z0)};
            DataPtr box;
            lock.unlock();  // the source may be an HDF5 scratch file: it takes the mutex itself
            try {
              box = source.read(begin, size);
            } catch (...) {
              lock.lock();
              throw;
            }
            lock.lock();
            const auto* v = dynamic_cast<const Volume<T>*>(box.get());
            if (!v || v->dims() != size) throw Error(file.string() + ": the volume's box reader gave no " + VoxelTraits<T>::id + " box");
            if (opt.compression > 0) {
              write_compressed_chunks(d.id, *v, opt.compression, opt.threads, file, dataset, begin);
              continue;
            }
            Handle space(H5Dget_space(d.id), H5Sclose);
            const hsize_t start[3] = {static_cast<hsize_t>(z0), static_cast<hsize_t>(y0), 0};
            const hsize_t count[3] = {static_cast<hsize_t>(size[2]), static_cast<hsize_t>(size[1]), static_cast<hsize_t>(size[0])};
            if (H5Sselect_hyperslab(space.id, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
              fail(file, "invalid box for dataset '" + dataset + "'");
            Handle mem(H5Screate_simple(3, count, nullptr), H5Sclose);
            if (H5Dwrite(d.id, native<T>(), mem.id, space.id, H5P_DEFAULT, v->data()) < 0)
              fail_write(file, "dataset '" + dataset + "'");
          }
      }
      if (H5Fflush(f.id, H5F_SCOPE_GLOBAL) < 0) fail_write(file, "dataset '" + dataset + "'");
      if (!d.close_now() || !f.close_now() || detail::first_write_errno() != 0) fail_write(file, "dataset '" + dataset + "'");
    });
  });
}

void create_volume_dataset(const fs::path& file, const std::string& dataset, const std::string& dtype, const Grid& grid,
                           const WriteOptions& opt) {
  check_write_args(dataset, opt);
  grid.validate();
  const hid_t type = native_of(dtype);
  std::lock_guard lock(hdf5_mutex());
  quiet();
  auto fd = create_dataset(file, dataset, type, grid, opt);
  if (H5Fflush(fd.first.id, H5F_SCOPE_GLOBAL) < 0) fail_write(file, "dataset '" + dataset + "'");
}

template <class T>
void write_box(const fs::path& file, const std::string& dataset, const Volume<T>& block, Dims begin) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset, true);
  for (int k = 0; k < 3; ++k)
    if (begin[k] < 0 || begin[k] + block.dims()[k] > o.dims[k])
      throw InputError(file.string() + ": block at (" + std::to_string(begin[0]) + ", " + std::to_string(begin[1]) + ", " +
                       std::to_string(begin[2]) + ") of size " + std::to_string(block.nx()) + "x" +
                       std::to_string(block.ny()) + "x" + std::to_string(block.nz()) + " is outside dataset '" +
                       dataset + "' (" + std::to_string(o.dims[0]) + "x" + std::to_string(o.dims[1]) + "x" +
                       std::to_string(o.dims[2]) + ")");
  if (block.size() == 0) return;
  hsize_t start[3] = {static_cast<hsize_t>(begin[2]), static_cast<hsize_t>(begin[1]), static_cast<hsize_t>(begin[0])};
  hsize_t count[3] = {static_cast<hsize_t>(block.nz()), static_cast<hsize_t>(block.ny()), static_cast<hsize_t>(block.nx())};
  if (H5Sselect_hyperslab(o.space.id, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
    fail(file, "invalid box for dataset '" + dataset + "'");
  Handle mem(H5Screate_simple(3, count, nullptr), H5Sclose);
  if (H5Dwrite(o.dset.id, native<T>(), mem.id, o.space.id, H5P_DEFAULT, block.data()) < 0)
    fail_write(file, "dataset '" + dataset + "'");
  if (H5Fflush(o.file.id, H5F_SCOPE_GLOBAL) < 0) fail_write(file, "dataset '" + dataset + "'");
}
template void write_box(const fs::path&, const std::string&, const Volume<uint8_t>&, Dims);
template void write_box(const fs::path&, const std::string&, const Volume<uint16_t>&, Dims);
template void write_box(const fs::path&, const std::string&, const Volume<uint32_t>&, Dims);
template void write_box(const fs::path&, const std::string&, const Volume<uint64_t>&, Dims);
template void write_box(const fs::path&, const std::string&, const Volume<int32_t>&, Dims);
template void write_box(const fs::path&, const std::string&, const Volume<float>&, Dims);
template void write_box(const fs::path&, const std::string&, const Volume<double>&, Dims);

std::string describe_file(const fs::path& file) {
  std::vector<std::string> names;
  {
    std::lock_guard lock(hdf5_mutex());
    quiet();
    Handle f = open_file(file);
    names = list_datasets(f.id);
  }
  std::ostringstream s;
  if (names.empty()) s << "  (no datasets)\n";
  for (const auto& n : names) {
    try {
      const VolumeInfo i = read_volume_info(file, n);
      s << "  " << n << ": " << i.dtype << " " << i.dims[0] << "x" << i.dims[1] << "x" << i.dims[2] << " (x,y,z)";
      if (i.chunks[0]) s << ", chunks " << i.chunks[0] << "x" << i.chunks[1] << "x" << i.chunks[2];
      for (const auto& fl : i.filters) s << ", " << fl;
      s << ", spacing " << i.spacing[0] << " " << i.spacing[1] << " " << i.spacing[2] << " " << i.unit
        << (i.has_spacing ? "" : " (default)");
      s << ", origin " << i.origin[0] << " " << i.origin[1] << " " << i.origin[2] << " " << i.unit
        << (i.has_unit ? "" : " (unit: default)") << "\n";
      const std::string enc = read_string_attribute(file, n, "encoding");
      if (!enc.empty()) s << "    encoding: " << enc << "\n";
    } catch (const InputError& e) {
      s << "  " << n << ": " << e.what() << "\n";
    }
  }
  return s.str();
}



void write_string_attribute(const fs::path& file, const std::string& dataset, const std::string& name,
                            const std::string& value) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Handle f = open_file(file, true);
  Handle d = open_dataset(f.id, file, dataset);
  Handle st(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(st.id, std::max<size_t>(value.size(), 1));
  H5Tset_cset(st.id, H5T_CSET_UTF8);
  Handle as(H5Screate(H5S_SCALAR), H5Sclose);
  Handle a(H5Acreate2(d.id, name.c_str(), st.id, as.id, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  std::string v = value;
  v.resize(std::max<size_t>(v.size(), 1));
  if (!a || H5Awrite(a.id, st.id, v.data()) < 0) fail_write(file, "cannot write attribute " + name);
  if (!a.close_now() || !d.close_now() || !f.close_now()) fail_write(file, "cannot close the file");
}

std::string read_string_attribute(const fs::path& file, const std::string& dataset, const std::string& name) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Handle f = open_file(file, false, dataset);
  Handle d = open_dataset(f.id, file, dataset);
  std::string out;
  const auto* names = std::begin(probe::kAttributeNames);
  const auto at = std::find_if(names, std::end(probe::kAttributeNames), [&](const char* n) { return name == n; });
  if (at == std::end(probe::kAttributeNames) || !probe::is_string_attribute(static_cast<size_t>(at - names)))
    throw Error("read_string_attribute: '" + name + "' is not one of the string attributes the readers read");
  read_string_attr(d.id, dataset, static_cast<size_t>(at - names), out, file);
  return out;
}

// ---------------------------------------------------------------- scratch volumes (out-of-core)
namespace {

const char* dtype_of_type_id(const std::string& type_id) {
  if (type_id == type_ids::volume_u8) return "uint8";
  if (type_id == type_ids::volume_u16) return "uint16";
  if (type_id == type_ids::volume_u32) return "uint32";
  if (type_id == type_ids::volume_u64) return "uint64";
  if (type_id == type_ids::volume_i32) return "int32";
  if (type_id == type_ids::volume_f32) return "float32";
  if (type_id == type_ids::volume_f64) return "float64";
  throw Error("scratch volume: '" + type_id + "' is not a volume type");
}

// An uncompressed, chunked HDF5 file holding one dataset, open for the store's lifetime; removed
// when the store is destroyed.
class Hdf5ScratchStore final : public VolumeStore {
public:
  Hdf5ScratchStore(const fs::path& file, const std::string& type_id, const Grid& grid, const Dims& chunk)
      : file_(file), type_(native_of(dtype_of_type_id(type_id))) {
    grid.validate();
    WriteOptions opt;
    opt.compression = 0;
    for (int k = 0; k < 3; ++k) opt.chunks[k] = std::max<int64_t>(1, chunk[k]);
    std::lock_guard lock(hdf5_mutex());
    quiet();
    // HDF5 keeps freed chunk buffers on free lists that never shrink (hundreds of MiB after a pass
    // over a large volume): under a memory budget they are limited to a few MiB.
    static std::once_flag limits;
    std::call_once(limits, [] { H5set_free_list_limits(1 << 20, 1 << 18, 1 << 20, 1 << 18, 4 << 20, 1 << 20); });
    try {
      auto [f, d] = create_dataset(file_, kDataset, type_, grid, opt);
      file_handle_ = std::move(f);
      d = Handle();
      // Reopened with a 16 MiB chunk cache, so that writing a block just read does not read its edge
      // chunks from the file again (HDF5's default cache, 1 MiB, made the 256³ bench 14x slower).
      // 521 slots and w0 = 0.75: with 10007 slots and w0 = 1 this HDF5 (1.10) let the cache grow to
      // half of a 1 GiB dataset (a 512³ components run: 700 instead of 280 MiB peak).
      Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
      H5Pset_chunk_cache(dapl.id, 521, kChunkCacheBytes, 0.75);
      dset_ = Handle(H5Dopen2(file_handle_.id, kDataset, dapl.id), H5Dclose);
      if (!dset_) fail_write(file_, "cannot open the scratch dataset");
    } catch (...) {
      std::error_code ec;
      fs::remove(file_, ec);
      throw;
    }
  }
  // Opens a flushed scratch file or one written by write_volume (resumed runs), read-only; removed
  // when the store is destroyed, as a new one.
  Hdf5ScratchStore(const fs::path& file, const std::string& type_id) : file_(file), type_(native_of(dtype_of_type_id(type_id))) {
    std::lock_guard lock(hdf5_mutex());
    quiet();
    file_handle_ = Handle(H5Fopen(file_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file_handle_) throw Error("cannot open the resumed scratch file " + file_.string() + hdf5_reason());
    Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
    H5Pset_chunk_cache(dapl.id, 521, kChunkCacheBytes, 0.75);
    dset_ = Handle(H5Dopen2(file_handle_.id, kDataset, dapl.id), H5Dclose);
    if (!dset_) throw Error("cannot open the resumed scratch file " + file_.string() + hdf5_reason());
  }
  // Data and metadata to disk.
  void flush() const {
    std::lock_guard lock(hdf5_mutex());
    if (H5Fflush(file_handle_.id, H5F_SCOPE_GLOBAL) < 0) fail_write(file_, "scratch data");
  }
  ~Hdf5ScratchStore() override {
    {
      std::lock_guard lock(hdf5_mutex());
      dset_ = Handle();
      file_handle_ = Handle();
    }
    std::error_code ec;
    fs::remove(file_, ec);
  }
  void read(const Dims& begin, const Dims& size, void* out) const override {
    std::lock_guard lock(hdf5_mutex());
    Handle mem, space;
    select(begin, size, mem, space);
    if (H5Dread(dset_.id, type_, mem.id, space.id, H5P_DEFAULT, out) < 0)
      throw Error("cannot read the scratch file " + file_.string() + hdf5_reason());
  }
  void write(const Dims& begin, const Dims& size, const void* in) override {
    std::lock_guard lock(hdf5_mutex());
    Handle mem, space;
    select(begin, size, mem, space);
    if (H5Dwrite(dset_.id, type_, mem.id, space.id, H5P_DEFAULT, in) < 0) fail_write(file_, "scratch data");
  }
  [[nodiscard]] const fs::path& file() const override { return file_; }

private:
  static constexpr const char* kDataset = "/volume";
  static constexpr size_t kChunkCacheBytes = size_t{16} << 20;
  void select(const Dims& begin, const Dims& size, Handle& mem, Handle& space) const {
    const hsize_t start[3] = {static_cast<hsize_t>(begin[2]), static_cast<hsize_t>(begin[1]), static_cast<hsize_t>(begin[0])};
    const hsize_t count[3] = {static_cast<hsize_t>(size[2]), static_cast<hsize_t>(size[1]), static_cast<hsize_t>(size[0])};
    space = Handle(H5Dget_space(dset_.id), H5Sclose);
    if (!space || H5Sselect_hyperslab(space.id, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0)
      throw Error("scratch file " + file_.string() + ": invalid box" + hdf5_reason());
    mem = Handle(H5Screate_simple(3, count, nullptr), H5Sclose);
  }
  fs::path file_;
  hid_t type_;
  Handle file_handle_, dset_;
};

// Registers the HDF5 scratch store with the framework (skel/out_of_core.hpp) at start-up, and the
// saving, flushing and reopening of stage volumes for resumed runs (skel/resume_io.hpp).
const bool kScratchStoreRegistered = [] {
  register_volume_store_factory([](const fs::path& file, const std::string& type_id, const Grid& grid, const Dims& chunk) {
    return create_scratch_store(file, type_id, grid, chunk);
  });
  ResumeVolumeIo io;
  io.save = [](const fs::path& file, const DataObject& volume) {
    WriteOptions o;
    o.compression = 0;
    write_volume(file, volume, "/volume", o);
  };
  io.flush = [](const VolumeStore& store) {
    if (const auto* h = dynamic_cast<const Hdf5ScratchStore*>(&store)) h->flush();
  };
  io.open = [](const fs::path& file, const std::string& type_id, const Grid& grid) {
    const VolumeInfo i = read_volume_info(file, "/volume");
    if (i.dims != grid.dims || i.dtype != dtype_of_type_id(type_id))
      throw Error(file.string() + ": holds " + i.dtype + " " + std::to_string(i.dims[0]) + "x" + std::to_string(i.dims[1]) +
                  "x" + std::to_string(i.dims[2]) + ", not the " + type_id + " volume the resume manifest names");
    return std::make_shared<ChunkedVolume>(grid, type_id, std::make_shared<Hdf5ScratchStore>(file, type_id));
  };
  register_resume_volume_io(std::move(io));
  return true;
}();

}  // namespace

std::shared_ptr<VolumeStore> create_scratch_store(const fs::path& file, const std::string& type_id, const Grid& grid,
                                                  const Dims& chunk) {
  (void)kScratchStoreRegistered;
  return std::make_shared<Hdf5ScratchStore>(file, type_id, grid, chunk);
}

}  // namespace skel::io
