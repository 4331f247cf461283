#include "skel/distributed.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <numeric>

namespace skel {

// ---------------------------------------------------------------- the communicator
namespace {
std::mutex& comm_mutex() {
  static std::mutex m;
  return m;
}
std::shared_ptr<Communicator>& comm_slot() {
  static std::shared_ptr<Communicator> c = std::make_shared<SerialCommunicator>();
  return c;
}
CommStats& stats_slot() {
  static CommStats s;
  return s;
}
std::atomic<int>& stage_depth() {
  static std::atomic<int> d{0};
  return d;
}

// Little byte writer/reader for the payloads (same machine layout on every rank: one program).
void put_raw(std::string& s, const void* p, size_t n) { s.append(static_cast<const char*>(p), n); }
template <class T>
void put(std::string& s, const T& v) {
  put_raw(s, &v, sizeof(T));
}
void put_str(std::string& s, const std::string& v) {
  put<uint64_t>(s, v.size());
  s += v;
}
struct Reader {
  const std::string& s;
  size_t pos = 0;
  template <class T>
  T get() {
    T v{};
    if (pos + sizeof(T) > s.size()) throw Error("rank exchange: truncated message");
    std::memcpy(&v, s.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
  std::string get_str() {
    const auto n = get<uint64_t>();
    if (pos + n > s.size()) throw Error("rank exchange: truncated message");
    std::string v = s.substr(pos, n);
    pos += n;
    return v;
  }
};

// Every exchange starts with one byte: 'R' (a rank still running its pipeline) or 'D' (a rank at
// the end of its run, in agree_outcome).
std::vector<std::string> timed_allgather(const std::string& bytes) {
  Communicator& c = communicator();
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::string> all = c.allgather(bytes);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (static_cast<int>(all.size()) != c.size()) throw Error("rank exchange: got " + std::to_string(all.size()) + " answers");
  std::lock_guard lock(comm_mutex());
  CommStats& st = stats_slot();
  ++st.collectives;
  st.seconds_waiting += s;
  st.bytes_sent += bytes.size() * static_cast<uint64_t>(c.size() - 1);
  for (int r = 0; r < c.size(); ++r)
    if (r != c.rank()) st.bytes_received += all[static_cast<size_t>(r)].size();
  return all;
}

std::string encode_outcome(const RankOutcome& o) {
  std::string s = "D";
  put<uint8_t>(s, o.ok ? 1 : 0);
  put<int64_t>(s, o.node);
  put_str(s, o.error);
  put(s, o.stats.collectives);
  put(s, o.stats.bytes_sent);
  put(s, o.stats.bytes_received);
  put(s, o.stats.seconds_waiting);
  put(s, o.stats.seconds_blocks);
  put(s, o.stats.blocks);
  put(s, o.stats.seconds_io);
  put(s, o.stats.bytes_read);
  put(s, o.stats.bytes_written);
  put(s, o.seconds);
  return s;
}
RankOutcome decode_outcome(const std::string& s) {
  Reader r{s, 1};
  RankOutcome o;
  o.ok = r.get<uint8_t>() != 0;
  o.node = r.get<int64_t>();
  o.error = r.get_str();
  o.stats.collectives = r.get<int64_t>();
  o.stats.bytes_sent = r.get<uint64_t>();
  o.stats.bytes_received = r.get<uint64_t>();
  o.stats.seconds_waiting = r.get<double>();
  o.stats.seconds_blocks = r.get<double>();
  o.stats.blocks = r.get<int64_t>();
  o.stats.seconds_io = r.get<double>();
  o.stats.bytes_read = r.get<uint64_t>();
  o.stats.bytes_written = r.get<uint64_t>();
  o.seconds = r.get<double>();
  return o;
}
}  // namespace

Communicator& communicator() {
  std::lock_guard lock(comm_mutex());
  return *comm_slot();
}

void set_communicator(std::shared_ptr<Communicator> c) {
  if (!c) c = std::make_shared<SerialCommunicator>();
  std::lock_guard lock(comm_mutex());
  comm_slot() = std::move(c);
  stats_slot() = CommStats{};
}

CommStats comm_stats() {
  std::lock_guard lock(comm_mutex());
  return stats_slot();
}

std::vector<std::string> exchange(const std::string& payload) {
  if (communicator().size() == 1) return {payload};
  std::vector<std::string> all = timed_allgather("R" + payload);
  const int me = communicator().rank();
  for (size_t r = 0; r < all.size(); ++r) {
    if (all[r].empty()) throw Error("rank exchange: empty message from rank " + std::to_string(r));
    if (all[r][0] == 'D') {
      const RankOutcome o = decode_outcome(all[r]);
      if (!o.ok) throw RankFailed(static_cast<int>(r), o.error);
      throw Error("rank " + std::to_string(r) + " finished its run while rank " + std::to_string(me) +
                  " was still running (the ranks ran different stages)");
    }
    all[r].erase(0, 1);
  }
  return all;
}

void sync_ranks() { (void)exchange({}); }

int64_t sum_over_ranks(int64_t v) { return sum_over_ranks(std::vector<int64_t>{v}).front(); }

std::vector<int64_t> sum_over_ranks(std::vector<int64_t> v) {
  if (!distributing()) return v;
  std::string s;
  put_raw(s, v.data(), v.size() * sizeof(int64_t));
  const std::vector<std::string> all = exchange(s);
  std::fill(v.begin(), v.end(), 0);
  for (size_t r = 0; r < all.size(); ++r) {
    if (all[r].size() != v.size() * sizeof(int64_t))
      throw Error("sum_over_ranks: rank " + std::to_string(r) + " gave " + std::to_string(all[r].size() / sizeof(int64_t)) +
                  " values, this rank " + std::to_string(v.size()));
    Reader rd{all[r]};
    for (auto& x : v) x += rd.get<int64_t>();
  }
  return v;
}

std::pair<double, double> minmax_over_ranks(double lo, double hi) {
  if (!distributing()) return {lo, hi};
  std::string s;
  put(s, lo);
  put(s, hi);
  for (const auto& b : exchange(s)) {
    Reader rd{b};
    lo = std::min(lo, rd.get<double>());
    hi = std::max(hi, rd.get<double>());
  }
  return {lo, hi};
}

std::string broadcast_from_root(const std::string& bytes) {
  if (communicator().size() == 1) return bytes;
  const bool root = communicator().rank() == 0;
  return exchange(root ? bytes : std::string()).front();
}

std::vector<RankOutcome> agree_outcome(const RankOutcome& mine) {
  const int n = communicator().size();
  if (n == 1) {
    RankOutcome o = mine;
    o.stats = comm_stats();
    return {o};
  }
  for (;;) {
    RankOutcome o = mine;
    o.stats = comm_stats();
    const std::vector<std::string> all = timed_allgather(encode_outcome(o));
    if (std::all_of(all.begin(), all.end(), [](const std::string& s) { return !s.empty() && s[0] == 'D'; })) {
      std::vector<RankOutcome> out;
      for (const auto& s : all) out.push_back(decode_outcome(s));
      return out;
    }
    // Some rank is still in an exchange of its run: it sees this rank's answer and ends its run too.
  }
}

// ---------------------------------------------------------------- distributed stages
DistributedStage::DistributedStage() : journal_(communicator().size() > 1 ? nullptr : current_block_journal()) {
  ++stage_depth();
}
DistributedStage::~DistributedStage() { --stage_depth(); }
bool distributed_stage_active() { return stage_depth().load() > 0; }
bool distributing() { return distributed_stage_active() && communicator().size() > 1; }

std::vector<int> assign_blocks(const std::vector<double>& costs, int ranks) {
  if (ranks < 1) throw Error("assign_blocks: no ranks");
  std::vector<size_t> order(costs.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return costs[a] > costs[b]; });
  std::vector<double> load(static_cast<size_t>(ranks), 0.0);
  std::vector<int> owner(costs.size(), 0);
  for (size_t b : order) {
    const size_t r = static_cast<size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    owner[b] = static_cast<int>(r);
    load[r] += std::max(0.0, costs[b]);
  }
  return owner;
}

int test_fail_rank() {
  const char* v = std::getenv("SKELFLOW_TEST_FAIL_RANK");
  if (!v || !*v) return -1;
  return std::atoi(v);
}

namespace {
// Ends a distributed section on every rank: each says whether it failed (and why); the failed rank
// rethrows its own exception, the others throw RankFailed for the first failed rank.
void conclude_section(const std::exception_ptr& failure, const std::string& message) {
  std::string status;
  put<uint8_t>(status, failure ? 1 : 0);
  put_str(status, message);
  const std::vector<std::string> all = exchange(status);
  if (failure) std::rethrow_exception(failure);
  for (size_t r = 0; r < all.size(); ++r) {
    Reader rd{all[r]};
    if (rd.get<uint8_t>() != 0) throw RankFailed(static_cast<int>(r), rd.get_str());
  }
}
}  // namespace

void on_root_rank(const std::function<void()>& f) {
  if (!distributing()) {
    f();
    return;
  }
  std::exception_ptr failure;
  std::string message;
  if (communicator().rank() == 0) {
    const auto t0 = std::chrono::steady_clock::now();
    try {
      if (test_fail_rank() == 0) throw Error("failure injected on rank 0 (SKELFLOW_TEST_FAIL_RANK)");
      f();
    } catch (const std::exception& e) {
      failure = std::current_exception();
      message = e.what();
    } catch (...) {
      failure = std::current_exception();
      message = "unknown error";
    }
    detail::add_block_seconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0);
  }
  conclude_section(failure, message);
}

std::vector<std::string> exchange_owned_items(int64_t n, const std::vector<double>& costs,
                                              const std::function<std::string(int64_t)>& f) {
  std::vector<std::string> out(static_cast<size_t>(std::max<int64_t>(0, n)));
  if (!distributing()) {
    for (int64_t i = 0; i < n; ++i) out[static_cast<size_t>(i)] = f(i);
    return out;
  }
  if (static_cast<int64_t>(costs.size()) != n) throw Error("exchange_owned_items: " + std::to_string(costs.size()) + " costs for " + std::to_string(n) + " items");
  const int me = communicator().rank();
  const std::vector<int> owner = assign_blocks(costs, communicator().size());
  // Payload: failed (1 byte), message, then (item, result) of each item this rank computed.
  std::string mine;
  std::exception_ptr failure;
  std::string message;
  std::string results;
  int64_t done = 0;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    for (int64_t i = 0; i < n; ++i) {
      if (owner[static_cast<size_t>(i)] != me) continue;
      if (test_fail_rank() == me) throw Error("failure injected on rank " + std::to_string(me) + " (SKELFLOW_TEST_FAIL_RANK)");
      const std::string r = f(i);
      put<int64_t>(results, i);
      put_str(results, r);
      ++done;
    }
  } catch (const std::exception& e) {
    failure = std::current_exception();
    message = e.what();
  } catch (...) {
    failure = std::current_exception();
    message = "unknown error";
  }
  detail::add_block_seconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), done);
  put<uint8_t>(mine, failure ? 1 : 0);
  put_str(mine, message);
  mine += results;
  const std::vector<std::string> all = exchange(mine);
  if (failure) std::rethrow_exception(failure);
  for (size_t r = 0; r < all.size(); ++r) {
    Reader rd{all[r]};
    if (rd.get<uint8_t>() != 0) throw RankFailed(static_cast<int>(r), rd.get_str());
    (void)rd.get_str();
    while (rd.pos < all[r].size()) {
      const auto i = rd.get<int64_t>();
      if (i < 0 || i >= n) throw Error("rank exchange: item " + std::to_string(i) + " out of range");
      out[static_cast<size_t>(i)] = rd.get_str();
    }
  }
  return out;
}

