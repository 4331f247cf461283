#pragma once
// Pipeline graph model: nodes (module + parameters), connections (input port <- node.port), the
// YAML format version 1 (load/save, canonical and lossless), and validation that reports every
// problem with the node, port or parameter and the YAML line:column before any work starts.
//
//   skelflow: 1
//   nodes:
//     phantom: {module: synthetic.network, params: {shape: rods, size: [128, 128, 128]}}
//     seg:     {module: segmentation.threshold, inputs: {image: phantom.image}, params: {low: 0.5}}
//   execution: {memory_budget: 2GiB}   # optional; out-of-core execution (docs/architecture.md)
//   gui: {}   # optional; preserved untouched
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <tuple>
#include <set>
#include <string>
#include <vector>

#include "skel/module.hpp"

namespace skel {

struct SourcePos {
  int line = 0, column = 0;  // 1-based; 0 = unknown (node built in code or in the GUI)
  [[nodiscard]] bool known() const { return line > 0; }
};

// "node.port"
struct PortRef {
  std::string node, port;
  [[nodiscard]] std::string str() const { return node + "." + port; }
  bool operator==(const PortRef&) const = default;
  bool operator<(const PortRef& o) const { return std::tie(node, port) < std::tie(o.node, o.port); }
};
// Parses "node.port" (the port is after the last '.'); nullopt if malformed.
std::optional<PortRef> parse_port_ref(const std::string& text);

struct PipelineNode {
  std::string id;
  std::string module;
  ParamMap params;                          // explicitly set parameters only (defaults are not stored)
  std::map<std::string, PortRef> inputs;    // input port -> upstream output
  // Where things were in the YAML file (for messages).
  SourcePos pos, module_pos;
  std::map<std::string, SourcePos> param_pos, input_pos;
  // Parameters set outside the file, with where they came from (e.g. "--set seg.low=0.5"): their
  // messages name that origin instead of a file position that holds another value.
  std::map<std::string, std::string> param_origin;
};

// The optional `execution:` section of a pipeline file: how it runs, not what it computes.
//   execution: {memory_budget: 2GiB, block: [64, 64, 32]}
struct ExecutionSettings {
  uint64_t memory_budget = 0;      // bytes; 0: no budget, every stage runs in memory
  std::string memory_budget_text;  // as written ("2GiB"), kept for saving
  Dims block{0, 0, 0};             // block shape (x, y, z); 0: chosen from the budget
  SourcePos memory_budget_pos, block_pos;
  [[nodiscard]] bool empty() const { return memory_budget == 0 && block == Dims{0, 0, 0}; }
  bool operator==(const ExecutionSettings& o) const { return memory_budget == o.memory_budget && block == o.block; }
};

struct Diagnostic {
  std::string file;     // pipeline file or empty
  SourcePos pos;
  std::string node;     // node id or empty
  std::string message;  // e.g. "param 'sigma': value -1 is out of range [0, inf]"
  // "file:line:col: node 'x': message"
  [[nodiscard]] std::string format() const;
};

class Pipeline {
public:
  Pipeline() = default;

  // Loading: YAML syntax errors and structural errors (not a mapping, bad node.port syntax, unknown
  // or duplicate keys, a second YAML document, nesting deeper than kMaxYamlDepth, wrong format
  // version) throw InputError with file:line:column; load_file() refuses what is not a regular file
  // or is larger than kMaxPipelineFileBytes before reading it. Semantic problems
  // (unknown module, bad params, ...) are left to validate().
  static Pipeline load_file(const std::filesystem::path& path);
  static Pipeline parse(const std::string& yaml_text, const std::string& file_name = "<string>",
                        const std::filesystem::path& base_dir = ".");
  // Canonical YAML: nodes in order, flow-style params, parameter values formatted by their spec
  // types, the `gui:` section preserved as loaded (or as set by set_gui_yaml).
  [[nodiscard]] std::string to_yaml() const;
  void save(const std::filesystem::path& path);  // atomic write; updates file() and base_dir()

