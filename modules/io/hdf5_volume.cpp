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
#include "io/hdf5_read.hpp"
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

// libhdf5's error printing off for the calling thread (Debian's libhdf5 is built thread-safe: its
// error settings are per thread, so a once-per-process call left other threads printing stacks).
void quiet() { detail::quiet_hdf5_errors_on_this_thread(); }

using h5::fail;
using h5::Handle;
using h5::hdf5_reason;
using h5::Opened;

// A failed write: a failure while running (Error), naming the file the user asked for (not the
// temporary it is written under) and the OS's reason when the driver saw one.
[[noreturn]] void fail_write(const fs::path& file, const std::string& what) {
  const int err = detail::first_write_errno();
  const std::string hdf5 = hdf5_reason();
  throw Error("cannot write " + display_path(file).string() + ": " + what + ": " +
              (err != 0 ? std::string(std::strerror(err)) : hdf5.empty() ? std::string("HDF5 error") : hdf5.substr(2, hdf5.size() - 3)));
}

// A user's file read in this process (the probe off or forked, hdf5_probe.hpp) is first walked by the
// structure probe together with the lookup of `dataset`, and the readers' attributes come from that
// walk (h5::set_attribute_source). Caller holds the mutex.
void probe_before_open(const fs::path& file, const std::string& dataset) {
  h5::set_attribute_source(&probed_attribute);
  std::error_code ec;
  if (fs::exists(file, ec) && !fs::is_directory(file, ec)) probe_hdf5_file(file, dataset);
}

// Opens `file`: for reading after the probe; for writing (Skelflow's own outputs, not probed) with the
// write driver that reports the OS's reason. Caller holds the mutex.
Handle open_file(const fs::path& file, bool write = false, const std::string& dataset = {}) {
  if (!write) {
    probe_before_open(file, dataset);
    return h5::open_file(file, false);
  }
  Handle fapl(detail::safe_write_fapl(), H5Pclose);
  return h5::open_file(file, true, fapl.id);
}

Opened open_volume(const fs::path& file, const std::string& dataset, bool write = false) {
  if (!write) {
    probe_before_open(file, dataset);
    return h5::open_volume(file, dataset);
  }
  Handle fapl(detail::safe_write_fapl(), H5Pclose);
  return h5::open_volume(file, dataset, true, fapl.id);
}

// The grid of the box [begin, begin + size) of a dataset with `info`'s spacing, origin and unit.
Grid box_grid(const VolumeInfo& info, Dims begin, Dims size) {
  Grid g(size);
  const Vec3& sp = info.spacing;
  g.spacing = sp;
  g.unit = info.unit;
  g.origin = {info.origin[0] + static_cast<double>(begin[0]) * sp[0], info.origin[1] + static_cast<double>(begin[1]) * sp[1],
              info.origin[2] + static_cast<double>(begin[2]) * sp[2]};
  return g;
}

template <class T>
Volume<T> read_into(Opened& o, const fs::path& file, const std::string& dataset, Dims begin, Dims size, int threads = 0) {
  Volume<T> v = Volume<T>::uninitialized(box_grid(h5::volume_info(o, file, dataset), begin, size));
  if (v.size() == 0) return v;
  h5::read_voxels<T>(o, file, dataset, begin, size, v.data(), threads);
  return v;
}

// ------------------------------------------------------------------ reading in the probe helper
// With the helper (hdf5_probe.hpp, the default) users' files are opened and read only there
// (hdf5_read.hpp says why): info and checks by request, the voxels box by box through the shared
// window, each box at most h5::kWindowBytes and, where a chunk fits the window, aligned to the
// dataset's chunks (so that no chunk is decoded twice).

// `whole`: a whole read follows; the helper made the checks before one (h5::check_whole_read), and
// a dataset that is empty or declares more than its file can hold is refused here, before this
// process allocates it.
VolumeInfo remote_info(const fs::path& file, const std::string& dataset, bool whole = false) {
  VolumeInfo info;
  std::string refusal;
  ask_hdf5_helper(file, dataset, static_cast<uint32_t>(h5::Request::info), {}, 0, [&](const std::string& payload, const void*) {
    if (!h5::decode_info(payload, info, &refusal))
      throw Error("the HDF5 probe helper gave a malformed answer for " + file.string());
  });
  if (whole && !refusal.empty()) throw InputError(refusal);
  return info;
}