namespace detail {
void add_block_seconds(double s, int64_t blocks) {
  std::lock_guard lock(comm_mutex());
  stats_slot().seconds_blocks += s;
  stats_slot().blocks += blocks;
}

void add_io(double s, uint64_t bytes_read, uint64_t bytes_written) {
  std::lock_guard lock(comm_mutex());
  stats_slot().seconds_io += s;
  stats_slot().bytes_read += bytes_read;
  stats_slot().bytes_written += bytes_written;
}

void run_owned_blocks(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label,
                      const std::function<void(const Block&)>& f, const std::function<double(const Block&)>& cost) {
  const int me = communicator().rank();
  const Dims c = layout.count();
  std::vector<Block> blocks;
  blocks.reserve(static_cast<size_t>(layout.total()));
  for (int64_t bz = 0; bz < c[2]; ++bz)
    for (int64_t by = 0; by < c[1]; ++by)
      for (int64_t bx = 0; bx < c[0]; ++bx) blocks.push_back(layout.at(bx, by, bz));
  std::vector<double> costs(blocks.size());
  for (size_t i = 0; i < blocks.size(); ++i)
    costs[i] = cost ? cost(blocks[i])
                    : static_cast<double>(blocks[i].size[0]) * static_cast<double>(blocks[i].size[1]) *
                          static_cast<double>(blocks[i].size[2]);
  const std::vector<int> owner = assign_blocks(costs, communicator().size());
  const int64_t mine = std::count(owner.begin(), owner.end(), me);
  std::exception_ptr failure;
  std::string message;
  const auto t0 = std::chrono::steady_clock::now();
  int64_t done = 0;
  try {
    report_blocks(interrupter, label, 0, mine);
    for (size_t i = 0; i < blocks.size(); ++i) {
      if (owner[i] != me) continue;
      if (test_fail_rank() == me)
        throw Error(label + ": failure injected on rank " + std::to_string(me) + " (SKELFLOW_TEST_FAIL_RANK)");
      f(blocks[i]);
      report_blocks(interrupter, label, ++done, mine);
    }
  } catch (const std::exception& e) {
    failure = std::current_exception();
    message = e.what();
  } catch (...) {
    failure = std::current_exception();
    message = "unknown error";
  }
  add_block_seconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), done);
  conclude_section(failure, message);
}
}  // namespace detail

}  // namespace skel
