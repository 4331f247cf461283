// The skelflow command line: exit codes, messages, --set, --report, SIGINT, and no partial outputs.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <grp.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <sstream>
#include <thread>

#include "cli.hpp"

namespace fs = std::filesystem;

namespace {

int setgroups_none() { return setgroups(0, nullptr); }

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

struct RunOptions {
  int after_ms = -1;                       // then send `signal`, or call `during` instead
  int signal = SIGINT;
  std::function<void(pid_t)> during;
  long file_size_limit = -1;               // RLIMIT_FSIZE in bytes (SIGXFSZ ignored), as `ulimit -f`
  bool unprivileged = false;               // run as user nobody when the tests run as root
};

// Runs `bin args...` with stdout and stderr read through a pipe (a file would fall under the file
// size limit too), with the limits and the signal or action of `o`.
Result run_with(const std::string& bin, const std::vector<std::string>& args, const RunOptions& o) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[1], STDOUT_FILENO);
    dup2(fds[1], STDERR_FILENO);
    close(fds[0]);
    close(fds[1]);
    if (o.file_size_limit >= 0) {
      const rlimit r{static_cast<rlim_t>(o.file_size_limit), static_cast<rlim_t>(o.file_size_limit)};
      signal(SIGXFSZ, SIG_IGN);  // writes beyond the limit fail with EFBIG instead of killing
      if (setrlimit(RLIMIT_FSIZE, &r) != 0) _exit(125);
    }
    if (o.unprivileged && geteuid() == 0 && (setgroups_none() != 0 || setgid(65534) != 0 || setuid(65534) != 0))
      _exit(124);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(bin.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  close(fds[1]);
  Result r;
  std::thread reader([&] {
    char buf[4096];
    for (ssize_t n; (n = read(fds[0], buf, sizeof buf)) > 0;) r.out.append(buf, static_cast<size_t>(n));
  });
  if (o.after_ms >= 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(o.after_ms));
    if (o.during) o.during(pid);
    else kill(pid, o.signal);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  reader.join();
  close(fds[0]);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Every file under `d` whose name marks it as a temporary or a backup.
std::vector<std::string> leftovers(const fs::path& d) {
  std::vector<std::string> r;
  for (const auto& e : fs::recursive_directory_iterator(d)) {
    const std::string n = e.path().filename().string();
    if (n.find("skelflow-tmp") != std::string::npos || n.find("skelflow-bak") != std::string::npos ||
        n.find(".tmp-") != std::string::npos)
      r.push_back(e.path().string());
  }
  return r;
}

// Waits (up to 10 s, for loaded machines) until `folder` holds a file whose name starts with `prefix`.
bool wait_for_file(const fs::path& folder, const std::string& prefix) {
  for (int i = 0; i < 1000; ++i) {
    std::error_code ec;
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec))
      if (it->path().filename().string().rfind(prefix, 0) == 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
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

// `info` on a graph file names its unit and ends its line (the description used to run into the
// shell prompt).
TEST(Cli, InfoOfAGraphFileNamesItsUnit) {
  fs::path d = scratch("info_graph");
  const std::string graphml = R"(<?xml version="1.0" encoding="UTF-8"?>
<graphml xmlns="http://graphml.graphdrawing.org/xmlns">
  <key id="u" for="graph" attr.name="unit" attr.type="string"/>
  <key id="x" for="node" attr.name="x" attr.type="double"/>
  <graph id="G" edgedefault="undirected">
    <data key="u">mm</data>
    <node id="a"><data key="x">0</data></node>
    <node id="b"><data key="x">2.5</data></node>
    <edge source="a" target="b"/>
  </graph>
</graphml>
)";
  Result i = run(SKELFLOW_BIN, {"info", write(d / "g.graphml", graphml).string()});
  EXPECT_EQ(i.code, 0) << i.out;
  EXPECT_NE(i.out.find("length 2.5 mm"), std::string::npos) << i.out;
  ASSERT_FALSE(i.out.empty());
  EXPECT_EQ(i.out.back(), '\n');
}

// Amira `.am` holds volumes and spatial graphs: `info` describes either (before: the volume reader
// claimed every .am and a graph file failed with "no 'define Lattice'"), and a file that is neither
// says what each reader found.
TEST(Cli, InfoOfAmiraFilesTellsVolumesFromGraphs) {
  fs::path d = scratch("info_amira");
  const std::string graph =
      "# AmiraMesh 3D ASCII 2.0\n\ndefine VERTEX 2\ndefine EDGE 1\ndefine POINT 2\n\n"
      "Parameters {\n  ContentType \"HxSpatialGraph\"\n}\n\n"
      "VERTEX { float[3] VertexCoordinates } @1\nEDGE { int[2] EdgeConnectivity } @2\n"
      "EDGE { int NumEdgePoints } @3\nPOINT { float[3] EdgePointCoordinates } @4\n\n"
      "@1\n0 0 0\n3 0 0\n\n@2\n0 1\n\n@3\n2\n\n@4\n0 0 0\n3 0 0\n";
  Result g = run(SKELFLOW_BIN, {"info", write(d / "g.am", graph).string()});
  EXPECT_EQ(g.code, 0) << g.out;
  EXPECT_NE(g.out.find("spatial graph"), std::string::npos) << g.out;
  const std::string lattice =
      "# AmiraMesh 3D ASCII 2.0\n\ndefine Lattice 2 2 1\n\nParameters {\n  BoundingBox 0 1 0 1 0 0,\n"
      "  CoordType \"uniform\"\n}\n\nLattice { byte Data } @1\n\n@1\n1 2 3 4\n";
  Result v = run(SKELFLOW_BIN, {"info", write(d / "v.am", lattice).string()});
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("uint8 2x2x1"), std::string::npos) << v.out;
  Result bad = run(SKELFLOW_BIN, {"info", write(d / "bad.am", "# AmiraMesh 3D ASCII 2.0\nhello\n").string()});
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("as volume file:"), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("as spatial graph:"), std::string::npos) << bad.out;
}

