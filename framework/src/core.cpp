#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <cmath>
#include <exception>
#include <iomanip>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "skel/data.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/interrupter.hpp"
#include "skel/parallel.hpp"
#include "skel/volume.hpp"

namespace skel {

void advise_huge_pages(void* data, size_t bytes) {
  constexpr uintptr_t kHuge = uintptr_t{2} << 20;
  if (bytes < 4 * kHuge) return;
  const uintptr_t b = (reinterpret_cast<uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t e = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (e > b) (void)madvise(reinterpret_cast<void*>(b), e - b, MADV_HUGEPAGE);
}

size_t release_pages(void* data, size_t bytes) {
  constexpr uintptr_t kPage = 4096;
  const uintptr_t b = (reinterpret_cast<uintptr_t>(data) + kPage - 1) & ~(kPage - 1);
  const uintptr_t e = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(kPage - 1);
  if (e <= b) return 0;
  return madvise(reinterpret_cast<void*>(b), e - b, MADV_DONTNEED) == 0 ? e - b : 0;
}

std::string location_prefix(const std::string& file, int line, int column) {
  std::string s = file;
  if (line > 0) {
    if (!s.empty()) s += ':';
    s += std::to_string(line);
    s += ':';
    s += std::to_string(column);
  }
  if (!s.empty()) s += ": ";
  return s;
}

std::string ErrorSite::context() const {
  return (line > 0 ? location_prefix(file, line, column) : std::string()) + "node '" + node + "' (" + module + ")";
}

Error::Error(ErrorSite site)
    : std::runtime_error(site.context() + ": " + site.message),
      site_(std::make_shared<const ErrorSite>(std::move(site))) {}

void rethrow_at(ErrorSite site) {
  try {
    throw;
  } catch (const Cancelled&) {
    throw;  // cancellation needs no place
  } catch (const InputError& e) {
    site.message = e.what();
    throw InputError(std::move(site));
  } catch (const Error& e) {
    site.message = e.what();
    throw Error(std::move(site));
  } catch (const std::bad_alloc&) {
    site.message = "out of memory";
    throw Error(std::move(site));
  } catch (const std::exception& e) {
    site.message = e.what();
    throw Error(std::move(site));
  } catch (...) {
    site.message = "unknown error";
    throw Error(std::move(site));
  }
}

void rethrow_with_context(const std::string& context) {
  try {
    throw;
  } catch (const Cancelled&) {
    throw;  // cancellation needs no context
  } catch (const InputError& e) {
    throw InputError(e.with_context(context));
  } catch (const Error& e) {
    throw Error(e.with_context(context));
  } catch (const std::bad_alloc&) {
    throw Error(context + ": out of memory");
  } catch (const std::exception& e) {
    throw Error(context + ": " + e.what());
  }
}

// ---------------------------------------------------------------- Interrupter
void Interrupter::report(double fraction) const {
  if (report_ && *report_) {
    fraction = std::clamp(fraction, 0.0, 1.0);
    (*report_)(begin_ + (end_ - begin_) * fraction);
  }
}
void Interrupter::check() const {
  if (cancelled()) throw Cancelled();
}
void Interrupter::check(double fraction) const {
  check();
  report(fraction);
}
void Interrupter::note(const std::string& text) const {
  if (note_ && *note_) (*note_)(text);
}
Interrupter Interrupter::sub(double begin, double end) const {
  Interrupter s = *this;
  s.begin_ = begin_ + (end_ - begin_) * begin;
  s.end_ = begin_ + (end_ - begin_) * end;
  return s;
}

// ---------------------------------------------------------------- parallel
int hardware_threads() {
  unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}
int effective_threads(int threads) { return threads <= 0 ? hardware_threads() : threads; }

void parallel_for(int64_t begin, int64_t end, int threads,
                  const std::function<void(int64_t, int64_t)>& body, int64_t grain) {
  if (end <= begin) return;
  threads = effective_threads(threads);
  grain = std::max<int64_t>(1, grain);
  if (threads == 1 || end - begin <= grain) {
    body(begin, end);
    return;
  }
#if defined(__SANITIZE_THREAD__) || defined(SKEL_PARALLEL_STD_THREADS)
  // ThreadSanitizer builds: Debian's libtbb is not instrumented, so TSan cannot see how TBB hands the
  // work to its workers and reports every read of data written before the loop as a race. Here the
  // same ranges go to std::threads (whose start and join TSan sees) from a shared counter, so each
  // report is about Skelflow's own accesses. The first exception stops the hand-out and is rethrown.
  {
    std::atomic<int64_t> next{begin};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex error_mutex;
    auto worker = [&] {
      while (!failed.load()) {
        const int64_t b = next.fetch_add(grain);
        if (b >= end) return;
        try {
          body(b, std::min(end, b + grain));
        } catch (...) {
          std::lock_guard<std::mutex> lock(error_mutex);
          if (!error) error = std::current_exception();
          failed = true;
        }
      }
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
    return;
  }
#endif
  // More arena slots than cores only makes TBB complain; the split into ranges stays the same.
  tbb::task_arena arena(std::min(threads, std::max(2, hardware_threads())));
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int64_t>(begin, end, static_cast<size_t>(grain)),
                      [&](const tbb::blocked_range<int64_t>& r) { body(r.begin(), r.end()); });
  });
}

