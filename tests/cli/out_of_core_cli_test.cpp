// The command line of out-of-core runs: --memory-budget and --scratch (errors, exit codes), the
// block-wise stages listed by `skelflow validate`, progress in blocks, and the scratch files of a
// dead run removed by the next one.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct Result {
  int code = -1;
  std::string out;  // stdout + stderr
};

Result run(const std::vector<std::string>& args) {
  const fs::path log = fs::temp_directory_path() / ("skel_ooc_cli_" + std::to_string(getpid()) + ".log");
  const std::string bin = SKELFLOW_BIN;
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::freopen(log.c_str(), "w", stdout);
    (void)f;
    dup2(fileno(stdout), fileno(stderr));
    std::vector<char*> argv{const_cast<char*>(bin.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
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
  EXPECT_NE(r.out.find("block-wise under --memory-budget: seg, dist\n"), std::string::npos) << r.out;
  std::ofstream(d / "q.yaml") << kPipeline << "execution: {memory_budget: 512MiB}\n";
  r = run({"validate", (d / "q.yaml").string()});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("memory budget 512 MiB: block-wise: seg, dist\n"), std::string::npos) << r.out;
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