// A closed terminal (SIGHUP) and Ctrl+\ (SIGQUIT) cancel as SIGTERM and Ctrl+C do: exit code 130,
// no output and no temporary left (before: killed by the signal, the temporary stayed).
TEST(Cli, HangupAndQuitCancelLikeTerm) {
  for (int sig : {SIGTERM, SIGHUP, SIGQUIT}) {
    fs::path d = scratch("signal_" + std::to_string(sig));
    fs::path p = write(d / "p.yaml", std::string(kGood) +
                                         "  slow: {module: test.slow, inputs: {volume: x.volume}, params: {seconds: 60}}\n");
    RunOptions o;
    o.after_ms = 0;
    o.during = [&](pid_t pid) {
      EXPECT_TRUE(wait_for_file(d / "out", ".sum.txt."));  // running, with a temporary to remove
      kill(pid, sig);
    };
    Result r = run_with(SKELFLOW_TESTCLI, {"run", p.string(), "--threads", "2"}, o);
    EXPECT_EQ(r.code, 130) << "signal " << sig << ": " << r.out;
    EXPECT_NE(r.out.find("skelflow: interrupted; no partial outputs were left"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(d / "out" / "sum.txt"));
    EXPECT_EQ(leftovers(d), std::vector<std::string>{}) << "signal " << sig;
  }
}

// While a run goes on, its temporary carries the run id and the process id.
TEST(Cli, TemporariesNameTheRunAndTheProcess) {
  fs::path d = scratch("tmpname");
  fs::path p = write(d / "p.yaml", std::string(kGood) +
                                       "  slow: {module: test.slow, inputs: {volume: x.volume}, params: {seconds: 60}}\n");
  std::vector<std::string> seen;
  pid_t child = 0;
  RunOptions o;
  o.after_ms = 600;
  o.during = [&](pid_t pid) {
    child = pid;
    EXPECT_TRUE(wait_for_file(d / "out", ".sum.txt."));
    for (const auto& e : fs::directory_iterator(d / "out")) seen.push_back(e.path().filename().string());
    kill(pid, SIGINT);
  };
  Result r = run_with(SKELFLOW_TESTCLI, {"run", p.string(), "--threads", "2"}, o);
  EXPECT_EQ(r.code, 130) << r.out;
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_TRUE(std::regex_match(seen[0], std::regex("\\.sum\\.txt\\.skelflow-tmp-[0-9a-f]{8}-" + std::to_string(child))))
      << seen[0];
  EXPECT_EQ(leftovers(d), std::vector<std::string>{});
}

// The next run into a folder removes what a killed run left there, and says so in one line; the
// temporaries of a process still running are left alone.
TEST(Cli, StaleTemporariesOfDeadRunsAreRemovedAndReported) {
  fs::path d = scratch("stale");
  fs::path p = write(d / "p.yaml", kGood);
  fs::create_directories(d / "out");
  const pid_t dead = fork();
  if (dead == 0) _exit(0);
  waitpid(dead, nullptr, 0);
  const fs::path stale = d / "out" / (".sum.txt.skelflow-tmp-0badc0de-" + std::to_string(dead));
  const fs::path live = d / "out" / (".other.h5.skelflow-tmp-12345678-" + std::to_string(getpid()));
  write(stale, "partial");
  write(live, "being written");
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--report", (d / "run.json").string()});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(d / "out" / "sum.txt"));
  const std::string line = "skelflow: cleaned up after a run that did not finish (1 file): removed " + stale.string() + "\n";
  EXPECT_NE(r.out.find(line), std::string::npos) << r.out;
  EXPECT_NE(read_text(d / "run.json").find("\"notes\": [\"cleaned up after a run that did not finish (1 file): removed " +
                                           stale.string() + "\"]"),
            std::string::npos)
      << read_text(d / "run.json");
}

// An output that cannot be moved into place after another was: the other is restored, the run
// fails with exit code 1, and the report says what happened (before: the first output stayed
// replaced and no report was written).
TEST(Cli, AFailedCommitRestoresTheOutputsAndWritesTheReport) {
  fs::path d = scratch("commit");
  fs::path p = write(d / "p.yaml", R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [4, 4, 4]}}
  a: {module: test.write, inputs: {volume: src.volume}, params: {path: out/a.txt}}
  slow: {module: test.slow, inputs: {volume: src.volume}, params: {seconds: 3}}
  b: {module: test.write, inputs: {volume: slow.volume}, params: {path: out/summary.csv}}
)");
  fs::create_directories(d / "out");
  write(d / "out" / "a.txt", "old a");
  RunOptions o;
  o.after_ms = 0;
  o.during = [&](pid_t) {
    // Once the run has checked its outputs and node a has written its temporary.
    EXPECT_TRUE(wait_for_file(d / "out", ".a.txt.skelflow-tmp-"));
    fs::create_directories(d / "out" / "summary.csv" / "blocked");
  };
  Result r = run_with(SKELFLOW_TESTCLI, {"run", p.string(), "--threads", "2", "--report", (d / "run.json").string()}, o);
  EXPECT_EQ(r.code, 1) << r.out;
  const std::string msg = "skelflow: cannot replace " + (d / "out" / "summary.csv").string() +
                          ": it is a folder; no output was changed (1 file already moved was taken back: 1 restored, 0 removed)\n";
  EXPECT_NE(r.out.find(msg), std::string::npos) << r.out;
  EXPECT_EQ(read_text(d / "out" / "a.txt"), "old a");
  EXPECT_EQ(leftovers(d), std::vector<std::string>{});
  const std::string report = read_text(d / "run.json");
  EXPECT_NE(report.find("\"ok\": false"), std::string::npos) << report;
  EXPECT_NE(report.find("it is a folder; no output was changed"), std::string::npos) << report;
  EXPECT_NE(report.find("\"notes\": [\"restored the previous " + (d / "out" / "a.txt").string() + "\"]"), std::string::npos)
      << report;
}

