#include "io/hdf5_write_driver.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <new>

namespace skel::io::detail {
namespace {

std::atomic<int> g_first_errno{0};

struct File {
  H5FD_t pub;  // first: HDF5 casts between the two
  int fd = -1;
  haddr_t eoa = 0, eof = 0;
  dev_t dev = 0;
  ino_t ino = 0;
  bool failed = false;  // a write failed: the file is given up
};

constexpr haddr_t kMaxAddr = (haddr_t{1} << (8 * sizeof(off_t) - 1)) - 1;

File* as_file(H5FD_t* f) { return reinterpret_cast<File*>(f); }
const File* as_file(const H5FD_t* f) { return reinterpret_cast<const File*>(f); }

void record(File* f, int err) {
  f->failed = true;
  int expected = 0;
  g_first_errno.compare_exchange_strong(expected, err == 0 ? EIO : err);
}

H5FD_t* open_file(const char* name, unsigned flags, hid_t, haddr_t maxaddr) {
  if (!name || !*name || maxaddr == 0 || maxaddr == HADDR_UNDEF || maxaddr > kMaxAddr) return nullptr;
  int o = (flags & H5F_ACC_RDWR) ? O_RDWR : O_RDONLY;
  if (flags & H5F_ACC_TRUNC) o |= O_TRUNC;
  if (flags & H5F_ACC_CREAT) o |= O_CREAT;
  if (flags & H5F_ACC_EXCL) o |= O_EXCL;
  const int fd = ::open(name, o | O_CLOEXEC, 0666);
  if (fd < 0) {
    // HDF5 first tries to open an existing file without O_CREAT: only a failed create counts.
    int expected = 0;
    if (flags & H5F_ACC_CREAT) g_first_errno.compare_exchange_strong(expected, errno);
    return nullptr;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    return nullptr;
  }
  auto* f = static_cast<File*>(std::calloc(1, sizeof(File)));
  if (!f) {
    ::close(fd);
    return nullptr;
  }
  new (f) File();
  f->fd = fd;
  f->eof = static_cast<haddr_t>(st.st_size);
  f->dev = st.st_dev;
  f->ino = st.st_ino;
  return &f->pub;
}

herr_t close_file(H5FD_t* file) {
  File* f = as_file(file);
  const int r = ::close(f->fd);
  if (r != 0 && !f->failed) record(f, errno);
  const bool failed = r != 0 && !f->failed;
  f->~File();
  std::free(f);
  return failed ? -1 : 0;
}

int compare(const H5FD_t* a, const H5FD_t* b) {
  const File *x = as_file(a), *y = as_file(b);
  if (x->dev != y->dev) return x->dev < y->dev ? -1 : 1;
  if (x->ino != y->ino) return x->ino < y->ino ? -1 : 1;
  return 0;
}

herr_t query(const H5FD_t*, unsigned long* flags) {
  if (flags)
    *flags = H5FD_FEAT_AGGREGATE_METADATA | H5FD_FEAT_ACCUMULATE_METADATA | H5FD_FEAT_DATA_SIEVE |
             H5FD_FEAT_AGGREGATE_SMALLDATA | H5FD_FEAT_POSIX_COMPAT_HANDLE;
  return 0;
}

haddr_t get_eoa(const H5FD_t* file, H5FD_mem_t) { return as_file(file)->eoa; }
herr_t set_eoa(H5FD_t* file, H5FD_mem_t, haddr_t addr) {
  as_file(file)->eoa = addr;
  return 0;
}
haddr_t get_eof(const H5FD_t* file, H5FD_mem_t) { return as_file(file)->eof; }
herr_t get_handle(H5FD_t* file, hid_t, void** handle) {
  *handle = &as_file(file)->fd;
  return 0;
}

herr_t read_at(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, void* buf) {
  File* f = as_file(file);
  if (addr == HADDR_UNDEF || addr + size > f->eoa) return -1;
  auto* p = static_cast<unsigned char*>(buf);
  while (size > 0) {
    const ssize_t n = ::pread(f->fd, p, size, static_cast<off_t>(addr));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return -1;
    if (n == 0) {  // past the end of the file: zeros, as sec2 does
      std::memset(p, 0, size);
      break;
    }
    p += n;
    addr += static_cast<haddr_t>(n);
    size -= static_cast<size_t>(n);
  }
  return 0;
}

herr_t write_at(H5FD_t* file, H5FD_mem_t, hid_t, haddr_t addr, size_t size, const void* buf) {
  File* f = as_file(file);
  if (addr == HADDR_UNDEF || addr + size > f->eoa) return -1;
  if (f->failed) return 0;  // given up: nothing more reaches the disk
  const haddr_t end = addr + size;
  const auto* p = static_cast<const unsigned char*>(buf);
  while (size > 0) {
    const ssize_t n = ::pwrite(f->fd, p, size, static_cast<off_t>(addr));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      record(f, errno);
      return -1;
    }
    p += n;
    addr += static_cast<haddr_t>(n);
    size -= static_cast<size_t>(n);
  }
  if (end > f->eof) f->eof = end;
  return 0;
}

herr_t truncate_file(H5FD_t* file, hid_t, hbool_t) {
  File* f = as_file(file);
  if (f->failed || f->eoa == f->eof) return 0;
  if (::ftruncate(f->fd, static_cast<off_t>(f->eoa)) != 0) {
    record(f, errno);
    return -1;
  }
  f->eof = f->eoa;
  return 0;
}

H5FD_class_t make_class() {
  H5FD_class_t c;
  std::memset(&c, 0, sizeof c);
  c.name = "skelflow_safe_write";
  c.maxaddr = kMaxAddr;
  c.fc_degree = H5F_CLOSE_WEAK;
  c.open = open_file;
  c.close = close_file;
  c.cmp = compare;
  c.query = query;
  c.get_eoa = get_eoa;
  c.set_eoa = set_eoa;
  c.get_eof = get_eof;
  c.get_handle = get_handle;
  c.read = read_at;
  c.write = write_at;
  c.truncate = truncate_file;
  const H5FD_mem_t map[] = H5FD_FLMAP_DICHOTOMY;
  for (int i = 0; i < H5FD_MEM_NTYPES; ++i) c.fl_map[i] = map[i];
  return c;
}

hid_t driver_id() {
  static const H5FD_class_t cls = make_class();
  static hid_t id = -1;
  // H5_term_library closes registered drivers at exit; register again if the id went stale.
  if (id < 0 || H5Iis_valid(id) <= 0) id = H5FDregister(&cls);
  return id;
}

}  // namespace

hid_t safe_write_fapl() {
  g_first_errno.store(0);
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  if (fapl >= 0 && H5Pset_driver(fapl, driver_id(), nullptr) < 0) {
    H5Pclose(fapl);
    return -1;
  }
  return fapl;
}

int first_write_errno() { return g_first_errno.load(); }

}  // namespace skel::io::detail
