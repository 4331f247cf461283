#pragma once
// Executes a validated Pipeline: topological order, independent nodes in parallel, results cached by
// a hash of module + parameters + input identities (changing one parameter re-runs only that node and
// its dependants), intermediates freed early in headless runs, progress, cancellation, transactional
// output files, and a run report.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "skel/pipeline.hpp"

namespace skel {

enum class NodeState { Idle, Stale, Waiting, Running, Done, Cached, Error, Cancelled };
const char* to_string(NodeState s);

struct NodeStatus {
  NodeState state = NodeState::Idle;
  double progress = 0.0;   // 0..1 while running
  std::string message;     // error message or last warning
};

struct ExecOptions {
  int threads = 0;                        // total thread budget; 0 = all hardware threads
  std::filesystem::path output_dir;       // relative output paths resolve here if set; every output
                                          // must then lie inside it (validation error otherwise)
  bool allow_outside_output_dir = false;  // --allow-outside-output-dir: lifts that confinement
  bool keep_outputs = false;              // GUI: keep every output in the cache for viewing
  std::vector<std::string> targets;       // run only these and what they need; empty = all
  std::map<std::string, ParamMap> overrides;  // --set node.param=value (already typed)
  const std::atomic<bool>* cancel = nullptr;  // extra external cancel flag (signal handler)
  // Callbacks may be called from worker threads, at most ~20 times per second per node for progress.
  std::function<void(const std::string& node, const NodeStatus&)> on_status;
  std::function<void(double overall)> on_progress;
  std::function<void(const std::string& node, const std::string& message)> on_warning;
  // Run-level notes (not about one node), e.g. stale temporary files of dead runs removed.
  std::function<void(const std::string& message)> on_notice;
  // Out-of-core execution (docs/architecture.md): a memory budget in bytes (0: the pipeline's
  // `execution: memory_budget`, or none), the block shape (0: the pipeline's, else from the
  // budget) and the folder of the scratch files (empty: next to the first output file).
  uint64_t memory_budget = 0;
  Dims block{0, 0, 0};
  std::filesystem::path scratch_dir;
  // --resume: continue a run of this pipeline that was killed, from the stages it finished (their
  // volumes and tables kept in the scratch folder); refused when the pipeline, its parameters, its
  // input files, the budget or the block shape changed. Without it such leftovers are removed.
  bool resume = false;
  // Per-block resume (skel/block_journal.hpp): block-wise stages journal their finished blocks, so
  // that --resume continues a killed stage from them. false (--no-block-resume): no journal, a
  // killed stage runs again from its first block (saves the journal's writes: up to twice the
  // stage's scratch volumes of disk).
  bool block_resume = true;
  // Outputs of a node that ran (not of cached nodes), called once when it finishes; the CLI keeps
  // the small summary tables from here without keep_outputs (which would keep every volume).
  std::function<void(const std::string& node, const std::map<std::string, DataPtr>& outputs)> on_outputs;
};

struct NodeReport {
  std::string id, module;
  bool cached = false;          // result came from the cache
  double seconds = 0;           // wall time of run()
  double peak_rss_mib = 0;      // process peak RSS when the node finished
  double rss_mib = 0;           // process RSS when the node finished (0 for nodes under 10 ms)
  // Process CPU time (user + system, every thread) while the node ran: its own work, plus that of
  // the nodes running beside it. Less sensitive than `seconds` to a machine shared with other work.
  double cpu_seconds = 0;
  std::map<std::string, uint64_t> output_bytes;
  std::map<std::string, std::string> output_units;  // physical unit per output port that has one
  std::vector<std::string> outputs_written;  // final file paths
  std::vector<std::string> warnings;
};

// One rank of a run on several processes (skelflow-mpi; skel/distributed.hpp).
struct RankReport {
  int rank = 0;
  bool ok = true;
  double seconds = 0;          // wall time of its run
  double seconds_blocks = 0;   // computing its share of the distributed block loops
  double seconds_waiting = 0;  // inside collectives (waiting for other ranks, transfers)
  int64_t blocks = 0;          // blocks it computed in distributed loops
  int64_t collectives = 0;
  uint64_t bytes_sent = 0, bytes_received = 0;  // by its collectives
  double seconds_io = 0;                        // reading and writing shared scratch volumes
  uint64_t bytes_read = 0, bytes_written = 0;   // by those reads and writes
};

struct RunReport {
  std::string pipeline;
  bool ok = false;
  std::string error;            // first error, if any
  double seconds = 0;
  double peak_rss_mib = 0;
  int threads = 0;
  std::vector<NodeReport> nodes;  // in completion order
  // What the run did besides its nodes: stale temporaries removed before it ran, outputs taken back
  // when moving them into place failed.
  std::vector<std::string> notes;
  std::vector<RankReport> ranks;  // several processes only (skelflow-mpi): one per rank
  [[nodiscard]] std::string to_json() const;
};

// What a run will do, decided before anything runs (Executor::plan, and the first phase of run).
struct PlannedNode {
  std::string id, module;
  uint64_t cache_key = 0;         // module + effective parameters + the upstream nodes' keys
  bool cached = false;            // the cache holds its results (and its files exist): it will not run
  std::vector<size_t> inputs_from;  // indices (in ExecutionPlan::nodes) of the nodes it reads from
  std::vector<size_t> users;        // indices of the nodes reading its outputs
  bool blockwise = false;           // runs block by block (a memory budget and a block-wise module)
};

// An output file a planned node will write: a Path parameter with PathRole::Output that is set.
struct PlannedOutput {
  std::string node, param;
  std::filesystem::path path;  // final path, resolved against ExecutionPlan::output_base
};

struct ExecutionPlan {
  Pipeline pipeline;               // the pipeline that runs: overrides applied, validated
  std::vector<PlannedNode> nodes;  // what the targets need (all nodes if none), in topological order
  int threads = 0;                 // thread budget
  std::filesystem::path input_base, output_base;  // relative input / output paths resolve here
  std::vector<PlannedOutput> outputs;              // the files the planned nodes write, in node order
  uint64_t memory_budget = 0;      // bytes; 0: everything in memory
  Dims block{0, 0, 0};             // block shape given by the user; 0: from the budget per node
  std::filesystem::path scratch_dir;  // where on-disk volumes go (set when memory_budget > 0)
  // Index in `nodes`, or -1.
  [[nodiscard]] int64_t index_of(const std::string& id) const;
};

class Executor {
public:
  explicit Executor(const Registry& registry = Registry::instance());
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  // Validates, then runs. Throws InputError (invalid pipeline/input: nothing ran, or a node found
  // its input wrong), Error (a node failed, or moving the outputs into place failed), Cancelled.
  // Before any node runs, every output's folder must be creatable and writable and no output may
  // be an existing folder (InputError at the node's parameter otherwise), and stale temporaries of
  // dead runs are removed from the output folders (reported through on_notice and report notes).
  // A node's error reads "file:line:col: node 'id' (module): ..." (no position for nodes built in
  // code) and Error::site() holds the node.
  // Output files are moved into place as one set only when the whole run succeeds; otherwise none
  // is left, and a failure while moving them takes back the ones already moved.
  // The report is filled in every case (see last_report; its `error` is the message thrown).
  RunReport run(const Pipeline& pipeline, const ExecOptions& options = {});
  // The first phase of run() on its own: applies the overrides, validates (throws as run() does),
  // orders what the targets need and marks what the cache already holds. Runs nothing.
  [[nodiscard]] ExecutionPlan plan(const Pipeline& pipeline, const ExecOptions& options = {}) const;
  // Requests cancellation of the current run (thread-safe; the run stops within about a second).
  void cancel();

  // Cached output of a node for the current parameters (nullptr if not computed or stale).
  [[nodiscard]] DataPtr output(const Pipeline& pipeline, const std::string& node, const std::string& port) const;
  // Nodes whose results are in the cache for the current parameters and inputs.
  [[nodiscard]] std::set<std::string> up_to_date(const Pipeline& pipeline) const;
  [[nodiscard]] RunReport last_report() const;
  // How many times run() was called on a module (tests: proves caching).
  [[nodiscard]] int64_t modules_run() const { return modules_run_.load(); }
  void clear_cache();

private:
  struct Impl;
  class Scheduler;  // one run's state: ready nodes, results, first error, output files
  std::unique_ptr<Impl> impl_;
  std::atomic<int64_t> modules_run_{0};
};

// Peak resident set size of this process (MiB) and current RSS.
double peak_rss_mib();
double current_rss_mib();

}  // namespace skel
