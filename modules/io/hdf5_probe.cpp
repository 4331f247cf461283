// The HDF5 structure probe (hdf5_probe.hpp): the readers' metadata walk (hdf5_probe_walk.hpp) in a
// persistent helper process (skelflow-hdf5-probe), or in a forked child when the helper is not found.
#include "io/hdf5_probe.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
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

#include "io/hdf5_probe_walk.hpp"
#include "io/hdf5_read.hpp"
#include "skel/error.hpp"

extern char** environ;

namespace fs = std::filesystem;

namespace skel::io {

namespace {

// Memory the walk may map beyond what its process had mapped (the helper's start-up mapping, or this
// process's for the forked child): probe::memory_limit_bytes(), SKEL_HDF5_PROBE_MEMORY_MB, default
// 1 GiB. The readers' metadata walk needs a few MiB, the voxel walk up to 64 MiB plus libhdf5's chunk
// cache; 1 GiB stays below libFuzzer's -malloc_limit_mb=1024, so that a larger metadata allocation
// fails in the probe instead of being reported by the fuzzer.
uint64_t child_memory() {
  try {
    return probe::memory_limit_bytes();
  } catch (const std::invalid_argument& e) {
    throw Error(e.what());
  }
}

std::string too_much_memory(const fs::path& file);
constexpr double kDefaultTimeout = 60;
// Exit status of the helper when AddressSanitizer stopped it (its exitcode, hdf5_probe_main.cpp).
constexpr int kSanitizerExit = 66;
constexpr const char* kHelperName = "skelflow-hdf5-probe";

enum class Mode { off, helper, fork };

Mode probe_mode() {
  const char* v = std::getenv("SKEL_HDF5_PROBE");
  if (!v || !*v || std::string(v) == "1") return Mode::helper;
  if (std::string(v) == "0") return Mode::off;
  if (std::string(v) == "fork") return Mode::fork;
  throw Error(std::string("SKEL_HDF5_PROBE must be 0 (off), 1 (the helper program, the default) or fork, got '") + v + "'");
}

double probe_timeout() {
  const char* v = std::getenv("SKEL_HDF5_PROBE_TIMEOUT");
  if (!v || !*v) return kDefaultTimeout;
  char* end = nullptr;
  const double s = std::strtod(v, &end);
  if (end == v || *end != '\0' || !std::isfinite(s) || s <= 0)
    throw Error(std::string("SKEL_HDF5_PROBE_TIMEOUT must be a number of seconds > 0, got '") + v + "'");
  return std::min(s, 1e7);  // ~4 months: "no limit" without overflowing the clock arithmetic
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
  std::map<std::string, probe::ObjectAttributes> attributes;  // the readers' attributes, per object walked
  std::map<std::string, std::string> infos;  // the helper's answers to info requests, per dataset
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

// What the request that failed was doing: the walk reads the file's structure, the others read
// what the reader asked for (hdf5_read.hpp).
thread_local const char* g_doing = "reading its structure";

std::string damaged(const fs::path& file, const std::string& what) {
  return file.string() + " is damaged: the HDF5 library " + what + " " + g_doing + " in a separate process; not opened";
}

std::string too_much_memory(const fs::path& file) {
  return damaged(file, "needed more than " + std::to_string(child_memory() >> 20) + " MiB of memory") +
         " (SKEL_HDF5_PROBE_MEMORY_MB sets the limit)";
}

std::string timed_out(const fs::path& file, double timeout) {
  return damaged(file, "did not finish within " + format_seconds(timeout) + " s") + " (SKEL_HDF5_PROBE_TIMEOUT sets the limit)";
}

// The verdict on a probe process that ended before it answered (status from waitpid).
std::string ended(const fs::path& file, int status) {
  if (WIFSIGNALED(status)) return damaged(file, "crashed (" + signal_name(WTERMSIG(status)) + ")");
  if (WIFEXITED(status) && WEXITSTATUS(status) == probe::kWalkOutOfMemory)
    return too_much_memory(file);
  if (WIFEXITED(status) && WEXITSTATUS(status) == kSanitizerExit) return damaged(file, "made a memory error (AddressSanitizer)");
  return damaged(file, "failed (exit status " + std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")");
}

std::chrono::steady_clock::time_point deadline_after(double timeout) {
  return std::chrono::steady_clock::now() +
         std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(timeout));
}

// Milliseconds to `deadline`, rounded up, at least 0.
int ms_until(std::chrono::steady_clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::microseconds>(deadline - std::chrono::steady_clock::now()).count();
  if (left <= 0) return 0;
  return static_cast<int>(std::min<long long>((left + 999) / 1000, 1 << 30));
}

void reap(pid_t pid, int* status = nullptr) {
  int s = 0;
  while (waitpid(pid, &s, 0) < 0 && errno == EINTR) {
  }
  if (status) *status = s;
}

void add_names(const std::string& out, std::set<std::string>& names) {
  for (size_t b = 0; b < out.size();) {
    const size_t e = out.find('\0', b);
    if (e == std::string::npos) break;
    names.insert(out.substr(b, e - b));
    b = e + 1;
  }
}

// A walk's answer into `result`; "" when it decodes, else the refusal (a walk that sent bytes out of
// the protocol did not finish as it should have).
std::string take_answer(const fs::path& file, const std::string& payload, probe::WalkResult& result) {
  if (probe::decode(payload, result)) return "";
  result = probe::WalkResult{};
  return damaged(file, "gave a malformed answer");
}

// ------------------------------------------------------------------ the helper program, as a worker

// The helper program: SKEL_HDF5_PROBE_HELPER, else skelflow-hdf5-probe beside this program (or
// beside the shared object this code is in, or in its ../bin), else the one of the build tree; ""
// when there is none.
std::string find_helper() {
  if (const char* v = std::getenv("SKEL_HDF5_PROBE_HELPER"); v && *v) {
    if (::access(v, X_OK) != 0)
      throw Error(std::string("SKEL_HDF5_PROBE_HELPER=") + v + " is not an executable program: " + std::strerror(errno));
    return v;
  }
  std::vector<fs::path> dirs;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) dirs.push_back(self.parent_path());
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&probe_hdf5_file), &info) != 0 && info.dli_fname && info.dli_fname[0] == '/') {
    const fs::path object = fs::path(info.dli_fname).parent_path();
    dirs.push_back(object);
    dirs.push_back(object.parent_path() / "bin");
  }
  for (const auto& d : dirs) {
    const fs::path p = d / kHelperName;
    if (::access(p.c_str(), X_OK) == 0) return p.string();
  }
