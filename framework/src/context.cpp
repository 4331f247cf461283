#include "context.hpp"

#include <unistd.h>

#include <algorithm>
#include <system_error>

#include "skel/fs.hpp"
#include "skel/parallel.hpp"
#include "skel/run_module.hpp"

namespace fs = std::filesystem;

namespace skel::detail {

fs::path resolve_path(const fs::path& base, const std::string& p) {
  fs::path path(p);
  if (path.is_absolute() || base.empty()) return path.lexically_normal();
  return (base / path).lexically_normal();
}

OutputFiles::OutputFiles() : run_id_(make_run_id()) {}

fs::path OutputFiles::add(const fs::path& final_path) {
  std::lock_guard lock(mutex_);
  for (const auto& [tmp, fin] : files_) {
    if (fin == final_path) throw InputError("two outputs would be written to the same file " + final_path.string());
  }
  std::error_code ec;
  if (final_path.has_parent_path()) fs::create_directories(final_path.parent_path(), ec);
  if (ec) throw InputError("cannot create folder " + final_path.parent_path().string() + ": " + ec.message());
  fs::path tmp = temp_sibling(final_path, run_id_);
  files_.emplace_back(tmp, final_path);
  return tmp;
}

void OutputFiles::commit(std::vector<std::string>* notes) {
  std::lock_guard lock(mutex_);
  struct Moved {
    fs::path fin, bak;
    bool had_old;
  };
  std::vector<Moved> moved;
  size_t next = 0;
  try {
    for (; next < files_.size(); ++next) {
      const auto& [tmp, fin] = files_[next];
      std::error_code ec;
      if (!fs::exists(fs::symlink_status(tmp, ec))) continue;  // the module chose not to write
      const auto st = fs::symlink_status(fin, ec);
      const bool had_old = fs::exists(st);
      if (fs::is_directory(st)) throw Error("cannot replace " + fin.string() + ": it is a folder");
      const fs::path bak = backup_sibling(fin, run_id_);
      if (had_old && ::link(fin.c_str(), bak.c_str()) != 0) {
        // No hard links here (some network and FUSE file systems): move the old file aside.
        fs::rename(fin, bak, ec);
        if (ec) throw Error("cannot keep a backup of " + fin.string() + ": " + ec.message());
      }
      fs::rename(tmp, fin, ec);
      if (ec) {
        std::error_code e2;
        if (had_old) fs::rename(bak, fin, e2);  // this file's own step, undone
        throw Error("cannot move the new " + fin.string() + " into place: " + ec.message());
      }
      moved.push_back({fin, bak, had_old});
    }
  } catch (const std::exception& e) {
    size_t restored = 0, removed = 0;
    for (auto it = moved.rbegin(); it != moved.rend(); ++it) {
      std::error_code ec;
      if (it->had_old) {
        fs::rename(it->bak, it->fin, ec);
        if (!ec) ++restored;
        if (notes) notes->push_back(ec ? "could not restore " + it->fin.string() + " from " + it->bak.string() + ": " + ec.message()
                                       : "restored the previous " + it->fin.string());
      } else {
        fs::remove(it->fin, ec);
        if (!ec) ++removed;
        if (notes) notes->push_back("removed the new " + it->fin.string());
      }
    }
    for (size_t k = next; k < files_.size(); ++k) {
      std::error_code ec;
      fs::remove_all(files_[k].first, ec);
    }
    files_.clear();
    std::string what = std::string(e.what()) + "; no output was changed";
    if (!moved.empty())
      what += " (" + std::to_string(moved.size()) + (moved.size() == 1 ? " file already moved was" : " files already moved were") +
              " taken back: " + std::to_string(restored) + " restored, " + std::to_string(removed) +
              " removed)";
    throw Error(what);
  }
  for (const auto& m : moved) {
    std::error_code ec;
    if (m.had_old) fs::remove(m.bak, ec);
  }
  files_.clear();
}

void OutputFiles::rollback() {
  std::lock_guard lock(mutex_);
  for (auto& [tmp, fin] : files_) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
  }
  files_.clear();
}

std::vector<fs::path> OutputFiles::finals() const {
  std::lock_guard lock(mutex_);
  std::vector<fs::path> r;
  for (const auto& f : files_) r.push_back(f.second);
  return r;
}

NodeContext::NodeContext(const ModuleSpec& spec, std::string node_id, std::map<std::string, DataPtr> inputs,
                         ParamMap params, int threads, Interrupter progress, fs::path input_base,
                         fs::path output_base, OutputFiles& files,
                         std::function<void(const std::string&)> on_warning)
    : spec_(spec), node_id_(std::move(node_id)), inputs_(std::move(inputs)), params_(std::move(params)),
      threads_(threads), progress_(std::move(progress)), input_base_(std::move(input_base)),
      output_base_(std::move(output_base)), files_(files), on_warning_(std::move(on_warning)) {}

