// The metadata walk of the HDF5 structure probe (hdf5_probe_walk.hpp).
#include "io/hdf5_probe_walk.hpp"

#include <hdf5.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <cstring>
#include <new>
#include <type_traits>
#include <string>
#include <vector>

namespace skel::io::probe {

namespace {

bool g_out_of_memory = false;

herr_t note_allocation_failure(unsigned, const H5E_error2_t* e, void*) {
  if (e && (e->min_num == H5E_NOSPACE || e->min_num == H5E_CANTALLOC)) g_out_of_memory = true;
  return 0;
}

// HDF5's automatic error handler in the child: prints nothing, notes failed allocations.
herr_t on_hdf5_error(hid_t stack, void*) {
  H5Ewalk2(stack, H5E_WALK_DOWNWARD, note_allocation_failure, nullptr);
  return 0;
}

void close_if(hid_t id, herr_t (*close)(hid_t)) {
  if (id >= 0) close(id);
}

// Every path prefix of `name` looked up as open_dataset does ("/a", "/a/b", ...).
void look_up(hid_t file, const std::string& name) {
  std::string partial;
  size_t pos = 1;
  while (pos <= name.size()) {
    const size_t slash = name.find('/', pos);
    const size_t end = slash == std::string::npos ? name.size() : slash;
    partial = name.substr(0, end);
    if (end > pos && H5Lexists(file, partial.c_str(), H5P_DEFAULT) <= 0) return;
    pos = end + 1;
  }
}

Attribute read_vec3(hid_t obj, const char* name) {
  Attribute r;
  if (H5Aexists(obj, name) <= 0) return r;
  r.kind = Attribute::Kind::unreadable;
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  const hid_t s = a >= 0 ? H5Aget_space(a) : -1;
  const hssize_t n = s >= 0 ? H5Sget_simple_extent_npoints(s) : -1;
  if (n == 3) {
    double v[3];
    if (H5Aread(a, H5T_NATIVE_DOUBLE, v) >= 0) {
      r.kind = Attribute::Kind::numbers;
      r.numbers = {v[0], v[1], v[2]};
    }
  } else if (n >= 0) {
    r.kind = Attribute::Kind::wrong_count;
    r.count = n;
  }
  close_if(s, H5Sclose);
  close_if(a, H5Aclose);
  return r;
}

Attribute read_string(hid_t obj, const char* name) {
  Attribute r;
  if (H5Aexists(obj, name) <= 0) return r;
  r.kind = Attribute::Kind::unreadable;
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  const hid_t t = a >= 0 ? H5Aget_type(a) : -1;
  const H5T_class_t cls = t >= 0 ? H5Tget_class(t) : H5T_NO_CLASS;
  if (cls == H5T_STRING) {
    const hid_t mem = H5Tcopy(H5T_C_S1);
    H5Tset_cset(mem, H5Tget_cset(t));  // HDF5 converts no character sets: read as stored (ASCII or UTF-8)
    if (H5Tis_variable_str(t) > 0) {
      H5Tset_size(mem, H5T_VARIABLE);
      char* value = nullptr;
      if (H5Aread(a, mem, &value) >= 0) {
        const size_t n = value ? strnlen(value, kMaxStringBytes + 1) : 0;
        r.kind = n > kMaxStringBytes ? Attribute::Kind::too_long : Attribute::Kind::text;
        if (n <= kMaxStringBytes && value) r.text.assign(value, n);
        H5free_memory(value);
      }
    } else {
      const size_t n = H5Tget_size(t);
      if (n > kMaxStringBytes) {
        r.kind = Attribute::Kind::too_long;
      } else {
        std::string buf(n + 1, '\0');
        H5Tset_size(mem, n + 1);
        if (H5Aread(a, mem, buf.data()) >= 0) {
          r.kind = Attribute::Kind::text;
          r.text = buf.c_str();
        }
      }
    }
    close_if(mem, H5Tclose);
  } else if (cls != H5T_NO_CLASS) {
    r.kind = Attribute::Kind::not_string;
  }
  close_if(t, H5Tclose);
  close_if(a, H5Aclose);
  return r;
}

herr_t touch_attribute(hid_t obj, const char* name, const H5A_info_t*, void*) {
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return 0;
  const hid_t s = H5Aget_space(a), t = H5Aget_type(a);
  if (s >= 0) H5Sget_simple_extent_npoints(s);
  if (t >= 0) {
    H5Tget_class(t);
    H5Tget_size(t);
  }
  close_if(t, H5Tclose);
  close_if(s, H5Sclose);
  H5Aclose(a);
  return 0;
}

// What open_volume, check_declared_size and read_volume_info ask of a dataset, and its chunk index.
void walk_dataset(hid_t file, const std::string& name) {
  const hid_t dapl = H5Pcreate(H5P_DATASET_ACCESS);
  H5Pset_chunk_cache(dapl, 12421, 256u << 20, 1.0);
  const hid_t d = H5Dopen2(file, name.c_str(), dapl);
  H5Pclose(dapl);
  if (d < 0) return;
  const hid_t space = H5Dget_space(d);
  hsize_t dims[3] = {0, 0, 0};
  const bool three_d = space >= 0 && H5Sget_simple_extent_ndims(space) == 3;
  if (three_d) H5Sget_simple_extent_dims(space, dims, nullptr);
  const hid_t type = H5Dget_type(d);
  if (type >= 0) {
    H5Tget_class(type);
    H5Tget_size(type);
    H5Tget_sign(type);
  }
  const hid_t plist = H5Dget_create_plist(d);
  if (plist >= 0) {
    if (H5Pget_layout(plist) == H5D_CHUNKED) {
      hsize_t c[3];
      H5Pget_chunk(plist, 3, c);
      hsize_t n = 0;
      if (space >= 0 && H5Dget_num_chunks(d, space, &n) >= 0 && n > 0) {  // walks the whole chunk index
        hsize_t offset[H5S_MAX_RANK];
        unsigned mask = 0;
        haddr_t addr = 0;
        hsize_t size = 0;
        H5Dget_chunk_info(d, space, 0, offset, &mask, &addr, &size);
        H5Dget_chunk_info(d, space, n - 1, offset, &mask, &addr, &size);
      }
    }
    const int nf = H5Pget_nfilters(plist);
    for (int i = 0; i < nf; ++i) {
      unsigned flags = 0, config = 0;
      size_t nelem = 0;
      char fname[64] = {0};
      const H5Z_filter_t f = H5Pget_filter2(plist, static_cast<unsigned>(i), &flags, &nelem, nullptr, sizeof fname, fname, &config);
      if (f >= 0) H5Zfilter_avail(f);
    }
    H5Pget_external_count(plist);
  }
  // The voxels themselves: libhdf5 1.10.8 trusts a chunk's inflated size and a compact dataset's header
  // sizes when it copies voxels out in H5Dread (heap overflows and SEGVs in H5VM_memcpyvv under
  // H5D__select_read on mutated deflated files, libFuzzer session 8). The walk therefore reads, as the
  // readers will, the whole dataset when it declares at most 64 MiB (native type), else the first
  // and the last chunk (or row) only: a damaged chunk in the middle of a large file is not seen here.
  const double held = static_cast<double>(H5Dget_storage_size(d));
  hsize_t file_bytes = 0;
  const bool sized = H5Fget_filesize(file, &file_bytes) >= 0;
  if (three_d && type >= 0) {
    const hid_t native = H5Tget_native_type(type, H5T_DIR_ASCEND);
    const size_t bytes = native >= 0 ? H5Tget_size(native) : 0;
    const double total = static_cast<double>(dims[0]) * static_cast<double>(dims[1]) * static_cast<double>(dims[2]);
    // Files the readers refuse before H5Dread (stored size beyond the file, more voxels declared
    // than the stored data can hold: io/hdf5_volume.cpp) are not read here either, so they keep
    // the readers' clearer message.
    const int filters = plist >= 0 ? H5Pget_nfilters(plist) : 0;
    const double stored = total * static_cast<double>(H5Tget_size(type));
    const bool refused_before_reading = (sized && held > static_cast<double>(file_bytes)) ||
                                        stored > held * (filters > 0 ? 1100.0 : 1.0);
    if (bytes > 0 && total > 0 && !refused_before_reading) {
      hsize_t box[3] = {dims[0], dims[1], dims[2]};
      if (total * static_cast<double>(bytes) > double(64u << 20)) {
        box[0] = box[1] = 1;
        box[2] = dims[2];
        if (plist >= 0 && H5Pget_layout(plist) == H5D_CHUNKED) {
          hsize_t c[3];
          if (H5Pget_chunk(plist, 3, c) == 3)
            for (int k = 0; k < 3; ++k) box[k] = std::min(c[k], dims[k]);
        }
      }
      const double n = static_cast<double>(box[0]) * static_cast<double>(box[1]) * static_cast<double>(box[2]);
      if (n * static_cast<double>(bytes) <= double(256u << 20)) {
        std::vector<unsigned char> buffer(static_cast<size_t>(n) * bytes);
        const hid_t mem = H5Screate_simple(3, box, nullptr);
        for (int last = 0; last < 2; ++last) {
          hsize_t start[3] = {0, 0, 0};
          if (last)
            for (int k = 0; k < 3; ++k) start[k] = dims[k] - box[k];
          if (H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, box, nullptr) >= 0)
            H5Dread(d, native, mem, space, H5P_DEFAULT, buffer.data());
          if (box[0] == dims[0] && box[1] == dims[1] && box[2] == dims[2]) break;
        }
        close_if(mem, H5Sclose);
      }
    }
    close_if(native, H5Tclose);
  }
  close_if(plist, H5Pclose);
  close_if(type, H5Tclose);
  close_if(space, H5Sclose);
  H5Dclose(d);
}

// An object by name: its attributes (all of them opened, the readers' ones read as the readers
// read them, their values noted in `result`) and, for a dataset, walk_dataset.
void walk_object(hid_t file, const std::string& name, WalkResult& result) {
  look_up(file, name);
  const hid_t obj = H5Oopen(file, name.c_str(), H5P_DEFAULT);
  if (obj < 0) return;
  hsize_t at = 0;
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_NATIVE, &at, touch_attribute, nullptr);
  ObjectAttributes attributes;
  for (size_t i = 0; i < kAttributeCount; ++i)
    attributes[i] = is_string_attribute(i) ? read_string(obj, kAttributeNames[i]) : read_vec3(obj, kAttributeNames[i]);
  result.attributes[name] = std::move(attributes);
  const H5I_type_t kind = H5Iget_type(obj);
  H5Oclose(obj);
  if (kind == H5I_DATASET) walk_dataset(file, name);
}

