// The HDF5 structure probe (hdf5_probe.hpp): the readers' metadata walk in a forked, limited child.
#include "io/hdf5_probe.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#define SKEL_PROBE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SKEL_PROBE_ASAN 1
#endif
#endif
#ifdef SKEL_PROBE_ASAN
#include <sanitizer/common_interface_defs.h>
#endif

#include "skel/error.hpp"

namespace fs = std::filesystem;

namespace skel::io {

namespace {

// Address space the child may map beyond what the process had mapped when it forked. The readers'
// metadata walk needs a few MiB; 1 GiB stays below libFuzzer's -malloc_limit_mb=1024, so that a
// larger metadata allocation fails in the child instead of being reported by the fuzzer.
constexpr uint64_t kChildMemory = uint64_t{1} << 30;
constexpr double kDefaultTimeout = 60;
// Exit codes of the child.
constexpr int kChildOk = 0;
constexpr int kChildOutOfMemory = 3;
// Bytes of dataset names the child reports at most (names beyond are probed again when asked for).
constexpr size_t kMaxNameBytes = size_t{1} << 20;

// The attributes the readers read (hdf5_volume.cpp: read_geometry, read_string_attribute).
constexpr const char* kVec3Attributes[] = {"spacing", "origin", "element_size_um"};
constexpr const char* kStringAttributes[] = {"unit", "encoding"};

bool probe_enabled() {
  const char* v = std::getenv("SKEL_HDF5_PROBE");
  return !(v && std::string(v) == "0");
}

double probe_timeout() {
  const char* v = std::getenv("SKEL_HDF5_PROBE_TIMEOUT");
  if (!v || !*v) return kDefaultTimeout;
  char* end = nullptr;
  const double s = std::strtod(v, &end);
  if (end == v || *end != '\0' || !std::isfinite(s) || s <= 0)
    throw Error(std::string("SKEL_HDF5_PROBE_TIMEOUT must be a number of seconds > 0, got '") + v + "'");
  return s;
}

// ------------------------------------------------------------------ the child (libhdf5 only)

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

void read_vec3(hid_t obj, const char* name) {
  if (H5Aexists(obj, name) <= 0) return;
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  const hid_t s = a >= 0 ? H5Aget_space(a) : -1;
  if (s >= 0 && H5Sget_simple_extent_npoints(s) == 3) {
    double v[3];
    H5Aread(a, H5T_NATIVE_DOUBLE, v);
  }
  close_if(s, H5Sclose);
  close_if(a, H5Aclose);
}

void read_string(hid_t obj, const char* name) {
  if (H5Aexists(obj, name) <= 0) return;
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  const hid_t t = a >= 0 ? H5Aget_type(a) : -1;
  if (t >= 0 && H5Tget_class(t) == H5T_STRING) {
    const hid_t mem = H5Tcopy(H5T_C_S1);
    H5Tset_cset(mem, H5Tget_cset(t));
    if (H5Tis_variable_str(t) > 0) {
      H5Tset_size(mem, H5T_VARIABLE);
      char* value = nullptr;
      if (H5Aread(a, mem, &value) >= 0) H5free_memory(value);
    } else {
      const size_t n = H5Tget_size(t);
      std::string buf(n + 1, '\0');
      H5Tset_size(mem, n + 1);
      H5Aread(a, mem, buf.data());
    }
    close_if(mem, H5Tclose);
  }
  close_if(t, H5Tclose);
  close_if(a, H5Aclose);
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
  if (space >= 0 && H5Sget_simple_extent_ndims(space) == 3) {
    hsize_t dims[3];
    H5Sget_simple_extent_dims(space, dims, nullptr);
  }
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
  H5Dget_storage_size(d);
  hsize_t file_size = 0;
  H5Fget_filesize(file, &file_size);
  close_if(plist, H5Pclose);
  close_if(type, H5Tclose);
  close_if(space, H5Sclose);
  H5Dclose(d);
}

// An object by name: its attributes (all of them opened, the readers' ones read as the readers
// read them) and, for a dataset, walk_dataset.
void walk_object(hid_t file, const std::string& name) {
  look_up(file, name);
  const hid_t obj = H5Oopen(file, name.c_str(), H5P_DEFAULT);
  if (obj < 0) return;
  hsize_t at = 0;
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_NATIVE, &at, touch_attribute, nullptr);
  for (const char* a : kVec3Attributes) read_vec3(obj, a);
  for (const char* a : kStringAttributes) read_string(obj, a);
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

void write_all(int fd, const std::string& s) {
  size_t done = 0;
  while (done < s.size()) {
    const ssize_t n = ::write(fd, s.data() + done, s.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    done += static_cast<size_t>(n);
  }
}

// The readers' walk over the whole file, then the lookup of `dataset`; reports the names of the
// datasets it walked on `out` (NUL-separated).
int walk_file(const char* path, const std::string& dataset, int out) {
  if (H5Fis_hdf5(path) <= 0) return kChildOk;  // the reader refuses it in-process, as before
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  const hid_t file = H5Fopen(path, H5F_ACC_RDONLY, fapl);
  H5Pclose(fapl);
  if (file < 0) return g_out_of_memory ? kChildOutOfMemory : kChildOk;
  Visited v;
  H5Ovisit2(file, H5_INDEX_NAME, H5_ITER_NATIVE, collect, &v, H5O_INFO_BASIC);
  if (v.objects.empty()) v.objects.push_back("/");
  for (const auto& o : v.objects) walk_object(file, o);
  if (!dataset.empty() && dataset[0] == '/') {
    look_up(file, dataset);
    walk_object(file, dataset);
    // The group whose element_size_um read_geometry reads.
    const std::string group = dataset.substr(0, dataset.rfind('/'));
    walk_object(file, group.empty() ? "/" : group);
  }
  H5Fclose(file);
  if (g_out_of_memory) return kChildOutOfMemory;
  std::string names;
  for (const auto& d : v.datasets) {
    if (names.size() + d.size() + 1 > kMaxNameBytes) break;
    names += d;
    names += '\0';
  }
  write_all(out, names);
  return kChildOk;
}

[[noreturn]] void child_main(const char* path, const std::string& dataset, int out, pid_t parent, uint64_t address_limit,
                             double timeout) {
  // Die with the parent; the parent's handlers (libFuzzer's, sanitizers', the CLI's) do not apply here.
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) _exit(kChildOk);
  for (int s : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTRAP, SIGSYS, SIGALRM, SIGXCPU, SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGPIPE})
    signal(s, SIG_DFL);
  sigset_t all;
  sigemptyset(&all);
  sigprocmask(SIG_SETMASK, &all, nullptr);
#ifdef SKEL_PROBE_ASAN
  __sanitizer_set_death_callback(nullptr);  // libFuzzer's would save the input as its own finding
#endif
  // Silent: the verdict is the exit status (a sanitizer's report of libhdf5's bug would otherwise
  // reach the user's terminal; SKEL_HDF5_PROBE=0 reproduces it in-process).
  const int null = open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null >= 0) {
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
  }
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  const rlimit as{address_limit, address_limit};
  setrlimit(RLIMIT_AS, &as);
  alarm(static_cast<unsigned>(std::ceil(timeout)) + 2);  // a second stop, should the parent be gone
  H5Eset_auto2(H5E_DEFAULT, on_hdf5_error, nullptr);
  int code = kChildOk;
  try {
    code = walk_file(path, dataset, out);
  } catch (...) {  // std::bad_alloc of the names under the address-space limit
    code = kChildOutOfMemory;
  }
  _exit(code);
}

