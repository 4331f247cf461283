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

// What is not a regular file, or is larger than a pipeline may be, is refused before it is read
// (`validate /dev/zero` used to read 4 GB and die of bad_alloc).
TEST(Cli, PipelineFileMustBeARegularFileOfSaneSize) {
  Result z = run(SKELFLOW_TESTCLI, {"validate", "/dev/zero"});
  EXPECT_EQ(z.code, 2) << z.out;
  EXPECT_EQ(z.out, "skelflow: /dev/zero: not a regular file (a pipeline is a YAML file)\n");
  fs::path d = scratch("huge");
  Result dir = run(SKELFLOW_TESTCLI, {"run", d.string()});
  EXPECT_EQ(dir.code, 2) << dir.out;
  EXPECT_NE(dir.out.find(d.string() + ": not a regular file"), std::string::npos) << dir.out;
  const fs::path big = d / "big.yaml";
  std::ofstream(big) << kGood;
  fs::resize_file(big, (64u << 20) + 1);  // sparse: costs no disk
  Result b = run(SKELFLOW_TESTCLI, {"validate", big.string()});
  EXPECT_EQ(b.code, 2) << b.out;
  EXPECT_EQ(b.out, "skelflow: " + big.string() + ": the file is larger than the 64 MiB a pipeline file may have\n");
}

TEST(Cli, ThreadsMustBeAWholeNumber) {
  fs::path d = scratch("threads");
  fs::path p = write(d / "p.yaml", kGood);
  for (const char* bad : {"1abc", "", "-1", "2.5", "99999"}) {
    Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--threads", bad});
    EXPECT_EQ(r.code, 2) << bad << ": " << r.out;
    EXPECT_NE(r.out.find(std::string("skelflow: --threads ") + bad + ": expected a whole number"), std::string::npos)
        << r.out;
  }
  EXPECT_FALSE(fs::exists(d / "out"));
}

// With --output-dir D, no output may land outside D: '..', absolute paths and symbolic links inside D
// that lead out are refused before anything runs, at the parameter's line:column, unless
// --allow-outside-output-dir; `validate` checks the same with the same options.
TEST(Cli, OutputsConfinedToOutputDir) {
  fs::path d = scratch("confined");
  const fs::path out = d / "out", victim = d / "victim";
  fs::create_directories(out);
  fs::create_directories(victim);
  fs::create_directory_symlink(victim, out / "link");
  const std::string head = "skelflow: 1\nnodes:\n  src: {module: test.source, params: {size: [4, 4, 4]}}\n";
  const std::string up = head + "  w: {module: test.write, inputs: {volume: src.volume}, params: {path: ../escape.txt}}\n";
  const std::string abs = head + "  w: {module: test.write, inputs: {volume: src.volume}, params: {path: " +
                          (victim / "abs.txt").string() + "}}\n";
  const std::string link = head + "  w: {module: test.write, inputs: {volume: src.volume}, params: {path: link/sum.txt}}\n";
  const std::string inside = head + "  w: {module: test.write, inputs: {volume: src.volume}, params: {path: a/../b/sum.txt}}\n";
  struct Case {
    std::string name, yaml, resolved;
  };
  for (const Case& c : {Case{"up", up, (d / "escape.txt").string()}, Case{"abs", abs, (victim / "abs.txt").string()},
                        Case{"link", link, (victim / "sum.txt").string()}}) {
    const fs::path p = write(d / (c.name + ".yaml"), c.yaml);
    for (const char* cmd : {"run", "validate"}) {
      Result r = run(SKELFLOW_TESTCLI, {cmd, p.string(), "--output-dir", out.string()});
      EXPECT_EQ(r.code, 2) << c.name << ": " << r.out;
      EXPECT_NE(r.out.find("skelflow: " + p.string() + ":4:72: node 'w': param 'path': output '"), std::string::npos)
          << c.name << ": " << r.out;
      EXPECT_NE(r.out.find("' resolves to " + c.resolved + ", outside the output folder " + fs::canonical(out).string() +
                           " (--allow-outside-output-dir allows it)"),
                std::string::npos)
          << c.name << ": " << r.out;
    }
    EXPECT_TRUE(fs::is_empty(victim)) << c.name;
    EXPECT_FALSE(fs::exists(d / "escape.txt")) << c.name;
    // Without --output-dir there is nothing to confine to; with the override the file is written.
    Result ok = run(SKELFLOW_TESTCLI, {"run", p.string(), "--output-dir", out.string(), "--allow-outside-output-dir"});
    EXPECT_EQ(ok.code, 0) << c.name << ": " << ok.out;
    EXPECT_TRUE(fs::exists(c.resolved)) << c.name;
    fs::remove(c.resolved);
  }
  const fs::path p = write(d / "inside.yaml", inside);
  Result ok = run(SKELFLOW_TESTCLI, {"run", p.string(), "--output-dir", out.string()});
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::exists(out / "b" / "sum.txt"));
}
