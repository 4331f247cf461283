// skel/distributed.hpp: block assignment by cost, the loops and reductions over ranks, and the
// failure protocol (a failed rank ends every rank's run with its error). Ranks are simulated by
// threads of this process sharing one Communicator (the MPI transport is tested by tests/mpi/).
#include "skel/distributed.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <condition_variable>
#include <map>
#include <mutex>
#include <numeric>
#include <set>
#include <thread>

#include "skel/executor.hpp"

using namespace skel;

namespace {

thread_local int t_rank = 0;

// N threads as N ranks: allgather is a barrier that hands every thread all buffers.
class ThreadComm final : public Communicator {
public:
  explicit ThreadComm(int n) : n_(n), slots_(static_cast<size_t>(n)) {}
  [[nodiscard]] int rank() const override { return t_rank; }
  [[nodiscard]] int size() const override { return n_; }
  std::vector<std::string> allgather(const std::string& bytes) override {
    std::unique_lock lock(m_);
    const int64_t gen = gen_;
    slots_[static_cast<size_t>(t_rank)] = bytes;
    if (++arrived_ == n_) {
      result_ = slots_;
      arrived_ = 0;
      ++gen_;
      cv_.notify_all();
    } else {
      cv_.wait(lock, [&] { return gen_ != gen; });
    }
    return result_;
  }

private:
  int n_;
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<std::string> slots_, result_;
  int arrived_ = 0;
  int64_t gen_ = 0;
};

// Runs f(rank) on n threads as n ranks; returns what each threw ("" for none).
std::vector<std::string> on_ranks(int n, const std::function<void(int)>& f) {
  set_communicator(std::make_shared<ThreadComm>(n));
  std::vector<std::string> errors(static_cast<size_t>(n));
  std::vector<std::thread> threads;
  for (int r = 0; r < n; ++r)
    threads.emplace_back([&, r] {
      t_rank = r;
      try {
        f(r);
      } catch (const std::exception& e) {
        errors[static_cast<size_t>(r)] = e.what();
      }
    });
  for (auto& t : threads) t.join();
  set_communicator(nullptr);
  return errors;
}

}  // namespace

TEST(Distributed, SerialByDefault) {
  EXPECT_EQ(communicator().rank(), 0);
  EXPECT_EQ(communicator().size(), 1);
  EXPECT_FALSE(distributing());
  const DistributedStage stage;
  EXPECT_TRUE(distributed_stage_active());
  EXPECT_FALSE(distributing());  // one rank: nothing is split
  EXPECT_EQ(sum_over_ranks(int64_t{7}), 7);
  EXPECT_EQ(broadcast_from_root("abc"), "abc");
  // The loop is for_each_block: every block, in z, y, x order.
  const BlockLayout layout({10, 7, 5}, {4, 3, 2});
  std::vector<Dims> seen;
  for_each_owned_block(layout, Interrupter(), "t", [&](const Block& b) { seen.push_back(b.index); });
  ASSERT_EQ(static_cast<int64_t>(seen.size()), layout.total());
  EXPECT_EQ(seen.front(), (Dims{0, 0, 0}));
  EXPECT_EQ(seen[1], (Dims{1, 0, 0}));
  EXPECT_EQ(seen.back(), (Dims{2, 2, 2}));
}

TEST(Distributed, AssignBlocksBalancesCostsNotCounts) {
  // One expensive block (an object) and many empty ones: round-robin would give rank 0 the object
  // and a third of the rest; longest-first gives the object a rank of its own.
  std::vector<double> costs(31, 1.0);
  costs[0] = 30.0;
  const std::vector<int> owner = assign_blocks(costs, 3);
  ASSERT_EQ(owner.size(), costs.size());
  std::vector<double> load(3, 0.0);
  for (size_t i = 0; i < costs.size(); ++i) {
    ASSERT_GE(owner[i], 0);
    ASSERT_LT(owner[i], 3);
    load[static_cast<size_t>(owner[i])] += costs[i];
  }
  EXPECT_EQ(std::count(owner.begin(), owner.end(), owner[0]), 1);  // the object's rank gets nothing else
  EXPECT_DOUBLE_EQ(*std::max_element(load.begin(), load.end()), 30.0);
  EXPECT_EQ(owner, assign_blocks(costs, 3));  // the same on every rank
  // Equal costs: counts differ by at most one.
  const std::vector<int> even = assign_blocks(std::vector<double>(10, 2.0), 4);
  std::map<int, int> count;
  for (int r : even) ++count[r];
  EXPECT_EQ(count.size(), 4u);
  for (const auto& [r, c] : count) EXPECT_TRUE(c == 2 || c == 3) << r;
  EXPECT_THROW(assign_blocks(costs, 0), Error);
}