struct Visited {
  std::vector<std::string> objects, datasets;
};

herr_t collect(hid_t, const char* name, const H5O_info_t* info, void* data) {
  auto* v = static_cast<Visited*>(data);
  const std::string path = std::string(name) == "." ? std::string("/") : std::string("/") + name;
  v->objects.push_back(path);
  if (info->type == H5O_TYPE_DATASET) v->datasets.push_back(path);
  return 0;
}

// The readers' walk over the whole file, then the lookup of `dataset`.
int walk(const char* path, const std::string& dataset, std::string& payload) {
  WalkResult result;
  std::string group;
  if (!dataset.empty() && dataset[0] == '/') {
    const size_t slash = dataset.rfind('/');
    group = dataset.substr(0, slash == 0 ? 1 : slash);  // "/a" -> "/", "/a/b" -> "/a"
  }
  if (H5Fis_hdf5(path) <= 0) {  // the reader refuses it in-process, as before
    payload = encode(result, dataset, group);
    return kWalkOk;
  }
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  const hid_t file = H5Fopen(path, H5F_ACC_RDONLY, fapl);
  H5Pclose(fapl);
  if (file < 0) {
    payload = encode(result, dataset, group);
    return g_out_of_memory ? kWalkOutOfMemory : kWalkOk;
  }
  Visited v;
  H5Ovisit2(file, H5_INDEX_NAME, H5_ITER_NATIVE, collect, &v, H5O_INFO_BASIC);
  if (v.objects.empty()) v.objects.push_back("/");
  for (const auto& o : v.objects) walk_object(file, o, result);
  if (!dataset.empty() && dataset[0] == '/') {
    look_up(file, dataset);
    walk_object(file, dataset, result);
    walk_object(file, group, result);  // the group whose element_size_um read_geometry reads
  }
  H5Fclose(file);
  if (g_out_of_memory) return kWalkOutOfMemory;
  for (const auto& d : v.datasets) {
    if (result.names.size() + d.size() + 1 > kMaxNameBytes) break;
    result.names += d;
    result.names += '\0';
  }
  payload = encode(result, dataset, group);
  return kWalkOk;
}

