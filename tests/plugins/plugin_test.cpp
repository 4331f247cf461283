// Plugins: modules in shared libraries loaded at start (skel/plugin.hpp). Each TEST runs in its own
// process (gtest_discover_tests), so every one starts with an empty plugin list.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "skel/executor.hpp"
#include "skel/module.hpp"
#include "skel/pipeline.hpp"
#include "skel/plugin.hpp"
#include "skel/volume.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

fs::path scratch(const std::string& name) {
  fs::path d = fs::current_path() / "plugin_scratch" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string canonical(const char* p) { return fs::canonical(p).string(); }

// Nothing from the user's own plugin folder: only what a test names.
void isolate(const fs::path& home) {
  setenv("XDG_DATA_HOME", (home / "xdg").c_str(), 1);
  unsetenv("SKELFLOW_PLUGIN_PATH");
}

// Runs a shell command line, returns its exit code and its stdout + stderr.
std::pair<int, std::string> shell(const std::string& cmd) {
  std::string out;
  FILE* f = popen((cmd + " 2>&1").c_str(), "r");
  if (!f) return {-1, ""};
  char buf[4096];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) out.append(buf, n);
  const int status = pclose(f);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

}  // namespace

TEST(Plugin, LoadsFromPluginPathAndRunsInAPipeline) {
  const fs::path d = scratch("pipeline");
  isolate(d);
  setenv("SKELFLOW_PLUGIN_PATH", (std::string("/no/such/skelflow/folder:") + PLUGIN_GOOD_DIR).c_str(), 1);
  ASSERT_EQ(Registry::instance().find("plugin_test.invert"), nullptr);
  const PluginLoadReport& r = load_plugins();
  ASSERT_EQ(r.loaded.size(), 1u);
  EXPECT_EQ(r.loaded[0].file, canonical(PLUGIN_INVERT));
  EXPECT_EQ(r.loaded[0].modules, std::vector<std::string>{"plugin_test.invert"});
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0], "SKELFLOW_PLUGIN_PATH: /no/such/skelflow/folder: no such file or folder");
  EXPECT_EQ(&load_plugins(), &r) << "loaded once";

  const ModuleSpec* spec = Registry::instance().find("plugin_test.invert");
  ASSERT_NE(spec, nullptr);
  EXPECT_EQ(plugin_of_module("plugin_test.invert"), canonical(PLUGIN_INVERT));
  EXPECT_EQ(plugin_of_module("test.mask"), "") << "built in";
  ASSERT_NE(spec->find_param("value"), nullptr);
  EXPECT_EQ(spec->find_param("value")->doc, "value of the voxels that were background");

  // test.mask (all ones) -> invert (value 7: all zero) -> invert (value 9: all nine).
  Pipeline p = Pipeline::parse("skelflow: 1\nnodes:\n"
                               "  src: {module: test.mask}\n"
                               "  a: {module: plugin_test.invert, inputs: {mask: src.mask}, params: {value: 7}}\n"
                               "  b: {module: plugin_test.invert, inputs: {mask: a.mask}, params: {value: 9}}\n",
                               "p.yaml");
  Executor ex;
  ExecOptions keep;
  keep.keep_outputs = true;
  ex.run(p, keep);
  auto a = std::dynamic_pointer_cast<const VolumeU8>(ex.output(p, "a", "mask"));
  auto b = std::dynamic_pointer_cast<const VolumeU8>(ex.output(p, "b", "mask"));
  ASSERT_TRUE(a && b);
  ASSERT_EQ(b->size(), 8);
  for (int64_t i = 0; i < b->size(); ++i) {
    EXPECT_EQ((*a)[i], 0);
    EXPECT_EQ((*b)[i], 9);
  }
  // The plugin's parameter spec validates like a built-in one's.
  Pipeline bad = Pipeline::parse("skelflow: 1\nnodes:\n  src: {module: test.mask}\n"
                                 "  a: {module: plugin_test.invert, inputs: {mask: src.mask}, params: {value: 300}}\n",
                                 "bad.yaml");
  std::string all;
  for (const auto& e : validate(bad)) all += e.format() + "\n";
  EXPECT_TRUE(has(all, "bad.yaml:4:") && has(all, "node 'a': param 'value': value 300 is out of range [1, 255]")) << all;
}

TEST(Plugin, UserFolderIsSearched) {
  const fs::path d = scratch("user_folder");
  isolate(d);
  const fs::path folder = d / "xdg" / "skelflow" / "plugins";
  fs::create_directories(folder);
  fs::copy_file(PLUGIN_INVERT, folder / "invert.so");
  std::ofstream(folder / "README.txt") << "not a library: skipped\n";
  const PluginLoadReport& r = load_plugins();
  EXPECT_EQ(r.searched, std::vector<std::string>{folder.string()});
  ASSERT_EQ(r.loaded.size(), 1u);
  EXPECT_EQ(r.loaded[0].file, fs::canonical(folder / "invert.so").string());
  EXPECT_TRUE(r.errors.empty()) << r.errors.front();
  EXPECT_NE(Registry::instance().find("plugin_test.invert"), nullptr);
}