void parallel_chunks(int64_t begin, int64_t end, int64_t chunks, int threads,
                     const std::function<void(int64_t, int64_t, int64_t)>& body) {
  if (chunks <= 0) return;
  const int64_t n = std::max<int64_t>(0, end - begin);
  auto run_chunk = [&](int64_t c) {
    const int64_t b = begin + n * c / chunks, e = begin + n * (c + 1) / chunks;
    body(c, b, e);
  };
  parallel_for(0, chunks, threads, [&](int64_t c0, int64_t c1) {
    for (int64_t c = c0; c < c1; ++c) run_chunk(c);
  });
}

// ---------------------------------------------------------------- data / volume
const std::vector<std::string>& all_volume_types() {
  static const std::vector<std::string> t{type_ids::volume_u8,  type_ids::volume_u16,
                                          type_ids::volume_u32, type_ids::volume_u64,
                                          type_ids::volume_i32, type_ids::volume_f32,
                                          type_ids::volume_f64};
  return t;
}
const std::vector<std::string>& integer_volume_types() {
  static const std::vector<std::string> t{type_ids::volume_u8, type_ids::volume_u16,
                                          type_ids::volume_u32, type_ids::volume_u64,
                                          type_ids::volume_i32};
  return t;
}

void Grid::validate() const {
  static const char* axis[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 0) {
      throw InputError("dims " + std::string(axis[a]) + " = " + std::to_string(dims[a]) +
                       "; expected >= 0");
    }
    if (!(spacing[a] > 0.0) || !std::isfinite(spacing[a])) {
      std::ostringstream s;
      s << "spacing " << axis[a] << " = " << spacing[a] << "; expected > 0";
      throw InputError(s.str());
    }
    if (!std::isfinite(origin[a])) {
      throw InputError("origin " + std::string(axis[a]) + " is not finite");
    }
  }
  // Overflow guard: product of dims must fit in int64.
  if (dims[0] > 0 && dims[1] > 0 && dims[2] > 0) {
    const double n = static_cast<double>(dims[0]) * static_cast<double>(dims[1]) * static_cast<double>(dims[2]);
    if (n > 9.0e18) throw InputError("volume dims are too large");
  }
}

const Grid& volume_grid(const DataObject& data, const std::string& what) {
  return visit_volume(data, what, [](const auto& v) -> const Grid& { return v.grid(); });
}

// ---------------------------------------------------------------- fs
namespace {
constexpr const char* kTmpTag = ".skelflow-tmp-";
constexpr const char* kBakTag = ".skelflow-bak-";

std::filesystem::path tagged_sibling(const std::filesystem::path& final_path, const char* tag, const std::string& run_id) {
  return final_path.parent_path() /
         ("." + final_path.filename().string() + tag + (run_id.empty() ? make_run_id() : run_id) + "-" +
          std::to_string(static_cast<long>(getpid())));
}

bool process_alive(long pid) {
  if (pid <= 0) return false;
  return kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}
}  // namespace

