#pragma once
// Running one pipeline on several processes (issue 17: MPI). Every rank parses and runs the same
// pipeline (SPMD); the block-wise stages that opt in (a DistributedStage in their run()) split their
// blocks over the ranks and share their scratch volumes (one parallel HDF5 file per volume); every
// other stage runs on every rank alike, on private scratch volumes. Framework and modules see only
// the Communicator below: `skelflow-mpi` (mpi/) installs one over MPI_COMM_WORLD, every other
// program has the serial one (one rank). See docs/architecture.md, "Running on several processes".
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "skel/block_journal.hpp"
#include "skel/error.hpp"
#include "skel/out_of_core.hpp"

namespace skel {

// The transport: rank, size and one collective, an all-gather of byte buffers. Implementations
// need not be thread-safe: collectives are called from one thread of each rank, in the same order.
class Communicator {
public:
  virtual ~Communicator() = default;
  [[nodiscard]] virtual int rank() const = 0;
  [[nodiscard]] virtual int size() const = 0;
  // Every rank's `bytes`, in rank order (collective: every rank must call it).
  virtual std::vector<std::string> allgather(const std::string& bytes) = 0;
  // Whether runs agree on their outcome and list every rank in the run report (skelflow-mpi, also
  // with one rank); the serial program does neither.
  [[nodiscard]] virtual bool reports_ranks() const { return size() > 1; }
};

// One process: rank 0 of 1.
class SerialCommunicator final : public Communicator {
public:
  [[nodiscard]] int rank() const override { return 0; }
  [[nodiscard]] int size() const override { return 1; }
  std::vector<std::string> allgather(const std::string& bytes) override { return {bytes}; }
};

// The process's communicator (serial unless a program installed another before running).
Communicator& communicator();
void set_communicator(std::shared_ptr<Communicator> c);

// What the collectives of this process cost, for the run report.
struct CommStats {
  int64_t collectives = 0;
  uint64_t bytes_sent = 0, bytes_received = 0;
  double seconds_waiting = 0;  // wall time inside collectives (waiting for the slowest rank + transfer)
  double seconds_blocks = 0;   // wall time computing this rank's share of distributed block loops
  int64_t blocks = 0;          // blocks this rank computed in distributed loops
  double seconds_io = 0;       // wall time reading and writing shared scratch volumes (part of seconds_blocks)
  uint64_t bytes_read = 0, bytes_written = 0;  // moved by those reads and writes (file side)
};
CommStats comm_stats();

// A rank that failed: thrown on the other ranks at the next exchange, "rank R: MESSAGE".
class RankFailed : public Error {
public:
  RankFailed(int rank, const std::string& message)
      : Error("rank " + std::to_string(rank) + ": " + message), failed_rank(rank) {}
  int failed_rank;
};

// The collective every rank's run goes through (collective: every rank must call it, in the same
// order): every rank's payload in rank order. When another rank reports a failure (its run ended
// with an error and it is waiting in agree_outcome), throws RankFailed with that rank's message.
std::vector<std::string> exchange(const std::string& payload);
// A barrier through exchange (so a failed rank is noticed).
void sync_ranks();
// Reductions of what each rank found in its blocks of a distributed loop: over the ranks when
// distributing() (collective), else the value itself.
int64_t sum_over_ranks(int64_t v);
std::vector<int64_t> sum_over_ranks(std::vector<int64_t> v);  // element-wise; equal lengths on every rank
std::pair<double, double> minmax_over_ranks(double lo, double hi);
// Rank 0's `bytes` on every rank.
std::string broadcast_from_root(const std::string& bytes);

// The end of a run on every rank (collective): each rank says whether its run succeeded (and if not,
// the error and the pipeline node index it occurred at, or -1). Returns every rank's outcome in rank
// order. A rank that failed waits here, answering the exchanges of the others with its failure,
// until every rank has reached this point.
struct RankOutcome {
  bool ok = true;
  int64_t node = -1;
  std::string error;
  CommStats stats;
  double seconds = 0;
};
std::vector<RankOutcome> agree_outcome(const RankOutcome& mine);

// Marks the block-wise stage now running as distributed over the ranks (RAII, in a module's run()
// before it makes its scratch volumes): scratch volumes made while one is alive are shared by all
// ranks (the store factory of skelflow-mpi asks distributed_stage_active()), and
// for_each_owned_block splits blocks over the ranks. Without one, or with one rank, nothing changes.
// With several ranks the stage keeps no block journal (skel/block_journal.hpp): a distributed stage
// killed mid-way runs again from its first block on `--resume` (every rank's blocks of it; the
// stages before it are loaded, and non-distributed stages resume per block on every rank).
class DistributedStage {
public:
  DistributedStage();
  ~DistributedStage();
  DistributedStage(const DistributedStage&) = delete;
  DistributedStage& operator=(const DistributedStage&) = delete;

private:
  ScopedBlockJournal journal_;
};
bool distributed_stage_active();
// True when blocks are split over ranks now: a distributed stage is active and there are 2+ ranks.
bool distributing();

// Splits blocks of the given costs over `ranks`: longest-processing-time first (blocks in falling
// cost, each to the rank with the least total cost so far; ties to the lower block index and rank).
// Deterministic: every rank computes the same owners. Returns the owner rank per block.
std::vector<int> assign_blocks(const std::vector<double>& costs, int ranks);

// A distributed loop over items 0..n-1 that need not be blocks of one layout (thinning's wavefront
// levels): when distributing, this rank calls f(i) for the items assign_blocks(costs) gives it, in
// increasing i, and one exchange gives every rank every item's result (f's return value), indexed by
// item. An exception thrown by f on any rank ends the loop on every rank (RankFailed on the others).
// When not distributing: f(i) for every i in order. Counted in the run report's blocks.
std::vector<std::string> exchange_owned_items(int64_t n, const std::vector<double>& costs,
                                              const std::function<std::string(int64_t)>& f);

// A part of a distributed stage that one rank computes: when distributing, rank 0 runs f while the
// others wait (sync_ranks); an exception from f ends the stage on every rank (RankFailed on the
// others). Otherwise f().
void on_root_rank(const std::function<void()>& f);

// For tests of failure handling: SKELFLOW_TEST_FAIL_RANK=R makes rank R throw at its first block of
// a distributed loop (or in on_root_rank, for R = 0).
int test_fail_rank();

namespace detail {
void add_block_seconds(double s, int64_t blocks);
// A read or write of a shared scratch volume by this rank (skelflow-mpi's store).
void add_io(double s, uint64_t bytes_read, uint64_t bytes_written);
void run_owned_blocks(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label,
                      const std::function<void(const Block&)>& f, const std::function<double(const Block&)>& cost);
}  // namespace detail

// for_each_block (skel/out_of_core.hpp) when not distributing. When distributing: this rank calls
// f(block) for the blocks assign_blocks gives it (cost: `cost(block)`, default the block's voxel
// count), in z, y, x order, then waits for every rank (sync_ranks); an exception thrown by f on any
// rank ends the loop on every rank with that error (on the other ranks as RankFailed). What f
// accumulates covers this rank's blocks only: reduce it over the ranks (sum_over_ranks, exchange).
template <class F>
void for_each_owned_block(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label, F&& f,
                          const std::function<double(const Block&)>& cost = {}) {
  if (!distributing()) {
    for_each_block(layout, interrupter, label, std::forward<F>(f));
    return;
  }
  detail::run_owned_blocks(layout, interrupter, label, [&](const Block& b) { f(b); }, cost);
}

}  // namespace skel