TEST(Plugin, WrongAbiTagIsRefusedWithTheFileAndBothTags) {
  isolate(scratch("abi"));
  const size_t before = Registry::instance().specs().size();
  const std::string e = load_plugin(PLUGIN_BAD_ABI);
  EXPECT_TRUE(has(e, "plugin " + canonical(PLUGIN_BAD_ABI) + ": built for another Skelflow or compiler ABI")) << e;
  EXPECT_TRUE(has(e, "\n  expected ABI tag: " + plugin_abi_tag() + "\n")) << e;
  EXPECT_TRUE(has(e, "\n  found ABI tag:    skelflow 0.0.1 plugin-api 0; layout ModuleSpec=1/1")) << e;
  EXPECT_EQ(Registry::instance().find("plugin_test.bad_abi"), nullptr) << "its register function never ran";
  EXPECT_EQ(Registry::instance().specs().size(), before);
  EXPECT_TRUE(loaded_plugins().empty());
  // The tag names the version, the compiler ABI and the layout of the module API.
  const std::string tag = plugin_abi_tag();
  EXPECT_EQ(tag.rfind("skelflow " SKELFLOW_VERSION_TEXT " plugin-api ", 0), 0u) << tag;
  for (const char* part : {"; layout ", " ModuleSpec=", " RunContext=", " Registry=", " VolumeU8="})
    EXPECT_TRUE(has(tag, part)) << part << " in " << tag;
}

TEST(Plugin, CollisionsAreRefusedNamingBothFiles) {
  isolate(scratch("collide"));
  ASSERT_EQ(load_plugin(PLUGIN_INVERT), "");
  const std::string e = load_plugin(PLUGIN_COLLIDE);
  EXPECT_EQ(e, "plugin " + canonical(PLUGIN_COLLIDE) + ": module 'plugin_test.invert' is already defined by module "
                   "'plugin_test.invert' of plugin " + canonical(PLUGIN_INVERT) + "; the plugin is not loaded");
  EXPECT_EQ(Registry::instance().find("plugin_test.invert_not"), nullptr) << "refused as a whole";
  EXPECT_EQ(plugin_of_module("plugin_test.invert"), canonical(PLUGIN_INVERT)) << "the first one stays";

  const std::string b = load_plugin(PLUGIN_COLLIDE_BUILTIN);
  EXPECT_EQ(b, "plugin " + canonical(PLUGIN_COLLIDE_BUILTIN) +
                   ": module 'test.mask' is already defined by the built-in module 'test.mask'; the plugin is not loaded");
  EXPECT_EQ(Registry::instance().find("test.mask_not"), nullptr);
  EXPECT_EQ(loaded_plugins().size(), 1u);
  EXPECT_EQ(load_plugin(PLUGIN_INVERT), "") << "the same file again is no collision";
  EXPECT_EQ(loaded_plugins().size(), 1u);
}

TEST(Plugin, StaticInitialiserRegistrationIsRefused) {
  isolate(scratch("static_init"));
  const std::string e = load_plugin(PLUGIN_STATIC_INIT);
  EXPECT_EQ(e, "plugin " + canonical(PLUGIN_STATIC_INIT) +
                   ": registers module 'plugin_test.early' from a static initialiser (SKEL_REGISTER_MODULE), before "
                   "its ABI can be checked; list its modules in SKELFLOW_PLUGIN(...) instead");
  EXPECT_EQ(Registry::instance().find("plugin_test.early"), nullptr);
  // Registration goes to the registry again afterwards (the capture ended).
  Registry::instance().add(ModuleSpec("plugin_test.after", "added by the test"), nullptr);
  EXPECT_NE(Registry::instance().find("plugin_test.after"), nullptr);
}

TEST(Plugin, AnExceptionWhileRegisteringRefusesThePluginAsAWhole) {
  isolate(scratch("broken_spec"));
  EXPECT_EQ(load_plugin(PLUGIN_BROKEN_SPEC), "plugin " + canonical(PLUGIN_BROKEN_SPEC) +
                                                 ": registering its modules failed: ModuleSpec::range called before any param");
  EXPECT_EQ(Registry::instance().find("plugin_test.good_half"), nullptr);
  EXPECT_EQ(Registry::instance().find("plugin_test.broken"), nullptr);
  EXPECT_TRUE(loaded_plugins().empty());
}

