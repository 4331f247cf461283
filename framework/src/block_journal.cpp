// Per-block resume journals (skel/block_journal.hpp).
//
// File format (host byte order; the file is read back only by the same build on the same machine):
//   "skelflow-blocks 1\n", u64 stage key
//   records, each ending with the FNV-1a hash of its bytes before the hash:
//     'W' u64 name length, name, i64 begin[3], i64 size[3], u64 byte count, bytes, u64 hash
//     'C' i64 pass, i64 block index, u64 payload length, payload, u64 hash
// A write belongs to the block of the next commit; writes after the last commit (a block that was
// running when the process died) and a torn tail are ignored and cut off when the journal is opened.
#include "skel/block_journal.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <map>
#include <utility>
#include <vector>

#include "skel/error.hpp"

namespace fs = std::filesystem;

namespace skel {

namespace {

thread_local BlockJournal* t_journal = nullptr;

constexpr char kMagic[] = "skelflow-blocks 2\n";
constexpr size_t kMagicSize = sizeof(kMagic) - 1;

uint64_t fnv(const char* p, size_t n, uint64_t h = 1469598103934665603ull) {
  for (size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(p[i]);
    h *= 1099511628211ull;
  }
  return h;
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
  std::map<std::pair<int64_t, int64_t>, std::string> committed;  // of the earlier run, with payloads
  struct Write {
    std::string name;
    Dims begin{}, size{};
    uint64_t offset = 0, bytes = 0;  // of the data in the file
  };
  std::vector<Write> kept;  // the earlier run's committed writes, in order
  std::string pending;      // this run's writes since the last commit

  [[noreturn]] void fail(const std::string& what) const {
    throw Error("resume journal " + file.string() + ": " + what + ": " + std::strerror(errno));
  }
  void write_all(const std::string& b) const {
    size_t done = 0;
    while (done < b.size()) {
      const ssize_t n = ::write(fd, b.data() + done, b.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail("cannot write");
      done += static_cast<size_t>(n);
    }
  }
  // Reads the valid prefix of an earlier run's journal of stage `key`; returns its length (0: none).
  uint64_t load(uint64_t key) {
    const int in = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (in < 0) return 0;
    std::string b;
    char buf[1 << 16];
    for (;;) {
      const ssize_t n = ::read(in, buf, sizeof buf);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      b.append(buf, static_cast<size_t>(n));
    }
    ::close(in);
    uint64_t file_key = 0;
    if (b.size() < kMagicSize + 8 || b.compare(0, kMagicSize, kMagic) != 0) return 0;
    std::memcpy(&file_key, b.data() + kMagicSize, 8);
    if (file_key != key) return 0;
    size_t pos = kMagicSize + 8, valid = pos;
    std::vector<Write> uncommitted;
    auto get = [&](void* out, size_t n) {
      if (pos + n > b.size()) return false;
      std::memcpy(out, b.data() + pos, n);
      pos += n;
      return true;
    };
    for (;;) {
      const size_t start = pos;
      char kind = 0;
      if (!get(&kind, 1)) break;
      uint64_t hash = 0;
      if (kind == 'W') {
        Write w;
        uint64_t len = 0;
        if (!get(&len, 8) || len > b.size() - pos) break;
        w.name = b.substr(pos, len);
        pos += len;
        if (!get(w.begin.data(), 24) || !get(w.size.data(), 24) || !get(&w.bytes, 8) || w.bytes > b.size() - pos) break;
        w.offset = pos;
        pos += w.bytes;
        if (!get(&hash, 8) || hash != fnv(b.data() + start, pos - 8 - start)) break;
        uncommitted.push_back(std::move(w));
      } else if (kind == 'C') {
        int64_t pass = 0, index = 0;
        uint64_t len = 0;
        if (!get(&pass, 8) || !get(&index, 8) || !get(&len, 8) || len > b.size() - pos) break;
        std::string payload = b.substr(pos, len);
        pos += len;
        if (!get(&hash, 8) || hash != fnv(b.data() + start, pos - 8 - start)) break;
        committed[{pass, index}] = std::move(payload);
        for (auto& w : uncommitted) kept.push_back(std::move(w));
        uncommitted.clear();
        valid = pos;
      } else {
        break;
      }
    }
    return valid;
  }
};

BlockJournalFile::BlockJournalFile(fs::path file, uint64_t key) : s_(std::make_unique<State>()) {
  s_->file = std::move(file);
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
  }
  if (::fsync(s_->fd) != 0) s_->fail("cannot sync");
}

BlockJournalFile::~BlockJournalFile() {
  if (s_ && s_->fd >= 0) ::close(s_->fd);
}

int64_t BlockJournalFile::begin_pass() {
  std::lock_guard lock(s_->m);
  s_->active = true;
  return s_->passes++;
}

const std::string* BlockJournalFile::kept(int64_t pass, int64_t index) const {
  const auto it = s_->committed.find({pass, index});
  return it == s_->committed.end() ? nullptr : &it->second;
}

void BlockJournalFile::commit(int64_t pass, int64_t index, std::string_view payload) {
  std::lock_guard lock(s_->m);
  std::string& b = s_->pending;
  const size_t start = b.size();
  b.push_back('C');
  put(b, pass);
  put(b, index);
  put(b, static_cast<uint64_t>(payload.size()));
  b.append(payload);
  put(b, fnv(b.data() + start, b.size() - start));
  s_->write_all(b);
  if (::fdatasync(s_->fd) != 0) s_->fail("cannot sync");
  b.clear();
}

int64_t BlockJournalFile::kept_blocks() const { return static_cast<int64_t>(s_->committed.size()); }

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
    if (!s_.active) return;
    const uint64_t bytes = static_cast<uint64_t>(size[0] * size[1] * size[2] * bpv_);
    std::string& b = s_.pending;
    const size_t start = b.size();
    b.push_back('W');
    put(b, static_cast<uint64_t>(name_.size()));
    b += name_;
    b.append(reinterpret_cast<const char*>(begin.data()), 24);
    b.append(reinterpret_cast<const char*>(size.data()), 24);
    put(b, bytes);
    b.append(static_cast<const char*>(in), bytes);
    put(b, fnv(b.data() + start, b.size() - start));
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

std::shared_ptr<VolumeStore> BlockJournalFile::wrap(const std::string& name, int64_t bytes_per_voxel,
                                                    std::shared_ptr<VolumeStore> inner) {
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
