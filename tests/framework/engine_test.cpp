// Pipeline model, YAML, validation and executor, on the test-only modules.
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <set>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <time.h>

#include "context.hpp"
#include "skel/executor.hpp"
#include "skel/pipeline.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"
#include "test_modules.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

std::string validation_errors(const std::string& yaml) {
  Pipeline p = Pipeline::parse(yaml, "p.yaml");
  std::string all;
  for (const auto& d : validate(p)) all += d.format() + "\n";
  return all;
}

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

const char* kChain = R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [6, 5, 4]}}
  a: {module: test.scale, inputs: {volume: src.volume}, params: {factor: 3}}
  b: {module: test.scale, inputs: {volume: src.volume}, params: {factor: -1.5}}
  sum: {module: test.sum, inputs: {a: a.volume, b: b.volume}}
)";

}  // namespace

// ---------------------------------------------------------------- registry
TEST(Registry, FindsModulesAndRejectsDuplicates) {
  auto& r = Registry::instance();
  ASSERT_NE(r.find("test.source"), nullptr);
  EXPECT_EQ(r.find("test.source")->family(), "test");
  EXPECT_EQ(r.find("no.such"), nullptr);
  EXPECT_NE(error_of([&] { r.add(ModuleSpec("test.source", "again"), nullptr); }).find("registered twice"),
            std::string::npos);
  EXPECT_NE(error_of([&] { (void)r.create("no.such"); }).find("unknown module 'no.such'"), std::string::npos);
  auto specs = r.specs();
  EXPECT_TRUE(std::is_sorted(specs.begin(), specs.end(),
                             [](auto* a, auto* b) { return a->name() < b->name(); }));
}

// ---------------------------------------------------------------- YAML loading errors
TEST(PipelineYaml, SyntaxErrorHasLineAndColumn) {
  std::string e = error_of([] { Pipeline::parse("skelflow: 1\nnodes:\n  a: {module: test.source\n", "x.yaml"); });
  EXPECT_NE(e.find("x.yaml:"), std::string::npos) << e;
  EXPECT_NE(e.find("YAML syntax error"), std::string::npos) << e;
}

TEST(PipelineYaml, StructuralErrors) {
  EXPECT_NE(error_of([] { Pipeline::parse("nodes: {}\n", "x.yaml"); }).find("missing 'skelflow: 1'"),
            std::string::npos);
  EXPECT_NE(error_of([] { Pipeline::parse("skelflow: 2\nnodes: {}\n", "x.yaml"); }).find("x.yaml:1:11: unsupported format version '2'"),
            std::string::npos);
  EXPECT_NE(error_of([] { Pipeline::parse("skelflow: 1\nnodes: {}\nextra: 1\n", "x.yaml"); })
                .find("x.yaml:3:1: unknown top-level key 'extra'"),
            std::string::npos);
  std::string dup = error_of([] {
    Pipeline::parse("skelflow: 1\nnodes:\n  a: {module: test.source}\n  a: {module: test.source}\n", "x.yaml");
  });
  EXPECT_NE(dup.find("x.yaml:4:3: duplicate node id 'a' (first defined at line 3)"), std::string::npos) << dup;
  std::string badref = error_of([] {
    Pipeline::parse("skelflow: 1\nnodes:\n  a: {module: test.scale, inputs: {volume: srcvolume}}\n", "x.yaml");
  });
  EXPECT_NE(badref.find("x.yaml:3:44: node 'a': input 'volume': 'srcvolume' is not of the form node.port"),
            std::string::npos)
      << badref;
  EXPECT_NE(error_of([] { Pipeline::parse("skelflow: 1\nnodes:\n  a: {params: {}}\n", "x.yaml"); })
                .find("node 'a' has no 'module'"),
            std::string::npos);
  EXPECT_NE(error_of([] { Pipeline::parse("skelflow: 1\nnodes:\n  a: {module: m, colour: red}\n", "x.yaml"); })
                .find("x.yaml:3:18: node 'a': unknown key 'colour'"),
            std::string::npos);
}

// ---------------------------------------------------------------- validation: every error, with position
TEST(PipelineValidate, UnknownModuleSuggests) {
  std::string e = validation_errors("skelflow: 1\nnodes:\n  s: {module: test.sourse}\n");
  EXPECT_NE(e.find("p.yaml:3:15: node 's': unknown module 'test.sourse' (did you mean 'test.source'?)"),
            std::string::npos)
      << e;
}

