// skelflow-hdf5-probe: the helper program of the HDF5 structure probe (hdf5_probe.hpp). It runs the
// readers' metadata walk (hdf5_probe_walk.hpp) of a user's .h5 file in a process of its own, built
// with AddressSanitizer where the compiler has it (CMake option SKEL_HDF5_PROBE_ASAN), so that a
// memory error of libhdf5 that would not crash a process (a heap overflow in memcpy) stops it.
//
//   skelflow-hdf5-probe --worker PARENT_PID   serve requests on stdin (a socket from hdf5_probe.cpp)
//   skelflow-hdf5-probe FILE [DATASET]        walk one file; exit status 0 (the walk finished), 3
//                                             (libhdf5 ran out of its memory), or the sanitizer's
//                                             report on stderr: to see why a file was refused
//
// Worker protocol (native byte order, one request at a time, on the socket that is stdin):
//   request  u32 path bytes, u32 dataset bytes, u32 seconds for alarm(), u32 request id (> 0),
//            u32 kind (h5::Request: 0 the walk, else the readers' requests of hdf5_read.hpp),
//            u32 extra bytes, path, dataset, extra (the kind's fixed part)
//   reply    u32 request id, u32 outcome (kWalkOk, kWalkOutOfMemory, kWalkDied, h5::kRefused,
//            h5::kFailed), u32 payload bytes, payload: for the walk the encoded WalkResult (the dataset
//            names walked and the readers' attributes, hdf5_probe_walk.hpp), for the other kinds
//            their answer or the error's message; for kWalkDied the walker's wait status
// Descriptor 3 (h5::kWindowFd) is the client's shared memory window: read requests write the voxels
// of their box there.
// The worker is a small server that forks a walker from its initialised state; the walker answers
// requests until it dies or retires. A crash, a sanitizer report (exit status 66) or alarm() ends
// the walker during a request: the server answers that request with kWalkDied and forks the next
// walker, so the client refuses that file and goes on with the same worker. A walker retires itself
// after running out of memory, when libhdf5 kept objects open, or when its address space grew by more
// than 256 MiB. The worker ends at EOF on stdin and when its parent dies (PR_SET_PDEATHSIG); the
// client kills its process group when a request runs past the timeout.
#include <hdf5.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "io/hdf5_probe_walk.hpp"
#include "io/hdf5_read.hpp"

// AddressSanitizer's settings when the helper is built with it (ASAN_OPTIONS adds to them; the
// client removes the caller's ASAN_OPTIONS and LSAN_OPTIONS from the worker's environment): no leak
// check (libhdf5 leaks on corrupt files; the worker's memory is bounded by retiring), a failed
// allocation returns NULL as glibc's would (libhdf5 then reports it), none above 1 GiB, a report
// ends the process with status 66; SIGSEGV, SIGBUS, SIGFPE, SIGILL and SIGABRT are left to kill it
// (the client names the signal).
extern "C" const char* __asan_default_options() {
  return "detect_leaks=0:allocator_may_return_null=1:max_allocation_size_mb=1024:quarantine_size_mb=64:"
         "exitcode=66:abort_on_error=0:disable_coredump=1:handle_segv=0:handle_sigbus=0:handle_sigfpe=0:handle_sigill=0:handle_abort=0";
}

namespace {

using namespace skel::io::probe;
namespace h5 = skel::io::h5;

constexpr uint64_t kRetireGrowth = uint64_t{256} << 20;  // growth after which the worker retires
constexpr uint32_t kMaxRequestBytes = uint32_t{1} << 20;

// True when this process has mapped more than kRetireGrowth beyond `base` (address space or, under
// AddressSanitizer, whose allocator range is reserved at start-up, private writable memory).
bool grown(const MemoryUse& base) {
  const MemoryUse now = memory_use();
  return now.size > base.size + kRetireGrowth || now.data > base.data + kRetireGrowth;
}

// The memory limit of SKEL_HDF5_PROBE_MEMORY_MB (the client checked it), else the default.
uint64_t memory_limit() {
  try {
    return memory_limit_bytes();
  } catch (const std::exception&) {
    return kDefaultMemoryMiB << 20;
  }
}

bool read_all(int fd, void* data, size_t n) {
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<size_t>(r);
  }
  return true;
}

bool write_all(int fd, const void* data, size_t n) {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t r = ::write(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<size_t>(r);
  }
  return true;
}

