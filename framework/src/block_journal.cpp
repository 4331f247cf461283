// Per-block resume journals (skel/block_journal.hpp).
//
// File format (host byte order; the file is read back only by the same build on the same machine):
//   "skelflow-blocks 2\n", u64 stage key
//   records, each ending with a checksum (below) of its bytes before it:
//     'W' u64 name length, name, i64 begin[3], i64 size[3], u64 byte count, bytes, u64 hash
//     'C' i64 pass, i64 block index, u64 payload length, payload, u64 hash
//     'B' u64 count, count × (i64 pass, i64 block index, u64 payload length, payload), u64 hash
// A write belongs to the commit ('C', or 'B': several blocks at once) that follows it; writes after
// the last commit (a block that was running when the process died) and a torn tail are ignored and
// cut off when the journal is opened.
//
// Size. A stage whose passes rewrite its volumes (chamfer's sweeps, the EDT's passes, thinning)
// would journal many times its volumes' bytes. So the journal is bounded: once it holds more than
// twice the bytes of the stage's scratch volumes (and at least min_bytes), later blocks of the pass
// are not journaled (their commits are kept in memory; a kill resumes from the last block written),
// and when the next pass begins the journal is compacted in place: the volumes as they are (read
// back from the scratch stores) and one 'B' record committing every block so far. A kill while it
// is compacted leaves writes without a commit: the stage then starts over.
//
// Records are appended with write(): they survive kill -9 (the kernel holds them) without a sync
// per block; like the rest of the resume state they are not meant to survive a crash of the
// machine (the checksums cut off what such a crash tore).
#include "skel/block_journal.hpp"

#include <fcntl.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <mutex>
#include <utility>
#include <vector>

#include "skel/error.hpp"

namespace fs = std::filesystem;

namespace skel {

namespace {

thread_local BlockJournal* t_journal = nullptr;

constexpr char kMagic[] = "skelflow-blocks 2\n";
constexpr size_t kMagicSize = sizeof(kMagic) - 1;
constexpr size_t kHeaderSize = kMagicSize + 8;

// A checksum of n bytes: four independent lanes of 64-bit words (several GB/s), the tail and the
// lanes folded by FNV-1a.
uint64_t checksum(const char* p, size_t n) {
  constexpr uint64_t k = 0x9E3779B97F4A7C15ull;
  uint64_t h[4] = {k, k ^ 0x243F6A8885A308D3ull, k ^ 0x13198A2E03707344ull, k ^ 0xA4093822299F31D0ull};
  size_t i = 0;
  for (; i + 32 <= n; i += 32)
    for (int l = 0; l < 4; ++l) {
      uint64_t w;
      std::memcpy(&w, p + i + 8 * l, 8);
      h[l] = ((h[l] ^ w) * k);
      h[l] ^= h[l] >> 29;
    }
  uint64_t f = 1469598103934665603ull ^ n;
  auto fold = [&](const char* q, size_t m) {
    for (size_t j = 0; j < m; ++j) {
      f ^= static_cast<unsigned char>(q[j]);
      f *= 1099511628211ull;
    }
  };
  fold(reinterpret_cast<const char*>(h), sizeof h);
  fold(p + i, n - i);
  return f;
}
// A write record's hash: of its header and of its bytes.
uint64_t write_hash(const char* header, size_t header_size, const char* data, size_t bytes) {
  return checksum(header, header_size) * 31 + checksum(data, bytes);
}

template <class T>
void put(std::string& b, const T& v) {
  b.append(reinterpret_cast<const char*>(&v), sizeof v);
}

}  // namespace

BlockJournal* current_block_journal() { return t_journal; }
ScopedBlockJournal::ScopedBlockJournal(BlockJournal* journal) : previous_(t_journal) { t_journal = journal; }
ScopedBlockJournal::~ScopedBlockJournal() { t_journal = previous_; }

struct BlockJournalFile::State {
  fs::path file;
  int fd = -1;
  std::mutex m;
  int64_t passes = 0;
  bool active = false;  // a pass has begun: writes are journaled
  bool full = false;    // over the bound: writes are not journaled, commits wait in `commits`
  uint64_t bytes = 0;   // of the file
  uint64_t min_bytes = 0;
  struct Commit {
    int64_t pass = 0, index = 0;
    std::string payload;
  };
  std::vector<Commit> commits;  // every commit, of the earlier runs and of this one (for compaction)
  std::map<std::pair<int64_t, int64_t>, std::string> committed;  // of the earlier run, with payloads
  struct Write {
    std::string name;
    Dims begin{}, size{};
    uint64_t offset = 0, bytes = 0;  // of the data in the file
  };
  std::vector<Write> kept;  // the earlier run's committed writes, in order
  struct Volume {
    int64_t bytes_per_voxel = 0;
    Dims dims{};
    std::weak_ptr<VolumeStore> inner;
  };
  std::map<std::string, Volume> volumes;  // the wrapped scratch volumes