TEST(Distributed, OwnedBlocksCoverTheLayoutOnceAndReduce) {
  const BlockLayout layout({23, 17, 11}, {5, 4, 3});
  std::mutex m;
  std::multiset<std::array<int64_t, 3>> seen;
  std::vector<int64_t> sums(3, -1);
  std::vector<std::pair<double, double>> ranges(3);
  const auto errors = on_ranks(3, [&](int r) {
    const DistributedStage stage;
    ASSERT_TRUE(distributing());
    int64_t voxels = 0;
    double lo = 1e9, hi = -1e9;
    for_each_owned_block(layout, Interrupter(), "t", [&](const Block& b) {
      std::lock_guard lock(m);
      seen.insert(b.index);
      voxels += b.size[0] * b.size[1] * b.size[2];
      lo = std::min(lo, static_cast<double>(b.begin[0]));
      hi = std::max(hi, static_cast<double>(b.begin[0]));
    });
    sums[static_cast<size_t>(r)] = sum_over_ranks(voxels);
    ranges[static_cast<size_t>(r)] = minmax_over_ranks(lo, hi);
    EXPECT_EQ(broadcast_from_root("rank " + std::to_string(r)), "rank 0");
  });
  for (const auto& e : errors) EXPECT_EQ(e, "");
  EXPECT_EQ(static_cast<int64_t>(seen.size()), layout.total());
  const std::set<std::array<int64_t, 3>> distinct(seen.begin(), seen.end());
  EXPECT_EQ(distinct.size(), seen.size());  // each block once
  for (int r = 0; r < 3; ++r) {
    EXPECT_EQ(sums[static_cast<size_t>(r)], 23 * 17 * 11);
    EXPECT_EQ(ranges[static_cast<size_t>(r)], std::make_pair(0.0, 20.0));
  }
}

TEST(Distributed, AFailingBlockEndsTheLoopOnEveryRank) {
  const BlockLayout layout({16, 16, 16}, {4, 4, 4});
  const auto errors = on_ranks(3, [&](int r) {
    const DistributedStage stage;
    for_each_owned_block(layout, Interrupter(), "t", [&](const Block&) {
      if (r == 1) throw InputError("block broke");
    });
  });
  EXPECT_EQ(errors[1], "block broke");  // its own exception, as it was
  EXPECT_EQ(errors[0], "rank 1: block broke");
  EXPECT_EQ(errors[2], "rank 1: block broke");
}

// Thinning's wavefronts and skeleton_to_graph's gather: every item computed once, by the rank
// assign_blocks names, and every rank gets every item's result in item order.
TEST(Distributed, OwnedItemsAreComputedOnceAndEveryRankGetsEveryResult) {
  const std::vector<double> costs{5, 1, 1, 9, 0, 3, 3, 2, 7, 1};
  const int64_t n = static_cast<int64_t>(costs.size());
  const std::vector<int> owner = assign_blocks(costs, 3);
  std::mutex m;
  std::vector<int> computed_by(costs.size(), -1), times(costs.size(), 0);
  std::vector<std::vector<std::string>> got(3);
  const auto errors = on_ranks(3, [&](int r) {
    const DistributedStage stage;
    got[static_cast<size_t>(r)] = exchange_owned_items(n, costs, [&](int64_t i) {
      std::lock_guard lock(m);
      computed_by[static_cast<size_t>(i)] = r;
      ++times[static_cast<size_t>(i)];
      return "item " + std::to_string(i) + std::string(static_cast<size_t>(i), 'x');
    });
  });
  for (const auto& e : errors) EXPECT_EQ(e, "");
  for (int64_t i = 0; i < n; ++i) {
    EXPECT_EQ(times[static_cast<size_t>(i)], 1) << i;
    EXPECT_EQ(computed_by[static_cast<size_t>(i)], owner[static_cast<size_t>(i)]) << i;
    for (int r = 0; r < 3; ++r)
      EXPECT_EQ(got[static_cast<size_t>(r)][static_cast<size_t>(i)], "item " + std::to_string(i) + std::string(static_cast<size_t>(i), 'x'));
  }
  // One process: every item in order.
  std::vector<int64_t> order;
  const auto one = exchange_owned_items(3, {1, 1, 1}, [&](int64_t i) {
    order.push_back(i);
    return std::to_string(i);
  });
  EXPECT_EQ(order, (std::vector<int64_t>{0, 1, 2}));
  EXPECT_EQ(one, (std::vector<std::string>{"0", "1", "2"}));
}