// Closes what libhdf5 still holds open after a walk of a corrupt file; true when nothing is left (a
// file left open would be shared by the next H5Fopen of the same file, with its stale metadata).
bool close_leftovers() {
  const ssize_t n = H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL);
  if (n <= 0) return n == 0;
  std::vector<hid_t> ids(static_cast<size_t>(n));
  const ssize_t got = H5Fget_obj_ids(H5F_OBJ_ALL, H5F_OBJ_ALL, ids.size(), ids.data());
  for (ssize_t i = 0; i < got; ++i) {
    const hid_t id = ids[static_cast<size_t>(i)];
    switch (H5Iget_type(id)) {
      case H5I_FILE: H5Fclose(id); break;
      case H5I_GROUP: H5Gclose(id); break;
      case H5I_DATASET: H5Dclose(id); break;
      case H5I_DATATYPE: H5Tclose(id); break;
      case H5I_ATTR: H5Aclose(id); break;
      default: break;
    }
  }
  return H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL) == 0;
}

// Exit status of a walker that retires itself (the server starts a new one, the client sees nothing).
constexpr int kRetired = 5;

// A walker: serves requests on stdin until EOF (exit 0) or until it retires (kRetired, after its
// reply). `current` (shared with the server) holds the id of the request being walked, 0 between
// requests, so that the server knows whether a death ended a request.
int walk_requests(const MemoryUse& base, volatile uint32_t* current) {
  std::string path, dataset, extra, payload;
  for (;;) {
    uint32_t head[6];
    if (!read_all(STDIN_FILENO, head, sizeof head)) return 0;
    if (head[0] > kMaxRequestBytes || head[1] > kMaxRequestBytes || head[3] == 0 || head[4] >= h5::kRequestKinds ||
        head[5] > kMaxRequestBytes)
      return 2;
    path.assign(head[0], '\0');
    dataset.assign(head[1], '\0');
    extra.assign(head[5], '\0');
    if (!read_all(STDIN_FILENO, path.data(), path.size()) || !read_all(STDIN_FILENO, dataset.data(), dataset.size()) ||
        !read_all(STDIN_FILENO, extra.data(), extra.size()))
      return 0;
    *current = head[3];
    alarm(head[2]);  // a second stop, should the client be gone
    const auto kind = static_cast<h5::Request>(head[4]);
    int outcome = kWalkOk;
    if (kind == h5::Request::walk) {
      outcome = walk_file(path.c_str(), dataset, payload);
    } else {
      forget_out_of_memory();
      outcome = h5::serve_request(kind, path, dataset, extra, h5::kWindowFd, payload);
      if (outcome != kWalkOutOfMemory && out_of_memory_noted()) {
        outcome = kWalkOutOfMemory;
        payload.clear();
      }
      // The chunk decoder turns libhdf5's error printing off per thread; the walk's handler, which
      // notes failed allocations, comes back for this thread.
      quiet_hdf5_errors();
    }
    alarm(0);
    const bool clean = close_leftovers();
    // A refused read (an InputError: a wrong name, a damaged chunk) leaves the walker as it was.
    const bool retire = (outcome != kWalkOk && outcome != h5::kRefused) || !clean || grown(base);
    const uint32_t reply[3] = {head[3], static_cast<uint32_t>(outcome), static_cast<uint32_t>(payload.size())};
    // stdin is a socket: the reply goes back on it.
    if (!write_all(STDIN_FILENO, reply, sizeof reply) || !write_all(STDIN_FILENO, payload.data(), payload.size())) return 0;
    *current = 0;
    if (retire) return kRetired;
  }
}

