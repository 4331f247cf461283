#pragma once
// Internal: the RunContext implementation shared by the executor and run_module.
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <mutex>
#include <string>
#include <vector>

#include "skel/module.hpp"

namespace skel::detail {

// Files written by one run: temporaries (named after the run, see skel/fs.hpp) moved into place
// together when the run succeeds, removed otherwise.
class OutputFiles {
public:
  OutputFiles();
  // Registers `final_path` and returns the temporary to write it to; creates its folder.
  std::filesystem::path add(const std::filesystem::path& final_path);
  // Moves every written temporary into place as one set. A file being replaced is kept as a backup
  // until the whole set is in place; if any step fails, the files already moved are taken back
  // (previous files restored, new ones removed), the remaining temporaries are removed, and Error
  // is thrown saying which file failed and that nothing was changed. `notes` (optional) receives
  // one line per file taken back.
  void commit(std::vector<std::string>* notes = nullptr);
  void rollback();   // removes every temporary (never throws)
  [[nodiscard]] std::vector<std::filesystem::path> finals() const;
  [[nodiscard]] const std::string& run_id() const { return run_id_; }
  ~OutputFiles() { rollback(); }

private:
  mutable std::mutex mutex_;
  std::string run_id_;
  std::vector<std::pair<std::filesystem::path, std::filesystem::path>> files_;  // tmp, final
};

class NodeContext final : public RunContext {
public:
  NodeContext(const ModuleSpec& spec, std::string node_id, std::map<std::string, DataPtr> inputs,
              ParamMap params, int threads, Interrupter progress, std::filesystem::path input_base,
              std::filesystem::path output_base, OutputFiles& files,
              std::function<void(const std::string&)> on_warning);

  [[nodiscard]] DataPtr input_data(const std::string& port) const override;
  [[nodiscard]] DataPtr take_input_data(const std::string& port) override;
  // The executor hands input `port` over for in-place use (RunContext::take_input).
  void hand_over(const std::string& port) { handed_over_.insert(port); }
  [[nodiscard]] bool output_wanted(const std::string& port) const override { return !unwanted_.contains(port); }
  // The executor drops output `port` unread (RunContext::output_wanted).
  void set_unwanted(const std::string& port) { unwanted_.insert(port); }
  [[nodiscard]] const ParamValue& param_value(const std::string& name) const override;
  void output(const std::string& port, DataPtr data) override;
  using RunContext::output;
  [[nodiscard]] const Interrupter& progress() const override { return progress_; }
  [[nodiscard]] int threads() const override { return threads_; }
  [[nodiscard]] const std::string& node_id() const override { return node_id_; }
  [[nodiscard]] const ModuleSpec& spec() const override { return spec_; }
  void warn(const std::string& message) override;
  [[nodiscard]] std::filesystem::path input_path(const std::string& param_name) const override;
  [[nodiscard]] std::filesystem::path output_path(const std::string& param_name) override;
  [[nodiscard]] std::filesystem::path final_output_path(const std::string& param_name) const override;

  // Out-of-core: the blocks of a block-wise node (see RunContext::blocks()).
  void set_blocks(const BlockPlan* blocks) { blocks_ = blocks; }
  [[nodiscard]] const BlockPlan* blocks() const override { return blocks_; }

  std::map<std::string, DataPtr>& outputs() { return outputs_; }
  [[nodiscard]] const std::vector<std::string>& warnings() const { return warnings_; }
  [[nodiscard]] const std::vector<std::string>& written() const { return written_; }

private:
  const ModuleSpec& spec_;
  std::string node_id_;
  std::map<std::string, DataPtr> inputs_;
  ParamMap params_;
  int threads_;
  Interrupter progress_;
  std::filesystem::path input_base_, output_base_;
  OutputFiles& files_;
  std::function<void(const std::string&)> on_warning_;
  std::map<std::string, DataPtr> outputs_;
  std::vector<std::string> warnings_, written_;
  std::map<std::string, std::filesystem::path> tmp_paths_;
  const BlockPlan* blocks_ = nullptr;
  std::set<std::string> handed_over_, unwanted_;
};

// Resolves a (possibly relative) path against `base`.
std::filesystem::path resolve_path(const std::filesystem::path& base, const std::string& p);

}  // namespace skel::detail