TEST(PipelineValidate, UnknownAndMistypedAndOutOfRangeParams) {
  std::string e = validation_errors(
      "skelflow: 1\nnodes:\n"
      "  s: {module: test.source, params: {sise: [1, 2, 3]}}\n"
      "  t: {module: test.scale, inputs: {volume: s.volume}, params: {factor: abc}}\n"
      "  u: {module: test.scale, inputs: {volume: s.volume}, params: {factor: 1000}}\n"
      "  v: {module: test.source, params: {size: [1, 2]}}\n");
  EXPECT_NE(e.find("p.yaml:3:43: node 's': unknown parameter 'sise' of test.source (did you mean 'size'?)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("p.yaml:4:72: node 't': param 'factor': expected float, got 'abc'"), std::string::npos) << e;
  EXPECT_NE(e.find("p.yaml:5:72: node 'u': param 'factor': value 1000 is out of range [-100, 100]"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("node 'v': param 'size': expected a list of 3 values, got 2"), std::string::npos) << e;
}

TEST(PipelineValidate, PortsTypesAndMissingInputs) {
  std::string e = validation_errors(
      "skelflow: 1\nnodes:\n"
      "  s: {module: test.source}\n"
      "  m: {module: test.mask}\n"
      "  a: {module: test.scale, inputs: {volum: s.volume}}\n"
      "  b: {module: test.scale, inputs: {volume: s.vol}}\n"
      "  c: {module: test.scale, inputs: {volume: m.mask}}\n"
      "  d: {module: test.scale, inputs: {volume: nobody.volume}}\n");
  EXPECT_NE(e.find("p.yaml:5:43: node 'a': unknown input port 'volum' of test.scale (did you mean 'volume'?)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("p.yaml:5:3: node 'a': required input 'volume' (volume.f32) is not connected"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("p.yaml:6:44: node 'b': input 'volume': node 's' (test.source) has no output 'vol'"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("p.yaml:7:44: node 'c': input 'volume': type mismatch: m.mask gives volume.u8, but 'volume' takes volume.f32"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("node 'd': input 'volume': no node 'nobody'"), std::string::npos) << e;
}

TEST(PipelineValidate, Cycle) {
  std::string e = validation_errors(
      "skelflow: 1\nnodes:\n"
      "  a: {module: test.scale, inputs: {volume: b.volume}}\n"
      "  b: {module: test.scale, inputs: {volume: a.volume}}\n");
  EXPECT_EQ(e, "p.yaml:3:3: the pipeline has a cycle: 'a' -> 'b' -> 'a'\n");
}

// Only the nodes on the cycle are named (not those behind it), at the first of them in the file,
// by validate() and by topological_order() alike.
TEST(PipelineValidate, CycleNamesOnlyItsNodes) {
  const std::string yaml =
      "skelflow: 1\nnodes:\n"
      "  behind: {module: test.scale, inputs: {volume: c.volume}}\n"
      "  a: {module: test.scale, inputs: {volume: c.volume}}\n"
      "  b: {module: test.scale, inputs: {volume: a.volume}}\n"
      "  c: {module: test.scale, inputs: {volume: b.volume}}\n"
      "  self: {module: test.scale, inputs: {volume: self.volume}}\n";
  const std::string e = validation_errors(yaml);
  EXPECT_EQ(e, "p.yaml:4:3: the pipeline has a cycle: 'a' -> 'b' -> 'c' -> 'a'\n");
  const Pipeline p = Pipeline::parse(yaml, "p.yaml");
  EXPECT_EQ(error_of([&] { (void)p.topological_order(); }), "p.yaml:4:3: the pipeline has a cycle: 'a' -> 'b' -> 'c' -> 'a'");
  const Pipeline one = Pipeline::parse("skelflow: 1\nnodes:\n  self: {module: test.scale, inputs: {volume: self.volume}}\n", "q.yaml");
  EXPECT_EQ(error_of([&] { (void)one.topological_order(); }), "q.yaml:3:3: the pipeline has a cycle: 'self' -> 'self'");
}

// Keys given twice, a second document and deep nesting are load errors at their line:column.
TEST(PipelineYaml, DuplicateKeysSecondDocumentAndDepth) {
  auto load_error = [](const std::string& yaml) { return error_of([&] { (void)Pipeline::parse(yaml, "p.yaml"); }); };
  EXPECT_EQ(load_error("skelflow: 1\nnodes: {}\nskelflow: 1\n"),
            "p.yaml:3:1: top-level key 'skelflow' given twice (first at line 1)");
  EXPECT_EQ(load_error("skelflow: 1\nnodes:\n  a: {module: test.source, module: test.scale}\n"),
            "p.yaml:3:28: node 'a': key 'module' given twice (first at line 3)");
  EXPECT_EQ(load_error("skelflow: 1\nnodes: {}\n---\nskelflow: 1\n"),
            "p.yaml:3:1: a second YAML document (after '---'); a pipeline file holds one document");
  const std::string deep = "skelflow: 1\nnodes: {a: {module: test.source, params: {size: " + std::string(500, '[') +
                           std::string(500, ']') + "}}}\n";
  EXPECT_EQ(load_error(deep), "p.yaml:2:" + std::to_string(49 + kMaxYamlDepth - 4) +
                                  ": mappings and lists nested deeper than 64 levels");
  // (the root mapping, nodes, a, params: the 61st '[' at column 49 + 60 is level 65) Depth 64 itself loads.
  std::string ok = "skelflow: 1\nnodes: {}\ngui: ";
  ok += std::string(kMaxYamlDepth - 1, '[') + std::string(kMaxYamlDepth - 1, ']') + "\n";
  EXPECT_EQ(load_error(ok), "(no error)");
}

// Two outputs into one file, also through a symbolic link of a folder, are found by validate() at
// the second writer, naming the first with its line:column; files are compared after resolving links.
TEST(PipelineValidate, TwoWritersOfOneFile) {
  const fs::path d = scratch("two_writers");
  fs::create_directories(d / "real");
  fs::create_directory_symlink(d / "real", d / "alias");
  Pipeline p = Pipeline::parse(
      "skelflow: 1\nnodes:\n"
      "  src: {module: test.source, params: {size: [2, 2, 2]}}\n"
      "  w1: {module: test.write, inputs: {volume: src.volume}, params: {path: real/t.txt}}\n"
      "  w2: {module: test.write, inputs: {volume: src.volume}, params: {path: alias/t.txt}}\n"
      "  w3: {module: test.write, inputs: {volume: src.volume}, params: {path: real/../real/t.txt}}\n"
      "  w4: {module: test.write, inputs: {volume: src.volume}, params: {path: alias/other.txt}}\n",
      "p.yaml", d);
  std::string all;
  for (const auto& x : validate(p)) all += x.format() + "\n";
  const std::string f = fs::canonical(d / "real").string() + "/t.txt";
  EXPECT_EQ(all, "p.yaml:5:73: node 'w2': param 'path': writes the same file " + f +
                     " as node 'w1' param 'path' (p.yaml:4:73)\n"
                     "p.yaml:6:73: node 'w3': param 'path': writes the same file " + f +
                     " as node 'w1' param 'path' (p.yaml:4:73)\n");
  // The executor refuses before any node runs.
  Executor ex;
  EXPECT_NE(error_of([&] { ex.run(p); }).find("node 'w2': param 'path': writes the same file"), std::string::npos);
  EXPECT_EQ(ex.modules_run(), 0);
  EXPECT_TRUE(fs::is_empty(d / "real"));
}

// Declared extensions of an output path are checked (unless the named format choice is not auto);
// input files must exist.
TEST(PipelineValidate, OutputExtensionsAndMissingInputs) {
  Registry reg;
  reg.add(ModuleSpec("x.write", "writes")
              .path("path", "", PathRole::Output, "file")
              .extensions({".H5", ".hdf5"}, "format")
              .choice("format", {"auto", "raw"}, "auto", "format"),
          nullptr);
  reg.add(ModuleSpec("x.read", "reads").path("path", "", PathRole::Input, "file"), nullptr);
  const fs::path d = scratch("extensions");
  std::ofstream(d / "here.bin") << "x";
  Pipeline p = Pipeline::parse(
      "skelflow: 1\nnodes:\n"
      "  a: {module: x.write, params: {path: out/a.tif}}\n"
      "  b: {module: x.write, params: {path: out/b.HDF5}}\n"
      "  c: {module: x.write, params: {path: out/c, format: raw}}\n"
      "  d: {module: x.write, params: {path: out/d}}\n"
      "  e: {module: x.read, params: {path: missing.bin}}\n"
      "  f: {module: x.read, params: {path: here.bin}}\n"
      "  g: {module: x.read, params: {path: out}}\n",
      "p.yaml", d);
  fs::create_directories(d / "out");
  std::string all;
  for (const auto& x : validate(p, reg)) all += x.format() + "\n";
  EXPECT_EQ(all,
            "p.yaml:3:39: node 'a': param 'path': 'out/a.tif': unknown extension '.tif'; x.write writes .h5 or .hdf5 (or set 'format')\n"
            "p.yaml:6:39: node 'd': param 'path': 'out/d': no file extension; x.write writes .h5 or .hdf5 (or set 'format')\n"
            "p.yaml:7:38: node 'e': param 'path': input file '" + (d / "missing.bin").string() + "' not found\n"
            "p.yaml:9:38: node 'g': param 'path': '" + (d / "out").string() + "' is a folder, not a file\n");
  EXPECT_THROW(ModuleSpec("x.y", "z").param("n", 1, "n").extensions({".a"}), Error);
}

TEST(PipelineValidate, ValidPipelineHasNoDiagnostics) {
  EXPECT_EQ(validation_errors(kChain), "");
}

// ---------------------------------------------------------------- round trip
TEST(PipelineYaml, RoundTripIsLosslessAndCanonical) {
  const std::string text = std::string(kChain) +
                           "  w: {module: test.write, inputs: {volume: sum.volume}, params: {path: \"out/1.txt\"}}\n"
                           "gui:\n  positions: {src: [0, 0], a: [120.5, -3]}\n  zoom: 1.25\n";
  Pipeline p = Pipeline::parse(text, "p.yaml");
  std::string y1 = p.to_yaml();
  Pipeline q = Pipeline::parse(y1, "q.yaml");
  EXPECT_TRUE(p == q) << y1;
  EXPECT_EQ(q.to_yaml(), y1);  // canonical: saving again changes nothing
  EXPECT_NE(y1.find("factor: 3.0"), std::string::npos) << y1;  // typed by the spec
  EXPECT_NE(y1.find("zoom: 1.25"), std::string::npos) << y1;
  EXPECT_EQ(q.find("a")->inputs.at("volume").str(), "src.volume");
}

TEST(PipelineYaml, StringsThatLookLikeNumbersStayStrings) {
  Pipeline p;
  p.add_node("w", "test.write");
  p.set_param("w", "path", std::string("123"));
  Pipeline q = Pipeline::parse(p.to_yaml());
  EXPECT_EQ(std::get<std::string>(q.find("w")->params.at("path")), "123");
  p.set_param("w", "path", std::string("true"));
  q = Pipeline::parse(p.to_yaml());
  EXPECT_EQ(std::get<std::string>(q.find("w")->params.at("path")), "true");
}

TEST(PipelineEdit, ConnectRefusesWithReason) {
  Pipeline p = Pipeline::parse(kChain);
  p.add_node("m", "test.mask");
  p.add_node("x", "test.scale");
  EXPECT_NE(p.connect({"m", "mask"}, "x", "volume").find("type mismatch"), std::string::npos);
  EXPECT_NE(p.connect({"sum", "volume"}, "src", "volume").find("has no input"), std::string::npos);
  EXPECT_NE(p.connect({"sum", "volume"}, "a", "volume").find("cycle"), std::string::npos);
  EXPECT_EQ(p.connect({"sum", "volume"}, "x", "volume"), "");
  EXPECT_TRUE(validate(p).empty());
  p.rename_node("sum", "total");
  EXPECT_EQ(p.find("x")->inputs.at("volume").node, "total");
  p.remove_node("total");
  EXPECT_TRUE(p.find("x")->inputs.empty());
  EXPECT_EQ(p.unique_id("test.scale"), "scale");
  EXPECT_EQ(p.unique_id("a"), "a2");
}

// ---------------------------------------------------------------- executor
TEST(Executor, RunsAndCachesOnlyWhatChanged) {
  Pipeline p = Pipeline::parse(kChain);
  Executor ex;
  ExecOptions o;
  o.keep_outputs = true;
  o.threads = 2;
  ex.run(p, o);
  EXPECT_EQ(ex.modules_run(), 4);
  auto sum1 = std::dynamic_pointer_cast<const VolumeF32>(ex.output(p, "sum", "volume"));
  ASSERT_TRUE(sum1);
  EXPECT_FLOAT_EQ((*sum1)[5], 5 * 3.0f - 5 * 1.5f);
  const int src_before = skel::test_counters::g_source_runs.load(), scale_before = skel::test_counters::g_scale_runs.load();
  // Same pipeline again: nothing runs.
  ex.run(p, o);
  EXPECT_EQ(ex.modules_run(), 4);
  // Change one parameter of `b`: only b and sum re-run.
  p.set_param("b", "factor", 2.0);
  EXPECT_EQ(ex.up_to_date(p), (std::set<std::string>{"src", "a"}));
  RunReport r = ex.run(p, o);
  EXPECT_EQ(ex.modules_run(), 6);
  EXPECT_EQ(skel::test_counters::g_source_runs.load(), src_before);
  EXPECT_EQ(skel::test_counters::g_scale_runs.load(), scale_before + 1);
  int cached = 0;
  for (const auto& n : r.nodes) cached += n.cached;
  EXPECT_EQ(cached, 2);
  auto sum2 = std::dynamic_pointer_cast<const VolumeF32>(ex.output(p, "sum", "volume"));
  EXPECT_FLOAT_EQ((*sum2)[5], 5 * 3.0f + 5 * 2.0f);
  // Outputs are shared, not copied: the cached source volume is the same object.
  EXPECT_EQ(ex.output(p, "src", "volume").get(), ex.output(p, "src", "volume").get());
}

TEST(Executor, ParallelEqualsSequential) {
  Pipeline p = Pipeline::parse(kChain);
  for (int i = 0; i < 6; ++i) {
    std::string id = "s";  // not "s" + to_string(i): GCC 12 reports a false -Wrestrict there
    id += std::to_string(i);
    p.add_node(id, "test.scale");
    p.set_param(id, "factor", 1.0 + i);
    ASSERT_EQ(p.connect({"sum", "volume"}, id, "volume"), "");
  }
  Executor e1, e4;
  ExecOptions o1, o4;
  o1.threads = 1;
  o4.threads = 4;
  o1.keep_outputs = o4.keep_outputs = true;
  e1.run(p, o1);
  e4.run(p, o4);
  for (int i = 0; i < 6; ++i) {
    std::string id = "s" + std::to_string(i);
    auto a = std::dynamic_pointer_cast<const VolumeF32>(e1.output(p, id, "volume"));
    auto b = std::dynamic_pointer_cast<const VolumeF32>(e4.output(p, id, "volume"));
    ASSERT_TRUE(a && b);
    EXPECT_TRUE(*a == *b);
  }
}

TEST(Executor, TargetsRunOnlyWhatIsNeeded) {
  Pipeline p = Pipeline::parse(kChain);
  Executor ex;
  ExecOptions o;
  o.keep_outputs = true;
  o.targets = {"a"};
  RunReport r = ex.run(p, o);
  EXPECT_EQ(r.nodes.size(), 2u);
  EXPECT_EQ(ex.up_to_date(p), (std::set<std::string>{"src", "a"}));
}

TEST(Executor, HeadlessFreesIntermediates) {
  Pipeline p = Pipeline::parse(kChain);
  Executor ex;
  RunReport r = ex.run(p, {});
  EXPECT_TRUE(r.ok);
  EXPECT_EQ(ex.output(p, "src", "volume"), nullptr);  // nothing kept
  EXPECT_EQ(r.nodes.size(), 4u);
  EXPECT_GT(r.nodes.front().output_bytes.at("volume"), 0u);
  std::string json = r.to_json();
  EXPECT_NE(json.find("\"peak_rss_mib\""), std::string::npos);
  EXPECT_NE(json.find("\"id\": \"sum\""), std::string::npos);
}

TEST(Executor, CancellationStopsQuicklyAndLeavesNoFiles) {
  fs::path dir = scratch("cancel");
  Pipeline p = Pipeline::parse(
      "skelflow: 1\nnodes:\n"
      "  src: {module: test.source}\n"
      "  w: {module: test.write, inputs: {volume: src.volume}, params: {path: early.txt}}\n"
      "  slow: {module: test.slow, inputs: {volume: src.volume}, params: {seconds: 30}}\n",
      "c.yaml", dir);
  Executor ex;
  std::atomic<bool> flag{false};
  ExecOptions o;
  o.cancel = &flag;
  std::thread t([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    flag = true;
  });
  auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(ex.run(p, o), Cancelled);
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.join();
  EXPECT_LT(secs, 1.5);
  EXPECT_FALSE(fs::exists(dir / "early.txt"));
  EXPECT_TRUE(fs::is_empty(dir));  // no temporaries either
  EXPECT_EQ(ex.last_report().error, "cancelled");
}

TEST(Executor, FailureNamesTheNodeAndLeavesNoFiles) {
  fs::path dir = scratch("fail");
  Pipeline p = Pipeline::parse(
      "skelflow: 1\nnodes:\n"
      "  src: {module: test.source}\n"
      "  w: {module: test.write, inputs: {volume: src.volume}, params: {path: sub/out.txt}}\n"
      "  bad: {module: test.fail, inputs: {volume: src.volume}}\n",
      "f.yaml", dir);
  Executor ex;
  ExecOptions o;
  o.threads = 1;
  std::string e = error_of([&] { ex.run(p, o); });
  // Run-time errors carry the node's place in the file, in the format of validation errors.
  EXPECT_EQ(e, "f.yaml:5:3: node 'bad' (test.fail): failed on purpose");
  EXPECT_FALSE(fs::exists(dir / "sub" / "out.txt"));
  p.set_param("bad", "input_error", true);
  EXPECT_THROW(ex.run(p, o), InputError);
  // Without the failing node the file appears, at the path relative to the pipeline folder.
  p.remove_node("bad");
  RunReport r = ex.run(p, o);
  EXPECT_TRUE(fs::exists(dir / "sub" / "out.txt"));
  ASSERT_EQ(r.nodes.back().outputs_written.size(), 1u);
  EXPECT_EQ(r.nodes.back().outputs_written[0], (dir / "sub" / "out.txt").string());
}

TEST(Executor, InvalidPipelineRunsNothing) {
  Pipeline p = Pipeline::parse("skelflow: 1\nnodes:\n  s: {module: test.source, params: {offset: x}}\n", "i.yaml");
  Executor ex;
  std::string e = error_of([&] { ex.run(p, {}); });
  EXPECT_NE(e.find("i.yaml:3:45: node 's': param 'offset': expected float, got 'x'"), std::string::npos) << e;
  EXPECT_EQ(ex.modules_run(), 0);
}

TEST(Executor, OverridesApply) {
  Pipeline p = Pipeline::parse(kChain);
  Executor ex;
  ExecOptions o;
  o.keep_outputs = true;
  o.overrides["a"]["factor"] = parse_param_text("10");
  ex.run(p, o);
  // The override does not change the pipeline itself.
  EXPECT_EQ(std::get<int64_t>(p.find("a")->params.at("factor")), 3);
  EXPECT_THROW(
      {
        ExecOptions bad;
        bad.overrides["nobody"]["x"] = int64_t{1};
        ex.run(p, bad);
      },
      InputError);
}

// ---------------------------------------------------------------- run_module
TEST(RunModule, ValidatesAndRuns) {
  auto r = run_module("test.source", {}, {{"size", std::vector<int64_t>{3, 4, 5}}});
  auto v = r.get<VolumeF32>("volume");
  EXPECT_EQ(v->dims(), (Dims{3, 4, 5}));
  EXPECT_NE(error_of([] { run_module("test.source", {}, {{"bogus", int64_t{1}}}); }).find("unknown parameter 'bogus'"),
            std::string::npos);
  EXPECT_NE(error_of([] { run_module("test.scale", {}, {}); }).find("required input 'volume' is not connected"),
            std::string::npos);
  DataPtr mask = std::make_shared<VolumeU8>(Dims{1, 1, 1});
  EXPECT_NE(error_of([&] { run_module("test.scale", {{"volume", mask}}); }).find("does not accept volume.u8"),
            std::string::npos);
  auto s = run_module("test.scale", {{"volume", r.data("volume")}}, {{"factor", int64_t{2}}});
  EXPECT_FLOAT_EQ((*s.get<VolumeF32>("volume"))[1], 2.0f);
}

// ---------------------------------------------------------------- run-time error positions
namespace {
ExecOptions targets(std::vector<std::string> t) {
  ExecOptions o;
  o.targets = std::move(t);
  return o;
}
}  // namespace

TEST(Executor, RunTimeErrorCarriesTheNodeSite) {
  Pipeline p = Pipeline::parse(
      "skelflow: 1\nnodes:\n"
      "  src: {module: test.source}\n"
      "  bad:\n    module: test.fail\n    inputs: {volume: src.volume}\n    params: {input_error: true}\n",
      "pipes/site.yaml");
  Executor ex;
  try {
    ex.run(p);
    FAIL() << "no error";
  } catch (const InputError& e) {  // the kind the module threw is kept
    EXPECT_STREQ(e.what(), "pipes/site.yaml:4:3: node 'bad' (test.fail): the input is bad on purpose");
    ASSERT_NE(e.site(), nullptr);
    EXPECT_EQ(e.site()->file, "pipes/site.yaml");
    EXPECT_EQ(e.site()->line, 4);
    EXPECT_EQ(e.site()->column, 3);
    EXPECT_EQ(e.site()->node, "bad");
    EXPECT_EQ(e.site()->module, "test.fail");
    EXPECT_EQ(e.site()->message, "the input is bad on purpose");
  }
  EXPECT_EQ(ex.last_report().error, "pipes/site.yaml:4:3: node 'bad' (test.fail): the input is bad on purpose");
}

TEST(Executor, PipelineBuiltInCodeHasNoPosition) {
  Pipeline p;
  p.add_node("src", "test.source");
  p.add_node("bad", "test.fail");
  ASSERT_EQ(p.connect({"src", "volume"}, "bad", "volume"), "");
  Executor ex;
  try {
    ex.run(p);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "node 'bad' (test.fail): failed on purpose");
    ASSERT_NE(e.site(), nullptr);
    EXPECT_EQ(e.site()->line, 0);
  }
  // Validation errors are unchanged: no site.
  p.set_param("src", "offset", std::string("x"));
  try {
    ex.run(p);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.site(), nullptr);
  }
}

TEST(Executor, SavingMovesPositionsToTheSavedFile) {
  fs::path dir = scratch("save_pos");
  Pipeline p = Pipeline::parse(
      "skelflow: 1\nnodes:\n\n\n  src: {module: test.source}\n  bad: {module: test.fail, inputs: {volume: src.volume}}\n",
      "old.yaml", dir);
  p.add_node("late", "test.fail");
  p.save(dir / "new.yaml");
  EXPECT_EQ(p.find("src")->pos.line, 3);
  EXPECT_EQ(p.find("late")->pos.line, 8);
  Executor ex;
  EXPECT_EQ(error_of([&] { ex.run(p, targets({"bad"})); }),
            (dir / "new.yaml").string() + ":5:3: node 'bad' (test.fail): failed on purpose");
}

TEST(Executor, OverrideErrorsNameTheOverride) {
  Pipeline p = Pipeline::parse(kChain, "chain.yaml");
  Executor ex;
  ExecOptions o;
  o.overrides["aa"]["factor"] = int64_t{1};
  EXPECT_EQ(error_of([&] { ex.run(p, o); }), "--set aa.factor=1: no node 'aa' in chain.yaml (did you mean 'a'?)");
  o.overrides.clear();
  o.overrides["a"]["factor"] = int64_t{1000};
  EXPECT_EQ(error_of([&] { ex.run(p, o); }),
            "--set a.factor=1000: node 'a': param 'factor': value 1000 is out of range [-100, 100]");
  o.overrides.clear();
  o.overrides["a"]["factr"] = int64_t{1};
  EXPECT_EQ(error_of([&] { ex.run(p, o); }),
            "--set a.factr=1: node 'a': unknown parameter 'factr' of test.scale (did you mean 'factor'?)");
  o.overrides.clear();
  o.overrides["a"]["factor"] = std::string("big");
  EXPECT_EQ(error_of([&] { ex.run(p, o); }), "--set a.factor=big: node 'a': param 'factor': expected float, got 'big'");
  EXPECT_EQ(ex.modules_run(), 0);
}

// ---------------------------------------------------------------- phases
TEST(ExecutorPlan, OrdersTargetsAndMarksCachedNodes) {
  Pipeline p = Pipeline::parse(kChain);
  Executor ex;
  ExecutionPlan all = ex.plan(p);
  ASSERT_EQ(all.nodes.size(), 4u);
  EXPECT_EQ(all.nodes[0].id, "src");
  EXPECT_EQ(all.nodes[3].id, "sum");
  EXPECT_EQ(all.nodes[0].users, (std::vector<size_t>{1, 2}));
  EXPECT_EQ(all.nodes[3].inputs_from, (std::vector<size_t>{1, 2}));
  for (const auto& n : all.nodes) EXPECT_FALSE(n.cached) << n.id;
  ExecutionPlan a = ex.plan(p, targets({"a"}));
  ASSERT_EQ(a.nodes.size(), 2u);
  EXPECT_EQ(a.index_of("a"), 1);
  EXPECT_EQ(a.index_of("b"), -1);
  EXPECT_EQ(a.nodes[1].cache_key, all.nodes[1].cache_key);
  // After a run that keeps outputs, everything is cached; an override changes a node and its users.
  ExecOptions keep;
  keep.keep_outputs = true;
  ex.run(p, keep);
  for (const auto& n : ex.plan(p).nodes) EXPECT_TRUE(n.cached) << n.id;
  ExecOptions o;
  o.overrides["a"]["factor"] = int64_t{4};
  ExecutionPlan changed = ex.plan(p, o);
  EXPECT_TRUE(changed.nodes[0].cached);
  EXPECT_FALSE(changed.nodes[1].cached);
  EXPECT_TRUE(changed.nodes[2].cached);
  EXPECT_FALSE(changed.nodes[3].cached);
  EXPECT_EQ(std::get<int64_t>(changed.pipeline.find("a")->params.at("factor")), 4);
  EXPECT_EQ(ex.modules_run(), 4);  // planning runs nothing
  EXPECT_THROW((void)ex.plan(p, targets({"nobody"})), InputError);
}

TEST(Executor, NodeReadingTwoPortsOfOneNodeDoesNotFreeItForOthers) {
  // `sum` reads src twice; `a` reads it once and may run after `sum` (one worker): headless runs
  // free a result when its last reader is done, counted per reading node.
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [3, 3, 3]}}
  sum: {module: test.sum, inputs: {a: src.volume, b: src.volume}}
  a: {module: test.scale, inputs: {volume: src.volume}}
)");
  Executor ex;
  ExecOptions one;
  one.threads = 1;
  RunReport r = ex.run(p, one);
  EXPECT_TRUE(r.ok);
  EXPECT_EQ(r.nodes.size(), 3u);
}