TEST(Plugin, NonPluginsAndUnloadableFilesAreNamedWithTheReason) {
  const fs::path d = scratch("non_plugin");
  isolate(d);
  const std::string e = load_plugin(PLUGIN_NOT_A_PLUGIN);
  EXPECT_TRUE(has(e, "plugin " + canonical(PLUGIN_NOT_A_PLUGIN) + ": not a Skelflow plugin (no skelflow_plugin_abi: ")) << e;
  EXPECT_TRUE(has(e, "undefined symbol: skelflow_plugin_abi")) << e;  // dlerror()

  std::ofstream(d / "garbage.so") << "this is no shared library\n";
  const std::string g = load_plugin((d / "garbage.so").string());
  EXPECT_TRUE(has(g, "plugin " + fs::canonical(d / "garbage.so").string() + ": cannot load: ")) << g;
  EXPECT_TRUE(has(g, "garbage.so: ")) << "dlerror() names the file and why: " << g;
  EXPECT_EQ(load_plugin((d / "missing.so").string()), "plugin " + (d / "missing.so").string() + ": no such file");
  EXPECT_TRUE(loaded_plugins().empty());
}

// The real skelflow binary: plugin modules listed with their file, usable in validate and run; a
// refused plugin is a warning naming its file, and the command goes on.
TEST(Plugin, CommandLineListsValidatesAndRunsPluginModules) {
  const fs::path d = scratch("cli");
  const std::string env = "env -u SKELFLOW_PLUGIN_PATH XDG_DATA_HOME='" + (d / "xdg").string() +
                          "' SKELFLOW_PLUGIN_PATH='" + PLUGIN_GOOD_DIR + ":" + PLUGIN_BAD_ABI + "' ";
  const std::string bin = std::string("'") + SKELFLOW_BIN + "' ";
  auto [mc, modules] = shell(env + bin + "modules");
  EXPECT_EQ(mc, 0) << modules;
  EXPECT_TRUE(has(modules, "plugin_test.invert")) << modules;
  EXPECT_TRUE(has(modules, "  [plugin " + canonical(PLUGIN_INVERT) + "]\n")) << modules;
  EXPECT_TRUE(has(modules, "skelflow: warning: plugin " + canonical(PLUGIN_BAD_ABI) + ": built for another Skelflow")) << modules;
  auto [vc, version] = shell(env + bin + "--version");
  EXPECT_EQ(vc, 0);
  EXPECT_TRUE(has(version, "\nplugin: " + canonical(PLUGIN_INVERT) + ": plugin_test.invert\n")) << version;
  EXPECT_TRUE(has(version, "\nplugin ABI: " + plugin_abi_tag() + "\n")) << version;

  std::ofstream(d / "p.yaml") << "skelflow: 1\nnodes:\n"
                                 "  phantom: {module: synthetic.network, params: {size: [24, 24, 24], seed: 3}}\n"
                                 "  inv: {module: plugin_test.invert, inputs: {mask: phantom.mask}, params: {value: 5}}\n"
                                 "  save: {module: io.write_volume, inputs: {volume: inv.mask}, params: {path: inv.nrrd, compression: 0}}\n";
  auto [valc, val] = shell(env + bin + "validate '" + (d / "p.yaml").string() + "'");
  EXPECT_EQ(valc, 0) << val;
  auto [rc, run] = shell(env + bin + "run --quiet --threads 1 '" + (d / "p.yaml").string() + "'");
  ASSERT_EQ(rc, 0) << run;
  std::ifstream nrrd(d / "inv.nrrd", std::ios::binary);
  const std::string file((std::istreambuf_iterator<char>(nrrd)), std::istreambuf_iterator<char>());
  ASSERT_TRUE(has(file, "\nencoding: raw\n")) << file.substr(0, 400);
  ASSERT_GT(file.size(), 24u * 24u * 24u);
  const std::string bytes = file.substr(file.size() - 24 * 24 * 24);  // the voxels follow the header
  int64_t fives = 0, zeros = 0;
  for (char c : bytes) {
    fives += c == 5;
    zeros += c == 0;
  }
  EXPECT_EQ(fives + zeros, 24 * 24 * 24) << "only 0 and 5";
  EXPECT_GT(fives, 0);
  EXPECT_GT(zeros, 0);
  // Without the plugin the module is unknown.
  auto [uc, unknown] = shell("env -u SKELFLOW_PLUGIN_PATH XDG_DATA_HOME='" + (d / "xdg").string() + "' " + bin +
                             "validate '" + (d / "p.yaml").string() + "'");
  EXPECT_EQ(uc, 2);
  EXPECT_TRUE(has(unknown, "plugin_test.invert")) << unknown;
}