#ifdef SKEL_HDF5_PROBE_BUILD_PATH
  if (::access(SKEL_HDF5_PROBE_BUILD_PATH, X_OK) == 0) return SKEL_HDF5_PROBE_BUILD_PATH;
#endif
  return "";
}

struct Worker {
  pid_t pid = -1;
  int fd = -1;       // this process's end of the socket
  pid_t owner = -1;  // the process that started it (a forked copy of this process must not use it)
  std::string helper;
  // The shared memory window of read requests (hdf5_read.hpp): a memfd that is the worker's
  // descriptor h5::kWindowFd, mapped here read-only; grown when a request needs more.
  int window_fd = -1;
  uint64_t window_bytes = 0;
  void* window = nullptr;
};

std::mutex g_worker_mutex;
Worker g_worker;
int64_t g_workers_started = 0;
uint32_t g_request_id = 0;

// Ends the worker (caller holds g_worker_mutex): closing the socket makes it exit; it is reaped.
void stop_worker(bool kill_it) {
  if (g_worker.window) munmap(g_worker.window, g_worker.window_bytes);
  if (g_worker.window_fd >= 0) close(g_worker.window_fd);
  if (g_worker.owner != getpid()) {  // inherited through fork: not this process's child
    if (g_worker.fd >= 0) close(g_worker.fd);
    g_worker = Worker{};
    return;
  }
  if (g_worker.fd >= 0) close(g_worker.fd);
  if (g_worker.pid > 0) {
    if (kill_it) kill(-g_worker.pid, SIGKILL);  // its process group: the server and its walker
    reap(g_worker.pid);
  }
  g_worker = Worker{};
}