// --report may not name an output of the pipeline, through any spelling of its path, nor the
// pipeline itself: refused before anything runs (before: the output was silently overwritten).
TEST(Cli, ReportMayNotOverwriteAnOutputOrThePipeline) {
  fs::path d = scratch("report_clash");
  fs::path p = write(d / "p.yaml", kGood);
  fs::create_directories(d / "out");
  fs::create_directory_symlink(d / "out", d / "link");
  for (const fs::path& rep : {d / "out" / "sum.txt", d / "link" / "sum.txt", d / "out" / ".." / "out" / "sum.txt"}) {
    Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--report", rep.string()});
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(r.out, "skelflow: --report " + rep.string() +
                         ": this is an output of the pipeline (node 'w', parameter 'path'); choose another file for "
                         "the report\n");
    EXPECT_FALSE(fs::exists(d / "out" / "sum.txt"));
  }
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--report", p.string()});
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("this is the pipeline file"), std::string::npos) << r.out;
  EXPECT_EQ(read_text(p), kGood);
}

// One writer per kind of data, each writing `out/<file>` from a small synthetic source.
struct Writer {
  std::string module, port_in, source, file;
};
const std::vector<Writer>& writers() {
  static const std::vector<Writer> w{
      {"io.write_table", "table", "alt.summary", "t.csv"},
      {"io.write_transform", "transform", "alt.transform", "t.tfm"},
      {"io.write_landmarks", "landmarks", "alt.landmarks", "l.landmarkAscii"},
      {"io.write_volume", "volume", "alt.before_mask", "v.h5"},
      {"io.write_graph", "graph", "tree.graph", "g.graphml"},
  };
  return w;
}
std::string writer_pipeline(const Writer& w, const std::string& folder) {
  const bool tree = w.source.rfind("tree.", 0) == 0;
  return std::string("skelflow: 1\nnodes:\n") +
         (tree ? "  tree: {module: synthetic.vessel_tree, params: {size: [32, 32, 32]}}\n"
               : "  alt: {module: synthetic.altered_network, params: {size: [48, 48, 48], landmarks: 3}}\n") +
         "  w: {module: " + w.module + ", inputs: {" + w.port_in + ": " + w.source + "}, params: {path: " + folder + "/" +
         w.file + "}}\n";
}