// A node with two outputs of which only one is read: headless runs drop the unread one as soon as
// the node is done (not when the read one is released), so an unread volume costs nothing downstream.
namespace {
std::weak_ptr<const DataObject> g_unread;
std::atomic<int> g_unread_alive_when_read{-1};
std::atomic<int> g_unread_wanted{-1}, g_read_wanted{-1};  // RunContext::output_wanted in TwoOutputs
class TwoOutputs final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test_engine.two_outputs", "Two volumes, `read` and `unread`")
        .output<VolumeU8>("read", "read downstream")
        .output<VolumeU8>("unread", "read by nobody in the test");
  }
  void run(RunContext& ctx) override {
    g_unread_wanted = ctx.output_wanted("unread") ? 1 : 0;
    g_read_wanted = ctx.output_wanted("read") ? 1 : 0;
    auto unread = std::make_shared<VolumeU8>(Dims{4, 4, 4});
    g_unread = unread;
    ctx.output("read", VolumeU8(Dims{2, 2, 2}, 1));
    ctx.output("unread", DataPtr(std::move(unread)));
  }
};
SKEL_REGISTER_MODULE(TwoOutputs);
class ReadsOne final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test_engine.reads_one", "Records whether test_engine.two_outputs' unread volume is alive")
        .input<VolumeU8>("volume", "any volume");
  }
  void run(RunContext&) override { g_unread_alive_when_read = g_unread.expired() ? 0 : 1; }
};
SKEL_REGISTER_MODULE(ReadsOne);
}  // namespace