// The worker's environment: this process's, without the sanitizer settings meant for it (the helper
// sets its own, hdf5_probe_main.cpp), and no symbolizing of the reports nobody reads (that started
// llvm-symbolizer for every file with a memory error: 40 % of the fuzz target's time).
std::vector<std::string> worker_environment() {
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    const std::string v = *e;
    if (v.rfind("ASAN_OPTIONS=", 0) == 0 || v.rfind("LSAN_OPTIONS=", 0) == 0 || v.rfind("UBSAN_OPTIONS=", 0) == 0) continue;
    env.push_back(v);
  }
  env.push_back("ASAN_OPTIONS=symbolize=0");
  env.push_back("UBSAN_OPTIONS=symbolize=0:print_stacktrace=0:halt_on_error=1");
  return env;
}

bool send_all(int fd, const void* data, size_t n) {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t r = ::send(fd, p, n, MSG_NOSIGNAL);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<size_t>(r);
  }
  return true;
}

enum class Receive { done, ended, late };

// Reads exactly `n` bytes before `deadline`: done, ended (EOF or error: the worker is gone) or late.
// The deadline first: what is there only after it came too late (poll's timeout is in whole
// milliseconds, longer than a limit below one).
Receive receive(int fd, void* data, size_t n, std::chrono::steady_clock::time_point deadline) {
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    if (std::chrono::steady_clock::now() >= deadline) return Receive::late;
    pollfd q{fd, POLLIN, 0};
    const int ms = ms_until(deadline);
    const int r = poll(&q, 1, ms);
    if (r < 0 && errno == EINTR) continue;
    if (r == 0) return Receive::late;
    if (r < 0) return Receive::ended;
    const ssize_t got = ::recv(fd, p, n, 0);
    if (got < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    if (got <= 0) return Receive::ended;
    p += got;
    n -= static_cast<size_t>(got);
  }
  return Receive::done;
}