DataPtr NodeContext::input_data(const std::string& port) const {
  if (!spec_.find_input(port)) throw Error("module " + spec_.name() + " asked for undeclared input '" + port + "'");
  auto it = inputs_.find(port);
  return it == inputs_.end() ? nullptr : it->second;
}

DataPtr NodeContext::take_input_data(const std::string& port) {
  if (handed_over_.erase(port) == 0) return nullptr;
  auto it = inputs_.find(port);
  // Only this context holds the data (the executor let go of it when handing it over).
  if (it == inputs_.end() || !it->second || it->second.use_count() != 1) return nullptr;
  return it->second;
}

const ParamValue& NodeContext::param_value(const std::string& name) const {
  auto it = params_.find(name);
  if (it == params_.end()) throw Error("module " + spec_.name() + " asked for undeclared parameter '" + name + "'");
  return it->second;
}

void NodeContext::output(const std::string& port, DataPtr data) {
  const PortSpec* p = spec_.find_output(port);
  if (!p) throw Error("module " + spec_.name() + " produced undeclared output '" + port + "'");
  if (data && std::find(p->types.begin(), p->types.end(), data->type_id()) == p->types.end())
    throw Error("module " + spec_.name() + " produced " + data->type_id() + " on output '" + port + "'");
  outputs_[port] = std::move(data);
}

void NodeContext::warn(const std::string& message) {
  warnings_.push_back(message);
  if (on_warning_) on_warning_(message);
}

fs::path NodeContext::input_path(const std::string& param_name) const {
  return resolve_path(input_base_, std::get<std::string>(param_value(param_name)));
}

fs::path NodeContext::final_output_path(const std::string& param_name) const {
  return resolve_path(output_base_, std::get<std::string>(param_value(param_name)));
}

fs::path NodeContext::output_path(const std::string& param_name) {
  auto it = tmp_paths_.find(param_name);
  if (it != tmp_paths_.end()) return it->second;
  fs::path fin = final_output_path(param_name);
  fs::path tmp = files_.add(fin);
  tmp_paths_[param_name] = tmp;
  written_.push_back(fin.string());
  return tmp;
}

}  // namespace skel::detail

namespace skel {

DataPtr ModuleRunResult::data(const std::string& port) const {
  auto it = outputs.find(port);
  if (it == outputs.end() || !it->second) throw Error("the module produced no output '" + port + "'");
  return it->second;
}

std::optional<ParamValue> coerce_param(const ParamSpec& spec, const ParamValue& v);

ModuleRunResult run_module(const std::string& module, const std::map<std::string, DataPtr>& inputs,
                           const ParamMap& params, const RunModuleOptions& options) {
  const Registry& reg = Registry::instance();
  const ModuleSpec* spec = reg.find(module);
  if (!spec) throw InputError("unknown module '" + module + "'");
  ParamMap eff;
  for (const auto& p : spec->params()) eff[p.name] = p.default_value;
  for (const auto& [name, value] : params) {
    const ParamSpec* p = spec->find_param(name);
    if (!p) throw InputError(module + ": unknown parameter '" + name + "'");
    auto c = coerce_param(*p, value);
    std::string msg = c ? p->check(*c) : std::string("expected ") + to_string(p->type);
    if (!msg.empty()) throw InputError(module + ": param '" + name + "': " + msg);
    eff[p->name] = *c;
  }
  for (const auto& [port, data] : inputs) {
    const PortSpec* ps = spec->find_input(port);
    if (!ps) throw InputError(module + ": unknown input port '" + port + "'");
    if (data && std::find(ps->types.begin(), ps->types.end(), data->type_id()) == ps->types.end())
      throw InputError(module + ": input '" + port + "' does not accept " + data->type_id());
  }
  for (const auto& ps : spec->inputs()) {
    auto it = inputs.find(ps.name);
    if (ps.required && (it == inputs.end() || !it->second))
      throw InputError(module + ": required input '" + ps.name + "' is not connected");
  }
  detail::OutputFiles files;
  Interrupter progress(options.on_progress ? options.on_progress : [](double) {}, options.cancel);
  detail::NodeContext ctx(*spec, module, inputs, eff, effective_threads(options.threads), progress,
                          options.base_dir, options.base_dir, files, nullptr);
  auto mod = reg.create(module);
  mod->run(ctx);
  files.commit();
  ModuleRunResult r;
  r.outputs = std::move(ctx.outputs());
  r.warnings = ctx.warnings();
  return r;
}

}  // namespace skel
