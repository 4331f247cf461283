// Per-block resume of every block-wise stage that keeps one (skel/block_journal.hpp): a run killed
// with kill -9 in the middle of a stage, started again with --resume, keeps the blocks the stage's
// journal committed ("resumed node 'X' from N finished block(s)") and ends with the bytes of an
// uninterrupted run. Each test kills one run per stage, in a later pass of the multi-pass stages
// (chamfer's sweeps, the EDT's y/z passes, components' union and label passes, thinning's passes).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli_process.hpp"

namespace fs = std::filesystem;

namespace {

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("resume_blocks_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

pid_t start(const std::vector<std::string>& args, const fs::path& log, int delay_ms) {
  return skel::test_cli::start_skelflow(args, log, delay_ms);
}
using skel::test_cli::resume_dir;
using skel::test_cli::text_of;

// The blocks committed in a stage's journal (the format of framework/src/block_journal.cpp,
// "skelflow-blocks 2"); a record still being written ends the count.
int64_t journal_commits(const fs::path& file) {
  const std::string b = text_of(file);
  const std::string magic = "skelflow-blocks 2\n";
  if (b.compare(0, magic.size(), magic) != 0) return 0;
  size_t pos = magic.size() + 8;
  int64_t commits = 0;
  auto u64 = [&](uint64_t& v) {
    if (pos + 8 > b.size()) return false;
    std::memcpy(&v, b.data() + pos, 8);
    pos += 8;
    return true;
  };
  while (pos < b.size()) {
    const char kind = b[pos++];
    uint64_t n = 0;
    if (kind == 'W') {
      if (!u64(n)) break;
      pos += n + 48;
      if (!u64(n)) break;
      pos += n + 8;
    } else if (kind == 'C') {
      pos += 16;
      if (!u64(n)) break;
      pos += n + 8;
      if (pos > b.size()) break;
      ++commits;
    } else if (kind == 'B') {  // a compacted journal: every commit so far
      uint64_t count = 0;
      if (!u64(count)) break;
      for (uint64_t k = 0; k < count && pos <= b.size(); ++k) {
        pos += 16;
        if (!u64(n)) break;
        pos += n;
      }
      pos += 8;
      if (pos > b.size()) break;
      commits = static_cast<int64_t>(count);
    } else {
      break;
    }
    if (pos > b.size()) break;
  }
  return commits;
}

struct Chain {
  std::map<std::string, int64_t> kept;  // per stage killed: the blocks the next run resumed from
  std::vector<std::string> killed;      // the stages killed, in order
  int exit_code = -1;                   // of the run that ended on its own
  std::string last_output;
};

// Runs `args` slowly; whenever a stage in `min_commits` that was not killed yet has committed at
// least that many blocks, kills the run with SIGKILL and starts it again with --resume, until a run
// ends on its own.
Chain kill_in_every_stage(const std::vector<std::string>& args, const fs::path& scratch_dir,
                          const std::map<std::string, int64_t>& min_commits) {
  Chain c;
  const fs::path log = fs::temp_directory_path() / ("skel_resume_blocks_" + std::to_string(getpid()) + ".log");
  std::vector<std::string> a = args;
  for (int round = 0; round < 20; ++round) {
    const pid_t pid = start(a, log, 15);
    bool killed = false;
    int status = 0;
    for (int i = 0; i < 24000; ++i) {  // up to 120 s on a loaded machine
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      if (waitpid(pid, &status, WNOHANG) == pid) break;  // ended on its own
      const fs::path d = resume_dir(scratch_dir);
      if (d.empty()) continue;
      for (const auto& [stage, least] : min_commits) {
        if (c.kept.count(stage) != 0 || std::find(c.killed.begin(), c.killed.end(), stage) != c.killed.end()) continue;
        if (journal_commits(d / (stage + ".blocks")) < least) continue;
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
        c.killed.push_back(stage);
        break;
      }
      if (killed) break;
    }
    const std::string out = text_of(log);
    // What this run resumed from (the stage killed before it).
    for (const auto& [stage, least] : min_commits) {
      const std::string note = "resumed node '" + stage + "' from ";
      if (const size_t at = out.find(note); at != std::string::npos)
        c.kept[stage] = std::stoll(out.substr(at + note.size()));
    }
    if (!killed) {
      c.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      c.last_output = out;
      break;
    }
    if (a.back() != "--resume") a.push_back("--resume");
  }
  fs::remove(log);
  return c;
}

// Runs the pipeline `yaml` uninterrupted (reference) and killed in every stage of `min_commits`;
// checks that every stage was killed once and resumed from at least its minimum of blocks, that the
// files in `outputs` are the reference's bytes, and that nothing is left in the scratch folder.
void check_resume_chain(const std::string& name, const std::string& yaml, const std::map<std::string, int64_t>& min_commits,
                        const std::vector<std::string>& outputs) {
  const fs::path d = scratch(name);
  std::ofstream(d / "p.yaml") << yaml;
  const fs::path s = d / "scratch";
  fs::create_directories(s);
  const fs::path log = d / "ref.log";
  const pid_t ref = start({"run", (d / "p.yaml").string(), "--output-dir", (d / "ref").string(), "--quiet"}, log, 0);
  int status = 0;
  waitpid(ref, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << text_of(log);

  const Chain c = kill_in_every_stage({"run", (d / "p.yaml").string(), "--scratch", s.string()}, s, min_commits);
  EXPECT_EQ(c.exit_code, 0) << c.last_output;
  for (const auto& [stage, least] : min_commits) {
    const auto it = c.kept.find(stage);
    ASSERT_NE(it, c.kept.end()) << "stage '" << stage << "' was not killed and resumed from its blocks; last output:\n"
                                << c.last_output;
    EXPECT_GE(it->second, least) << stage;
  }
  EXPECT_EQ(c.killed.size(), min_commits.size());
  for (const auto& o : outputs) {
    const std::string expected = text_of(d / "ref" / "out" / o);
    ASSERT_FALSE(expected.empty()) << o;
    EXPECT_EQ(text_of(d / "out" / o), expected) << o << " differs from the uninterrupted run's";
  }
  EXPECT_TRUE(fs::is_empty(s)) << "scratch or resume state left behind";
}

}  // namespace

TEST(ResumeBlocksCli, KilledInEverySegmentationAndDistanceStageGivesTheUninterruptedBytes) {
  // 26×22×18 voxels in blocks of 12³: 12 blocks (chamfer: 12 + 60 visits, EDT: 4 + 6 + 6 slabs,
  // components and fill_cavities: 2 passes of 12, the unions in memory between them).
  const std::string yaml = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: mixed, size: [26, 22, 18], period: 11, radius: 2.5, noise: 0.2}}
  lit: {module: segmentation.illumination_z, inputs: {image: phantom.image}, params: {percentile: 0.1}}
  seg: {module: segmentation.threshold, inputs: {image: lit.image}, params: {method: otsu}}
  filled: {module: segmentation.fill_cavities, inputs: {mask: seg.mask}}
  parts: {module: segmentation.connected_components, inputs: {mask: filled.mask}, params: {connectivity: 6}}
  dist: {module: distance.chamfer, inputs: {mask: parts.mask}}
  edt: {module: distance.euclidean, inputs: {mask: parts.mask}}
  save_lit: {module: io.write_volume, inputs: {volume: lit.image}, params: {path: out/lit.h5}}
  save_lit_table: {module: io.write_table, inputs: {table: lit.table}, params: {path: out/lit.csv}}
  save_seg_table: {module: io.write_table, inputs: {table: seg.table}, params: {path: out/seg.csv}}
  save_filled: {module: io.write_volume, inputs: {volume: filled.mask}, params: {path: out/filled.h5}}
  save_labels: {module: io.write_volume, inputs: {volume: parts.labels}, params: {path: out/labels.h5}}
  save_parts: {module: io.write_table, inputs: {table: parts.table}, params: {path: out/parts.csv}}
  save_dist: {module: io.write_volume, inputs: {volume: dist.distance}, params: {path: out/dist.h5}}
  save_edt: {module: io.write_volume, inputs: {volume: edt.distance}, params: {path: out/edt.h5}}
execution: {memory_budget: 1MiB, block: [12, 12, 12]}
)";
  // Killed in: the scaling pass; the mask pass (after Otsu's two read passes); the fill pass (after
  // the 12 blocks of the background pieces); the pieces pass of components (its pieces come back from the journal); a chamfer sweep
  // (after the 12 start blocks); the EDT's y pass (after the 4 x slabs).
  check_resume_chain("segmentation_distance", yaml,
                     {{"lit", 3}, {"seg", 3}, {"filled", 14}, {"parts", 5}, {"dist", 30}, {"edt", 6}},
                     {"lit.h5", "lit.csv", "seg.csv", "filled.h5", "labels.h5", "parts.csv", "dist.h5", "edt.h5"});
}