void start_worker(const std::string& helper, const fs::path& file, double timeout) {
  const auto fail = [&](const std::string& what, int err) {
    throw Error("cannot check the HDF5 file " + file.string() + " in a separate process: " + what + ": " + std::strerror(err) +
                " (SKEL_HDF5_PROBE=0 reads trusted files without this check)");
  };
  int sv[2];
  if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) fail("socketpair", errno);
  // The worker's end becomes its stdin; it must not be 0-2 already (dup2 onto itself would keep
  // close-on-exec).
  int child_end = sv[1];
  if (child_end <= 2) {
    child_end = fcntl(sv[1], F_DUPFD_CLOEXEC, 3);
    close(sv[1]);
    if (child_end < 0) {
      close(sv[0]);
      fail("fcntl", errno);
    }
  }
  // The window of read requests becomes the worker's descriptor h5::kWindowFd (3); here it is above
  // 3, so that the dup2 of the socket onto 0 and of the window onto 3 cannot clobber each other.
  int window = memfd_create("skelflow-hdf5-window", MFD_CLOEXEC);
  if (window >= 0 && window <= h5::kWindowFd) {
    const int moved = fcntl(window, F_DUPFD_CLOEXEC, h5::kWindowFd + 1);
    close(window);
    window = moved;
  }
  if (window < 0) {
    const int err = errno;
    close(sv[0]);
    close(child_end);
    fail("memfd_create", err);
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, child_end, STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, window, h5::kWindowFd);
  // Silent: a sanitizer's report of libhdf5's bug would otherwise reach the user's terminal
  // (`skelflow-hdf5-probe FILE` shows it).
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  // Nothing else of this process: descriptors opened without close-on-exec (std::ofstream's, a
  // caller's pipe) would stay open as long as the worker lives.
  posix_spawn_file_actions_addclosefrom_np(&actions, h5::kWindowFd + 1);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none, all;
  sigemptyset(&none);
  sigfillset(&all);
  sigdelset(&all, SIGKILL);
  sigdelset(&all, SIGSTOP);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &all);  // not this process's ignored signals or handlers
  // Its own process group: a Ctrl-C at the terminal cancels the run (which stops asking), not the walk.
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
  const std::string parent = std::to_string(getpid());
  std::vector<std::string> env = worker_environment();
  std::vector<char*> envp;
  for (auto& e : env) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::string arg0 = helper, arg1 = "--worker", arg2 = parent;
  char* argv[] = {arg0.data(), arg1.data(), arg2.data(), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, helper.c_str(), &actions, &attr, argv, envp.data());
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  close(child_end);
  if (rc != 0) {
    close(sv[0]);
    close(window);
    fail("cannot start " + helper, rc);
  }
  g_worker = Worker{pid, sv[0], getpid(), helper, window, 0, nullptr};
  ++g_workers_started;
  // Wait until it is ready: a helper that cannot start (a missing shared library such as libasan8,
  // a wrong program) is an error about the helper, not a verdict on the user's file.
  uint32_t ready = 0;
  const Receive got = receive(g_worker.fd, &ready, sizeof ready, deadline_after(std::max(timeout, 10.0)));
  if (got == Receive::done && ready == probe::kWorkerReady) return;
  kill(-pid, SIGKILL);
  close(g_worker.fd);
  close(g_worker.window_fd);
  int status = 0;
  reap(pid, &status);
  g_worker = Worker{};
  const std::string how = got == Receive::late     ? "did not start within " + format_seconds(std::max(timeout, 10.0)) + " s"
                          : WIFEXITED(status)      ? "exited with status " + std::to_string(WEXITSTATUS(status))
                          : WIFSIGNALED(status)    ? "was killed by " + signal_name(WTERMSIG(status))
                                                   : "did not answer as expected";
  throw Error("cannot check the HDF5 file " + file.string() + ": the probe helper " + helper + " " + how +
              " (run it with a file to see why; SKEL_HDF5_PROBE_HELPER names another, SKEL_HDF5_PROBE=0 reads trusted files "
              "without this check)");
}


// Makes the window at least `bytes` long (caller holds g_worker_mutex, a worker runs).
void grow_window(uint64_t bytes, const fs::path& file) {
  if (bytes <= g_worker.window_bytes) return;
  const uint64_t want = (bytes + (uint64_t{1} << 20) - 1) & ~((uint64_t{1} << 20) - 1);
  if (g_worker.window) munmap(g_worker.window, g_worker.window_bytes);
  g_worker.window = nullptr;
  g_worker.window_bytes = 0;
  if (ftruncate(g_worker.window_fd, static_cast<off_t>(want)) != 0)
    throw Error("cannot read the HDF5 file " + file.string() + " through the probe helper: the shared window of " +
                std::to_string(want >> 20) + " MiB: " + std::strerror(errno));
  // Mapped once and populated: a fault per 4 KiB page, a window's worth per read, cost more than
  // the copy on this kind of virtual machine (shared memory gets no huge pages here).
  void* map = mmap(nullptr, want, PROT_READ, MAP_SHARED | MAP_POPULATE, g_worker.window_fd, 0);
  if (map == MAP_FAILED)
    throw Error("cannot read the HDF5 file " + file.string() + " through the probe helper: mapping the shared window of " +
                std::to_string(want >> 20) + " MiB: " + std::strerror(errno));
  g_worker.window = map;
  g_worker.window_bytes = want;
}

