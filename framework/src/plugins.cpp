// The plugin loader (skel/plugin.hpp, docs/plugins.md): one for the CLI, the GUI and Python.
#include "skel/plugin.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <system_error>

#include "registry_capture.hpp"
#include "skel/text.hpp"

namespace skel {

namespace fs = std::filesystem;

std::string plugin_abi_tag() { return plugin_detail::abi_tag_of_this_build(); }

namespace {

std::mutex& loader_mutex() {
  static std::mutex m;
  return m;
}
std::vector<LoadedPlugin>& loaded() {
  static std::vector<LoadedPlugin> v;
  return v;
}
std::map<std::string, std::string>& origins() {  // module name -> plugin file
  static std::map<std::string, std::string> m;
  return m;
}
std::vector<std::string> names_of(const Registry& r) {
  std::vector<std::string> v;
  for (const ModuleSpec* s : r.specs()) v.push_back(s->name());
  return v;
}

// Sets Registry::instance()'s capture for the lifetime of the guard, so every registration the
// plugin's code makes lands in `into` (also one through Registry::instance() instead of the
// registry it was given).
class CaptureGuard {
public:
  explicit CaptureGuard(Registry& into) { detail::set_registry_capture(&into); }
  ~CaptureGuard() { detail::set_registry_capture(nullptr); }
  CaptureGuard(const CaptureGuard&) = delete;
  CaptureGuard& operator=(const CaptureGuard&) = delete;
};

std::string dl_error() {
  const char* e = dlerror();
  return e ? e : "unknown dlopen error";
}

// The plugin file that gave module `name`, or a description of the built-in module.
std::string provider(const std::string& name) {
  auto it = origins().find(name);  // the caller holds the loader's lock
  const std::string o = it == origins().end() ? std::string() : it->second;
  return o.empty() ? "the built-in module '" + name + "'" : "module '" + name + "' of plugin " + o;
}

bool is_shared_library(const fs::path& p) {
  const std::string n = p.filename().string();
  return n.size() > 3 && (n.ends_with(".so") || n.find(".so.") != std::string::npos);
}

}  // namespace

std::string load_plugin(const std::string& file) {
  std::lock_guard lock(loader_mutex());
  std::error_code ec;
  const fs::path path = fs::weakly_canonical(fs::absolute(file), ec);
  const std::string shown = ec ? file : path.string();
  for (const auto& p : loaded())
    if (p.file == shown) return {};  // the same file named twice (a folder and the file)
  if (!fs::is_regular_file(path, ec)) return "plugin " + file + ": no such file";

  // dlopen runs the plugin's static initialisers: a registration made there would bypass the ABI
  // check, so it is captured (and the plugin refused) instead of reaching the registry.
  Registry at_load;
  void* handle = nullptr;
  {
    CaptureGuard capture(at_load);
    dlerror();
    handle = dlopen(shown.c_str(), RTLD_NOW | RTLD_LOCAL);
  }
  if (!handle) return "plugin " + shown + ": cannot load: " + dl_error();
  auto refuse = [&](std::string message) {
    at_load = Registry();  // drops the factories and specs (code of the plugin) before unloading
    dlclose(handle);
    return message;
  };
  using AbiFn = const char* (*)();
  using RegisterFn = void (*)(Registry&);
  dlerror();
  auto abi = reinterpret_cast<AbiFn>(dlsym(handle, "skelflow_plugin_abi"));
  if (!abi) {
    return refuse("plugin " + shown + ": not a Skelflow plugin (no skelflow_plugin_abi: " + dl_error() +
                  "); a plugin ends with SKELFLOW_PLUGIN(...) from skel/plugin.hpp");
  }
  auto reg = reinterpret_cast<RegisterFn>(dlsym(handle, "skelflow_plugin_register"));
  if (!reg) {
    return refuse("plugin " + shown + ": not a Skelflow plugin (no skelflow_plugin_register: " + dl_error() +
                  "); a plugin ends with SKELFLOW_PLUGIN(...) from skel/plugin.hpp");
  }
  const std::string expected = plugin_abi_tag();
  const char* found_c = abi();
  const std::string found = found_c ? found_c : "";
  if (found != expected) {
    return refuse("plugin " + shown + ": built for another Skelflow or compiler ABI; rebuild it against this "
                  "Skelflow\n  expected ABI tag: " + expected + "\n  found ABI tag:    " + found);
  }
  if (!at_load.specs().empty() || !at_load.inspectors().empty()) {
    const std::string what =
        at_load.specs().empty() ? std::string("a file inspector") : "module '" + names_of(at_load).front() + "'";
    return refuse("plugin " + shown + ": registers " + what +
                  " from a static initialiser (SKEL_REGISTER_MODULE), before its ABI can be checked; list "
                  "its modules in SKELFLOW_PLUGIN(...) instead");
  }
  // The staged registry holds the plugin's specs and factories for the life of the process; the
  // global registry's factories call into it.
  auto staged = std::make_shared<Registry>();
  std::string failure;  // the exception (an object of the plugin's code) is gone before dlclose
  try {
    CaptureGuard capture(*staged);
    reg(*staged);
  } catch (const std::exception& e) {
    failure = e.what();
  } catch (...) {
    failure = "an exception that is no std::exception";
  }
  if (!failure.empty()) {
    staged.reset();
    return refuse("plugin " + shown + ": registering its modules failed: " + failure);
  }
  std::vector<std::string> names = names_of(*staged);
  if (names.empty()) {
    staged.reset();
    return refuse("plugin " + shown + ": registers no module");
  }
  for (const auto& n : names) {
    if (Registry::instance().find(n)) {
      const std::string other = provider(n);
      staged.reset();
      return refuse("plugin " + shown + ": module '" + n + "' is already defined by " + other +
                    "; the plugin is not loaded");
    }
  }
  for (const ModuleSpec* spec : staged->specs()) {
    Registry::instance().add(*spec, [staged, name = spec->name()] { return staged->create(name); });
    origins()[spec->name()] = shown;
  }
  for (const FileInspector& i : staged->inspectors()) Registry::instance().add_inspector(i);
  loaded().push_back({shown, std::move(names)});
  return {};  // the handle stays open for the life of the process: the registry holds its code
}

std::vector<std::string> plugin_search_path() {
  std::vector<std::string> r;
  if (const char* env = std::getenv("SKELFLOW_PLUGIN_PATH")) {
    for (const auto& part : text::split(env, ':'))
      if (!part.empty()) r.push_back(part);
  }
  fs::path user;
  if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg) {
    user = fs::path(xdg) / "skelflow" / "plugins";
  } else if (const char* home = std::getenv("HOME"); home && *home) {
    user = fs::path(home) / ".local" / "share" / "skelflow" / "plugins";
  }
  std::error_code ec;
  if (!user.empty() && fs::is_directory(user, ec)) r.push_back(user.string());
  return r;
}