// An output folder the user cannot write to is found before anything runs, with the same exit code
// (2) and message for every writer (before: 1 for tables, transforms and landmarks, 2 for volumes
// and graphs, each with its own wording).
TEST(Cli, EveryWriterReportsAnUnwritableFolderAlike) {
  fs::path d = scratch("unwritable");
  fs::permissions(d, fs::perms::all);  // the unprivileged run reads its pipelines here
  fs::create_directories(d / "locked");
  fs::permissions(d / "locked", fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                                    fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec);
  for (const auto& w : writers()) {
    fs::path p = write(d / (w.module + ".yaml"), writer_pipeline(w, "locked"));
    fs::permissions(p, fs::perms::all);
    RunOptions o;
    o.unprivileged = true;
    Result r = run_with(SKELFLOW_BIN, {"run", p.string(), "--quiet"}, o);
    if (r.code == 124) GTEST_SKIP() << "cannot run as an unprivileged user here";
    EXPECT_EQ(r.code, 2) << w.module << ": " << r.out;
    // At the parameter's value in the file.
    const std::string text = writer_pipeline(w, "locked");
    const size_t line4 = text.find("  w: ");
    const std::string column = std::to_string(text.find("locked/") - line4 + 1);
    EXPECT_EQ(r.out, "skelflow: " + p.string() + ":4:" + column + ": node 'w' (" + w.module + "): parameter 'path': cannot write into folder " +
                         (d / "locked").string() + ": Permission denied\n");
    EXPECT_TRUE(fs::is_empty(d / "locked"));
  }
}

// A write that fails while running (here: beyond the file size limit, as when the disk is full)
// is exit code 1 with one message shape for every writer, naming the file asked for and the OS's
// reason; no temporary is left and nothing crashes (before: HDF5 crashed in H5F__close_cb at exit,
// rc 139, after printing a message naming its temporary of a temporary).
TEST(Cli, EveryWriterReportsAFailedWriteAlike) {
  fs::path d = scratch("fsize");
  for (const auto& w : writers()) {
    fs::path p = write(d / (w.module + ".yaml"), writer_pipeline(w, "out"));
    RunOptions o;
    o.file_size_limit = 0;
    Result r = run_with(SKELFLOW_BIN, {"run", p.string(), "--quiet"}, o);
    EXPECT_EQ(r.code, 1) << w.module << ": " << r.out;
    const std::string head = "skelflow: " + p.string() + ":4:3: node 'w' (" + w.module + "): cannot write " +
                             (d / "out" / w.file).string() + ": ";
    EXPECT_EQ(r.out.rfind(head, 0), 0u) << r.out;
    EXPECT_EQ(r.out.substr(r.out.size() - std::min<size_t>(r.out.size(), 17)), ": File too large\n") << r.out;
    EXPECT_EQ(r.out.find('\n'), r.out.size() - 1) << "one line: " << r.out;
    EXPECT_TRUE(fs::is_empty(d / "out")) << w.module;
  }
}