TEST(Executor, HeadlessDropsAnOutputNobodyReadsWhenItsNodeIsDone) {
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  two: {module: test_engine.two_outputs}
  user: {module: test_engine.reads_one, inputs: {volume: two.read}}
)");
  ExecOptions one;
  one.threads = 1;
  {
    Executor ex;
    g_unread_alive_when_read = -1;
    ASSERT_TRUE(ex.run(p, one).ok);
    EXPECT_EQ(g_unread_alive_when_read.load(), 0);  // dropped before `user` ran
    EXPECT_EQ(g_unread_wanted.load(), 0);  // the module was told, so it may skip it
    EXPECT_EQ(g_read_wanted.load(), 1);
  }
  {
    Executor ex;
    ExecOptions keep = one;
    keep.keep_outputs = true;  // the GUI: every output stays for viewing
    g_unread_alive_when_read = -1;
    ASSERT_TRUE(ex.run(p, keep).ok);
    EXPECT_EQ(g_unread_alive_when_read.load(), 1);
    EXPECT_NE(ex.output(p, "two", "unread"), nullptr);
    EXPECT_EQ(g_unread_wanted.load(), 1);
  }
  {
    Executor ex;
    ExecOptions target = one;
    target.targets = {"two", "user"};  // a target's outputs are what the caller asked for
    g_unread_alive_when_read = -1;
    ASSERT_TRUE(ex.run(p, target).ok);
    EXPECT_EQ(g_unread_alive_when_read.load(), 1);
    EXPECT_EQ(g_unread_wanted.load(), 1);
  }
}

