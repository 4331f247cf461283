#pragma once
// Runs one registered module outside a pipeline: for tests, benchmarks and library users.
// The same validation as the pipeline engine applies (unknown/mistyped parameters, ranges, missing
// required inputs, port types), and output files are written transactionally.
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "skel/module.hpp"

namespace skel {

struct RunModuleOptions {
  int threads = 0;                      // 0 = all hardware threads
  std::filesystem::path base_dir = ".";  // relative input/output paths resolve against it
  const std::atomic<bool>* cancel = nullptr;
  std::function<void(double)> on_progress{};  // fraction 0..1; may be called from worker threads
};

struct ModuleRunResult {
  std::map<std::string, DataPtr> outputs;
  std::vector<std::string> warnings;

  [[nodiscard]] DataPtr data(const std::string& port) const;  // throws Error if absent
  template <class T>
  [[nodiscard]] std::shared_ptr<const T> get(const std::string& port) const {
    auto t = std::dynamic_pointer_cast<const T>(data(port));
    if (!t) throw Error("output '" + port + "' has type " + data(port)->type_id());
    return t;
  }
};

// Throws InputError for invalid parameters/inputs (message names the parameter or port), Error or
// InputError from the module itself, Cancelled when cancelled. Output files appear only on success.
ModuleRunResult run_module(const std::string& module, const std::map<std::string, DataPtr>& inputs,
                           const ParamMap& params = {}, const RunModuleOptions& options = {});

}  // namespace skel