// One request of `kind` to the worker (caller holds g_worker_mutex), starting it when none runs.
// Returns "" when the worker answered (`outcome` and `out` hold its reply), else the refusal: the
// request ran past the timeout, or the process serving it died (the worker goes on, or is replaced).
std::string exchange(const std::string& helper, const fs::path& file, const std::string& dataset, h5::Request kind,
                     const std::string& extra, uint64_t window_bytes, double timeout, uint32_t& outcome, std::string& out) {
  const std::string path = file.string();
  if (path.size() > (size_t{1} << 20) || dataset.size() > (size_t{1} << 20) || extra.size() > (size_t{1} << 20))
    throw InputError(path + ": the file or dataset name is too long to be checked");
  for (int attempt = 0;; ++attempt) {
    if (g_worker.owner != getpid() || g_worker.helper != helper) stop_worker(false);
    if (g_worker.pid > 0) {
      // A worker that ended between requests (it failed, or the thread that started it ended:
      // PR_SET_PDEATHSIG) is reaped and replaced.
      int status = 0;
      const pid_t w = waitpid(g_worker.pid, &status, WNOHANG);
      if (w == g_worker.pid || (w < 0 && errno == ECHILD)) {
        g_worker.pid = -1;
        stop_worker(false);
      }
    }
    if (g_worker.pid <= 0) start_worker(helper, file, timeout);
    grow_window(window_bytes, file);
    if (kind == h5::Request::walk) {
      std::lock_guard lock(g_cache_mutex);
      ++g_started;
    }
    const auto deadline = deadline_after(timeout);
    const uint32_t id = ++g_request_id == 0 ? ++g_request_id : g_request_id;
    const uint32_t head[6] = {static_cast<uint32_t>(path.size()), static_cast<uint32_t>(dataset.size()),
                              static_cast<uint32_t>(std::ceil(timeout)) + 2, id, static_cast<uint32_t>(kind),
                              static_cast<uint32_t>(extra.size())};
    const bool sent = send_all(g_worker.fd, head, sizeof head) && send_all(g_worker.fd, path.data(), path.size()) &&
                      send_all(g_worker.fd, dataset.data(), dataset.size()) && send_all(g_worker.fd, extra.data(), extra.size());
    uint32_t reply[3] = {0, 0, 0};
    out.clear();
    Receive got = sent ? Receive::done : Receive::ended;
    // Answers to an earlier request (none is expected: requests are answered in order) are skipped.
    while (got == Receive::done) {
      got = receive(g_worker.fd, reply, sizeof reply, deadline);
      if (got != Receive::done) break;
      if (reply[2] > probe::kMaxPayloadBytes + (uint64_t{64} << 20)) {  // not the protocol: a worker gone wrong
        kill(-g_worker.pid, SIGKILL);
        got = Receive::ended;
        break;
      }
      out.assign(reply[2], '\0');
      got = receive(g_worker.fd, out.data(), out.size(), deadline);
      if (got == Receive::done && reply[0] == id) break;
    }
    if (got == Receive::late) {
      stop_worker(true);
      return timed_out(file, timeout);
    }
    if (got == Receive::ended) {
      const pid_t pid = g_worker.pid;
      close(g_worker.fd);
      g_worker.fd = -1;
      g_worker.pid = -1;
      int status = 0;
      reap(pid, &status);
      stop_worker(false);
      // Killed by a SIGKILL this process did not send before it answered: most likely
      // PR_SET_PDEATHSIG (the thread that started it ended just now). Once more with a new worker.
      if (attempt == 0 && ((WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) || !sent)) continue;
      return ended(file, status);
    }
    if (reply[1] == probe::kWalkDied) {  // the process serving it died on this file; the worker goes on
      int status = 0;
      if (out.size() == sizeof status) std::memcpy(&status, out.data(), sizeof status);
      return ended(file, status);
    }
    outcome = reply[1];
    return "";
  }
}