void put_u32(std::string& out, uint32_t v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); }

bool get(const std::string& in, size_t& at, void* data, size_t n) {
  if (n > in.size() - at) return false;
  std::memcpy(data, in.data() + at, n);
  at += n;
  return true;
}

// One object's record: u32 name bytes, name, then per attribute u8 kind and its value (numbers: 3
// doubles; text: u32 bytes and the bytes; wrong_count: i64 count).
void put_record(std::string& out, const std::string& name, const ObjectAttributes& attributes) {
  put_u32(out, static_cast<uint32_t>(name.size()));
  out += name;
  for (const Attribute& a : attributes) {
    out += static_cast<char>(a.kind);
    if (a.kind == Attribute::Kind::numbers) out.append(reinterpret_cast<const char*>(a.numbers.data()), sizeof(double) * 3);
    if (a.kind == Attribute::Kind::text) {
      put_u32(out, static_cast<uint32_t>(a.text.size()));
      out += a.text;
    }
    if (a.kind == Attribute::Kind::wrong_count) out.append(reinterpret_cast<const char*>(&a.count), sizeof a.count);
  }
}


}  // namespace

uint64_t memory_limit_bytes() {
  const char* v = std::getenv("SKEL_HDF5_PROBE_MEMORY_MB");
  if (!v || !*v) return kDefaultMemoryMiB << 20;
  char* end = nullptr;
  errno = 0;
  const unsigned long long mib = std::strtoull(v, &end, 10);
  if (end == v || *end != '\0' || errno != 0 || v[0] == '-' || mib < 64 || mib > (1ull << 20))
    throw std::invalid_argument(std::string("SKEL_HDF5_PROBE_MEMORY_MB must be a number of MiB from 64 to 1048576, got '") + v + "'");
  return static_cast<uint64_t>(mib) << 20;
}