// ------------------------------------------------------------------ the parent

// Bytes of address space this process has mapped (/proc/self/statm, first field, in pages).
uint64_t mapped_bytes() {
  std::ifstream in("/proc/self/statm");
  uint64_t pages = 0;
  in >> pages;
  return pages * static_cast<uint64_t>(sysconf(_SC_PAGESIZE));
}

struct Stamp {
  dev_t dev = 0;
  ino_t ino = 0;
  off_t size = 0;
  int64_t mtime_ns = 0, ctime_ns = 0;
  bool operator==(const Stamp&) const = default;
};

struct Verdict {
  Stamp stamp;
  std::string refusal;          // empty: the file may be read
  std::set<std::string> names;  // dataset names the probes covered
};

std::mutex g_cache_mutex;
std::map<std::string, Verdict> g_cache;
int64_t g_started = 0;

std::string signal_name(int sig) {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGABRT: return "SIGABRT";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGKILL: return "SIGKILL";
    case SIGALRM: return "SIGALRM";
    case SIGTRAP: return "SIGTRAP";
    case SIGSYS: return "SIGSYS";
    default: return "signal " + std::to_string(sig);
  }
}

std::string format_seconds(double s) {
  std::ostringstream o;
  o << s;
  return o.str();
}

// Runs one probe process; returns the refusal ("" when the file may be read) and the names it covered.
std::string run_probe(const fs::path& file, const std::string& dataset, std::set<std::string>& names) {
  const double timeout = probe_timeout();
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0)
    throw Error("cannot check the HDF5 file " + file.string() + " in a separate process: pipe: " + std::strerror(errno) +
                " (SKEL_HDF5_PROBE=0 reads trusted files without this check)");
  const uint64_t limit = mapped_bytes() + kChildMemory;
  const pid_t parent = getpid();
  const std::string path = file.string();
  const auto start = std::chrono::steady_clock::now();  // the time counts from the fork
  const pid_t pid = fork();
  if (pid < 0) {
    const int err = errno;
    close(fds[0]);
    close(fds[1]);
    throw Error("cannot check the HDF5 file " + file.string() + " in a separate process: fork: " + std::strerror(err) +
                " (SKEL_HDF5_PROBE=0 reads trusted files without this check)");
  }
  if (pid == 0) {
    close(fds[0]);
    child_main(path.c_str(), dataset, fds[1], parent, limit, timeout);
  }
  {
    std::lock_guard lock(g_cache_mutex);
    ++g_started;
  }
  close(fds[1]);
  fcntl(fds[0], F_SETFL, O_NONBLOCK);
  // Reads what the child reports and waits for it, at most `timeout` seconds. The pipe is not relied
  // on for the end: a process forked meanwhile by another thread may hold its write end.
  const auto deadline = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(timeout));
  std::string out;
  int status = 0;
  bool timed_out = false;
  auto drain = [&] {
    char buf[65536];
    for (;;) {
      const ssize_t n = read(fds[0], buf, sizeof buf);
      if (n > 0) {
        if (out.size() < kMaxNameBytes) out.append(buf, static_cast<size_t>(n));
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      return;
    }
  };
  for (;;) {
    // The deadline first: a child the parent sees only after the deadline did not finish in time.
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) {
      kill(pid, SIGKILL);
      while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      timed_out = true;
      break;
    }
    const pid_t w = waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    if (w < 0 && errno != EINTR) {
      status = -1;
      break;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count();
    pollfd p{fds[0], POLLIN, 0};
    // Short polls: the child's exit is seen by waitpid within 20 ms even when the pipe stays open.
    if (poll(&p, 1, static_cast<int>(std::min<long long>(left + 1, 20))) > 0) drain();
  }
  drain();
  close(fds[0]);
  const std::string what = file.string() + " is damaged: the HDF5 library ";
  const std::string tail = " reading its structure in a separate process; not opened";
  if (timed_out) return what + "did not finish within " + format_seconds(timeout) + " s" + tail + " (SKEL_HDF5_PROBE_TIMEOUT sets the limit)";
  if (status == -1) return "";  // the child was reaped elsewhere (a SIGCHLD handler): no verdict, read as before
  if (WIFSIGNALED(status)) return what + "crashed (" + signal_name(WTERMSIG(status)) + ")" + tail;
  if (WIFEXITED(status) && WEXITSTATUS(status) == kChildOutOfMemory)
    return what + "needed more than " + std::to_string(kChildMemory >> 20) + " MiB of memory" + tail;
  if (WIFEXITED(status) && WEXITSTATUS(status) != kChildOk)
    return what + "failed (exit status " + std::to_string(WEXITSTATUS(status)) + ", e.g. a sanitizer report)" + tail;
  for (size_t b = 0; b < out.size();) {
    const size_t e = out.find('\0', b);
    if (e == std::string::npos) break;
    names.insert(out.substr(b, e - b));
    b = e + 1;
  }
  return "";
}

}  // namespace