// The walk of `file` by the worker (caller holds g_worker_mutex); returns the refusal ("" when the
// file may be read) and the names it covered.
std::string ask_worker(const std::string& helper, const fs::path& file, const std::string& dataset, double timeout,
                       probe::WalkResult& result) {
  uint32_t outcome = 0;
  std::string out;
  const std::string refusal = exchange(helper, file, dataset, h5::Request::walk, {}, 0, timeout, outcome, out);
  if (!refusal.empty()) return refusal;
  if (outcome == probe::kWalkOutOfMemory) return too_much_memory(file);
  return take_answer(file, out, result);
}

// ------------------------------------------------------------------ the forked child (no helper)

[[noreturn]] void child_main(const char* path, const std::string& dataset, int out, pid_t parent, const probe::MemoryUse& base,
                             uint64_t memory, double timeout) {
  // Die with the parent; the parent's handlers (libFuzzer's, sanitizers', the CLI's) do not apply here.
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (getppid() != parent) _exit(probe::kWalkOk);
  for (int s : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTRAP, SIGSYS, SIGALRM, SIGXCPU, SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGPIPE})
    signal(s, SIG_DFL);
  sigset_t all;
  sigemptyset(&all);
  sigprocmask(SIG_SETMASK, &all, nullptr);
#ifdef SKEL_PROBE_ASAN
  __sanitizer_set_death_callback(nullptr);  // libFuzzer's would save the input as its own finding
#endif
  const int null = open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null >= 0) {
    dup2(null, STDOUT_FILENO);
    dup2(null, STDERR_FILENO);
  }
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  probe::limit_memory(base, memory);
  probe::exit_on_fault_at_the_limit();
  alarm(static_cast<unsigned>(std::ceil(timeout)) + 2);  // a second stop, should the parent be gone
  probe::quiet_hdf5_errors();
  std::string payload;
  const int code = probe::walk_file(path, dataset, payload);
  if (code == probe::kWalkOk) {
    size_t done = 0;
    while (done < payload.size()) {
      const ssize_t n = ::write(out, payload.data() + done, payload.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      done += static_cast<size_t>(n);
    }
  }
  _exit(code);
}

// One forked probe process; returns the refusal ("" when the file may be read) and the names it covered.
std::string fork_probe(const fs::path& file, const std::string& dataset, double timeout, probe::WalkResult& result) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0)
    throw Error("cannot check the HDF5 file " + file.string() + " in a separate process: pipe: " + std::strerror(errno) +
                " (SKEL_HDF5_PROBE=0 reads trusted files without this check)");
  const probe::MemoryUse base = probe::memory_use();
  const uint64_t memory = child_memory();
  const pid_t parent = getpid();
  const std::string path = file.string();
  const auto deadline = deadline_after(timeout);  // the time counts from the fork
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
    child_main(path.c_str(), dataset, fds[1], parent, base, memory, timeout);
  }
  {
    std::lock_guard lock(g_cache_mutex);
    ++g_started;
  }
  close(fds[1]);
  fcntl(fds[0], F_SETFL, O_NONBLOCK);
  // Reads what the child reports and waits for it, at most `timeout` seconds. The pipe is not relied
  // on for the end: a process forked meanwhile by another thread may hold its write end.
  std::string out;
  int status = 0;
  bool late = false;
  auto drain = [&] {
    char buf[65536];
    for (;;) {
      const ssize_t n = read(fds[0], buf, sizeof buf);
      if (n > 0) {
        if (out.size() <= probe::kMaxPayloadBytes) out.append(buf, static_cast<size_t>(n));
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      return;
    }
  };
  for (;;) {
    // The deadline first: a child the parent sees only after the deadline did not finish in time.
    if (std::chrono::steady_clock::now() >= deadline) {
      kill(pid, SIGKILL);
      reap(pid, &status);
      late = true;
      break;
    }
    const pid_t w = waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    if (w < 0 && errno != EINTR) {
      status = -1;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    // Short polls: the child's exit is seen by waitpid within 20 ms even when the pipe stays open.
    if (poll(&p, 1, std::min(ms_until(deadline) + 1, 20)) > 0) drain();
  }
  drain();
  close(fds[0]);
  if (late) return timed_out(file, timeout);
  if (status == -1) return "";  // the child was reaped elsewhere (a SIGCHLD handler): no verdict, read as before
  if (!(WIFEXITED(status) && WEXITSTATUS(status) == probe::kWalkOk)) return ended(file, status);
  return take_answer(file, out, result);
}

// The cache's key for `file` and its stamp now; false when it is not a regular file.
bool cache_key(const fs::path& file, std::string& key, Stamp& stamp) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  stamp = Stamp{st.st_dev, st.st_ino, st.st_size, int64_t{st.st_mtim.tv_sec} * 1000000000 + st.st_mtim.tv_nsec,
                int64_t{st.st_ctim.tv_sec} * 1000000000 + st.st_ctim.tv_nsec};
  std::error_code ec;
  fs::path abs = fs::absolute(file, ec);
  key = (ec ? file : abs.lexically_normal()).string();
  return true;
}

}  // namespace

