// The skelflow command line: exit codes, messages, --set, --report, SIGINT, and no partial outputs.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;

namespace {

struct Result {
  int code = -1;
  std::string out;  // stdout + stderr
};

// Runs `bin args...` with stdout/stderr captured to a file; optionally sends SIGINT after `kill_after_ms`.
Result run(const std::string& bin, const std::vector<std::string>& args, int kill_after_ms = -1) {
  fs::path log = fs::temp_directory_path() / ("skel_cli_" + std::to_string(getpid()) + ".log");
  pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::freopen(log.c_str(), "w", stdout);
    (void)f;
    dup2(fileno(stdout), fileno(stderr));
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(bin.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  if (kill_after_ms >= 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(kill_after_ms));
    kill(pid, SIGINT);
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
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("cli_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

fs::path write(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
  return p;
}

const char* kGood = R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [4, 4, 4]}}
  x: {module: test.scale, inputs: {volume: src.volume}, params: {factor: 2}}
  w: {module: test.write, inputs: {volume: x.volume}, params: {path: out/sum.txt}}
)";

}  // namespace

TEST(Cli, RunSucceedsWritesOutputsAndReport) {
  fs::path d = scratch("ok");
  fs::path p = write(d / "p.yaml", kGood);
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--report", (d / "run.json").string(), "--threads", "2"});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(d / "out" / "sum.txt"));
  std::ifstream j(d / "run.json");
  std::stringstream ss;
  ss << j.rdbuf();
  EXPECT_NE(ss.str().find("\"ok\": true"), std::string::npos);
  EXPECT_NE(ss.str().find("\"module\": \"test.scale\""), std::string::npos);
  EXPECT_NE(r.out.find("wrote " + (d / "out" / "sum.txt").string()), std::string::npos) << r.out;
}

TEST(Cli, SetAndOutputDir) {
  fs::path d = scratch("set");
  fs::path p = write(d / "p.yaml", kGood);
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--set", "x.factor=0", "--output-dir", (d / "elsewhere").string()});
  EXPECT_EQ(r.code, 0) << r.out;
  std::ifstream in(d / "elsewhere" / "out" / "sum.txt");
  double s = -1;
  in >> s;
  EXPECT_EQ(s, 0.0);
  EXPECT_FALSE(fs::exists(d / "out"));
  Result bad = run(SKELFLOW_TESTCLI, {"run", p.string(), "--set", "x.factor=1000"});
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("node 'x': param 'factor': value 1000 is out of range"), std::string::npos) << bad.out;
  // The message names the override, not the file's own value.
  EXPECT_NE(bad.out.find("skelflow: --set x.factor=1000: node 'x': param 'factor': value 1000 is out of range"),
            std::string::npos)
      << bad.out;
  Result malformed = run(SKELFLOW_TESTCLI, {"run", p.string(), "--set", "x.factor=[1,"});
  EXPECT_EQ(malformed.code, 2) << malformed.out;
  EXPECT_NE(malformed.out.find("skelflow: --set x.factor=[1,: cannot read the value '[1,'"), std::string::npos)
      << malformed.out;
  Result no_param = run(SKELFLOW_TESTCLI, {"run", p.string(), "--set", "x.=1"});
  EXPECT_EQ(no_param.code, 2) << no_param.out;
  EXPECT_NE(no_param.out.find("skelflow: --set x.=1: expected node.param=value"), std::string::npos) << no_param.out;
}

TEST(Cli, InvalidPipelineExitsWith2) {
  fs::path d = scratch("invalid");
  fs::path p = write(d / "p.yaml", "skelflow: 1\nnodes:\n  a: {module: test.scale}\n");
  Result r = run(SKELFLOW_TESTCLI, {"validate", p.string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find(p.string() + ":3:3: node 'a': required input 'volume'"), std::string::npos) << r.out;
  Result r2 = run(SKELFLOW_TESTCLI, {"run", (d / "missing.yaml").string()});
  EXPECT_EQ(r2.code, 2);
  EXPECT_NE(r2.out.find("missing.yaml: pipeline file not found"), std::string::npos) << r2.out;
  Result r3 = run(SKELFLOW_TESTCLI, {"frobnicate"});
  EXPECT_EQ(r3.code, 2);
  Result ok = run(SKELFLOW_TESTCLI, {"validate", write(d / "good.yaml", kGood).string()});
  EXPECT_EQ(ok.code, 0) << ok.out;
}

TEST(Cli, FailureWhileRunningExitsWith1AndLeavesNothing) {
  fs::path d = scratch("fail");
  fs::path p = write(d / "p.yaml", std::string(kGood) + "  bad: {module: test.fail, inputs: {volume: x.volume}}\n");
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--threads", "1"});
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("node 'bad' (test.fail): failed on purpose"), std::string::npos) << r.out;
  // At the node's place in the file, as validation errors are.
  EXPECT_NE(r.out.find("skelflow: " + p.string() + ":6:3: node 'bad' (test.fail): failed on purpose\n"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(d / "out" / "sum.txt"));
}

TEST(Cli, SigintCancelsWith130AndNoPartialOutputs) {
  fs::path d = scratch("sigint");
  fs::path p = write(d / "p.yaml", std::string(kGood) +
                                       "  slow: {module: test.slow, inputs: {volume: x.volume}, params: {seconds: 60}}\n");
  auto t0 = std::chrono::steady_clock::now();
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string()}, 500);
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.code, 130) << r.out;
  EXPECT_LT(secs, 3.0);
  EXPECT_NE(r.out.find("interrupted"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "out" / "sum.txt"));
  for (const auto& e : fs::recursive_directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

TEST(Cli, ModulesDocsAndInfo) {
  Result r = run(SKELFLOW_TESTCLI, {"modules", "--markdown"});
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("### `test.scale`"), std::string::npos);
  EXPECT_NE(r.out.find("| `factor` | float | `2` | [-100, 100] |"), std::string::npos) << r.out.substr(0, 2000);
  fs::path d = scratch("info");
  Result i = run(SKELFLOW_TESTCLI, {"info", write(d / "p.yaml", kGood).string()});
  EXPECT_EQ(i.code, 0) << i.out;
  EXPECT_NE(i.out.find("Skelflow pipeline, 3 nodes"), std::string::npos) << i.out;
  Result u = run(SKELFLOW_TESTCLI, {"info", write(d / "x.unknownext", "hello").string()});
  EXPECT_EQ(u.code, 2);
  EXPECT_NE(u.out.find("unknown file type '.unknownext'"), std::string::npos) << u.out;
}
