// The command line of out-of-core runs: --memory-budget and --scratch (errors, exit codes), the
// block-wise stages listed by `skelflow validate`, progress in blocks, the scratch files of a
// dead run removed by the next one, and --resume after kill -9 (the same bytes as an uninterrupted
// run; refused when a parameter changed).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <chrono>
#include <csignal>
#include <fstream>
#include <thread>
#include <sstream>
#include <string>
#include <vector>

#include "cli_process.hpp"

namespace fs = std::filesystem;

namespace {

struct Result {
  int code = -1;
  std::string out;  // stdout + stderr
};

Result run(const std::vector<std::string>& args) {
  const fs::path log = fs::temp_directory_path() / ("skel_ooc_cli_" + std::to_string(getpid()) + ".log");
  const pid_t pid = skel::test_cli::start_skelflow(args, log, 0);
  int status = 0;
  waitpid(pid, &status, 0);
  Result r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  r.out = ss.str();
  fs::remove(log);
  return r;
}

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("ooc_cli_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

const char* kPipeline = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: rods, size: [30, 26, 21]}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}}
  dist: {module: distance.chamfer, inputs: {mask: seg.mask}}
  save: {module: io.write_volume, inputs: {volume: dist.distance}, params: {path: out/dist.h5}}
)";

}  // namespace

TEST(OutOfCoreCli, ValidateListsTheBlockwiseStages) {
  const fs::path d = scratch("validate");
  std::ofstream(d / "p.yaml") << kPipeline;
  Result r = run({"validate", (d / "p.yaml").string()});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("block-wise under --memory-budget: seg, dist, save\n"), std::string::npos) << r.out;
  std::ofstream(d / "q.yaml") << kPipeline << "execution: {memory_budget: 512MiB}\n";
  r = run({"validate", (d / "q.yaml").string()});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("memory budget 512 MiB: block-wise: seg, dist, save\n"), std::string::npos) << r.out;
  std::ofstream(d / "bad.yaml") << kPipeline << "execution: {memory_budget: lots}\n";
  r = run({"validate", (d / "bad.yaml").string()});
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("bad.yaml:7:28: execution: memory_budget: 'lots' is not a memory size"), std::string::npos) << r.out;
}

TEST(OutOfCoreCli, OptionErrorsExitWith2) {
  const fs::path d = scratch("options");
  std::ofstream(d / "p.yaml") << kPipeline;
  Result r = run({"run", (d / "p.yaml").string(), "--memory-budget", "2 bananas"});
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--memory-budget: unknown unit 'bananas' in '2 bananas'"), std::string::npos) << r.out;
  r = run({"run", (d / "p.yaml").string(), "--scratch", (d / "s").string()});
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("scratch files are only made under a memory budget"), std::string::npos) << r.out;
  r = run({"run", (d / "p.yaml").string(), "--memory-budget"});
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_FALSE(fs::exists(d / "out"));
}