// ModuleSpec::output_type_from: validate() narrows an output's types from the parameters (here without
// a file) and reports what the function throws at the node.
namespace {
class TypedSource final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test_engine.typed_source", "A volume of the type named by `dtype`")
        .add_output("volume", {type_ids::volume_u8, type_ids::volume_f32}, "one voxel")
        .choice("dtype", {"u8", "f32", "broken"}, "u8", "voxel type; broken: the type cannot be told")
        .output_type_from("volume", [](const OutputTypeQuery& q) {
          const std::string t = std::get<std::string>(q.params.at("dtype"));
          if (t == "broken") throw InputError("cannot tell the voxel type");
          return DeducedOutput{{t == "u8" ? type_ids::volume_u8 : type_ids::volume_f32}, "dtype " + t};
        });
  }
  void run(RunContext& ctx) override {
    if (ctx.param<std::string>("dtype") == "u8") ctx.output("volume", VolumeU8(Dims{1, 1, 1}));
    else ctx.output("volume", VolumeF32(Dims{1, 1, 1}));
  }
};
SKEL_REGISTER_MODULE(TypedSource);
}  // namespace

TEST(Engine, OutputTypeFromNarrowsTypesAtValidation) {
  auto check = [](const std::string& dtype) {
    const std::string yaml = "skelflow: 1\nnodes:\n  src: {module: test_engine.typed_source, params: {dtype: " + dtype +
                             "}}\n  scale: {module: test.scale, inputs: {volume: src.volume}}\n";
    std::vector<std::string> r;
    for (const auto& d : validate(Pipeline::parse(yaml, "p.yaml"))) r.push_back(d.format());
    return r;
  };
  // Declared u8|f32 meets test.scale's f32 either way; the deduced type decides.
  EXPECT_TRUE(check("f32").empty());
  const auto u8 = check("u8");
  ASSERT_EQ(u8.size(), 1u);
  EXPECT_EQ(u8[0], "p.yaml:4:48: node 'scale': input 'volume': type mismatch: src.volume gives volume.u8 (dtype u8), but "
                   "'volume' takes volume.f32");
  const auto broken = check("broken");
  ASSERT_EQ(broken.size(), 1u);
  EXPECT_EQ(broken[0], "p.yaml:3:3: node 'src': cannot tell the voxel type");
  // Unknown output port: a programming error when the spec is built.
  EXPECT_THROW(ModuleSpec("x.y", "z").output_type_from("nope", {}), Error);
}