void probe_hdf5_file(const fs::path& file, const std::string& dataset) {
  const Mode mode = probe_mode();
  if (mode == Mode::off) return;
  std::string key;
  Stamp stamp;
  if (!cache_key(file, key, stamp)) return;  // the reader says what is wrong
  bool known = false;
  {
    std::lock_guard lock(g_cache_mutex);
    auto it = g_cache.find(key);
    if (it != g_cache.end() && it->second.stamp == stamp) {
      if (!it->second.refusal.empty()) throw InputError(it->second.refusal);
      if (dataset.empty() || (it->second.names.count(dataset) && it->second.attributes.count(dataset))) return;
      known = true;  // the file was walked; the lookup of this name (or its attributes) was not
    }
  }
  const double timeout = probe_timeout();
  child_memory();  // a wrong SKEL_HDF5_PROBE_MEMORY_MB is an error before any walk
  probe::WalkResult result;
  std::string refusal;
  {
    std::lock_guard lock(g_worker_mutex);
    const std::string helper = mode == Mode::helper ? find_helper() : std::string();
    refusal = helper.empty() ? fork_probe(file, dataset, timeout, result) : ask_worker(helper, file, dataset, timeout, result);
  }
  {
    std::lock_guard lock(g_cache_mutex);
    Verdict& v = g_cache[key];
    if (!known || !(v.stamp == stamp)) v = Verdict{stamp, {}, {}, {}, {}};
    v.refusal = refusal;
    add_names(result.names, v.names);
    for (auto& [object, attributes] : result.attributes) v.attributes[object] = std::move(attributes);
    if (!dataset.empty() && refusal.empty()) {
      v.names.insert(dataset);
      // Walked and not opened (not an object of the file): none of the readers' attributes.
      v.attributes.try_emplace(dataset);
    }
  }
  if (!refusal.empty()) throw InputError(refusal);
}

bool probed_attribute(const fs::path& file, const std::string& object, size_t index, probe::Attribute& out) {
  if (index >= probe::kAttributeCount) throw Error("probed_attribute: no attribute " + std::to_string(index));
  if (probe_mode() == Mode::off) return false;
  probe_hdf5_file(file, object);  // nothing when the cache covers the object
  std::string key;
  Stamp stamp;
  if (!cache_key(file, key, stamp)) return false;
  std::lock_guard lock(g_cache_mutex);
  const auto it = g_cache.find(key);
  if (it == g_cache.end() || !(it->second.stamp == stamp)) return false;  // changed meanwhile: read in-process
  const auto found = it->second.attributes.find(object);
  out = found == it->second.attributes.end() ? probe::Attribute{} : found->second[index];
  return true;
}

bool hdf5_reads_in_helper() { return probe_mode() == Mode::helper && !find_helper().empty(); }