// An HDF5 volume larger than the file size limit: the error, not a crash, and nothing of HDF5's
// own error stack on stderr ("HDF5-DIAG", "infinite loop closing library" before).
TEST(Cli, Hdf5WriteBeyondTheFileSizeLimitFailsCleanly) {
  fs::path d = scratch("h5_fsize");
  for (const char* compression : {"0", "1"}) {
    fs::path p = write(d / "p.yaml", std::string(R"(skelflow: 1
nodes:
  ph: {module: synthetic.network, params: {shape: rods, size: [64, 64, 64], seed: 1}}
  save: {module: io.write_volume, inputs: {volume: ph.image}, params: {path: out/image.h5, compression: )") +
                                         compression + "}}\n");
    RunOptions o;
    o.file_size_limit = 16384;
    Result r = run_with(SKELFLOW_BIN, {"run", p.string(), "--quiet"}, o);
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_EQ(r.out, "skelflow: " + p.string() + ":4:3: node 'save' (io.write_volume): cannot write " +
                         (d / "out" / "image.h5").string() + ": dataset '/volume': File too large\n");
    EXPECT_TRUE(fs::is_empty(d / "out"));
  }
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

// The summary table of a statistics node is printed at the end of a run, one aligned line per column
// with its unit; --quiet leaves it out.
TEST(Cli, RunPrintsStatisticsSummary) {
  fs::path d = scratch("summary");
  fs::path p = write(d / "p.yaml", R"(skelflow: 1
nodes:
  phantom: {module: synthetic.vessel_tree, params: {size: [32, 32, 32], seed: 1, roots: 2}}
  stats: {module: analysis.network_statistics, inputs: {graph: phantom.truth}}
)");
  Result r = run(SKELFLOW_BIN, {"run", p.string(), "--threads", "1"});
  ASSERT_EQ(r.code, 0) << r.out;
  const size_t h = r.out.find("stats.summary:\n");
  ASSERT_NE(h, std::string::npos) << r.out;
  const std::string rest = r.out.substr(h);
  std::regex line(R"(\n  total_length +[0-9.e+-]+  µm\n)");
  EXPECT_TRUE(std::regex_search(rest, line)) << rest;
  // the value column is aligned: every value ends in the same column
  std::istringstream in(rest);
  std::string l;
  std::getline(in, l);
  size_t end_col = 0;
  int lines = 0;
  while (std::getline(in, l) && l.rfind("  ", 0) == 0) {
    const size_t num_end = l.find_first_of(' ', l.find_first_not_of(' ', l.find_first_of(' ', 2)));
    const size_t e = num_end == std::string::npos ? l.size() : num_end;
    if (end_col == 0) end_col = e;
    EXPECT_EQ(e, end_col) << l;
    ++lines;
  }
  EXPECT_GE(lines, 10);
  Result q = run(SKELFLOW_BIN, {"run", p.string(), "--threads", "1", "-q"});
  EXPECT_EQ(q.code, 0);
  EXPECT_EQ(q.out.find("stats.summary"), std::string::npos) << q.out;
}

// ---------------------------------------------------------------- the command line as people expect it
namespace {
bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }
}  // namespace

TEST(Cli, VersionAndHelpOfEveryCommand) {
  Result v = run(SKELFLOW_TESTCLI, {"--version"});
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_EQ(v.out.rfind("skelflow 0.", 0), 0u) << v.out;
  EXPECT_EQ(v.out.back(), '\n');
  for (const std::string cmd : {"run", "validate", "modules", "info"}) {
    for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
             {cmd, "--help"}, {cmd, "-h"}, {"help", cmd}, {cmd, "some.yaml", "--help"}}) {
      Result h = run(SKELFLOW_TESTCLI, args);
      EXPECT_EQ(h.code, 0) << cmd << ": " << h.out;
      EXPECT_EQ(h.out.rfind("usage: skelflow " + cmd + " ", 0), 0u) << h.out;
      EXPECT_TRUE(has(h.out, "\nexample:\n  skelflow " + cmd + " ")) << h.out;
    }
  }
  Result run_help = run(SKELFLOW_TESTCLI, {"run", "--help"});
  for (const char* opt : {"--set", "--threads", "--output-dir", "--report", "--target", "--quiet"})
    EXPECT_TRUE(has(run_help.out, std::string("\n  ") + opt)) << opt << " missing in\n" << run_help.out;
  Result overview = run(SKELFLOW_TESTCLI, {"--help"});
  EXPECT_EQ(overview.code, 0);
  for (const char* cmd : {"run PIPELINE", "validate PIPELINE", "modules [", "info FILE"})
    EXPECT_TRUE(has(overview.out, std::string("\n  ") + cmd)) << overview.out;
  EXPECT_FALSE(has(overview.out, "options:")) << "the overview lists commands, each --help their options";
}