  [[nodiscard]] const std::vector<PipelineNode>& nodes() const { return nodes_; }
  [[nodiscard]] const PipelineNode* find(const std::string& id) const;
  [[nodiscard]] PipelineNode* find(const std::string& id);
  // Editing (GUI, tests). Throws InputError on a duplicate or unknown id.
  PipelineNode& add_node(const std::string& id, const std::string& module);
  void remove_node(const std::string& id);  // also removes connections from it
  void rename_node(const std::string& id, const std::string& new_id);  // updates connections
  void set_param(const std::string& node, const std::string& param, ParamValue value);
  void reset_param(const std::string& node, const std::string& param);  // back to the default
  // Connects `to_node.to_port` <- `from`. Returns an empty string on success, otherwise the reason
  // (unknown node/port, type mismatch, would create a cycle) and changes nothing.
  std::string connect(const PortRef& from, const std::string& to_node, const std::string& to_port,
                      const Registry& registry = Registry::instance());
  void disconnect(const std::string& to_node, const std::string& to_port);
  // A node id not used yet, e.g. "threshold2".
  [[nodiscard]] std::string unique_id(const std::string& stem) const;

  // The opaque `gui:` section as YAML text (node positions etc.); empty if none.
  [[nodiscard]] const std::string& gui_yaml() const { return gui_yaml_; }
  void set_gui_yaml(std::string yaml) { gui_yaml_ = std::move(yaml); }

  // The `execution:` section (empty when the file has none).
  [[nodiscard]] const ExecutionSettings& execution() const { return execution_; }
  void set_execution(ExecutionSettings e) { execution_ = std::move(e); }

  [[nodiscard]] const std::string& file() const { return file_; }
  // Folder relative paths resolve against (the pipeline file's folder).
  [[nodiscard]] const std::filesystem::path& base_dir() const { return base_dir_; }
  void set_base_dir(std::filesystem::path d) { base_dir_ = std::move(d); }

  // Nodes `targets` depend on (including them), or all when empty.
  [[nodiscard]] std::set<std::string> upstream_closure(const std::vector<std::string>& targets) const;
  // Topological order of all nodes (stable: file order among independent nodes). Throws InputError
  // naming the nodes on a cycle.
  [[nodiscard]] std::vector<std::string> topological_order() const;

  bool operator==(const Pipeline& o) const;  // same nodes, params, connections and gui section

private:
  std::vector<PipelineNode> nodes_;
  std::string gui_yaml_;
  ExecutionSettings execution_;
  std::string file_ = "<pipeline>";
  std::filesystem::path base_dir_ = ".";
};

// " (did you mean 'x'?)" for the candidate closest to `name` (edit distance 1 or 2); "" if none is.
std::string did_you_mean(const std::string& name, const std::vector<std::string>& candidates);

// Parses a value written as YAML text ("0.5", "true", "rods", "[128, 128, 64]"), as `--set` and the
// GUI need; throws InputError on malformed text.
ParamValue parse_param_text(const std::string& text);

// Converts `v` to the declared type of `spec` where that is lossless (int -> float, int list ->
// float list); returns nullopt if it cannot.
std::optional<ParamValue> coerce_param(const ParamSpec& spec, const ParamValue& v);

// Where a run's files go, for the file checks of validate().
struct PathPolicy {
  // Relative output paths resolve here; empty = the pipeline's folder (base_dir()). When set (the
  // `--output-dir` of a run), every output must resolve inside it, symbolic links of existing
  // folders followed, unless `allow_outside` (`--allow-outside-output-dir`).
  std::filesystem::path output_dir;
  bool allow_outside = false;
};

// All problems of `p` against the registry: unknown module, unknown/mistyped parameter, value out of
// range, unknown port, port type mismatch, missing required input, dangling connection, cycles (the
// nodes on one cycle), and the files: an input file that does not exist, an output file whose
// extension its writer does not accept, two outputs resolving to one file (symbolic links of the
// existing folders followed), an output outside `paths.output_dir`. Duplicate ids and YAML errors
// are caught when loading.
std::vector<Diagnostic> validate(const Pipeline& p, const Registry& registry = Registry::instance(),
                                 const PathPolicy& paths = {});
// Throws InputError with all diagnostics (one per line) if validate() finds any.
void validate_or_throw(const Pipeline& p, const Registry& registry = Registry::instance(),
                       const PathPolicy& paths = {});

// The largest pipeline file load_file() reads, and the deepest nesting of mappings and lists.
inline constexpr uintmax_t kMaxPipelineFileBytes = 64ull << 20;
inline constexpr int kMaxYamlDepth = 64;

// Parameters of `node` with defaults applied and values coerced to their declared types.
ParamMap effective_params(const PipelineNode& node, const ModuleSpec& spec);

}  // namespace skel