TEST(ResumeBlocksCli, KilledInThinningGeodesicAndGraphStagesGivesTheUninterruptedBytes) {
  const std::string yaml = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: mixed, size: [33, 29, 27], period: 13, radius: 2.5, noise: 0.2}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}, params: {low: 0.5}}
  edt: {module: distance.euclidean, inputs: {mask: seg.mask}}
  thin: {module: thinning.doht, inputs: {mask: seg.mask, priority: edt.distance}}
  geo: {module: geodesic.boundary_distance, inputs: {mask: seg.mask}, params: {threshold: 6}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: thin.skeleton, distance: edt.distance}, params: {with_manifold: true}}
  save_skel: {module: io.write_volume, inputs: {volume: thin.skeleton}, params: {path: out/skeleton.h5}}
  save_thin: {module: io.write_table, inputs: {table: thin.table}, params: {path: out/thinning.csv}}
  save_imp: {module: io.write_volume, inputs: {volume: geo.importance}, params: {path: out/importance.h5}}
  save_surf: {module: io.write_volume, inputs: {volume: geo.surface_skeleton}, params: {path: out/surface.h5}}
  save_geo: {module: io.write_table, inputs: {table: geo.table}, params: {path: out/geodesic.csv}}
  save_graph: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: out/graph.am}}
  save_manifold: {module: io.write_volume, inputs: {volume: graph.manifold}, params: {path: out/manifold.h5}}