TEST(OutOfCoreCli, BudgetRunRemovesADeadRunsScratchAndLeavesNone) {
  const fs::path d = scratch("run");
  std::ofstream(d / "p.yaml") << kPipeline;
  const fs::path s = d / "scratch";
  fs::create_directories(s);
  // A scratch file of a process that no longer runs (pid 2^22 + 1 is above Linux's pid_max).
  const fs::path stale = s / ".dist.distance.scratch.h5.skelflow-tmp-0badcafe-4194305";
  std::ofstream(stale) << "left by a killed run";
  Result r = run({"run", (d / "p.yaml").string(), "--memory-budget", "1MiB", "--scratch", s.string()});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(d / "out" / "dist.h5"));
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_NE(r.out.find("cleaned up after a run that did not finish"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::is_empty(s));
  // The same bytes as in memory.
  Result m = run({"run", (d / "p.yaml").string(), "--output-dir", (d / "mem").string()});
  EXPECT_EQ(m.code, 0) << m.out;
  auto bytes = [](const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(bytes(d / "out" / "dist.h5"), bytes(d / "mem" / "out" / "dist.h5"));
}

namespace {

// Starts skelflow with SKELFLOW_TEST_BLOCK_DELAY_MS set (every block-wise stage sleeps after each
// block), output to `log`; returns its pid.
pid_t start_slow(const std::vector<std::string>& args, const fs::path& log, int delay_ms) {
  return skel::test_cli::start_skelflow(args, log, delay_ms);
}
using skel::test_cli::resume_dir;
using skel::test_cli::text_of;

// Runs `args` slowly and kills it with SIGKILL once the manifest says `stage` finished and the next
// stage ran for a while (in the middle of its blocks). False when the run ended first.
bool kill_after(const std::vector<std::string>& args, const fs::path& scratch, const std::string& stage) {
  const fs::path log = fs::temp_directory_path() / ("skel_ooc_kill_" + std::to_string(getpid()) + ".log");
  const pid_t pid = start_slow(args, log, 20);
  bool killed = false;
  for (int i = 0; i < 3000; ++i) {  // up to 60 s on a loaded machine
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) break;  // ended on its own
    const fs::path d = resume_dir(scratch);
    if (!d.empty() && text_of(d / "manifest.txt").find("\ndone " + stage + " ") != std::string::npos) {
      std::this_thread::sleep_for(std::chrono::milliseconds(400));
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
      break;
    }
  }
  fs::remove(log);
  return killed;
}

}  // namespace

TEST(OutOfCoreCli, ResumeAfterKillGivesTheSameBytesAndRefusesChangedParameters) {
  const fs::path d = scratch("resume");
  // 8³ blocks: threshold and chamfer take a few seconds with 20 ms per block.
  std::ofstream(d / "p.yaml") << kPipeline << "execution: {memory_budget: 1MiB, block: [8, 8, 8]}\n";
  const fs::path s = d / "scratch";
  const std::vector<std::string> args = {"run", (d / "p.yaml").string(), "--scratch", s.string(), "--quiet"};
  // Uninterrupted, for reference.
  Result ref = run({"run", (d / "p.yaml").string(), "--output-dir", (d / "ref").string(), "--quiet"});
  ASSERT_EQ(ref.code, 0) << ref.out;
  const std::string expected = text_of(d / "ref" / "out" / "dist.h5");
  ASSERT_FALSE(expected.empty());

  // Killed while chamfer runs: the threshold's mask is kept, no output appears.
  ASSERT_TRUE(kill_after(args, s, "seg")) << "the run ended before it could be killed";
  const fs::path kept = resume_dir(s);
  ASSERT_FALSE(kept.empty());
  EXPECT_NE(text_of(kept / "manifest.txt").find("\nout seg mask volume seg.mask.h5 volume.u8 30 26 21 "), std::string::npos)
      << text_of(kept / "manifest.txt");
  EXPECT_FALSE(fs::exists(d / "out" / "dist.h5"));

  // A changed parameter: refused, naming the node; the kept state stays for a correct --resume.
  Result bad = run({"run", (d / "p.yaml").string(), "--scratch", s.string(), "--quiet", "--resume", "--set", "seg.low=0.25"});
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("--resume: cannot continue the run kept in " + kept.string() +
                         ": the parameters of node 'seg' changed since that run; run without --resume to start over"),
            std::string::npos)
      << bad.out;
  EXPECT_TRUE(fs::exists(kept / "manifest.txt"));
  EXPECT_FALSE(fs::exists(d / "out" / "dist.h5"));

  // Resumed: phantom and seg are not run again, the output is the uninterrupted run's bytes.
  Result ok = run({"run", (d / "p.yaml").string(), "--scratch", s.string(), "--resume", "--report", (d / "r.json").string()});
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_NE(ok.out.find("resumed from " + kept.string() + ": 1 finished stage(s) loaded, 2 to run"), std::string::npos) << ok.out;
  const std::string report = text_of(d / "r.json");
  EXPECT_NE(report.find("{\"id\": \"seg\", \"module\": \"segmentation.threshold\", \"cached\": true"), std::string::npos) << report;
  EXPECT_NE(report.find("{\"id\": \"phantom\", \"module\": \"synthetic.network\", \"cached\": true"), std::string::npos) << report;
  EXPECT_EQ(text_of(d / "out" / "dist.h5"), expected);
  EXPECT_TRUE(fs::is_empty(s)) << "scratch or resume state left behind";

  // Killed again, then started without --resume: the kept state is removed, and the run says so.
  fs::remove_all(d / "out");
  ASSERT_TRUE(kill_after(args, s, "seg"));
  Result fresh = run({"run", (d / "p.yaml").string(), "--scratch", s.string()});
  EXPECT_EQ(fresh.code, 0) << fresh.out;
  EXPECT_NE(fresh.out.find("removed the resume state of a run of this pipeline that did not finish (" + kept.string()), std::string::npos)
      << fresh.out;
  EXPECT_EQ(text_of(d / "out" / "dist.h5"), expected);
  EXPECT_TRUE(fs::is_empty(s));
}