std::string make_run_id() {
  static std::atomic<uint64_t> counter{0};
  std::random_device rd;
  const uint64_t r = (static_cast<uint64_t>(rd()) << 16) ^ (counter++ * 2654435761u) ^
                     static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  std::ostringstream s;
  s << std::hex << std::setw(8) << std::setfill('0') << (r & 0xffffffffu);
  return s.str();
}

std::filesystem::path temp_sibling(const std::filesystem::path& final_path, const std::string& run_id) {
  return tagged_sibling(final_path, kTmpTag, run_id);
}

std::filesystem::path backup_sibling(const std::filesystem::path& final_path, const std::string& run_id) {
  return tagged_sibling(final_path, kBakTag, run_id);
}

bool parse_temp_name(const std::filesystem::path& path, TempName& out) {
  const std::string name = path.filename().string();
  if (name.size() < 2 || name[0] != '.') return false;
  size_t at = name.rfind(kTmpTag);
  bool backup = false;
  if (at == std::string::npos) {
    at = name.rfind(kBakTag);
    backup = true;
  }
  if (at == std::string::npos || at < 2) return false;
  const std::string rest = name.substr(at + std::char_traits<char>::length(kTmpTag));  // both tags have one length
  const size_t dash = rest.find('-');
  if (dash == 0 || dash == std::string::npos || dash + 1 >= rest.size()) return false;
  const std::string id = rest.substr(0, dash), pid = rest.substr(dash + 1);
  if (!std::all_of(id.begin(), id.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; }))
    return false;
  if (pid.size() > 9 || !std::all_of(pid.begin(), pid.end(), [](char c) { return c >= '0' && c <= '9'; })) return false;
  out.backup = backup;
  out.final = path.parent_path() / name.substr(1, at - 1);
  out.run_id = id;
  out.pid = std::stol(pid);
  return true;
}

std::filesystem::path display_path(const std::filesystem::path& path) {
  TempName t;
  if (parse_temp_name(path, t) && !t.backup) return t.final;
  return path;
}

std::vector<std::string> remove_stale_temps(const std::filesystem::path& folder) {
  namespace fs = std::filesystem;
  std::vector<std::string> done;
  std::error_code ec;
  std::vector<std::pair<fs::path, TempName>> stale;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    TempName t;
    if (parse_temp_name(it->path(), t) && !process_alive(t.pid)) stale.emplace_back(it->path(), t);
  }
  std::sort(stale.begin(), stale.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [p, t] : stale) {
    std::error_code e;
    if (t.backup && !fs::exists(fs::symlink_status(t.final, e))) {
      fs::rename(p, t.final, e);
      if (!e) done.push_back("restored " + t.final.string() + " from " + p.filename().string());
      continue;
    }
    fs::remove_all(p, e);
    if (!e) done.push_back("removed " + p.string());
  }
  return done;
}

void write_atomically(const std::filesystem::path& final_path,
                      const std::function<void(const std::filesystem::path&)>& write) {
  namespace fs = std::filesystem;
  TempName t;
  if (parse_temp_name(final_path, t) && !t.backup) {
    // Already the engine's temporary: it renames (or removes) the file when the run ends.
    write(final_path);
    return;
  }
  if (final_path.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(final_path.parent_path(), ec);
    if (ec) {
      throw InputError("cannot create directory " + final_path.parent_path().string() + ": " +
                       ec.message());
    }
  }
  const fs::path tmp = temp_sibling(final_path);
  try {
    write(tmp);
    std::error_code ec;
    fs::rename(tmp, final_path, ec);
    if (ec) throw Error("cannot rename " + tmp.string() + " to " + final_path.string() + ": " + ec.message());
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
}

void write_file_atomically(const std::filesystem::path& path, const std::string& bytes) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    auto fail = [&](int err) {
      throw Error("cannot write " + display_path(path).string() + ": " + std::strerror(err));
    };
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) fail(errno);
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        const int err = errno;
        ::close(fd);
        fail(err);
      }
      done += static_cast<size_t>(n);
    }
    if (::close(fd) != 0) fail(errno);
  });
}

}  // namespace skel