TEST(Distributed, AFailingItemEndsTheExchangeOnEveryRank) {
  const auto errors = on_ranks(3, [&](int r) {
    const DistributedStage stage;
    (void)exchange_owned_items(6, std::vector<double>(6, 1.0), [&](int64_t) -> std::string {
      if (r == 2) throw InputError("item broke");
      return "ok";
    });
  });
  EXPECT_EQ(errors[2], "item broke");
  EXPECT_EQ(errors[0], "rank 2: item broke");
  EXPECT_EQ(errors[1], "rank 2: item broke");
}

// With several ranks a distributed stage keeps no block journal (its blocks are split by the number
// of ranks; --resume runs it again from its first block); with one rank it keeps the executor's.
TEST(Distributed, ADistributedStageHidesTheBlockJournalWithSeveralRanks) {
  struct NoJournal final : BlockJournal {
    int64_t begin_pass() override { return 0; }
    [[nodiscard]] const std::string* kept(int64_t, int64_t) const override { return nullptr; }
    void commit(int64_t, int64_t, std::string_view) override {}
  } journal;
  {
    const ScopedBlockJournal scoped(&journal);
    const DistributedStage stage;
    EXPECT_EQ(current_block_journal(), &journal);
  }
  std::vector<const BlockJournal*> seen(2, &journal), after(2, nullptr);
  const auto errors = on_ranks(2, [&](int r) {
    const ScopedBlockJournal scoped(&journal);
    {
      const DistributedStage stage;
      seen[static_cast<size_t>(r)] = current_block_journal();
    }
    after[static_cast<size_t>(r)] = current_block_journal();
  });
  for (int r = 0; r < 2; ++r) {
    EXPECT_EQ(errors[static_cast<size_t>(r)], "");
    EXPECT_EQ(seen[static_cast<size_t>(r)], nullptr);
    EXPECT_EQ(after[static_cast<size_t>(r)], &journal);  // given back when the stage ends
  }
}

TEST(Distributed, ARankThatFailedOutOfStepStopsTheOthersAtTheirNextExchange) {
  std::vector<std::vector<RankOutcome>> outcomes(3);
  const auto errors = on_ranks(3, [&](int r) {
    RankOutcome mine;
    if (r == 2) {  // failed before the others' next exchange: goes straight to the end of its run
      mine.ok = false;
      mine.node = 4;
      mine.error = "disk full";
      outcomes[2] = agree_outcome(mine);
      return;
    }
    try {
      sync_ranks();
      ADD_FAILURE() << "rank " << r << " did not notice rank 2's failure";
    } catch (const RankFailed& e) {
      EXPECT_EQ(e.failed_rank, 2);
      EXPECT_EQ(std::string(e.what()), "rank 2: disk full");
      mine.ok = false;
      mine.error = e.what();
    }
    outcomes[static_cast<size_t>(r)] = agree_outcome(mine);
  });
  for (const auto& e : errors) EXPECT_EQ(e, "");
  for (const auto& o : outcomes) {
    ASSERT_EQ(o.size(), 3u);
    EXPECT_FALSE(o[2].ok);
    EXPECT_EQ(o[2].node, 4);
    EXPECT_EQ(o[2].error, "disk full");
  }
}

TEST(Distributed, RunReportListsRanks) {
  RunReport r;
  r.ok = true;
  RankReport a;
  a.rank = 1;
  a.seconds = 2.0;
  a.seconds_waiting = 0.5;
  a.blocks = 7;
  a.bytes_sent = 120;
  a.seconds_io = 0.25;
  a.bytes_read = 4096;
  a.bytes_written = 8192;
  r.ranks.push_back(a);
  const std::string j = r.to_json();
  EXPECT_NE(j.find("\"ranks\": ["), std::string::npos) << j;
  EXPECT_NE(j.find("\"rank\": 1, \"ok\": true, \"seconds\": 2, \"seconds_blocks\": 0, \"seconds_waiting\": 0.5, "
                   "\"idle_share\": 0.25, \"blocks\": 7, \"collectives\": 0, \"bytes_sent\": 120, \"bytes_received\": 0, "
                   "\"seconds_io\": 0.25, \"bytes_read\": 4096, \"bytes_written\": 8192}"),
            std::string::npos)
      << j;
  EXPECT_EQ(RunReport{}.to_json().find("ranks"), std::string::npos);  // one process: as before
}