// Box extents (x, y, z) of at most `window` bytes of `elem`-byte values for a read of `size`:
// multiples of `unit` (the chunk shape, or 1) along the slowest axes first.
Dims window_box(const Dims& size, const std::array<int64_t, 3>& unit, int64_t elem, int64_t window) {
  Dims b = size;
  auto bytes = [&] { return b[0] * b[1] * b[2] * elem; };
  for (int k = 2; k >= 0 && bytes() > window; --k) {
    const int64_t rest = bytes() / b[k];  // bytes per unit of length along k
    b[k] = std::min(size[k], std::max(unit[k], window / (rest * unit[k]) * unit[k]));
  }
  return b;
}

template <class T>
void remote_read_voxels(const fs::path& file, const std::string& dataset, const VolumeInfo& info, Dims begin, Dims size,
                        T* out, int threads) {
  const int64_t elem = sizeof(T);
  const auto window = static_cast<int64_t>(std::max<uint64_t>(detail::hdf5_read_window(), sizeof(T)));
  std::array<int64_t, 3> unit{1, 1, 1};
  if (info.chunks[0] > 0 && info.chunks[1] > 0 && info.chunks[2] > 0) {
    const Dims c{std::min(info.chunks[0], size[0]), std::min(info.chunks[1], size[1]), std::min(info.chunks[2], size[2])};
    if (c[0] * c[1] * c[2] * elem <= window) unit = info.chunks;
  }
  const Dims box = window_box(size, unit, elem, window);
  // Box boundaries along one axis: aligned to `unit` in dataset coordinates.
  auto next = [&](int k, int64_t at) {
    const int64_t end = begin[k] + size[k];
    if (box[k] >= size[k]) return end;  // the whole axis in one box
    return std::min(end, at / unit[k] * unit[k] + box[k]);  // box[k] is a multiple of unit[k]
  };
  h5::ReadRequest r;
  r.memory_type = static_cast<uint32_t>(h5::memory_type_of<T>());
  r.threads = threads;
  r.own_chunks = detail::own_chunk_decoding_enabled() ? 1 : 0;
  for (int64_t z0 = begin[2]; z0 < begin[2] + size[2];) {
    const int64_t z1 = next(2, z0);
    for (int64_t y0 = begin[1]; y0 < begin[1] + size[1];) {
      const int64_t y1 = next(1, y0);
      for (int64_t x0 = begin[0]; x0 < begin[0] + size[0];) {
        const int64_t x1 = next(0, x0);
        r.begin[0] = x0, r.begin[1] = y0, r.begin[2] = z0;
        r.size[0] = x1 - x0, r.size[1] = y1 - y0, r.size[2] = z1 - z0;
        std::string extra(sizeof r, '\0');
        std::memcpy(extra.data(), &r, sizeof r);
        const uint64_t bytes = static_cast<uint64_t>(r.size[0] * r.size[1] * r.size[2] * elem);
        ask_hdf5_helper(file, dataset, static_cast<uint32_t>(h5::Request::read), extra, bytes,
                        [&](const std::string& payload, const void* window_data) {
                          h5::ReadAnswer a;
                          if (payload.size() != sizeof a)
                            throw Error("the HDF5 probe helper gave a malformed answer for " + file.string());
                          std::memcpy(&a, payload.data(), sizeof a);
                          detail::count_remote_chunk_reads(a.decoded, a.declined);
                          const T* src = static_cast<const T*>(window_data);
                          const int64_t n = r.size[0];
                          for (int64_t z = z0; z < z1; ++z)
                            for (int64_t y = y0; y < y1; ++y, src += n)
                              std::memcpy(out + ((z - begin[2]) * size[1] + (y - begin[1])) * size[0] + (x0 - begin[0]), src,
                                          static_cast<size_t>(n) * sizeof(T));
                        });
        x0 = x1;
      }
      y0 = y1;
    }
    z0 = z1;
  }
}

template <class T>
Volume<T> remote_read(const fs::path& file, const std::string& dataset, const VolumeInfo& info, Dims begin, Dims size,
                      int threads) {
  Volume<T> v = Volume<T>::uninitialized(box_grid(info, begin, size));
  if (v.size() > 0) remote_read_voxels<T>(file, dataset, info, begin, size, v.data(), threads);
  return v;
}