// The worker: a server that forks walkers from its initialised state (libraries loaded, AddressSanitizer
// and libhdf5 set up: a fork of this small process costs far less than starting the program again).
// When a walker dies during a request (a crash, a sanitizer report, alarm), the server answers that
// request with the walker's wait status and forks the next walker.
int serve(pid_t parent) {
  // Die with the parent (the thread that started this process, see hdf5_probe.cpp); EOF on stdin
  // ends the worker too.
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) return 0;
  H5open();
  // libhdf5 keeps freed objects of a kind on a free list only up to 64 KiB per list by default, so
  // the metadata cache of each opened file (a calloc of 524 KiB) is a fresh mapping under
  // AddressSanitizer, a page fault per 4 KiB: 2.6 ms per H5Fopen against 0.18 ms with room for it on
  // the list (every request opens the file). Arrays and blocks keep their limits.
  H5set_free_list_limits(4 << 20, 1 << 20, 4 << 20, 1 << 18, 16 << 20, 1 << 20);
  auto* current = static_cast<volatile uint32_t*>(mmap(nullptr, 4096, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0));
  if (current == MAP_FAILED) return 4;
  limit_memory(memory_use(), memory_limit());
  exit_on_fault_at_the_limit();
  const pid_t server = getpid();
  // Ready: the client waits for this before its first request (a helper that cannot start, e.g. a
  // missing shared library, is then an error about the helper, not a verdict on a file).
  if (!write_all(STDIN_FILENO, &kWorkerReady, sizeof kWorkerReady)) return 0;
  for (;;) {
    *current = 0;
    const pid_t walker = fork();
    if (walker < 0) return 4;
    if (walker == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != server) _exit(0);
      _exit(walk_requests(memory_use(), current));
    }
    int status = 0;
    while (waitpid(walker, &status, 0) < 0) {
      if (errno != EINTR) return 4;
    }
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return 0;  // EOF: the client is done
    if (WIFEXITED(status) && WEXITSTATUS(status) == kRetired) continue;
    const uint32_t id = *current;
    if (id == 0) continue;  // died between requests: nobody is waiting for an answer
    const uint32_t notice[4] = {id, kWalkDied, 4, static_cast<uint32_t>(status)};
    if (!write_all(STDIN_FILENO, notice, sizeof notice)) return 0;
  }
}

}  // namespace

int main(int argc, char** argv) {
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  quiet_hdf5_errors();
  if (argc == 3 && std::string(argv[1]) == "--worker") {
    char* end = nullptr;
    const long parent = std::strtol(argv[2], &end, 10);
    if (end == argv[2] || *end != '\0' || parent <= 0) return 2;
    std::_Exit(serve(static_cast<pid_t>(parent)));  // no atexit work: the walk's state is not worth tearing down
  }
  if (argc < 2 || argc > 3 || argv[1][0] == '-') {
    std::fprintf(stderr,
                 "usage: %s FILE [DATASET]\n"
                 "  walks the metadata of an HDF5 file as Skelflow's structure probe does (docs/reliability.md);\n"
                 "  exit status 0: the walk finished; 3: libhdf5 needed more than SKEL_HDF5_PROBE_MEMORY_MB (default\n"
                 "  1024 MiB); otherwise libhdf5 crashed\n"
                 "  or, in a build with AddressSanitizer, made a memory error (its report above, status 66)\n",
                 argv[0]);
    return 2;
  }
  limit_memory(memory_use(), memory_limit());
  exit_on_fault_at_the_limit();
  std::string payload;
  const int outcome = walk_file(argv[1], argc == 3 ? argv[2] : "", payload);
  if (outcome == kWalkOutOfMemory) {
    std::fprintf(stderr, "%s: the HDF5 library needed more than %llu MiB of memory\n", argv[1],
                 static_cast<unsigned long long>(memory_limit() >> 20));
    return outcome;
  }
  WalkResult result;
  decode(payload, result);
  for (size_t b = 0; b < result.names.size();) {
    const size_t e = result.names.find('\0', b);
    std::printf("%s\n", result.names.substr(b, e - b).c_str());
    b = e + 1;
  }
  // The readers' attributes as the walk read them.
  for (const auto& [object, attributes] : result.attributes)
    for (size_t i = 0; i < kAttributeCount; ++i) {
      const Attribute& a = attributes[i];
      if (a.kind == Attribute::Kind::absent) continue;
      std::printf("%s @%s: ", object.c_str(), kAttributeNames[i]);
      switch (a.kind) {
        case Attribute::Kind::numbers: std::printf("%.17g %.17g %.17g\n", a.numbers[0], a.numbers[1], a.numbers[2]); break;
        case Attribute::Kind::text: std::printf("\"%s\"\n", a.text.c_str()); break;
        case Attribute::Kind::wrong_count: std::printf("%lld values (3 expected)\n", static_cast<long long>(a.count)); break;
        case Attribute::Kind::not_string: std::printf("not a string\n"); break;
        case Attribute::Kind::too_long: std::printf("a string longer than %zu bytes\n", kMaxStringBytes); break;
        default: std::printf("cannot be read\n"); break;
      }
    }
  return 0;
}