TEST(Cli, UnknownOptionsAndCommandsAreNamedWithTheClosest) {
  fs::path d = scratch("unknown_option");
  fs::path p = write(d / "p.yaml", kGood);
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--thread", "2"});
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(has(r.out, "skelflow: run: unknown option '--thread' (did you mean '--threads'?); see 'skelflow run --help'"))
      << r.out;
  Result eq = run(SKELFLOW_TESTCLI, {"validate", p.string(), "--output-dri=x"});
  EXPECT_TRUE(has(eq.out, "validate: unknown option '--output-dri' (did you mean '--output-dir'?)")) << eq.out;
  Result m = run(SKELFLOW_TESTCLI, {"modules", "--markdwn"});
  EXPECT_EQ(m.code, 2);
  EXPECT_TRUE(has(m.out, "modules: unknown option '--markdwn' (did you mean '--markdown'?)")) << m.out;
  Result far = run(SKELFLOW_TESTCLI, {"info", "--frobnicate"});
  EXPECT_EQ(far.code, 2);
  EXPECT_TRUE(has(far.out, "info: unknown option '--frobnicate'; see 'skelflow info --help'")) << far.out;
  Result c = run(SKELFLOW_TESTCLI, {"valdate", p.string()});
  EXPECT_EQ(c.code, 2);
  EXPECT_TRUE(has(c.out, "skelflow: unknown command 'valdate' (did you mean 'validate'?)")) << c.out;
  Result v = run(SKELFLOW_TESTCLI, {"--verison"});
  EXPECT_EQ(v.code, 2);
  EXPECT_TRUE(has(v.out, "skelflow: unknown option '--verison' (did you mean '--version'?)")) << v.out;
}