template <class F>
DataPtr by_dtype(const std::string& t, F&& read) {
  if (t == "uint8") return std::make_shared<VolumeU8>(read(uint8_t{}));
  if (t == "uint16") return std::make_shared<VolumeU16>(read(uint16_t{}));
  if (t == "uint32") return std::make_shared<VolumeU32>(read(uint32_t{}));
  if (t == "uint64") return std::make_shared<VolumeU64>(read(uint64_t{}));
  if (t == "int8" || t == "int16" || t == "int32") return std::make_shared<VolumeI32>(read(int32_t{}));
  if (t == "float32") return std::make_shared<VolumeF32>(read(float{}));
  return std::make_shared<VolumeF64>(read(double{}));  // float64, int64
}

}  // namespace

VolumeInfo read_volume_info(const fs::path& file, const std::string& dataset) {
  if (hdf5_reads_in_helper()) return remote_info(file, dataset);
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  return h5::volume_info(o, file, dataset);
}

DataPtr read_volume(const fs::path& file, const std::string& dataset, int threads) {
  if (hdf5_reads_in_helper()) {
    const VolumeInfo info = remote_info(file, dataset, true);  // refuses an empty or oversized dataset
    return by_dtype(info.dtype, [&](auto tag) {
      return remote_read<decltype(tag)>(file, dataset, info, Dims{0, 0, 0}, info.dims, threads);
    });
  }
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  h5::check_whole_read(o, file, dataset);
  const Dims z{0, 0, 0};
  return by_dtype(o.dtype, [&](auto tag) { return read_into<decltype(tag)>(o, file, dataset, z, o.dims, threads); });
}

template <class T>
Volume<T> read_box(const fs::path& file, const std::string& dataset, Dims begin, Dims size) {
  auto check = [&](const Dims& dims) {
    for (int k = 0; k < 3; ++k)
      if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > dims[k])
        throw InputError(file.string() + ": box outside dataset '" + dataset + "'");
  };
  if (hdf5_reads_in_helper()) {
    const VolumeInfo info = remote_info(file, dataset);
    check(info.dims);
    return remote_read<T>(file, dataset, info, begin, size, 0);
  }
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  check(o.dims);
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
      auto [f, d] = create_dataset(tmp, dataset, detail::native_type<T>(), v.grid(), opt);
      if (v.size() > 0 && opt.compression > 0)
        write_compressed_chunks(d.id, v, opt.compression, opt.threads, file, dataset);
      else if (v.size() > 0 && H5Dwrite(d.id, detail::native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
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
      auto [f, d] = create_dataset(tmp, dataset, detail::native_type<T>(), source.grid, opt);
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
            if (H5Dwrite(d.id, detail::native_type<T>(), mem.id, space.id, H5P_DEFAULT, v->data()) < 0)
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
  if (H5Dwrite(o.dset.id, detail::native_type<T>(), mem.id, o.space.id, H5P_DEFAULT, block.data()) < 0)
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
  if (hdf5_reads_in_helper()) {
    std::string text;
    ask_hdf5_helper(file, "", static_cast<uint32_t>(h5::Request::describe), {}, 0,
                    [&](const std::string& payload, const void*) { text = payload; });
    return text;
  }
  std::lock_guard lock(hdf5_mutex());
  quiet();
  probe_before_open(file, "");
  return h5::describe(file, [&](const std::string& name) { probe_before_open(file, name); });
}

void write_string_attribute(const fs::path& file, const std::string& dataset, const std::string& name,
                            const std::string& value) {
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Handle f = open_file(file, true);
  Handle d = h5::open_dataset(f.id, file, dataset);
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
  if (hdf5_reads_in_helper()) {
    std::string value;
    ask_hdf5_helper(file, dataset, static_cast<uint32_t>(h5::Request::string_attribute), name, 0,
                    [&](const std::string& payload, const void*) { value = payload; });
    return value;
  }
  std::lock_guard lock(hdf5_mutex());
  quiet();
  Opened o = open_volume(file, dataset);
  return h5::string_attribute(o, file, dataset, name);
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