void ask_hdf5_helper(const fs::path& file, const std::string& dataset, uint32_t kind, const std::string& extra,
                     uint64_t window_bytes, const std::function<void(const std::string&, const void*)>& take) {
  if (kind == 0 || kind >= h5::kRequestKinds) throw Error("ask_hdf5_helper: no request kind " + std::to_string(kind));
  // The walk first (its verdict is cached): a file it refuses is not opened again.
  probe_hdf5_file(file, dataset);
  std::string key;
  Stamp stamp;
  const bool keyed = cache_key(file, key, stamp);
  // Info answers are cached with the verdict (read_box is asked per block of out-of-core runs).
  const bool info = kind == static_cast<uint32_t>(h5::Request::info);
  if (info && keyed) {
    std::string bytes;
    {
      std::lock_guard lock(g_cache_mutex);
      auto it = g_cache.find(key);
      if (it != g_cache.end() && it->second.stamp == stamp) {
        auto found = it->second.infos.find(dataset + '\0' + extra);
        if (found != it->second.infos.end()) bytes = found->second;
      }
    }
    if (!bytes.empty()) {
      take(bytes, nullptr);
      return;
    }
  }
  const double timeout = probe_timeout();
  uint32_t outcome = 0;
  std::string out, refusal;
  {
    std::lock_guard lock(g_worker_mutex);
    const std::string helper = find_helper();
    if (helper.empty()) throw Error("cannot read the HDF5 file " + file.string() + ": the probe helper " + kHelperName + " was not found");
    struct Doing {
      const char* before = g_doing;
      ~Doing() { g_doing = before; }
    } doing;
    g_doing = "reading it";
    refusal = exchange(helper, file, dataset, static_cast<h5::Request>(kind), extra, window_bytes, timeout, outcome, out);
    if (refusal.empty()) {
      switch (outcome) {
        case probe::kWalkOk:
          take(out, g_worker.window);
          if (info && keyed && !out.empty()) {
            std::lock_guard cache_lock(g_cache_mutex);
            auto it = g_cache.find(key);
            if (it != g_cache.end() && it->second.stamp == stamp) it->second.infos[dataset + '\0' + extra] = out;
          }
          return;
        case h5::kRefused: throw InputError(out);
        case h5::kFailed: throw Error(out);
        case probe::kWalkOutOfMemory: refusal = too_much_memory(file); break;
        default: refusal = damaged(file, "failed (outcome " + std::to_string(outcome) + ")"); break;
      }
    }
  }
  // The file crashed, outran or outgrew the helper: refused from now on, as a refusal of the walk is.
  if (keyed) {
    std::lock_guard lock(g_cache_mutex);
    auto it = g_cache.find(key);
    if (it != g_cache.end() && it->second.stamp == stamp) it->second.refusal = refusal;
  }
  throw InputError(refusal);
}

namespace detail {
int64_t hdf5_probes_started() {
  std::lock_guard lock(g_cache_mutex);
  return g_started;
}
int64_t hdf5_probe_workers_started() {
  std::lock_guard lock(g_worker_mutex);
  return g_workers_started;
}
int hdf5_probe_worker_pid() {
  std::lock_guard lock(g_worker_mutex);
  return g_worker.owner == getpid() ? g_worker.pid : -1;
}
std::string hdf5_probe_helper() { return probe_mode() == Mode::helper ? find_helper() : std::string(); }
void stop_hdf5_probe_worker() {
  std::lock_guard lock(g_worker_mutex);
  stop_worker(false);
}
namespace {
std::atomic<uint64_t> g_read_window{0};
}
void set_hdf5_read_window(uint64_t bytes) { g_read_window = bytes; }
uint64_t hdf5_read_window() {
  const uint64_t w = g_read_window.load();
  return w > 0 ? w : h5::kWindowBytes;
}
void forget_hdf5_probes() {
  std::lock_guard lock(g_cache_mutex);
  g_cache.clear();
}
}  // namespace detail

}  // namespace skel::io