const PluginLoadReport& load_plugins() {
  static const PluginLoadReport report = [] {
    PluginLoadReport rep;
    rep.searched = plugin_search_path();
    for (const auto& entry : rep.searched) {
      std::error_code ec;
      std::vector<fs::path> files;
      if (fs::is_directory(entry, ec)) {
        for (const auto& f : fs::directory_iterator(entry, ec))
          if (is_shared_library(f.path()) && !f.is_directory(ec)) files.push_back(f.path());
        if (ec) rep.errors.push_back("plugin folder " + entry + ": cannot list: " + ec.message());
        std::sort(files.begin(), files.end());  // a fixed order, so collisions name the same file
      } else if (fs::exists(entry, ec)) {
        files.push_back(entry);
      } else {
        rep.errors.push_back("SKELFLOW_PLUGIN_PATH: " + entry + ": no such file or folder");
      }
      for (const auto& f : files) {
        std::string e = load_plugin(f.string());
        if (!e.empty()) rep.errors.push_back(std::move(e));
      }
    }
    rep.loaded = loaded_plugins();
    return rep;
  }();
  return report;
}

const std::vector<LoadedPlugin>& loaded_plugins() { return loaded(); }

std::string plugin_of_module(const std::string& module) {
  std::lock_guard lock(loader_mutex());
  auto it = origins().find(module);
  return it == origins().end() ? std::string() : it->second;
}

}  // namespace skel
