#include "io/hdf5_chunks.hpp"

#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <optional>
#include <type_traits>
#include <vector>

#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace fs = std::filesystem;

namespace skel::io::detail {

namespace {

std::atomic<int64_t> g_decoded{0}, g_declined{0};

// A stored element type we decode: a standard integer or IEEE float of either byte order.
struct StoredType {
  bool is_float = false, is_signed = false;
  size_t size = 0;
  bool big_endian = false;
};

std::optional<StoredType> stored_type(hid_t type) {
  const struct {
    hid_t id;
    StoredType t;
  } known[] = {
      {H5T_STD_U8LE, {false, false, 1, false}},   {H5T_STD_U8BE, {false, false, 1, true}},
      {H5T_STD_I8LE, {false, true, 1, false}},    {H5T_STD_I8BE, {false, true, 1, true}},
      {H5T_STD_U16LE, {false, false, 2, false}},  {H5T_STD_U16BE, {false, false, 2, true}},
      {H5T_STD_I16LE, {false, true, 2, false}},   {H5T_STD_I16BE, {false, true, 2, true}},
      {H5T_STD_U32LE, {false, false, 4, false}},  {H5T_STD_U32BE, {false, false, 4, true}},
      {H5T_STD_I32LE, {false, true, 4, false}},   {H5T_STD_I32BE, {false, true, 4, true}},
      {H5T_STD_U64LE, {false, false, 8, false}},  {H5T_STD_U64BE, {false, false, 8, true}},
      {H5T_STD_I64LE, {false, true, 8, false}},   {H5T_STD_I64BE, {false, true, 8, true}},
      {H5T_IEEE_F32LE, {true, true, 4, false}},   {H5T_IEEE_F32BE, {true, true, 4, true}},
      {H5T_IEEE_F64LE, {true, true, 8, false}},   {H5T_IEEE_F64BE, {true, true, 8, true}},
  };
  for (const auto& k : known)
    if (H5Tequal(type, k.id) > 0) return k.t;
  H5Eclear2(H5E_DEFAULT);
  return std::nullopt;
}

// Whether every value of the stored type converts to T exactly as H5Dread's conversion to T's
// native type does: the same type, wider integers that hold every value, floats to a float at
// least as wide, integers to float32 up to 16 bits and to float64 (64-bit integers as a C cast,
// which is what HDF5's hard integer-to-double conversion does).
template <class T>
bool converts_exactly(const StoredType& s) {
  if constexpr (std::is_floating_point_v<T>) {
    if (s.is_float) return s.size <= sizeof(T);
    return sizeof(T) == 8 || s.size <= 2;
  } else {
    if (s.is_float) return false;
    if (s.is_signed) return std::is_signed_v<T> && s.size <= sizeof(T);
    return std::is_signed_v<T> ? s.size < sizeof(T) : s.size <= sizeof(T);
  }
}

template <class U>
U load(const unsigned char* p, bool swap) {
  U v;
  if (!swap) {
    std::memcpy(&v, p, sizeof(U));
    return v;
  }
  unsigned char b[sizeof(U)];
  for (size_t i = 0; i < sizeof(U); ++i) b[i] = p[sizeof(U) - 1 - i];
  std::memcpy(&v, b, sizeof(U));
  return v;
}

// Converts n stored elements at `src` to T.
template <class T>
void convert(const unsigned char* src, const StoredType& s, T* dst, int64_t n) {
  const bool swap = s.big_endian != (std::endian::native == std::endian::big) && s.size > 1;
  if (!swap && !s.is_float == !std::is_floating_point_v<T> && s.size == sizeof(T) &&
      s.is_signed == std::is_signed_v<T>) {
    std::memcpy(dst, src, static_cast<size_t>(n) * sizeof(T));
    return;
  }
  auto each = [&](auto tag) {
    using U = decltype(tag);
    for (int64_t i = 0; i < n; ++i) dst[i] = static_cast<T>(load<U>(src + static_cast<size_t>(i) * sizeof(U), swap));
  };
  if (s.is_float) {
    if (s.size == 4) each(float{});
    else each(double{});
  } else if (s.is_signed) {
    if (s.size == 1) each(int8_t{});
    else if (s.size == 2) each(int16_t{});
    else if (s.size == 4) each(int32_t{});
    else each(int64_t{});
  } else {
    if (s.size == 1) each(uint8_t{});
    else if (s.size == 2) each(uint16_t{});
    else if (s.size == 4) each(uint32_t{});
    else each(uint64_t{});
  }
}

struct Filter {
  enum Kind { shuffle, deflate, fletcher32 } kind;
  size_t element = 1;  // shuffle: bytes per element
};

// The dataset's filter pipeline in write order, or nullopt when it holds a filter we do not decode
// (or more than one deflate).
std::optional<std::vector<Filter>> filter_pipeline(hid_t dcpl) {
  std::vector<Filter> out;
  const int nf = H5Pget_nfilters(dcpl);
  if (nf < 0) return std::nullopt;
  int deflates = 0;
  for (int i = 0; i < nf; ++i) {
    unsigned flags = 0, config = 0, cd[8] = {0};
    size_t nelem = 8;
    char name[64] = {0};
    const H5Z_filter_t f = H5Pget_filter2(dcpl, static_cast<unsigned>(i), &flags, &nelem, cd, sizeof name, name, &config);
    if (f == H5Z_FILTER_SHUFFLE) {
      if (nelem < 1 || cd[0] == 0) return std::nullopt;
      out.push_back({Filter::shuffle, cd[0]});
    } else if (f == H5Z_FILTER_DEFLATE) {
      if (++deflates > 1) return std::nullopt;
      out.push_back({Filter::deflate, 1});
    } else if (f == H5Z_FILTER_FLETCHER32) {
      out.push_back({Filter::fletcher32, 1});
    } else {
      return std::nullopt;
    }
  }
  return out;
}

// HDF5's Fletcher32 (H5_checksum_fletcher32): 16-bit words, most significant byte first.
uint32_t fletcher32(const unsigned char* data, size_t bytes) {
  size_t len = bytes / 2;
  uint32_t sum1 = 0, sum2 = 0;
  while (len) {
    size_t tlen = len > 360 ? 360 : len;
    len -= tlen;
    do {
      sum1 += static_cast<uint32_t>((static_cast<uint32_t>(data[0]) << 8) | data[1]);
      data += 2;
      sum2 += sum1;
    } while (--tlen);
    sum1 = (sum1 & 0xffff) + (sum1 >> 16);
    sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  }
  if (bytes % 2) {
    sum1 += static_cast<uint32_t>(*data) << 8;
    sum2 += sum1;
    sum1 = (sum1 & 0xffff) + (sum1 >> 16);
    sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  }
  sum1 = (sum1 & 0xffff) + (sum1 >> 16);
  sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  return (sum2 << 16) | sum1;
}

// Undoes HDF5's shuffle for E-byte elements: byte j of element i was stored at j * count + i.
template <size_t E>
void unshuffle(const unsigned char* src, unsigned char* dst, size_t count) {
  for (size_t i = 0; i < count; ++i) {
    unsigned char v[E];
    for (size_t j = 0; j < E; ++j) v[j] = src[j * count + i];
    std::memcpy(dst + i * E, v, E);
  }
}

// The most a deflate stream expands (1032:1, with a margin), as the readers' check of a dataset's
// declared size against its stored size (hdf5_volume.cpp).
constexpr double kMaxDeflateRatio = 1100;

// One chunk of the box: its grid index, its first voxel (x, y, z) and, once read, its stored bytes.
struct ChunkJob {
  std::array<int64_t, 3> index{}, origin{};
  bool present = false;
  unsigned mask = 0;
  std::vector<unsigned char> raw;
};

// Each worker's buffers (stored bytes, two decoding buffers), kept from one read to the next up to
// kBufferPoolBytes in all: a fresh megabyte block costs a page fault per 4 KiB on every read_box call
// (libhdf5 keeps its chunk buffers on free lists for the same reason). Used only under the
// process-wide HDF5 mutex, which every caller of read_chunked_box holds.
struct WorkerBuffers {
  std::vector<unsigned char> raw, a, b;
};
constexpr size_t kBufferPoolBytes = size_t{32} << 20;
std::vector<WorkerBuffers>& buffer_pool() {
  static std::vector<WorkerBuffers> pool;
  return pool;
}
void trim_buffer_pool() {
  size_t kept = 0;
  for (WorkerBuffers& w : buffer_pool())
    for (std::vector<unsigned char>* v : {&w.raw, &w.a, &w.b}) {
      if (kept + v->capacity() > kBufferPoolBytes) std::vector<unsigned char>().swap(*v);
      kept += v->capacity();
    }
}

class Decoder {
public:
  Decoder(const fs::path& file, const std::string& dataset, std::vector<Filter> filters, size_t chunk_bytes)
      : file_(file), dataset_(dataset), filters_(std::move(filters)), chunk_bytes_(chunk_bytes) {}