TEST(OutOfCoreCli, ResumeAfterKillInTheMiddleOfAStageKeepsItsFinishedBlocks) {
  // Gaussian blocks are independent: a run killed in the middle of the stage resumes from the blocks
  // its journal committed (smooth.blocks in the resume folder), and the output is the uninterrupted
  // run's bytes.
  const fs::path d = scratch("resume_blocks");
  std::ofstream(d / "p.yaml") << R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: rods, size: [32, 24, 24]}}
  smooth: {module: segmentation.gaussian, inputs: {image: phantom.image}, params: {sigma: [1.5, 1.5, 1.5]}}
  save: {module: io.write_volume, inputs: {volume: smooth.image}, params: {path: out/smooth.h5}}
execution: {memory_budget: 1MiB, block: [8, 8, 8]}
)";
  const fs::path s = d / "scratch";
  Result ref = run({"run", (d / "p.yaml").string(), "--output-dir", (d / "ref").string(), "--quiet"});
  ASSERT_EQ(ref.code, 0) << ref.out;
  const std::string expected = text_of(d / "ref" / "out" / "smooth.h5");
  ASSERT_FALSE(expected.empty());

  // Killed once the journal holds several committed blocks (36 blocks of 8³ float voxels, 2 KiB each).
  const std::vector<std::string> args = {"run", (d / "p.yaml").string(), "--scratch", s.string(), "--quiet"};
  const fs::path log = fs::temp_directory_path() / ("skel_ooc_kill_blocks_" + std::to_string(getpid()) + ".log");
  const pid_t pid = start_slow(args, log, 30);
  bool killed = false;
  for (int i = 0; i < 3000 && !killed; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) break;
    const fs::path r = resume_dir(s);
    std::error_code ec;
    if (!r.empty() && fs::file_size(r / "smooth.blocks", ec) > 10 * 2048 && !ec) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
    }
  }
  fs::remove(log);
  ASSERT_TRUE(killed) << "the run ended before it could be killed";
  EXPECT_FALSE(fs::exists(d / "out" / "smooth.h5"));

  Result ok = run({"run", (d / "p.yaml").string(), "--scratch", s.string(), "--resume"});
  EXPECT_EQ(ok.code, 0) << ok.out;
  const size_t at = ok.out.find("resumed node 'smooth' from ");
  ASSERT_NE(at, std::string::npos) << ok.out;
  const int kept = std::stoi(ok.out.substr(at + std::string("resumed node 'smooth' from ").size()));
  EXPECT_GE(kept, 10) << ok.out;
  EXPECT_LT(kept, 36) << ok.out;
  EXPECT_EQ(text_of(d / "out" / "smooth.h5"), expected);
  EXPECT_TRUE(fs::is_empty(s)) << "scratch or resume state left behind";
}
