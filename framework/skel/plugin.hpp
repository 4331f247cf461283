#pragma once
// Plugins: modules in a shared library that Skelflow loads at start (docs/plugins.md).
//
// A plugin is compiled against the installed Skelflow (find_package(Skelflow), target
// Skelflow::framework) and ends with one line naming its module classes:
//
//   SKELFLOW_PLUGIN(Invert, VoxelCount)
//
// which defines the plugin's two entry points:
//   extern "C" const char* skelflow_plugin_abi();               the ABI tag it was compiled with
//   extern "C" void skelflow_plugin_register(skel::Registry&);  adds its modules
// The loader (load_plugins) compares the tag with its own before it calls the register function,
// so a plugin built for another Skelflow, compiler ABI or data layout registers nothing. Module
// classes of a plugin are NOT registered with SKEL_REGISTER_MODULE (that would run before the
// check; the loader refuses a plugin that does it).
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/interrupter.hpp"
#include "skel/module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/version.hpp"
#include "skel/volume.hpp"

namespace skel {

// Bumped by hand when the plugin interface changes in a way no sizeof shows (a virtual function
// added to RunContext, a changed meaning).
inline constexpr int kPluginInterfaceVersion = 1;

namespace plugin_detail {
// Internal linkage on purpose: the host and every plugin each compute the tag of their own build
// (an inline function with external linkage could resolve to the host's copy inside a plugin).
namespace {
inline std::string layout_entry(const char* name, size_t size, size_t align) {
  return std::string(name) + "=" + std::to_string(size) + "/" + std::to_string(align);
}
#define SKEL_PLUGIN_LAYOUT(T) layout_entry(#T, sizeof(T), alignof(T))
// "skelflow 0.1.0 plugin-api 1; gxx-abi 1017 libstdcxx 12 cxx11-abi 1; layout ModuleSpec=...".
inline std::string abi_tag_of_this_build() {
  std::string t = "skelflow " SKELFLOW_VERSION_TEXT " plugin-api " + std::to_string(kPluginInterfaceVersion);
#if defined(__GXX_ABI_VERSION)
  t += "; gxx-abi " + std::to_string(__GXX_ABI_VERSION);
#endif
#if defined(_GLIBCXX_RELEASE)
  t += " libstdcxx " + std::to_string(_GLIBCXX_RELEASE);
#elif defined(_LIBCPP_VERSION)
  t += " libcxx " + std::to_string(_LIBCPP_VERSION);
#endif
#if defined(_GLIBCXX_USE_CXX11_ABI)
  t += " cxx11-abi " + std::to_string(_GLIBCXX_USE_CXX11_ABI);
#endif
  const std::vector<std::string> layout = {
      SKEL_PLUGIN_LAYOUT(ModuleSpec),   SKEL_PLUGIN_LAYOUT(ParamSpec),   SKEL_PLUGIN_LAYOUT(PortSpec),
      SKEL_PLUGIN_LAYOUT(RunContext),   SKEL_PLUGIN_LAYOUT(Registry),    SKEL_PLUGIN_LAYOUT(Module),
      SKEL_PLUGIN_LAYOUT(DataObject),   SKEL_PLUGIN_LAYOUT(Grid),        SKEL_PLUGIN_LAYOUT(VolumeU8),
      SKEL_PLUGIN_LAYOUT(SpatialGraph), SKEL_PLUGIN_LAYOUT(Table),       SKEL_PLUGIN_LAYOUT(Interrupter),
      SKEL_PLUGIN_LAYOUT(ParamValue),   SKEL_PLUGIN_LAYOUT(std::string), SKEL_PLUGIN_LAYOUT(void*)};
  t += "; layout";
  for (const auto& l : layout) t += " " + l;
  return t;
}
#undef SKEL_PLUGIN_LAYOUT
}  // namespace

template <class... Modules>
void register_modules(Registry& registry) {
  (registry.add(Modules::spec(), [] { return std::unique_ptr<Module>(std::make_unique<Modules>()); }), ...);
}
}  // namespace plugin_detail

// The ABI tag of the running Skelflow (compiled into the framework library): a plugin loads only
// when its skelflow_plugin_abi() returns exactly this.
std::string plugin_abi_tag();

// A plugin that was loaded: its file and the modules it added (sorted).
struct LoadedPlugin {
  std::string file;
  std::vector<std::string> modules;
};

// What load_plugins() did: the plugins loaded, one message per file refused (each names the file
// and why: the expected and found tag, dlerror(), a name collision naming both files), and the
// places searched.
struct PluginLoadReport {
  std::vector<LoadedPlugin> loaded;
  std::vector<std::string> errors;
  std::vector<std::string> searched;
};

// The places plugins are looked for, in order: every entry of SKELFLOW_PLUGIN_PATH (colon-separated
// folders or files), then the user folder ($XDG_DATA_HOME/skelflow/plugins, or
// ~/.local/share/skelflow/plugins) when it exists.
std::vector<std::string> plugin_search_path();

// Loads every plugin (*.so files of the folders, and the files named) into Registry::instance().
// Called once at start by the CLI, the GUI and the Python module; later calls return the first
// report. A refused plugin registers nothing and is unloaded; the others still load.
const PluginLoadReport& load_plugins();

// Loads one plugin file now (load_plugins() uses it; tests call it directly). Returns the error
// message, or "" when it was loaded (then it is in loaded_plugins()).
std::string load_plugin(const std::string& file);

// The plugins loaded so far, in load order.
const std::vector<LoadedPlugin>& loaded_plugins();

// The plugin file that added module `module`, or "" for a built-in (or unknown) module.
std::string plugin_of_module(const std::string& module);

}  // namespace skel

// Defines the plugin's entry points for the module classes given (each with `static ModuleSpec
// spec()` and run(), as built-in modules). Write it once, at namespace scope, in one source file.
#define SKELFLOW_PLUGIN(...)                                                                       \
  extern "C" __attribute__((visibility("default"))) const char* skelflow_plugin_abi() {          \
    static const std::string tag = ::skel::plugin_detail::abi_tag_of_this_build();                 \
    return tag.c_str();                                                                            \
  }                                                                                                \
  extern "C" __attribute__((visibility("default"))) void skelflow_plugin_register(::skel::Registry& r) { \
    ::skel::plugin_detail::register_modules<__VA_ARGS__>(r);                                       \
  }                                                                                                \
  static_assert(true, "SKELFLOW_PLUGIN ends with a semicolon")