void probe_hdf5_file(const fs::path& file, const std::string& dataset) {
  if (!probe_enabled()) return;
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return;  // the reader says what is wrong
  Stamp stamp{st.st_dev, st.st_ino, st.st_size, int64_t{st.st_mtim.tv_sec} * 1000000000 + st.st_mtim.tv_nsec,
              int64_t{st.st_ctim.tv_sec} * 1000000000 + st.st_ctim.tv_nsec};
  std::error_code ec;
  fs::path abs = fs::absolute(file, ec);
  const std::string key = (ec ? file : abs.lexically_normal()).string();
  bool known = false;
  {
    std::lock_guard lock(g_cache_mutex);
    auto it = g_cache.find(key);
    if (it != g_cache.end() && it->second.stamp == stamp) {
      if (!it->second.refusal.empty()) throw InputError(it->second.refusal);
      if (dataset.empty() || it->second.names.count(dataset)) return;
      known = true;  // the file was walked; the lookup of this name was not
    }
  }
  std::set<std::string> names;
  const std::string refusal = run_probe(file, dataset, names);
  {
    std::lock_guard lock(g_cache_mutex);
    Verdict& v = g_cache[key];
    if (!known || !(v.stamp == stamp)) v = Verdict{stamp, {}, {}};
    v.refusal = refusal;
    v.names.insert(names.begin(), names.end());
    if (!dataset.empty() && refusal.empty()) v.names.insert(dataset);
  }
  if (!refusal.empty()) throw InputError(refusal);
}

namespace detail {
int64_t hdf5_probes_started() {
  std::lock_guard lock(g_cache_mutex);
  return g_started;
}
void forget_hdf5_probes() {
  std::lock_guard lock(g_cache_mutex);
  g_cache.clear();
}
}  // namespace detail

}  // namespace skel::io