TEST(Cli, ModulesNodesAndPortsAreSuggested) {
  Result m = run(SKELFLOW_TESTCLI, {"modules", "test.scal"});
  EXPECT_EQ(m.code, 2);
  EXPECT_TRUE(has(m.out, "unknown module 'test.scal' (did you mean 'test.scale'?)")) << m.out;
  Result names = run(SKELFLOW_TESTCLI, {"modules", "--names"});
  EXPECT_EQ(names.code, 0);
  EXPECT_TRUE(has(names.out, "\ntest.scale\n")) << names.out;
  EXPECT_FALSE(has(names.out, " ")) << "one bare name a line";

  fs::path d = scratch("suggest");
  fs::path p = write(d / "p.yaml", R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [4, 4, 4]}}
  x: {module: test.scale, inputs: {volume: srcc.volume}}
  y: {module: test.scale, inputs: {volume: src.volme}}
  z: {module: test.scale, inputs: {volum: src.volume}}
)");
  Result r = run(SKELFLOW_TESTCLI, {"validate", p.string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(has(r.out, ":4:44: node 'x': input 'volume': no node 'srcc' (did you mean 'src'?)")) << r.out;
  EXPECT_TRUE(has(r.out, "node 'y': input 'volume': node 'src' (test.source) has no output 'volme' (did you mean "
                         "'volume'?); its outputs: volume")) << r.out;
  EXPECT_TRUE(has(r.out, "node 'z': unknown input port 'volum' of test.scale (did you mean 'volume'?); its inputs: volume"))
      << r.out;
}

TEST(Cli, SetErrorsPointAtTheCommandLine) {
  fs::path d = scratch("set_errors");
  fs::path p = write(d / "p.yaml", kGood);
  Result param = run(SKELFLOW_TESTCLI, {"run", p.string(), "--set", "x.factr=3"});
  EXPECT_EQ(param.code, 2);
  EXPECT_TRUE(has(param.out, "skelflow: --set x.factr=3: node 'x': unknown parameter 'factr' of test.scale (did you mean "
                             "'factor'?)")) << param.out;
  EXPECT_FALSE(has(param.out, p.string() + ":")) << "the error is on the command line, not in the file";
  Result node = run(SKELFLOW_TESTCLI, {"run", p.string(), "--set", "xx.factor=3"});
  EXPECT_EQ(node.code, 2);
  EXPECT_TRUE(has(node.out, "skelflow: --set xx.factor=3: no node 'xx' in ")) << node.out;
  EXPECT_TRUE(has(node.out, "(did you mean 'x'?)")) << node.out;
}

TEST(Cli, DurationsOnTheProgressLine) {
  EXPECT_EQ(format_duration(0), "0s");
  EXPECT_EQ(format_duration(7.4), "7s");
  EXPECT_EQ(format_duration(59.4), "59s");
  EXPECT_EQ(format_duration(185), "3m05s");
  EXPECT_EQ(format_duration(3600 * 2 + 4 * 60 + 10), "2h04m");
  EXPECT_EQ(format_duration(-3), "0s");
  EXPECT_EQ(format_duration(std::nan("")), "0s");
}

TEST(Cli, PlainProgressLinesShowElapsedAndTimeLeft) {
  fs::path d = scratch("progress_times");
  fs::path p = write(d / "p.yaml", R"(skelflow: 1
nodes:
  s: {module: test.slow, params: {seconds: 6}}
)");
  Result r = run(SKELFLOW_TESTCLI, {"run", p.string(), "--threads", "1"});  // stderr is a file: plain lines
  ASSERT_EQ(r.code, 0) << r.out;
  std::smatch m;
  EXPECT_TRUE(std::regex_search(r.out, m, std::regex(R"(progress +\d+% \d+s, ~\d+s left \(s\))"))) << r.out;
}

TEST(Cli, BashCompletionOffersCommandsOptionsModulesAndNodes) {
  if (std::system("command -v bash >/dev/null 2>&1") != 0) GTEST_SKIP() << "no bash";
  fs::path d = scratch("completion");
  fs::path p = write(d / "p.yaml", kGood);
  auto complete = [&](const std::string& words) {
    fs::path out = d / "reply.txt";
    const std::string script = "source '" + std::string(SKEL_SOURCE_DIR) + "/scripts/skelflow-completion.bash'; "
                               "COMP_WORDS=(" + words + "); COMP_CWORD=$((${#COMP_WORDS[@]}-1)); _skelflow; "
                               "printf '%s\\n' \"${COMPREPLY[@]}\" > '" + out.string() + "'";
    fs::path sh = d / "complete.sh";
    std::ofstream(sh) << script << "\n";
    EXPECT_EQ(std::system(("cd '" + d.string() + "' && bash '" + sh.string() + "'").c_str()), 0);
    return read_text(out);
  };
  const std::string bin = std::string("'") + SKELFLOW_TESTCLI + "'";
  EXPECT_EQ(complete(bin + " va"), "validate\n");
  EXPECT_EQ(complete(bin + " run p.yaml --thr"), "--threads\n");
  EXPECT_EQ(complete(bin + " modules test.sc"), "test.scale\n");
  EXPECT_EQ(complete(bin + " run p.yaml --set x"), "x.\n");
  EXPECT_EQ(complete(bin + " run ''"), "p.yaml\n");
}