execution: {memory_budget: 1MiB, block: [12, 12, 12]}
)";
  // 27 blocks of 12³. Killed in: thinning's first pass (after the 27 blocks of the copy); geodesic's
  // blocks; the graph's gathering.
  check_resume_chain("thinning_geodesic_graph", yaml, {{"thin", 30}, {"geo", 4}, {"graph", 4}},
                     {"skeleton.h5", "thinning.csv", "importance.h5", "surface.h5", "geodesic.csv", "graph.am",
                      "manifold.h5"});
}

namespace {

TEST(ResumeBlocksCli, NoBlockResumeKeepsNoJournalAndGivesTheSameBytes) {
  // --no-block-resume: the stages keep no `<node>.blocks` journal (watched while the slowed-down
  // run goes), the stage outputs are still kept for --resume per stage, and the result is the same.
  const std::string yaml = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: mixed, size: [26, 22, 18], period: 11, radius: 2.5, noise: 0.2}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}, params: {method: otsu}}
  edt: {module: distance.euclidean, inputs: {mask: seg.mask}}
  save_edt: {module: io.write_volume, inputs: {volume: edt.distance}, params: {path: out/edt.h5}}
execution: {memory_budget: 1MiB, block: [12, 12, 12]}
)";
  const fs::path d = scratch("no_block_resume");
  std::ofstream(d / "p.yaml") << yaml;
  const fs::path s = d / "scratch";
  fs::create_directories(s);
  const fs::path log = d / "run.log";
  int status = 0;
  const pid_t ref = start({"run", (d / "p.yaml").string(), "--output-dir", (d / "ref").string(), "--quiet"}, log, 0);
  waitpid(ref, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << text_of(log);
  const pid_t pid = start({"run", (d / "p.yaml").string(), "--scratch", s.string(), "--no-block-resume"}, log, 10);
  bool saw_resume_dir = false, saw_journal = false;
  for (int i = 0; i < 24000; ++i) {
    if (waitpid(pid, &status, WNOHANG) == pid) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    const fs::path r = resume_dir(s);
    if (r.empty()) continue;
    saw_resume_dir = true;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(r, ec))
      if (e.path().extension() == ".blocks") saw_journal = true;
  }
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << text_of(log);
  EXPECT_TRUE(saw_resume_dir);  // the stage-level resume state is still kept
  EXPECT_FALSE(saw_journal);
  EXPECT_EQ(text_of(d / "out" / "edt.h5"), text_of(d / "ref" / "out" / "edt.h5"));
}

}  // namespace