// In-place execution (ModuleSpec::in_place, RunContext::take_input): the executor hands a node its
// input's buffer only when that node is the input's last reader and nothing else may still need it.
namespace {
std::atomic<int> g_in_place_taken{0}, g_in_place_runs{0};
std::atomic<int> g_scale_runs_before_take{-1};
class InPlaceScale final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test_engine.in_place_scale", "Doubles a float volume, in place when handed over")
        .input<VolumeF32>("volume", "input")
        .optional_input<VolumeF32>("other", "read only (tests: the same output on two ports)")
        .output<VolumeF32>("volume", "doubled")
        .param<double>("factor", 2.0, "factor")
        .in_place("volume", "volume");
  }
  void run(RunContext& ctx) override {
    ++g_in_place_runs;
    const auto f = static_cast<float>(ctx.param<double>("factor"));
    if (auto v = ctx.take_input<VolumeF32>("volume")) {
      ++g_in_place_taken;
      g_scale_runs_before_take = test_counters::g_scale_runs.load();
      for (auto& x : *v) x *= f;
      EXPECT_EQ(ctx.take_input<VolumeF32>("volume"), nullptr);  // handed over once
      ctx.output("volume", DataPtr(std::move(v)));
      return;
    }
    VolumeF32 out(*ctx.input<VolumeF32>("volume"));
    for (auto& x : out) x *= f;
    ctx.output("volume", std::move(out));
  }
};
SKEL_REGISTER_MODULE(InPlaceScale);