  [[noreturn]] void refuse(const ChunkJob& c, const std::string& why) const {
    throw InputError(file_.string() + ": dataset '" + dataset_ + "': chunk (" + std::to_string(c.index[0]) + ", " +
                     std::to_string(c.index[1]) + ", " + std::to_string(c.index[2]) + ") (x, y, z; its first voxel (" +
                     std::to_string(c.origin[0]) + ", " + std::to_string(c.origin[1]) + ", " + std::to_string(c.origin[2]) +
                     ")) " + why + ": the file is damaged");
  }

  // Undoes the filters of chunk `c` (its stored bytes in c.raw); returns the chunk's bytes, exactly
  // chunk_bytes_ of them, in `a` or `b` (scratch buffers of the caller, reused from chunk to chunk).
  const unsigned char* decode(const ChunkJob& c, std::vector<unsigned char>& a, std::vector<unsigned char>& b) const {
    const unsigned char* data = c.raw.data();
    size_t n = c.raw.size();
    if (n > size_t{1} << 32) refuse(c, "is stored in more bytes than HDF5 allows for one chunk");
    for (size_t k = filters_.size(); k-- > 0;) {
      if (k < 32 && (c.mask >> k) & 1u) continue;  // skipped when the chunk was written
      const Filter& f = filters_[k];
      if (f.kind == Filter::fletcher32) {
        if (n < 4) refuse(c, "is too short for its Fletcher32 checksum");
        n -= 4;
        const uint32_t stored = static_cast<uint32_t>(data[n]) | static_cast<uint32_t>(data[n + 1]) << 8 |
                                static_cast<uint32_t>(data[n + 2]) << 16 | static_cast<uint32_t>(data[n + 3]) << 24;
        const uint32_t sum = fletcher32(data, n);
        // HDF5 1.6.0-1.6.2 stored the checksum's bytes swapped in pairs; HDF5 accepts both.
        const uint32_t reversed = ((sum & 0x00ff00ffu) << 8) | ((sum >> 8) & 0x00ff00ffu);
        if (stored != sum && stored != reversed) refuse(c, "fails its Fletcher32 checksum");
      } else if (f.kind == Filter::deflate) {
        // What the filters before it (in write order) made of the chunk: its bytes plus 4 per
        // Fletcher32 applied before it; the inflated data must be exactly that long.
        size_t expected = chunk_bytes_;
        for (size_t j = 0; j < k; ++j)
          if (filters_[j].kind == Filter::fletcher32 && !(j < 32 && (c.mask >> j) & 1u)) expected += 4;
        // Deflate expands at most ~1032:1: a chunk whose shape claims more than that of its stored
        // bytes is damaged, and is refused before its buffer is allocated (a mutated chunk shape
        // of 1.8 GB in a 4 KB file, libFuzzer, session 9).
        if (static_cast<double>(expected) > kMaxDeflateRatio * static_cast<double>(n) + 4096)
          refuse(c, "claims " + std::to_string(expected) + " bytes but is stored in " + std::to_string(n) +
                        ", more than deflate can expand");
        std::vector<unsigned char>& out = data == a.data() ? b : a;
        out.resize(expected + 1);
        z_stream z{};
        if (inflateInit(&z) != Z_OK) throw Error(file_.string() + ": zlib cannot start (out of memory?)");
        z.next_in = const_cast<Bytef*>(data);
        z.avail_in = static_cast<uInt>(n);
        z.next_out = out.data();
        z.avail_out = static_cast<uInt>(expected + 1);  // one byte more: an overlong chunk is seen
        const int rc = inflate(&z, Z_FINISH);
        const size_t got = z.total_out;
        const std::string msg = z.msg ? z.msg : "";
        inflateEnd(&z);
        if (rc != Z_STREAM_END) {
          if (got > expected) refuse(c, "inflates to more than the " + std::to_string(expected) + " bytes of a chunk");
          refuse(c, "cannot be inflated" + (msg.empty() ? std::string(" (truncated)") : " (zlib: " + msg + ")"));
        }
        if (got != expected)
          refuse(c, "inflates to " + std::to_string(got) + " bytes, not the " + std::to_string(expected) + " of a chunk");
        data = out.data();
        n = got;
      } else if (f.element > 1) {  // shuffle: byte j of element i was stored at j * count + i
        std::vector<unsigned char>& out = data == a.data() ? b : a;
        out.resize(n);
        const size_t e = f.element, count = n / e;
        if (count > 1) {
          if (e == 2) unshuffle<2>(data, out.data(), count);
          else if (e == 4) unshuffle<4>(data, out.data(), count);
          else if (e == 8) unshuffle<8>(data, out.data(), count);
          else
            for (size_t j = 0; j < e; ++j) {
              const unsigned char* s = data + j * count;
              unsigned char* d = out.data() + j;
              for (size_t i = 0; i < count; ++i) d[i * e] = s[i];
            }
          std::memcpy(out.data() + count * e, data + count * e, n - count * e);
          data = out.data();
        }
      }
    }
    if (n != chunk_bytes_)
      refuse(c, "holds " + std::to_string(n) + " bytes after its filters, not the " + std::to_string(chunk_bytes_) +
                    " of a chunk");
    return data;
  }

private:
  const fs::path& file_;
  const std::string& dataset_;
  std::vector<Filter> filters_;
  size_t chunk_bytes_;
};

}  // namespace

bool own_chunk_decoding_enabled() {
  const char* v = std::getenv("SKEL_HDF5_OWN_CHUNKS");
  return !(v && std::string(v) == "0");
}

int64_t own_chunks_decoded() { return g_decoded.load(); }
int64_t own_chunk_reads_declined() { return g_declined.load(); }
void count_remote_chunk_reads(int64_t decoded, int64_t declined) {
  g_decoded += decoded;
  g_declined += declined;
}

template <class T>
bool read_chunked_box(hid_t dset, const fs::path& file, const std::string& dataset, const Dims& dims, const Dims& begin,
                      const Dims& size, T* out, int threads) {
  auto decline = [] {
    H5Eclear2(H5E_DEFAULT);
    ++g_declined;
    return false;
  };
  if (!own_chunk_decoding_enabled()) return decline();
  const hid_t dcpl = H5Dget_create_plist(dset);
  if (dcpl < 0) return decline();
  struct Closer {
    hid_t id;
    herr_t (*close)(hid_t);
    ~Closer() {
      if (id >= 0) close(id);
    }
  } dcpl_closer{dcpl, H5Pclose};
  if (H5Pget_layout(dcpl) != H5D_CHUNKED || H5Pget_external_count(dcpl) > 0) return decline();
  hsize_t hc[3];
  if (H5Pget_chunk(dcpl, 3, hc) != 3) return decline();
  const std::array<int64_t, 3> chunk{static_cast<int64_t>(hc[2]), static_cast<int64_t>(hc[1]), static_cast<int64_t>(hc[0])};
  for (int64_t c : chunk)
    if (c <= 0) return decline();
  // Unfiltered chunks too: through our kept buffers they read faster than by H5Dread, whose chunk
  // cache allocates each chunk afresh (256³ float32, 1 MiB chunks: 0.017 s against 0.30 s whole).
  auto filters = filter_pipeline(dcpl);
  if (!filters) return decline();
  const hid_t type = H5Dget_type(dset);
  if (type < 0) return decline();
  Closer type_closer{type, H5Tclose};
  const std::optional<StoredType> st = stored_type(type);
  if (!st || !converts_exactly<T>(*st)) return decline();
  H5D_fill_value_t fill_status;
  if (H5Pfill_value_defined(dcpl, &fill_status) < 0 || fill_status == H5D_FILL_VALUE_UNDEFINED) return decline();
  T fill{};
  if (H5Pget_fill_value(dcpl, native_type<T>(), &fill) < 0) return decline();
  hsize_t file_bytes = 0;
  const hid_t fid = H5Iget_file_id(dset);
  if (fid >= 0) {
    H5Fget_filesize(fid, &file_bytes);
    H5Fclose(fid);
  }
  H5Eclear2(H5E_DEFAULT);

  const double chunk_elems = static_cast<double>(chunk[0]) * static_cast<double>(chunk[1]) * static_cast<double>(chunk[2]);
  if (chunk_elems * static_cast<double>(st->size) > double(int64_t{1} << 32)) return decline();  // HDF5's own limit
  const size_t chunk_bytes = static_cast<size_t>(chunk_elems) * st->size;
  Decoder decoder(file, dataset, std::move(*filters), chunk_bytes);

  // The chunks the box touches, in the file's chunk order (z, y, x).
  std::array<int64_t, 3> first{}, last{};
  for (int k = 0; k < 3; ++k) {
    if (begin[k] < 0 || size[k] < 0 || begin[k] + size[k] > dims[k]) return decline();
    if (size[k] == 0) return true;
    first[k] = begin[k] / chunk[k];
    last[k] = (begin[k] + size[k] - 1) / chunk[k];
  }
  const int64_t sx = size[0], sy = size[1];
  // Copies the part of chunk `c` (decoded bytes `data`, or the fill value when null) inside the box.
  auto place = [&](const ChunkJob& c, const unsigned char* data) {
    const int64_t x0 = std::max(c.origin[0], begin[0]), x1 = std::min(c.origin[0] + chunk[0], begin[0] + size[0]);
    const int64_t y0 = std::max(c.origin[1], begin[1]), y1 = std::min(c.origin[1] + chunk[1], begin[1] + size[1]);
    const int64_t z0 = std::max(c.origin[2], begin[2]), z1 = std::min(c.origin[2] + chunk[2], begin[2] + size[2]);
    for (int64_t z = z0; z < z1; ++z)
      for (int64_t y = y0; y < y1; ++y) {
        T* dst = out + ((z - begin[2]) * sy + (y - begin[1])) * sx + (x0 - begin[0]);
        if (!data) {
          std::fill(dst, dst + (x1 - x0), fill);
          continue;
        }
        const int64_t at = ((z - c.origin[2]) * chunk[1] + (y - c.origin[1])) * chunk[0] + (x0 - c.origin[0]);
        convert(data + static_cast<size_t>(at) * st->size, *st, dst, x1 - x0);
      }
  };

  const int64_t nx = last[0] - first[0] + 1, ny = last[1] - first[1] + 1, nz = last[2] - first[2] + 1;
  const int64_t total = nx * ny * nz;
  // `workers` loops, each taking the next chunk: its lookup in the chunk index and its stored bytes
  // come from libhdf5 under `read_mutex` (one libhdf5 call at a time; the caller holds the
  // process-wide HDF5 mutex throughout, so no other thread of the process is inside libhdf5), the
  // decoding and copying run outside it, so one worker reads while the others inflate. Each worker
  // keeps its buffers from chunk to chunk. A box of one chunk is read on the calling thread alone.
  const int workers = static_cast<int>(std::min<int64_t>(effective_threads(threads), total));
  std::mutex read_mutex;
  std::atomic<int64_t> next{0};
  std::vector<WorkerBuffers>& pool = buffer_pool();
  if (pool.size() < static_cast<size_t>(workers)) pool.resize(static_cast<size_t>(workers));
  struct Trim {
    ~Trim() { trim_buffer_pool(); }
  } trim;
  parallel_chunks(0, workers, workers, workers, [&](int64_t worker, int64_t, int64_t) {
    WorkerBuffers& buffers = pool[static_cast<size_t>(worker)];
    ChunkJob c;
    std::vector<unsigned char> a, b;
    c.raw.swap(buffers.raw);
    a.swap(buffers.a);
    b.swap(buffers.b);
    struct GiveBack {
      WorkerBuffers& to;
      ChunkJob& c;
      std::vector<unsigned char>& a;
      std::vector<unsigned char>& b;
      ~GiveBack() {
        to.raw.swap(c.raw);
        to.a.swap(a);
        to.b.swap(b);
      }
    } give_back{buffers, c, a, b};
    try {
      for (int64_t k = next++; k < total; k = next++) {
        c.index = {first[0] + k % nx, first[1] + k / nx % ny, first[2] + k / (nx * ny)};
        for (int j = 0; j < 3; ++j) c.origin[j] = c.index[j] * chunk[j];
        const hsize_t offset[3] = {static_cast<hsize_t>(c.origin[2]), static_cast<hsize_t>(c.origin[1]),
                                   static_cast<hsize_t>(c.origin[0])};
        {
          std::lock_guard lock(read_mutex);
          quiet_hdf5_errors_on_this_thread();
          unsigned mask = 0;
          haddr_t addr = HADDR_UNDEF;
          hsize_t stored = 0;
          if (H5Dget_chunk_info_by_coord(dset, offset, &mask, &addr, &stored) < 0) {
            H5Eclear2(H5E_DEFAULT);
            decoder.refuse(c, "cannot be looked up in the chunk index");
          }
          c.present = addr != HADDR_UNDEF && stored > 0;
          if (c.present) {
            if (file_bytes > 0 && stored > file_bytes)
              decoder.refuse(c, "claims " + std::to_string(stored) + " stored bytes but the file has only " +
                                    std::to_string(file_bytes));
            c.raw.resize(static_cast<size_t>(stored));
            uint32_t read_mask = 0;
            if (H5Dread_chunk(dset, H5P_DEFAULT, offset, &read_mask, c.raw.data()) < 0) {
              H5Eclear2(H5E_DEFAULT);
              decoder.refuse(c, "cannot be read");
            }
            c.mask = read_mask;
          }
        }
        place(c, c.present ? decoder.decode(c, a, b) : nullptr);
        ++g_decoded;
      }
    } catch (...) {
      next = total;  // the other workers stop after their chunk
      throw;
    }
  });
  return true;
}

template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, uint8_t*, int);
template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, uint16_t*, int);
template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, uint32_t*, int);
template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, uint64_t*, int);
template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, int32_t*, int);
template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, float*, int);
template bool read_chunked_box(hid_t, const fs::path&, const std::string&, const Dims&, const Dims&, const Dims&, double*, int);

void quiet_hdf5_errors_on_this_thread() {
  thread_local bool done = false;
  if (!done) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    done = true;
  }
}

}  // namespace skel::io::detail