  [[noreturn]] void fail(const std::string& what) const {
    throw Error("resume journal " + file.string() + ": " + what + ": " + std::strerror(errno));
  }
  void write_all(const std::string& b) {
    size_t done = 0;
    while (done < b.size()) {
      const ssize_t n = ::write(fd, b.data() + done, b.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail("cannot write");
      done += static_cast<size_t>(n);
    }
    bytes += b.size();
  }
  // Appends a write record of `size` voxels at `begin` of volume `name` (no copy of the data).
  void append_write(const std::string& name, const Dims& begin, const Dims& size, int64_t bpv, const void* data) {
    const uint64_t n = static_cast<uint64_t>(size[0] * size[1] * size[2] * bpv);
    std::string h;
    h.push_back('W');
    put(h, static_cast<uint64_t>(name.size()));
    h += name;
    h.append(reinterpret_cast<const char*>(begin.data()), 24);
    h.append(reinterpret_cast<const char*>(size.data()), 24);
    put(h, n);
    const uint64_t hash = write_hash(h.data(), h.size(), static_cast<const char*>(data), n);
    iovec v[3] = {{h.data(), h.size()}, {const_cast<void*>(data), n}, {const_cast<uint64_t*>(&hash), 8}};
    size_t total = h.size() + n + 8, done = 0;
    int first = 0;
    while (done < total) {
      const ssize_t w = ::writev(fd, v + first, 3 - first);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) fail("cannot write");
      done += static_cast<size_t>(w);
      size_t left = static_cast<size_t>(w);
      while (first < 3 && left >= v[first].iov_len) left -= v[first++].iov_len;
      if (first < 3) {
        v[first].iov_base = static_cast<char*>(v[first].iov_base) + left;
        v[first].iov_len -= left;
      }
    }
    bytes += total;
  }
  [[nodiscard]] uint64_t volume_bytes() const {
    uint64_t b = 0;
    for (const auto& [name, v] : volumes)
      b += static_cast<uint64_t>(v.dims[0] * v.dims[1] * v.dims[2] * v.bytes_per_voxel);
    return b;
  }
  // Rewrites the journal as the volumes as they are and one record committing every block so far.
  void compact() {
    if (::ftruncate(fd, static_cast<off_t>(kHeaderSize)) != 0) fail("cannot compact");
    if (::lseek(fd, 0, SEEK_END) < 0) fail("cannot seek");
    bytes = kHeaderSize;
    constexpr int64_t piece = 4 << 20;  // bytes read at a time
    std::vector<char> buf;
    for (const auto& [name, v] : volumes) {
      const auto inner = v.inner.lock();
      if (!inner) continue;  // dropped: no later block reads it
      const Dims& d = v.dims;
      const int64_t row = d[0] * v.bytes_per_voxel;
      const int64_t ry = std::clamp<int64_t>(piece / std::max<int64_t>(row, 1), 1, std::max<int64_t>(d[1], 1));
      const int64_t rz = ry < d[1] ? 1 : std::max<int64_t>(1, piece / std::max<int64_t>(row * d[1], 1));
      for (int64_t z = 0; z < d[2]; z += rz)
        for (int64_t y = 0; y < d[1]; y += ry) {
          const Dims b{0, y, z}, s{d[0], std::min(ry, d[1] - y), std::min(rz, d[2] - z)};
          buf.resize(static_cast<size_t>(s[0] * s[1] * s[2] * v.bytes_per_voxel));
          inner->read(b, s, buf.data());
          append_write(name, b, s, v.bytes_per_voxel, buf.data());
        }
    }
    std::string r;
    r.push_back('B');
    put(r, static_cast<uint64_t>(commits.size()));
    for (const auto& c : commits) {
      put(r, c.pass);
      put(r, c.index);
      put(r, static_cast<uint64_t>(c.payload.size()));
      r += c.payload;
    }
    put(r, checksum(r.data(), r.size()));
    write_all(r);
    full = false;
  }
  // Reads the valid prefix of an earlier run's journal of stage `key`; returns its length (0: none).
  uint64_t load(uint64_t key) {
    const int in = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (in < 0) return 0;
    std::string b;
    std::vector<char> buf(1 << 16);
    for (;;) {
      const ssize_t n = ::read(in, buf.data(), buf.size());
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      b.append(buf.data(), static_cast<size_t>(n));
    }
    ::close(in);
    uint64_t file_key = 0;
    if (b.size() < kHeaderSize || b.compare(0, kMagicSize, kMagic) != 0) return 0;
    std::memcpy(&file_key, b.data() + kMagicSize, 8);
    if (file_key != key) return 0;
    size_t pos = kHeaderSize, valid = pos;
    std::vector<Write> uncommitted;
    auto get = [&](void* out, size_t n) {
      if (pos + n > b.size()) return false;
      std::memcpy(out, b.data() + pos, n);
      pos += n;
      return true;
    };
    // One block's commit entry (pass, index, payload) at pos.
    auto entry = [&](Commit& c) {
      uint64_t len = 0;
      if (!get(&c.pass, 8) || !get(&c.index, 8) || !get(&len, 8) || len > b.size() - pos) return false;
      c.payload = b.substr(pos, len);
      pos += len;
      return true;
    };
    for (;;) {
      const size_t start = pos;
      char kind = 0;
      if (!get(&kind, 1)) break;
      uint64_t hash = 0;
      std::vector<Commit> these;
      if (kind == 'W') {
        Write w;
        uint64_t len = 0;
        if (!get(&len, 8) || len > b.size() - pos) break;
        w.name = b.substr(pos, len);
        pos += len;
        if (!get(w.begin.data(), 24) || !get(w.size.data(), 24) || !get(&w.bytes, 8) || w.bytes > b.size() - pos) break;
        w.offset = pos;
        pos += w.bytes;
        if (!get(&hash, 8) ||
            hash != write_hash(b.data() + start, w.offset - start, b.data() + w.offset, w.bytes))
          break;
        uncommitted.push_back(std::move(w));
        continue;
      }
      if (kind == 'C') {
        Commit c;
        if (!entry(c)) break;
        these.push_back(std::move(c));
      } else if (kind == 'B') {
        uint64_t count = 0;
        if (!get(&count, 8) || count > b.size() - pos) break;
        bool ok = true;
        for (uint64_t i = 0; i < count && ok; ++i) {
          Commit c;
          ok = entry(c);
          these.push_back(std::move(c));
        }
        if (!ok) break;
      } else {
        break;
      }
      if (!get(&hash, 8) || hash != checksum(b.data() + start, pos - 8 - start)) break;
      if (kind == 'B') {  // a compacted journal: every commit is in this record
        committed.clear();
        commits.clear();
      }
      for (auto& c : these) {
        committed[{c.pass, c.index}] = c.payload;
        commits.push_back(std::move(c));
      }
      for (auto& w : uncommitted) kept.push_back(std::move(w));
      uncommitted.clear();
      valid = pos;
    }
    return valid;
  }
};

BlockJournalFile::BlockJournalFile(fs::path file, uint64_t key, uint64_t min_bytes) : s_(std::make_unique<State>()) {
  s_->file = std::move(file);
  s_->min_bytes = min_bytes;
  const uint64_t valid = s_->load(key);
  if (valid == 0) {
    s_->fd = ::open(s_->file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (s_->fd < 0) s_->fail("cannot create");
    std::string head(kMagic, kMagicSize);
    put(head, key);
    s_->write_all(head);
  } else {
    s_->fd = ::open(s_->file.c_str(), O_WRONLY | O_CLOEXEC);
    if (s_->fd < 0) s_->fail("cannot open");
    if (::ftruncate(s_->fd, static_cast<off_t>(valid)) != 0) s_->fail("cannot cut off the unfinished block");
    if (::lseek(s_->fd, 0, SEEK_END) < 0) s_->fail("cannot seek");
    s_->bytes = valid;
  }
  if (::fsync(s_->fd) != 0) s_->fail("cannot sync");
}

BlockJournalFile::~BlockJournalFile() {
  if (s_ && s_->fd >= 0) ::close(s_->fd);
}

int64_t BlockJournalFile::begin_pass() {
  std::lock_guard lock(s_->m);
  s_->active = true;
  // Compacted when the journal holds much more than the volumes (or commits wait), unless an earlier
  // run's writes to a volume not made yet still have to be replayed from it.
  const uint64_t v = s_->volume_bytes();
  const bool replayed = std::all_of(s_->kept.begin(), s_->kept.end(), [&](const State::Write& w) { return s_->volumes.count(w.name) != 0; });
  if (s_->passes > 0 && replayed && (s_->full || s_->bytes > std::max(s_->min_bytes, v + v / 2))) {
    s_->compact();
    s_->kept.clear();  // replayed; their offsets are gone
  }
  return s_->passes++;
}

const std::string* BlockJournalFile::kept(int64_t pass, int64_t index) const {
  const auto it = s_->committed.find({pass, index});
  return it == s_->committed.end() ? nullptr : &it->second;
}

void BlockJournalFile::commit(int64_t pass, int64_t index, std::string_view payload) {
  std::lock_guard lock(s_->m);
  s_->commits.push_back({pass, index, std::string(payload)});
  if (s_->full) return;  // written when the journal is compacted
  std::string b;
  b.push_back('C');
  put(b, pass);
  put(b, index);
  put(b, static_cast<uint64_t>(payload.size()));
  b.append(payload);
  put(b, checksum(b.data(), b.size()));
  s_->write_all(b);
  const uint64_t v = s_->volume_bytes();
  if (s_->bytes > std::max(s_->min_bytes, 2 * v)) s_->full = true;
}

int64_t BlockJournalFile::kept_blocks() const { return static_cast<int64_t>(s_->committed.size()); }

uint64_t BlockJournalFile::size() const {
  std::lock_guard lock(s_->m);
  return s_->bytes;
}

const fs::path& BlockJournalFile::file() const { return s_->file; }

namespace {

class JournaledStore final : public VolumeStore {
public:
  JournaledStore(BlockJournalFile::State& s, std::string name, int64_t bpv, std::shared_ptr<VolumeStore> inner)
      : s_(s), name_(std::move(name)), bpv_(bpv), inner_(std::move(inner)) {}
  void read(const Dims& begin, const Dims& size, void* out) const override { inner_->read(begin, size, out); }
  void write(const Dims& begin, const Dims& size, const void* in) override {
    inner_->write(begin, size, in);
    std::lock_guard lock(s_.m);
    if (s_.active && !s_.full) s_.append_write(name_, begin, size, bpv_, in);
  }
  [[nodiscard]] const fs::path& file() const override { return inner_->file(); }
  [[nodiscard]] const VolumeStore& inner() const { return *inner_; }

private:
  BlockJournalFile::State& s_;
  std::string name_;
  int64_t bpv_;
  std::shared_ptr<VolumeStore> inner_;
};

}  // namespace

const VolumeStore& BlockJournalFile::unwrap(const VolumeStore& store) {
  if (const auto* j = dynamic_cast<const JournaledStore*>(&store)) return j->inner();
  return store;
}

std::shared_ptr<VolumeStore> BlockJournalFile::wrap(const std::string& name, int64_t bytes_per_voxel, const Dims& dims,
                                                    std::shared_ptr<VolumeStore> inner) {
  {
    std::lock_guard lock(s_->m);
    s_->volumes[name] = State::Volume{bytes_per_voxel, dims, inner};
  }
  if (!s_->kept.empty()) {
    const int in = ::open(s_->file.c_str(), O_RDONLY | O_CLOEXEC);
    if (in < 0) s_->fail("cannot read");
    std::vector<char> buf;
    for (const auto& w : s_->kept) {
      if (w.name != name) continue;
      buf.resize(w.bytes);
      size_t done = 0;
      while (done < w.bytes) {
        const ssize_t n = ::pread(in, buf.data() + done, w.bytes - done, static_cast<off_t>(w.offset + done));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
          ::close(in);
          s_->fail("cannot read a kept block");
        }
        done += static_cast<size_t>(n);
      }
      inner->write(w.begin, w.size, buf.data());
    }
    ::close(in);
  }
  return std::make_shared<JournaledStore>(*s_, name, bytes_per_voxel, std::move(inner));
}

}  // namespace skel