struct InPlaceRun {
  bool ok = false;
  std::map<std::string, std::shared_ptr<const VolumeF32>> volumes;  // node -> its `volume` output
  std::map<std::string, const float*> buffers;                      // node -> its output's voxels
};
// Runs p keeping every node's `volume` output from on_outputs (only its address for `src`, or the nodes
// in `address_only`: a reference
// would keep the data alive and rightly stop the hand-over).
InPlaceRun run_in_place(const Pipeline& p, ExecOptions o, Executor* executor = nullptr,
                        const std::set<std::string>& address_only = {"src"}) {
  InPlaceRun r;
  std::mutex m;
  o.on_outputs = [&](const std::string& node, const std::map<std::string, DataPtr>& outputs) {
    auto it = outputs.find("volume");
    if (it == outputs.end()) return;
    auto v = std::dynamic_pointer_cast<const VolumeF32>(it->second);
    std::lock_guard lock(m);
    r.buffers[node] = v->data();
    if (!address_only.contains(node)) r.volumes[node] = v;
  };
  g_in_place_taken = 0;
  g_in_place_runs = 0;
  g_scale_runs_before_take = -1;
  Executor local;
  r.ok = (executor ? *executor : local).run(p, o).ok;
  return r;
}
VolumeF32 doubled_ramp(Dims d, float factor = 2.0f) {  // test.source's ramp, doubled
  VolumeF32 v(d);
  for (int64_t i = 0; i < v.size(); ++i) v[i] = factor * static_cast<float>(i % 97);
  return v;
}
}  // namespace

TEST(Executor, InPlaceHandsTheLastReaderItsInputBuffer) {
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [5, 4, 3]}}
  twice: {module: test_engine.in_place_scale, inputs: {volume: src.volume}}
)");
  ExecOptions one;
  one.threads = 1;
  InPlaceRun r = run_in_place(p, one);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(g_in_place_taken.load(), 1);
  EXPECT_EQ(r.buffers["twice"], r.buffers["src"]);  // written into the source's voxels
  EXPECT_TRUE(*r.volumes["twice"] == doubled_ramp(Dims{5, 4, 3}));
  // The GUI keeps every output: nothing is handed over, and the result is the same bit for bit.
  ExecOptions keep = one;
  keep.keep_outputs = true;
  Executor gui;
  InPlaceRun g = run_in_place(p, keep, &gui);
  ASSERT_TRUE(g.ok);
  EXPECT_EQ(g_in_place_taken.load(), 0);
  EXPECT_NE(g.buffers["twice"], g.buffers["src"]);
  EXPECT_TRUE(*g.volumes["twice"] == *r.volumes["twice"]);
  auto src = std::dynamic_pointer_cast<const VolumeF32>(gui.output(p, "src", "volume"));
  ASSERT_NE(src, nullptr);
  EXPECT_EQ(src->data()[7], 7.0f);  // the kept input is untouched
  // A headless run on the executor whose cache holds `src` from the GUI run: `src` comes from the
  // cache, which still holds it, so the new reader `again` (the last one, after the cached `twice`)
  // does not get it.
  Pipeline p2 = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [5, 4, 3]}}
  twice: {module: test_engine.in_place_scale, inputs: {volume: src.volume}}
  again: {module: test_engine.in_place_scale, inputs: {volume: src.volume}, params: {factor: 3}}
)");
  InPlaceRun c = run_in_place(p2, one, &gui);
  ASSERT_TRUE(c.ok);
  EXPECT_EQ(g_in_place_runs.load(), 1);
  EXPECT_EQ(g_in_place_taken.load(), 0);
  EXPECT_EQ(src->data()[7], 7.0f);
  EXPECT_TRUE(*c.volumes["again"] == doubled_ramp(Dims{5, 4, 3}, 3.0f));
}