MemoryUse memory_use() {
  MemoryUse use;
  std::FILE* f = std::fopen("/proc/self/status", "re");
  if (!f) return use;
  char line[256];
  while (std::fgets(line, sizeof line, f)) {
    unsigned long long kib = 0;
    if (std::sscanf(line, "VmSize: %llu kB", &kib) == 1) use.size = static_cast<uint64_t>(kib) << 10;
    if (std::sscanf(line, "VmData: %llu kB", &kib) == 1) use.data = static_cast<uint64_t>(kib) << 10;
  }
  std::fclose(f);
  return use;
}

namespace {
uint64_t g_size_limit = 0, g_data_limit = 0;
constexpr uint64_t kNearTheLimit = uint64_t{64} << 20;

// VmSize and VmData from /proc/self/status with system calls only (a signal handler).
bool memory_use_in_handler(uint64_t& size, uint64_t& data) {
  static char buf[4096];
  // Raw system calls: the sanitizer runtime's interceptors ask for the thread's stack bounds, which
  // needs memory, and there is none left.
  const long fd = syscall(SYS_openat, AT_FDCWD, "/proc/self/status", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const long n = syscall(SYS_read, fd, buf, sizeof buf - 1);
  syscall(SYS_close, fd);
  if (n <= 0) return false;
  buf[n] = '\0';
  // Plain loops: the sanitizer runtime's interceptors of strstr and strlen may need memory.
  const auto field = [&](const char* name) -> uint64_t {
    const char* p = nullptr;
    for (const char* line = buf; *line && !p; ++line) {
      if (line != buf && line[-1] != '\n') continue;
      size_t k = 0;
      while (name[k] && line[k] == name[k]) ++k;
      if (!name[k]) p = line + k;
    }
    if (!p) return 0;
    while (*p == ' ' || *p == '\t') ++p;
    uint64_t kib = 0;
    while (*p >= '0' && *p <= '9') kib = kib * 10 + static_cast<uint64_t>(*p++ - '0');
    return kib << 10;
  };
  size = field("VmSize:");
  data = field("VmData:");
  return true;
}

void on_fault(int sig) {
  uint64_t size = 0, data = 0;
  if (memory_use_in_handler(size, data) &&
      ((g_size_limit > 0 && size + kNearTheLimit > g_size_limit) || (g_data_limit > 0 && data + kNearTheLimit > g_data_limit)))
    syscall(SYS_exit_group, kWalkOutOfMemory);
  signal(sig, SIG_DFL);  // returning re-runs the faulting instruction, which now ends the process
}
}  // namespace

void exit_on_fault_at_the_limit() {
  struct sigaction sa {};
  sa.sa_handler = on_fault;
  sa.sa_flags = SA_RESETHAND;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGSEGV, &sa, nullptr);
  sigaction(SIGBUS, &sa, nullptr);
}