TEST(Executor, InPlaceNeverTakesABufferSomethingElseStillReads) {
  // Another node reads src too: whichever of the two runs first must not get the buffer; the one
  // that runs last may, once the other is done. Both results are right either way.
  Pipeline fan = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [6, 5, 4]}}
  twice: {module: test_engine.in_place_scale, inputs: {volume: src.volume}}
  other: {module: test.scale, inputs: {volume: src.volume}, params: {sleep_ms: 20}}
)");
  for (int threads : {1, 2}) {
    ExecOptions o;
    o.threads = threads;
    const int scale_runs = test_counters::g_scale_runs.load();
    InPlaceRun r = run_in_place(fan, o);
    ASSERT_TRUE(r.ok);
    EXPECT_TRUE(*r.volumes["twice"] == doubled_ramp(Dims{6, 5, 4}));
    EXPECT_TRUE(*r.volumes["other"] == doubled_ramp(Dims{6, 5, 4}));  // test.scale: factor 2
    if (g_in_place_taken.load() == 1) {
      EXPECT_EQ(g_scale_runs_before_take.load(), scale_runs + 1) << threads;
    }
  }
  // The same output on two ports of the node: not handed over (the other port still reads it).
  Pipeline twice_read = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [3, 3, 3]}}
  twice: {module: test_engine.in_place_scale, inputs: {volume: src.volume, other: src.volume}}
)");
  ExecOptions one;
  one.threads = 1;
  InPlaceRun r = run_in_place(twice_read, one);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(g_in_place_runs.load(), 1);
  EXPECT_EQ(g_in_place_taken.load(), 0);
  EXPECT_TRUE(*r.volumes["twice"] == doubled_ramp(Dims{3, 3, 3}));
  // A target's outputs are what the caller asked for: kept, not handed over.
  Pipeline chain = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [3, 3, 3]}}
  twice: {module: test_engine.in_place_scale, inputs: {volume: src.volume}}
)");
  ExecOptions target = one;
  target.targets = {"src", "twice"};
  r = run_in_place(chain, target);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(g_in_place_taken.load(), 0);
  // Under a memory budget volumes live on disk: nothing is handed over.
  ExecOptions budget = one;
  budget.memory_budget = 64ull << 20;
  budget.scratch_dir = scratch("in_place_budget");
  fs::create_directories(budget.scratch_dir);
  r = run_in_place(chain, budget);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(g_in_place_taken.load(), 0);
  EXPECT_TRUE(*r.volumes["twice"] == doubled_ramp(Dims{3, 3, 3}));
}

namespace {
class SlowTableReader final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("test_engine.slow_table_reader", "Reads a table for 300 ms")
        .input<Table>("table", "any table");
  }
  void run(RunContext& ctx) override {
    (void)ctx.input<Table>("table");
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  }
};
SKEL_REGISTER_MODULE(SlowTableReader);
}  // namespace

TEST(Executor, InPlaceIgnoresReadersOfTheUpstreamNodesOtherOutputs) {
  // `slow` reads sum.table while `twice` runs: it does not read sum.volume, so `twice` gets that
  // buffer (counted per output, not per upstream node: the vessel pipeline's phantom image is smoothed
  // in place while its truth graph is still being written).
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  src: {module: test.source, params: {size: [5, 4, 3]}}
  sum: {module: test.sum, inputs: {a: src.volume}}
  twice: {module: test_engine.in_place_scale, inputs: {volume: sum.volume}}
  slow: {module: test_engine.slow_table_reader, inputs: {table: sum.table}}
)");
  ExecOptions two;
  two.threads = 2;
  InPlaceRun r = run_in_place(p, two, nullptr, {"sum"});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(g_in_place_taken.load(), 1);
  EXPECT_EQ(r.buffers["twice"], r.buffers["sum"]);
  EXPECT_TRUE(*r.volumes["twice"] == doubled_ramp(Dims{5, 4, 3}));
}

TEST(Executor, TakeInputRefusesDataHeldElsewhereOrWrapped) {
  const ModuleSpec spec = InPlaceScale::spec();
  detail::OutputFiles files;
  auto make = [&](DataPtr d) {
    return std::make_unique<detail::NodeContext>(spec, "n", std::map<std::string, DataPtr>{{"volume", std::move(d)}},
                                                 ParamMap{}, 1, Interrupter{}, fs::path("."), fs::path("."), files,
                                                 [](const std::string&) {});
  };
  // Not handed over: nullptr.
  auto ctx = make(std::make_shared<VolumeF32>(Dims{2, 2, 2}));
  EXPECT_EQ(ctx->take_input<VolumeF32>("volume"), nullptr);
  // Handed over but someone else holds a reference: nullptr.
  auto held = std::make_shared<VolumeF32>(Dims{2, 2, 2});
  ctx = make(held);
  ctx->hand_over("volume");
  EXPECT_EQ(ctx->take_input<VolumeF32>("volume"), nullptr);
  // Handed over and held by the context alone: the data itself.
  ctx = make(std::make_shared<VolumeF32>(Dims{2, 2, 2}));
  ctx->hand_over("volume");
  auto taken = ctx->take_input<VolumeF32>("volume");
  ASSERT_NE(taken, nullptr);
  EXPECT_EQ(taken.get(), ctx->input_data("volume").get());
  // Wrapped outside memory (NumPy arrays from Python): never written.
  auto owner = std::make_shared<std::vector<float>>(8, 1.0f);
  ctx = make(std::make_shared<VolumeF32>(VolumeF32::wrap(Grid(Dims{2, 2, 2}), owner->data(), owner)));
  ctx->hand_over("volume");
  EXPECT_EQ(ctx->take_input<VolumeF32>("volume"), nullptr);
  // Another type than asked for: nullptr.
  ctx = make(std::make_shared<VolumeF32>(Dims{2, 2, 2}));
  ctx->hand_over("volume");
  EXPECT_EQ(ctx->take_input<VolumeU8>("volume"), nullptr);
  // An in_place declaration must name declared ports.
  EXPECT_THROW(ModuleSpec("x.y", "z").in_place("a", "b"), Error);
}

// The run report's cpu_seconds: the process's CPU time while a node ran (here one node at a time).
namespace {
class BusyCpu final : public Module {
public:
  static ModuleSpec spec() { return ModuleSpec("test_engine.busy_cpu", "Spins until its thread used 0.2 s of CPU"); }
  void run(RunContext&) override {
    auto thread_cpu = [] {
      timespec t{};
      clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
      return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
    };
    const double start = thread_cpu();
    volatile uint64_t x = 0;
    while (thread_cpu() - start < 0.2) x = x + 1;
  }
};
SKEL_REGISTER_MODULE(BusyCpu);
}  // namespace

TEST(Executor, ReportsCpuSecondsPerNode) {
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  busy: {module: test_engine.busy_cpu}
)");
  ExecOptions one;
  one.threads = 1;
  Executor ex;
  RunReport r = ex.run(p, one);
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.nodes.size(), 1u);
  EXPECT_GE(r.nodes[0].cpu_seconds, 0.19);  // rusage granularity
  EXPECT_LE(r.nodes[0].cpu_seconds, r.nodes[0].seconds * std::thread::hardware_concurrency() + 0.05);
  EXPECT_NE(r.to_json().find("\"cpu_seconds\": "), std::string::npos);
}