void limit_memory(const MemoryUse& base, uint64_t bytes) {
  g_size_limit = base.size + bytes;
  g_data_limit = base.data > 0 ? base.data + bytes : 0;
  const rlimit as{base.size + bytes, base.size + bytes};
  setrlimit(RLIMIT_AS, &as);
  if (base.data > 0) {
    const rlimit data{base.data + bytes, base.data + bytes};
    setrlimit(RLIMIT_DATA, &data);
  }
}

void quiet_hdf5_errors() { H5Eset_auto2(H5E_DEFAULT, on_hdf5_error, nullptr); }

static_assert(std::is_same_v<hid_t, int64_t>, "read_attribute takes an hid_t as int64_t");

Attribute read_attribute(int64_t obj, size_t index) {
  if (index >= kAttributeCount) return Attribute{};
  return is_string_attribute(index) ? read_string(obj, kAttributeNames[index]) : read_vec3(obj, kAttributeNames[index]);
}

// The answer: u32 names bytes, names, u32 records bytes, records (`first` and `second` first).
std::string encode(const WalkResult& r, const std::string& first, const std::string& second) {
  std::string records;
  const auto add = [&](const std::string& name) {
    const auto it = r.attributes.find(name);
    if (it == r.attributes.end()) return;
    std::string one;
    put_record(one, it->first, it->second);
    if (records.size() + one.size() <= kMaxRecordBytes) records += one;
  };
  add(first);
  if (second != first) add(second);
  for (const auto& [name, attributes] : r.attributes)
    if (name != first && name != second) add(name);
  std::string out;
  put_u32(out, static_cast<uint32_t>(r.names.size()));
  out += r.names;
  put_u32(out, static_cast<uint32_t>(records.size()));
  out += records;
  return out;
}

bool decode(const std::string& in, WalkResult& r) {
  r = WalkResult{};
  size_t at = 0;
  uint32_t n = 0;
  if (!get(in, at, &n, sizeof n) || n > kMaxNameBytes || n > in.size() - at) return false;
  r.names.assign(in, at, n);
  at += n;
  uint32_t records = 0;
  if (!get(in, at, &records, sizeof records) || records != in.size() - at) return false;
  while (at < in.size()) {
    uint32_t bytes = 0;
    if (!get(in, at, &bytes, sizeof bytes) || bytes > in.size() - at) return false;
    const std::string name(in, at, bytes);
    at += bytes;
    ObjectAttributes attributes;
    for (Attribute& a : attributes) {
      uint8_t kind = 0;
      if (!get(in, at, &kind, 1) || kind > static_cast<uint8_t>(Attribute::Kind::too_long)) return false;
      a.kind = static_cast<Attribute::Kind>(kind);
      if (a.kind == Attribute::Kind::numbers && !get(in, at, a.numbers.data(), sizeof(double) * 3)) return false;
      if (a.kind == Attribute::Kind::wrong_count && !get(in, at, &a.count, sizeof a.count)) return false;
      if (a.kind == Attribute::Kind::text) {
        uint32_t len = 0;
        if (!get(in, at, &len, sizeof len) || len > kMaxStringBytes || len > in.size() - at) return false;
        a.text.assign(in, at, len);
        at += len;
      }
    }
    r.attributes[name] = std::move(attributes);
  }
  return true;
}

bool out_of_memory_noted() { return g_out_of_memory; }
void forget_out_of_memory() { g_out_of_memory = false; }

int walk_file(const char* path, const std::string& dataset, std::string& payload) {
  g_out_of_memory = false;
  payload.clear();
  try {
    return walk(path, dataset, payload);
  } catch (const std::bad_alloc&) {  // the names under the address-space limit
    payload.clear();
    return kWalkOutOfMemory;
  }
}

}  // namespace skel::io::probe
