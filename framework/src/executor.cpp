#include "skel/executor.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <optional>
#include <fstream>
#include <sstream>
#include <thread>
#include <unordered_map>

#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "context.hpp"
#include "resume.hpp"
#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"
#include "skel/fs.hpp"
#include "skel/out_of_core.hpp"
#include "skel/parallel.hpp"
#include "skel/resume_io.hpp"
#include "skel/text.hpp"

namespace fs = std::filesystem;

namespace skel {

const char* to_string(NodeState s) {
  switch (s) {
    case NodeState::Idle: return "idle";
    case NodeState::Stale: return "stale";
    case NodeState::Waiting: return "waiting";
    case NodeState::Running: return "running";
    case NodeState::Done: return "done";
    case NodeState::Cached: return "cached";
    case NodeState::Error: return "error";
    case NodeState::Cancelled: return "cancelled";
  }
  return "?";
}

namespace {
double read_status_kib(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string line;
  const size_t n = std::char_traits<char>::length(key);
  while (std::getline(f, line)) {
    if (line.compare(0, n, key) == 0) return std::atof(line.c_str() + n);
  }
  return 0.0;
}

std::string json_escape(const std::string& s) {
  std::string r;
  for (char c : s) {
    switch (c) {
      case '"': r += "\\\""; break;
      case '\\': r += "\\\\"; break;
      case '\n': r += "\\n"; break;
      case '\t': r += "\\t"; break;
      case '\r': r += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          r += buf;
        } else {
          r += c;
        }
    }
  }
  return r;
}

std::string num(double d) { return text::format_double(d, 6); }

// FNV-1a 64-bit.
uint64_t fnv1a(const std::string& s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}
}  // namespace

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}
double current_rss_mib() { return read_status_kib("VmRSS:") / 1024.0; }

namespace {
double process_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  return s(u.ru_utime) + s(u.ru_stime);
}
}  // namespace

std::string RunReport::to_json() const {
  std::ostringstream o;
  o << "{\n  \"pipeline\": \"" << json_escape(pipeline) << "\",\n  \"ok\": " << (ok ? "true" : "false")
    << ",\n  \"error\": \"" << json_escape(error) << "\",\n  \"seconds\": " << num(seconds)
    << ",\n  \"peak_rss_mib\": " << num(peak_rss_mib) << ",\n  \"threads\": " << threads << ",\n  \"nodes\": [";
  for (size_t i = 0; i < nodes.size(); ++i) {
    const auto& n = nodes[i];
    o << (i ? ",\n" : "\n") << "    {\"id\": \"" << json_escape(n.id) << "\", \"module\": \"" << json_escape(n.module)
      << "\", \"cached\": " << (n.cached ? "true" : "false") << ", \"seconds\": " << num(n.seconds)
      << ", \"cpu_seconds\": " << num(n.cpu_seconds) << ", \"peak_rss_mib\": " << num(n.peak_rss_mib)
      << ", \"rss_mib\": " << num(n.rss_mib) << ", \"output_bytes\": {";
    size_t k = 0;
    for (const auto& [port, b] : n.output_bytes)
      o << (k++ ? ", " : "") << "\"" << json_escape(port) << "\": " << b;
    o << "}, \"units\": {";
    k = 0;
    for (const auto& [port, u] : n.output_units)
      o << (k++ ? ", " : "") << "\"" << json_escape(port) << "\": \"" << json_escape(u) << "\"";
    o << "}, \"files\": [";
    for (size_t j = 0; j < n.outputs_written.size(); ++j)
      o << (j ? ", " : "") << "\"" << json_escape(n.outputs_written[j]) << "\"";
    o << "], \"warnings\": [";
    for (size_t j = 0; j < n.warnings.size(); ++j)
      o << (j ? ", " : "") << "\"" << json_escape(n.warnings[j]) << "\"";
    o << "]}";
  }
  o << "\n  ]";
  if (!ranks.empty()) {
    // skelflow-mpi: per rank its wall time, its time in distributed block loops and in collectives
    // (idle share = waiting / seconds), the bytes its collectives moved, and its time and bytes
    // reading and writing shared scratch volumes.
    o << ",\n  \"ranks\": [";
    for (size_t i = 0; i < ranks.size(); ++i) {
      const auto& r = ranks[i];
      o << (i ? ",\n" : "\n") << "    {\"rank\": " << r.rank << ", \"ok\": " << (r.ok ? "true" : "false")
        << ", \"seconds\": " << num(r.seconds) << ", \"seconds_blocks\": " << num(r.seconds_blocks)
        << ", \"seconds_waiting\": " << num(r.seconds_waiting)
        << ", \"idle_share\": " << num(r.seconds > 0 ? r.seconds_waiting / r.seconds : 0.0) << ", \"blocks\": " << r.blocks
        << ", \"collectives\": " << r.collectives << ", \"bytes_sent\": " << r.bytes_sent
        << ", \"bytes_received\": " << r.bytes_received << ", \"seconds_io\": " << num(r.seconds_io)
        << ", \"bytes_read\": " << r.bytes_read << ", \"bytes_written\": " << r.bytes_written << "}";
    }
    o << "\n  ]";
  }
  o << ",\n  \"notes\": [";
  for (size_t j = 0; j < notes.size(); ++j) o << (j ? ", " : "") << "\"" << json_escape(notes[j]) << "\"";
  o << "]\n}\n";
  return o.str();
}

// ---------------------------------------------------------------- Executor
struct Executor::Impl {
  const Registry& registry;
  std::atomic<bool> cancel{false};
  mutable std::mutex cache_mutex;
  struct CacheEntry {
    std::map<std::string, DataPtr> outputs;
    std::vector<std::string> files;  // final paths written by this node
  };
  std::map<uint64_t, CacheEntry> cache;
  RunReport last;
  std::mutex run_mutex;  // one run at a time

  explicit Impl(const Registry& r) : registry(r) {}

  ExecutionPlan make_plan(const Pipeline& pipeline, const ExecOptions& options) const;
  std::vector<std::map<std::string, DataPtr>> lookup_cache(ExecutionPlan& plan) const;
  // Out-of-core runs: the resume folder (`dir`) and its manifest; with --resume, the finished stages
  // of a killed run loaded into `results` and marked cached (and the stages only they needed). Adds
  // notes; throws InputError when --resume cannot continue (saying why).
  detail::ResumeManifest prepare_resume(ExecutionPlan& plan, const ExecOptions& opt,
                                        std::vector<std::map<std::string, DataPtr>>& results,
                                        std::vector<std::string>& notes, fs::path& dir) const;

  // Cache keys of every node (module + effective params + upstream keys), in topological order.
  std::map<std::string, uint64_t> keys(const Pipeline& p, const std::vector<std::string>& order,
                                       const std::map<std::string, ParamMap>* overrides) const {
    std::map<std::string, uint64_t> k;
    std::unordered_map<std::string, const PipelineNode*> by_id;
    for (const auto& n : p.nodes()) by_id[n.id] = &n;
    for (const auto& id : order) {
      const PipelineNode* n = by_id.at(id);
      const ModuleSpec* spec = registry.find(n->module);
      std::string s = n->module + "\n";
      if (spec) {
        ParamMap eff = effective_params(*n, *spec);
        if (overrides)
          if (auto it = overrides->find(id); it != overrides->end())
            for (const auto& [name, v] : it->second) {
              const ParamSpec* ps = spec->find_param(name);
              if (ps) eff[ps->name] = coerce_param(*ps, v).value_or(v);
            }
        for (const auto& [name, v] : eff) s += name + "=" + std::to_string(v.index()) + ":" + format_value(v) + "\n";
        // Paths resolve against the pipeline folder: the same relative path in another folder differs.
        for (const auto& ps : spec->params())
          if (ps.type == ParamType::Path) s += "base=" + p.base_dir().string() + "\n";
      }
      for (const auto& [port, ref] : n->inputs) {
        auto it = k.find(ref.node);
        s += "in " + port + "<-" + std::to_string(it == k.end() ? 0 : it->second) + "." + ref.port + "\n";
      }
      k[id] = fnv1a(s);
    }
    return k;
  }
};

Executor::Executor(const Registry& registry) : impl_(std::make_unique<Impl>(registry)) {}
Executor::~Executor() = default;

void Executor::cancel() { impl_->cancel.store(true); }

void Executor::clear_cache() {
  std::lock_guard lock(impl_->cache_mutex);
  impl_->cache.clear();
}

RunReport Executor::last_report() const {
  std::lock_guard lock(impl_->cache_mutex);
  return impl_->last;
}

namespace {
// Cache keys of the pipeline as it is now; empty when it has a cycle.
template <class Impl>
std::map<std::string, uint64_t> current_keys(const Impl& im, const Pipeline& p) {
  try {
    return im.keys(p, p.topological_order(), nullptr);
  } catch (const Error&) {
    return {};
  }
}
}  // namespace

DataPtr Executor::output(const Pipeline& p, const std::string& node, const std::string& port) const {
  auto k = current_keys(*impl_, p);
  auto it = k.find(node);
  if (it == k.end()) return nullptr;
  std::lock_guard lock(impl_->cache_mutex);
  auto c = impl_->cache.find(it->second);
  if (c == impl_->cache.end()) return nullptr;
  auto o = c->second.outputs.find(port);
  return o == c->second.outputs.end() ? nullptr : o->second;
}

std::set<std::string> Executor::up_to_date(const Pipeline& p) const {
  std::set<std::string> r;
  auto k = current_keys(*impl_, p);
  std::lock_guard lock(impl_->cache_mutex);
  for (const auto& [id, key] : k)
    if (impl_->cache.count(key)) r.insert(id);
  return r;
}

int64_t ExecutionPlan::index_of(const std::string& id) const {
  for (size_t i = 0; i < nodes.size(); ++i)
    if (nodes[i].id == id) return static_cast<int64_t>(i);
  return -1;
}

namespace {

std::vector<std::string> node_ids(const Pipeline& p) {
  std::vector<std::string> ids;
  for (const auto& n : p.nodes()) ids.push_back(n.id);
  return ids;
}

// Applies `--set` overrides to `p`, remembering where each value came from so that validation
// reports a bad one as "--set node.param=value: ..." rather than at the file's own value.
void apply_overrides(Pipeline& p, const std::map<std::string, ParamMap>& overrides) {
  for (const auto& [node, params] : overrides) {
    PipelineNode* n = p.find(node);
    if (!n) {
      const std::string first = params.empty() ? std::string() : "." + params.begin()->first + "=" +
                                                                       format_value(params.begin()->second);
      throw InputError("--set " + node + first + ": no node '" + node + "' in " + p.file() +
                       did_you_mean(node, node_ids(p)));
    }
    for (const auto& [name, v] : params) {
      p.set_param(node, name, v);
      n->param_origin[name] = "--set " + node + "." + name + "=" + format_value(v);
    }
  }
}

}  // namespace

// ---------------------------------------------------------------- phase 1: plan
ExecutionPlan Executor::plan(const Pipeline& pipeline, const ExecOptions& options) const {
  ExecutionPlan plan = impl_->make_plan(pipeline, options);
  (void)impl_->lookup_cache(plan);
  return plan;
}

ExecutionPlan Executor::Impl::make_plan(const Pipeline& pipeline_in, const ExecOptions& opt) const {
  const Impl& im = *this;
  // Apply overrides to a copy, then validate everything before any work.
  ExecutionPlan plan;
  plan.pipeline = pipeline_in;
  Pipeline& p = plan.pipeline;
  apply_overrides(p, opt.overrides);
  for (const auto& t : opt.targets)
    if (!p.find(t)) throw InputError("no node '" + t + "' in " + p.file() + did_you_mean(t, node_ids(p)));
  validate_or_throw(p, im.registry, PathPolicy{opt.output_dir, opt.allow_outside_output_dir});
  const std::vector<std::string> order_all = p.topological_order();
  const std::set<std::string> wanted = p.upstream_closure(opt.targets);
  const auto keys = im.keys(p, order_all, nullptr);
  for (const auto& id : order_all) {
    if (!wanted.count(id)) continue;
    PlannedNode pn;
    pn.id = id;
    pn.module = p.find(id)->module;
    pn.cache_key = keys.at(id);
    plan.nodes.push_back(std::move(pn));
  }
  plan.threads = effective_threads(opt.threads);
  plan.input_base = p.base_dir();
  plan.output_base = opt.output_dir.empty() ? p.base_dir() : fs::absolute(opt.output_dir);
  for (const auto& pn : plan.nodes) {
    const PipelineNode& node = *p.find(pn.id);
    const ModuleSpec& spec = *im.registry.find(node.module);
    const ParamMap eff = effective_params(node, spec);
    for (const auto& ps : spec.params()) {
      if (ps.type != ParamType::Path || ps.path_role != PathRole::Output) continue;
      auto it = eff.find(ps.name);
      const auto* value = it == eff.end() ? nullptr : std::get_if<std::string>(&it->second);
      if (value && !value->empty())
        plan.outputs.push_back({pn.id, ps.name, detail::resolve_path(plan.output_base, *value)});
    }
  }

  // Out-of-core: the budget from the command line, else from the pipeline's `execution:` section.
  const ExecutionSettings& es = p.execution();
  plan.memory_budget = opt.memory_budget > 0 ? opt.memory_budget : es.memory_budget;
  plan.block = opt.block != Dims{0, 0, 0} ? opt.block : es.block;
  if (plan.memory_budget > 0) {
    if (!opt.scratch_dir.empty()) plan.scratch_dir = fs::absolute(opt.scratch_dir);
    else if (!plan.outputs.empty() && !plan.outputs.front().path.parent_path().empty())
      plan.scratch_dir = plan.outputs.front().path.parent_path();
    else plan.scratch_dir = plan.output_base.empty() ? fs::path(".") : plan.output_base;
    for (auto& pn : plan.nodes) pn.blockwise = im.registry.find(pn.module)->block_support().blockwise;
  }

  // Dependencies: each distinct upstream node once.
  std::unordered_map<std::string, size_t> idx;
  for (size_t i = 0; i < plan.nodes.size(); ++i) idx[plan.nodes[i].id] = i;
  for (size_t i = 0; i < plan.nodes.size(); ++i) {
    std::set<size_t> deps;
    for (const auto& [port, ref] : p.find(plan.nodes[i].id)->inputs) deps.insert(idx.at(ref.node));
    for (size_t d : deps) {
      plan.nodes[d].users.push_back(i);
      plan.nodes[i].inputs_from.push_back(d);
    }
  }
  return plan;
}

// ---------------------------------------------------------------- phase 1b: output folders
namespace {

// Why `out` cannot be written, or "" when it can: the nearest existing folder above it is not
// writable (or is a file). An output that is itself a folder is refused by validate(), which runs
// before this.
std::string output_problem(const fs::path& out) {
  std::error_code ec;
  fs::path dir = out.parent_path();
  if (dir.empty()) dir = ".";
  fs::path existing = dir;
  while (!fs::exists(existing, ec) && existing.has_parent_path() && existing != existing.parent_path())
    existing = existing.parent_path();
  if (!fs::is_directory(existing, ec)) {
    if (existing == dir) return "cannot write into " + dir.string() + ": it is a file, not a folder";
    return "cannot create folder " + dir.string() + ": " + existing.string() + " is a file, not a folder";
  }
  if (::access(existing.c_str(), W_OK | X_OK) != 0) {
    const int err = errno;
    return "cannot write into folder " + existing.string() + ": " + std::strerror(err);
  }
  return {};
}

// Every output must be writable before anything runs: a user-caused problem found before any work
// is an input error (exit code 2), the same for every writer.
void check_outputs(const ExecutionPlan& plan) {
  for (const auto& o : plan.outputs) {
    const std::string why = output_problem(o.path);
    if (why.empty()) continue;
    const PipelineNode& n = *plan.pipeline.find(o.node);
    auto at = n.param_pos.find(o.param);
    const SourcePos pos = at != n.param_pos.end() && at->second.known() ? at->second : n.pos;
    std::string where = "parameter '" + o.param + "'";
    if (auto origin = n.param_origin.find(o.param); origin != n.param_origin.end()) where = origin->second + ": " + where;
    throw InputError(ErrorSite{plan.pipeline.file(), pos.line, pos.column, n.id, n.module, where + ": " + why});
  }
  if (plan.memory_budget > 0) {
    const std::string why = output_problem(plan.scratch_dir / "scratch.h5");
    if (!why.empty()) throw InputError("scratch folder " + plan.scratch_dir.string() + " (--scratch): " + why);
  }
}

// Removes the temporaries that dead runs left in the output folders; returns one note or none.
std::vector<std::string> remove_stale_outputs(const ExecutionPlan& plan) {
  std::set<fs::path> folders;
  for (const auto& o : plan.outputs) folders.insert(o.path.parent_path().empty() ? fs::path(".") : o.path.parent_path());
  if (plan.memory_budget > 0 && fs::is_directory(plan.scratch_dir)) folders.insert(plan.scratch_dir);
  std::vector<std::string> done;
  for (const auto& f : folders)
    for (auto& d : remove_stale_temps(f)) done.push_back(std::move(d));
  if (done.empty()) return {};
  std::string note = "cleaned up after " + std::string(done.size() == 1 ? "a run" : "runs") +
                     " that did not finish (" + std::to_string(done.size()) + " file" + (done.size() == 1 ? "" : "s") + "): ";
  for (size_t i = 0; i < done.size(); ++i) note += (i ? "; " : "") + done[i];
  return {note};
}

}  // namespace

// ---------------------------------------------------------------- phase 2: cache lookup
// Marks the planned nodes whose results are cached (and whose output files still exist) and returns
// those results (empty maps for the others).
std::vector<std::map<std::string, DataPtr>> Executor::Impl::lookup_cache(ExecutionPlan& plan) const {
  std::vector<std::map<std::string, DataPtr>> results(plan.nodes.size());
  std::lock_guard lock(cache_mutex);
  for (size_t i = 0; i < plan.nodes.size(); ++i) {
    PlannedNode& n = plan.nodes[i];
    n.cached = false;
    auto c = cache.find(n.cache_key);
    if (c == cache.end()) continue;
    bool files_ok = std::all_of(c->second.files.begin(), c->second.files.end(),
                                [](const std::string& f) { return fs::exists(f); });
    if (!files_ok) continue;
    n.cached = true;
    results[i] = c->second.outputs;
  }
  return results;
}

// ---------------------------------------------------------------- phase 2b: resume state
namespace {
std::string hex8(uint64_t v) {
  char b[24];
  std::snprintf(b, sizeof b, "%08llx", static_cast<unsigned long long>(v & 0xffffffffull));
  return b;
}
// Several ranks: every rank's error (empty: none); the first in rank order is thrown on every rank.
// One process: its own.
void agree_on_error(const std::string& error) {
  if (communicator().size() == 1) {
    if (!error.empty()) throw InputError(error);
    return;
  }
  const std::vector<std::string> all = exchange(error);
  for (size_t r = 0; r < all.size(); ++r)
    if (!all[r].empty()) throw InputError(r == 0 ? all[r] : "rank " + std::to_string(r) + ": " + all[r]);
}
std::string budget_text(uint64_t budget, const Dims& block) {
  return format_byte_size(budget) + ", " +
         (block == Dims{0, 0, 0} ? std::string("blocks from the budget")
                                 : "blocks " + std::to_string(block[0]) + "x" + std::to_string(block[1]) + "x" +
                                       std::to_string(block[2]));
}
}  // namespace

detail::ResumeManifest Executor::Impl::prepare_resume(ExecutionPlan& plan, const ExecOptions& opt,
                                                      std::vector<std::map<std::string, DataPtr>>& results,
                                                      std::vector<std::string>& notes, fs::path& dir) const {
  dir.clear();
  if (plan.memory_budget == 0) {
    if (opt.resume)
      throw InputError("--resume: only runs under a memory budget (--memory-budget SIZE, or execution: {memory_budget: "
                       "SIZE} in the pipeline) keep what they finished");
    return {};
  }
  if (opt.keep_outputs) {  // the GUI keeps volumes in its cache; it has nothing to resume
    if (opt.resume) throw InputError("--resume: not available while outputs are kept for viewing");
    return {};
  }
  // skelflow-mpi (several ranks): one folder for the job; every rank keeps its own manifest there
  // (rank 0's is manifest.txt) and names its private files with ".rR"; the decisions below are taken
  // together (agree_on_error, kept stages ANDed over the ranks), so every rank loads the same stages
  // and runs the same ones. A run resumes only with the ranks and blocks of the run it continues.
  const int rank = communicator().rank(), ranks = communicator().size();
  const Pipeline& p = plan.pipeline;
  const std::string file = fs::absolute(p.file()).lexically_normal().string();
  std::string stem = fs::path(p.file()).stem().string();
  if (stem.empty()) stem = "pipeline";
  dir = plan.scratch_dir / (".skelflow-resume-" + stem + "-" + hex8(fnv1a(file + "\n" + plan.output_base.string())));
  const fs::path manifest_file = dir / detail::resume_manifest_name(rank, ranks);

  detail::ResumeManifest m;
  m.pid = static_cast<int64_t>(::getpid());
  m.ranks = ranks;
  std::string structure;
  for (const auto& n : p.nodes()) {
    structure += n.id + " " + n.module + "\n";
    for (const auto& [port, ref] : n.inputs) structure += "  " + port + " <- " + ref.node + "." + ref.port + "\n";
  }
  m.pipeline_hash = fnv1a(structure);
  m.keys = keys(p, p.topological_order(), nullptr);
  for (const auto& pn : plan.nodes) {
    const PipelineNode& node = *p.find(pn.id);
    const ModuleSpec& spec = *registry.find(node.module);
    const ParamMap eff = effective_params(node, spec);
    for (const auto& ps : spec.params()) {
      if (ps.type != ParamType::Path || ps.path_role != PathRole::Input) continue;
      auto it = eff.find(ps.name);
      const auto* value = it == eff.end() ? nullptr : std::get_if<std::string>(&it->second);
      if (!value || value->empty()) continue;
      const fs::path in = detail::resolve_path(plan.input_base, *value);
      m.inputs[in.string()] = detail::file_stamp(in);
    }
  }
  std::string params;
  for (const auto& [id, k] : m.keys) params += id + "=" + std::to_string(k) + "\n";
  for (const auto& [f, stamp] : m.inputs) params += f + "@" + stamp + "\n";
  m.params_hash = fnv1a(params);
  m.memory_budget = plan.memory_budget;
  m.block = plan.block;

  // Reading: every rank its own manifest; nothing is changed before every rank has read.
  std::error_code ec;
  const bool exists = broadcast_from_root(fs::exists(dir, ec) ? "1" : "0") == "1";
  const size_t n = plan.nodes.size();
  std::vector<char> kept(n, 0);
  std::optional<detail::ResumeManifest> old;
  std::string error;
  const std::string head = "--resume: cannot continue the run kept in " + dir.string() + ": ";
  const std::string tail = "; run without --resume to start over (that removes it)";
  if (exists) {
    std::string damaged;
    try {
      old = detail::parse_manifest(manifest_file);
    } catch (const Error& e) {
      damaged = e.what();
    }
    const ResumeVolumeIo* io = resume_volume_io();
    if (old && detail::other_process_alive(old->pid)) {
      error = "scratch folder " + plan.scratch_dir.string() + ": a running skelflow (pid " + std::to_string(old->pid) +
              ") keeps its resume state of this pipeline in " + dir.string() + "; wait for it to end, or give another --scratch";
    } else if (opt.resume) {
      if (!old) {
        error = head + damaged + tail;
      } else if (old->ranks != m.ranks) {
        error = head + "that run had " + std::to_string(old->ranks) + " rank(s), this one has " + std::to_string(m.ranks) +
                " (the blocks of the distributed stages are split by the number of ranks: resume with mpirun -np " +
                std::to_string(old->ranks) + (old->ranks == 1 ? ", or with skelflow" : "") + ")" + tail;
      } else if (old->pipeline_hash != m.pipeline_hash) {
        error = head + "the pipeline's nodes or connections changed since that run" + tail;
      } else if (old->memory_budget != m.memory_budget || old->block != m.block) {
        error = head + "the memory budget or block shape changed (that run: " + budget_text(old->memory_budget, old->block) +
                "; now: " + budget_text(m.memory_budget, m.block) + ")" + tail;
      } else {
        for (const auto& id : p.topological_order()) {
          auto a = old->keys.find(id);
          if (a == old->keys.end() || a->second != m.keys.at(id)) {
            error = head + "the parameters of node '" + id + "' changed since that run" + tail;
            break;
          }
        }
        for (const auto& [f, stamp] : m.inputs) {
          auto a = old->inputs.find(f);
          if (error.empty() && (a == old->inputs.end() || a->second != stamp))
            error = head + "the input file " + f + " changed since that run" + tail;
        }
        if (error.empty() && old->params_hash != m.params_hash) error = head + "the parameters changed since that run" + tail;
      }
      if (error.empty())
        for (size_t i = 0; i < n; ++i) {
          auto d = old->done.find(plan.nodes[i].id);
          if (d == old->done.end() || d->second.key != plan.nodes[i].cache_key || !io) continue;
          kept[i] = std::all_of(d->second.outputs.begin(), d->second.outputs.end(),
                                [&](const detail::ResumeOutput& o) { return fs::exists(dir / o.file, ec); });
        }
    }
  }
  agree_on_error(error);
  if (ranks > 1) {  // a stage is kept when every rank kept it
    for (const std::string& other : exchange(std::string(kept.begin(), kept.end()))) {
      if (other.size() != n) throw Error("--resume: the ranks plan different pipelines");
      for (size_t i = 0; i < n; ++i) kept[i] = static_cast<char>(kept[i] && other[i]);
    }
  }

  // Changing: loading what is kept, or removing the state of a run not continued, then this run's manifest.
  try {
    if (exists && opt.resume) {
      // Which stages run: a stage runs when it is not kept and its outputs are wanted (it ends the
      // pipeline, or a stage that runs reads them); a kept stage is loaded when they are wanted.
      const ResumeVolumeIo* io = resume_volume_io();
      std::vector<char> runs(n, 0), wanted(n, 0);
      for (size_t i = n; i-- > 0;) {
        wanted[i] = plan.nodes[i].users.empty() ||
                    std::any_of(plan.nodes[i].users.begin(), plan.nodes[i].users.end(), [&](size_t u) { return runs[u] != 0; });
        runs[i] = wanted[i] && !kept[i] && !plan.nodes[i].cached;
      }
      size_t loaded = 0;
      for (size_t i = 0; i < n; ++i) {
        if (runs[i] || plan.nodes[i].cached) continue;
        plan.nodes[i].cached = true;  // not run: loaded, or not needed by any stage that runs
        if (!kept[i] || !wanted[i]) continue;
        const auto& d = old->done.at(plan.nodes[i].id);
        for (const auto& o : d.outputs) {
          try {
            if (o.kind == "volume") results[i][o.port] = io->open(dir / o.file, o.type_id, o.grid);
            else results[i][o.port] = std::make_shared<Table>(detail::load_table(dir / o.file));
          } catch (const Error& e) {
            throw InputError(head + "the output '" + o.port + "' of node '" + plan.nodes[i].id + "' is damaged: " + e.what() + tail);
          }
        }
        m.done[plan.nodes[i].id] = d;
        ++loaded;
      }
      notes.push_back("resumed from " + dir.string() + ": " + std::to_string(loaded) + " finished stage(s) loaded, " +
                      std::to_string(std::count(runs.begin(), runs.end(), 1)) + " to run" +
                      (ranks > 1 ? " (on " + std::to_string(ranks) + " ranks)" : std::string()));
    } else if (exists) {
      if (rank == 0) fs::remove_all(dir, ec);
      notes.push_back("removed the resume state of a run of this pipeline that did not finish (" + dir.string() +
                      (old ? ", " + std::to_string(old->done.size()) + " finished stage(s)" : std::string()) +
                      "); `skelflow run --resume` continues such a run instead");
    } else if (opt.resume) {
      notes.push_back("--resume: no interrupted run of this pipeline in " + plan.scratch_dir.string() + "; running from the start");
    }
  } catch (const std::exception& e) {
    if (ranks == 1) throw;
    error = e.what();
  }
  agree_on_error(error);  // also: every rank has loaded its files, or rank 0 has removed the old folder
  try {
    fs::create_directories(dir, ec);
    write_file_atomically(manifest_file, detail::manifest_text(m));
  } catch (const std::exception& e) {
    if (ranks == 1) throw;
    error = e.what();
  }
  agree_on_error(error);
  return m;
}

// ---------------------------------------------------------------- phases 3 and 4: run nodes, schedule
// The state of one run: nodes waiting, ready, running, their results, the first error, the output
// files written so far. Worker threads share it under `m_`.
class Executor::Scheduler {
public:
  Scheduler(Impl& im, const ExecutionPlan& plan, const ExecOptions& opt,
            std::vector<std::map<std::string, DataPtr>> results, std::atomic<int64_t>& modules_run, RunReport& report)
      : im_(im), plan_(plan), opt_(opt), modules_run_(modules_run), report_(report), n_(plan.nodes.size()),
        results_(std::move(results)), progress_(n_, 0.0), state_(n_, NodeState::Waiting), pending_(n_, 0),
        consumers_(n_, 0) {
    for (size_t i = 0; i < n_; ++i) {
      node_of_.push_back(plan.pipeline.find(plan.nodes[i].id));
      idx_[plan.nodes[i].id] = i;
      pending_[i] = static_cast<int>(plan.nodes[i].inputs_from.size());
      consumers_[i] = static_cast<int>(plan.nodes[i].users.size());
    }
    for (size_t i = 0; i < n_; ++i) {
      status(i, NodeState::Waiting, 0.0, {});
      if (pending_[i] == 0) ready_.push_back(i);
    }
  }

  // Runs every node on a pool of workers; returns when all are done, or on the first error or a
  // cancellation once the running nodes have stopped.
  void run_all();
  // Phase 5: renames the output files into place and caches what ran (GUI), or removes the files
  // and rethrows the first error with its node's place in the pipeline file.
  void conclude(double seconds);

private:
  std::map<std::string, DataPtr> gather_inputs(size_t i);
  void run_module(size_t i, std::map<std::string, DataPtr> inputs, const std::set<std::string>& handed_over,
                  NodeReport& nr);
  std::set<std::string> hand_over_in_place(size_t i);
  void run_node(size_t i);
  void node_done(size_t i, NodeReport nr);
  void node_failed(size_t i);
  void release_inputs(size_t i);
  [[nodiscard]] bool output_read(size_t i, const std::string& port) const;
  [[nodiscard]] bool is_target(size_t i) const;
  // Headless runs drop an output of node i that no node reads as soon as i is done.
  [[nodiscard]] bool drops_unread_outputs(size_t i) const {
    return !opt_.keep_outputs && !plan_.nodes[i].users.empty() && !is_target(i);
  }
  void store_in_cache();
  BlockPlan block_plan(size_t i, const std::map<std::string, DataPtr>& inputs);
  std::shared_ptr<ChunkedVolume> make_scratch(size_t i, const std::string& port, const std::string& type_id,
                                              const Grid& grid, const Dims& chunk);
  void remove_scratch(bool keep_live);
  void agree_with_ranks(bool& cancelled);
  void checkpoint(size_t i, const NodeReport& nr);
  void remove_resume_dir();
  // Several ranks: ".rR", the mark of this rank's own files in the job's resume folder; else "".
  static std::string rank_suffix() {
    return communicator().size() > 1 ? ".r" + std::to_string(communicator().rank()) : std::string();
  }

  void status(size_t i, NodeState s, double prog, const std::string& msg) const {
    if (opt_.on_status) opt_.on_status(plan_.nodes[i].id, NodeStatus{s, prog, msg});
  }
  void overall() const {  // call with m_ held
    if (!opt_.on_progress || n_ == 0) return;
    double sum = 0;
    for (size_t i = 0; i < n_; ++i)
      sum += (state_[i] == NodeState::Done || state_[i] == NodeState::Cached) ? 1.0 : progress_[i];
    opt_.on_progress(sum / static_cast<double>(n_));
  }

  Impl& im_;
  const ExecutionPlan& plan_;
  const ExecOptions& opt_;
  std::atomic<int64_t>& modules_run_;
  RunReport& report_;
  const size_t n_;
  std::vector<const PipelineNode*> node_of_;
  std::unordered_map<std::string, size_t> idx_;  // node id -> index in plan_.nodes
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<size_t> ready_;
  std::vector<std::map<std::string, DataPtr>> results_;
  std::vector<double> progress_;
  std::vector<NodeState> state_;
  std::vector<int> pending_, consumers_;
  size_t finished_ = 0, running_ = 0;
  std::exception_ptr first_error_;
  int64_t first_error_node_ = -1;  // -1: none, or the error is a cancellation
  detail::OutputFiles files_;
  std::mutex scratch_m_;
  std::vector<fs::path> scratch_files_;  // every scratch file of this run (out-of-core)
  std::map<std::string, int> scratch_names_;
  // Resume state (resume.hpp): the folder holding the scratch files and the manifest; empty when
  // the run keeps none (no budget, or the GUI).
  fs::path resume_dir_;
  detail::ResumeManifest manifest_;
  std::mutex manifest_m_;
  // Per-block resume (skel/block_journal.hpp): the journal of each block-wise node while it runs.
  std::map<size_t, std::unique_ptr<BlockJournalFile>> journals_;  // guarded by scratch_m_
  BlockJournalFile* open_journal(size_t i);
  void close_journal(size_t i, bool finished);

public:
  void set_resume(fs::path dir, detail::ResumeManifest m) {
    resume_dir_ = std::move(dir);
    manifest_ = std::move(m);
  }
};

// The inputs of node i from its upstream results, checked against the port's types.
std::map<std::string, DataPtr> Executor::Scheduler::gather_inputs(size_t i) {
  const PipelineNode& node = *node_of_[i];
  const ModuleSpec& spec = *im_.registry.find(node.module);
  std::map<std::string, DataPtr> inputs;
  std::lock_guard lock(m_);
  for (const auto& [port, ref] : node.inputs) {
    const auto& r = results_[idx_.at(ref.node)];
    auto it = r.find(ref.port);
    if (it == r.end() || !it->second)
      throw InputError("input '" + port + "': node '" + ref.node + "' produced no output '" + ref.port + "'");
    const PortSpec* ip = spec.find_input(port);
    if (std::find(ip->types.begin(), ip->types.end(), it->second->type_id()) == ip->types.end())
      throw InputError("input '" + port + "': got " + it->second->type_id() + " from " + ref.str() +
                       ", but the port takes " + [&] {
                         std::string s;
                         for (const auto& t : ip->types) { if (!s.empty()) s += "|"; s += t; }
                         return s;
                       }());
    inputs[port] = it->second;
  }
  return inputs;
}

// Out-of-core: a module without block support reads its on-disk inputs into memory, unless they
// exceed the budget (an error naming the port and the sizes, before anything is loaded).
static std::map<std::string, DataPtr> load_for_in_memory_module(std::map<std::string, DataPtr> inputs, uint64_t budget,
                                                         const std::string& module) {
  uint64_t total = 0;
  for (const auto& [port, d] : inputs)
    if (auto* c = dynamic_cast<const ChunkedVolume*>(d.get())) {
      total += c->voxel_data_bytes();
      if (total > budget)
        throw InputError("input '" + port + "': the volume on disk (" + c->type_id() + " " + std::to_string(c->dims()[0]) +
                         "x" + std::to_string(c->dims()[1]) + "x" + std::to_string(c->dims()[2]) + ", " +
                         format_byte_size(c->voxel_data_bytes()) + ") does not fit the memory budget of " +
                         format_byte_size(budget) + ", and " + module +
                         " does not run block-wise; raise --memory-budget or use block-wise stages");
    }
  for (auto& [port, d] : inputs) d = materialize(d);
  return inputs;
}

// In-memory headless runs: the inputs node i may write in place (ModuleSpec::in_place). The upstream
// output is handed over (dropped from results_, so that only i's inputs hold it) when every other node
// reading that output is done (nodes reading other outputs of the same node do not matter: the
// phantom's truth graph may still be written while its image is smoothed), and nothing else may need
// it: it is no target, not kept for the GUI, not from the cache, and i reads it on no other port.
// NodeContext::take_input_data checks when the module asks that nobody else holds the data (a
// caller's reference, a node passing it through, the CLI's kept tables); without a taker the data is
// freed with i's inputs, as release_inputs would have freed it.
std::set<std::string> Executor::Scheduler::hand_over_in_place(size_t i) {
  std::set<std::string> ports;
  const PipelineNode& node = *node_of_[i];
  const ModuleSpec& spec = *im_.registry.find(node.module);
  if (spec.in_place_ports().empty() || opt_.keep_outputs || plan_.memory_budget > 0) return ports;
  std::lock_guard lock(m_);
  for (const auto& ip : spec.in_place_ports()) {
    auto it = node.inputs.find(ip.input);
    if (it == node.inputs.end()) continue;
    const PortRef& ref = it->second;
    const size_t d = idx_.at(ref.node);
    if (is_target(d) || plan_.nodes[d].cached) continue;
    const bool other_reader = std::any_of(plan_.nodes[d].users.begin(), plan_.nodes[d].users.end(), [&](size_t u) {
      if (u == i || state_[u] == NodeState::Done || state_[u] == NodeState::Cached) return false;
      return std::any_of(node_of_[u]->inputs.begin(), node_of_[u]->inputs.end(),
                         [&](const auto& in) { return in.second == ref; });
    });
    if (other_reader) continue;
    const bool read_twice = std::any_of(node.inputs.begin(), node.inputs.end(), [&](const auto& in) {
      return in.first != ip.input && in.second == ref;
    });
    if (read_twice) continue;
    results_[d].erase(ref.port);
    ports.insert(ip.input);
  }
  return ports;
}

// Calls the module's run() with progress, cancellation and warnings wired to the run.
void Executor::Scheduler::run_module(size_t i, std::map<std::string, DataPtr> inputs,
                                     const std::set<std::string>& handed_over, NodeReport& nr) {
  const PipelineNode& node = *node_of_[i];
  const ModuleSpec& spec = *im_.registry.find(node.module);
  ParamMap eff = effective_params(node, spec);
  auto last_report = std::make_shared<std::atomic<int64_t>>(0);
  Interrupter intr(
      [this, i, last_report](double f) {
        const int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                                std::chrono::steady_clock::now().time_since_epoch()).count();
        int64_t prev = last_report->load();
        if (now - prev < 50 && f < 1.0) return;
        last_report->store(now);
        std::lock_guard lock(m_);
        progress_[i] = f;
        status(i, NodeState::Running, f, {});
        overall();
      },
      &im_.cancel, [this, i](const std::string& text) {
        std::lock_guard lock(m_);
        status(i, NodeState::Running, progress_[i], text);
      });
  BlockPlan blocks;
  if (plan_.nodes[i].blockwise) blocks = block_plan(i, inputs);
  detail::NodeContext ctx(spec, node.id, std::move(inputs), std::move(eff), plan_.threads, intr, plan_.input_base,
                          plan_.output_base, files_, [this, i](const std::string& w) {
                            if (opt_.on_warning) opt_.on_warning(plan_.nodes[i].id, w);
                          });
  if (plan_.nodes[i].blockwise) ctx.set_blocks(&blocks);
  for (const std::string& port : handed_over) ctx.hand_over(port);
  if (drops_unread_outputs(i))
    for (const PortSpec& out : spec.outputs())
      if (!output_read(i, out.name)) ctx.set_unwanted(out.name);
  status(i, NodeState::Running, 0.0, {});
  auto mod = im_.registry.create(node.module);
  ++modules_run_;
  {
    const ScopedBlockJournal journal(plan_.nodes[i].blockwise && !resume_dir_.empty() && opt_.block_resume ? open_journal(i)
                                                                                                         : nullptr);
    mod->run(ctx);
  }
  intr.check();
  std::lock_guard lock(m_);
  results_[i] = std::move(ctx.outputs());
  if (opt_.on_outputs) opt_.on_outputs(node.id, results_[i]);
  nr.warnings = ctx.warnings();
  nr.outputs_written = ctx.written();
}

void Executor::Scheduler::run_node(size_t i) {
  const PipelineNode& node = *node_of_[i];
  NodeReport nr;
  nr.id = node.id;
  nr.module = node.module;
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_seconds();
  try {
    if (plan_.nodes[i].cached) {
      nr.cached = true;
    } else {
      auto inputs = gather_inputs(i);
      if (plan_.memory_budget > 0 && !plan_.nodes[i].blockwise)
        inputs = load_for_in_memory_module(std::move(inputs), plan_.memory_budget, node.module);
      const std::set<std::string> handed_over = hand_over_in_place(i);
      run_module(i, std::move(inputs), handed_over, nr);
      if (!resume_dir_.empty()) checkpoint(i, nr);
      close_journal(i, true);
    }
    nr.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    nr.cpu_seconds = process_cpu_seconds() - cpu0;
    nr.peak_rss_mib = peak_rss_mib();
    // Reading /proc costs ~10 µs: skip it for nodes too short to change the resident set much.
    if (nr.seconds > 0.01) nr.rss_mib = current_rss_mib();
    node_done(i, std::move(nr));
  } catch (...) {
    node_failed(i);
  }
}

// Records a finished node and makes its users ready.
void Executor::Scheduler::node_done(size_t i, NodeReport nr) {
  std::lock_guard lock(m_);
  for (const auto& [port, d] : results_[i])
    if (d) {
      nr.output_bytes[port] = d->bytes();
      if (auto u = d->physical_unit(); !u.empty()) nr.output_units[port] = std::move(u);
    }
  // Headless: an output that no node reads is dropped now, not when the node's other outputs are
  // released (an unread label volume of connected_components would otherwise stay, in memory or as a
  // scratch file, until its mask had been read by every user: 4 bytes per voxel for nothing).
  if (drops_unread_outputs(i)) std::erase_if(results_[i], [&](const auto& kv) { return !output_read(i, kv.first); });
  state_[i] = plan_.nodes[i].cached ? NodeState::Cached : NodeState::Done;
  progress_[i] = 1.0;
  status(i, state_[i], 1.0, nr.warnings.empty() ? std::string() : nr.warnings.back());
  report_.nodes.push_back(std::move(nr));
  release_inputs(i);
  for (size_t u : plan_.nodes[i].users)
    if (--pending_[u] == 0) ready_.push_back(u);
  overall();
}

// Records the exception being handled: the first real error wins over cancellations; stops the others.
void Executor::Scheduler::node_failed(size_t i) {
  std::lock_guard lock(m_);
  bool cancelled = false;
  try {
    throw;
  } catch (const Cancelled&) {
    cancelled = true;
  } catch (...) {
  }
  state_[i] = cancelled ? NodeState::Cancelled : NodeState::Error;
  std::string msg;
  try {
    throw;
  } catch (const std::exception& e) {
    msg = e.what();
  } catch (...) {
    msg = "unknown error";
  }
  status(i, state_[i], progress_[i], msg);
  if (!first_error_ || (!cancelled && first_error_node_ < 0)) {
    if (!cancelled || !first_error_) {
      first_error_ = std::current_exception();
      first_error_node_ = cancelled ? -1 : static_cast<int64_t>(i);
    }
  }
  im_.cancel.store(true);  // stop the others
}

bool Executor::Scheduler::is_target(size_t i) const {
  return std::find(opt_.targets.begin(), opt_.targets.end(), plan_.nodes[i].id) != opt_.targets.end();
}

// True when a node reading node i reads its output `port`.
bool Executor::Scheduler::output_read(size_t i, const std::string& port) const {
  const std::string& id = plan_.nodes[i].id;
  for (size_t u : plan_.nodes[i].users)
    for (const auto& [in, ref] : node_of_[u]->inputs)
      if (ref.node == id && ref.port == port) return true;
  return false;
}

// m_ held; headless: drop results nobody needs any more. Counted per upstream node (not per port),
// as consumers_ is: a node reading two ports of one node must not free it for its other users.
void Executor::Scheduler::release_inputs(size_t i) {
  for (size_t d : plan_.nodes[i].inputs_from) {
    if (--consumers_[d] == 0 && !opt_.keep_outputs && !is_target(d))
      results_[d].clear();
  }
}

// A pool of `node_workers` threads pulls ready nodes; each node gets the whole thread budget (TBB's
// global scheduler keeps the total number of busy threads at the hardware count).
void Executor::Scheduler::run_all() {
  // Under a memory budget one node runs at a time: each may use the whole budget.
  const size_t node_workers = plan_.memory_budget > 0 ? 1 :
      std::min<size_t>(static_cast<size_t>(std::clamp(plan_.threads, 1, 4)), std::max<size_t>(n_, 1));
  std::vector<std::thread> pool;
  auto stop_now = [&] { return im_.cancel.load(); };
  for (size_t w = 0; w < node_workers; ++w) {
    pool.emplace_back([&] {
      std::unique_lock lock(m_);
      for (;;) {
        cv_.wait(lock, [&] { return finished_ == n_ || stop_now() || !ready_.empty(); });
        if (finished_ == n_ || stop_now()) return;
        size_t i = ready_.front();
        ready_.pop_front();
        ++running_;
        lock.unlock();
        run_node(i);
        lock.lock();
        --running_;
        ++finished_;
        cv_.notify_all();
      }
    });
  }
  {
    std::unique_lock lock(m_);
    while (finished_ < n_ && !(stop_now() && running_ == 0)) {
      if (opt_.cancel && opt_.cancel->load()) im_.cancel.store(true);
      if (stop_now()) cv_.notify_all();
      cv_.wait_for(lock, std::chrono::milliseconds(50));
    }
    cv_.notify_all();
  }
  for (auto& t : pool) t.join();
}

// The blocks of a block-wise node: the user's block shape, or the largest the budget allows for the
// module's halo and bytes per voxel on the grid of its first volume input.
BlockPlan Executor::Scheduler::block_plan(size_t i, const std::map<std::string, DataPtr>& inputs) {
  const ModuleSpec& spec = *im_.registry.find(plan_.nodes[i].module);
  BlockPlan b;
  b.memory_budget = plan_.memory_budget;
  Dims grid{64, 64, 64};
  for (const auto& [port, d] : inputs)
    if (d && voxel_bytes(d->type_id()) > 0) {
      grid = any_volume_grid(*d, "input '" + port + "'").dims;
      break;
    }
  b.block = plan_.block != Dims{0, 0, 0}
                ? plan_.block
                : block_for_budget(plan_.memory_budget, spec.block_support().halo, spec.block_support().bytes_per_voxel, grid);
  b.block_from_user = plan_.block != Dims{0, 0, 0};
  // Chunks of at most 32³ that divide the block: a block's interior is whole chunks (skelflow-mpi
  // writes shared scratch volumes a chunk at a time), its halo covers whole chunks but for a thin edge.
  b.chunk = scratch_chunk(b.block);
  b.scratch = [this, i, chunk = b.chunk](const std::string& port, const std::string& type_id, const Grid& g) {
    return make_scratch(i, port, type_id, g, chunk);
  };
  return b;
}

// A scratch volume in the scratch folder, named like the run's temporaries (so that a later run
// removes it if this process dies) and recorded for removal at the end of the run.
std::shared_ptr<ChunkedVolume> Executor::Scheduler::make_scratch(size_t i, const std::string& port,
                                                                 const std::string& type_id, const Grid& grid,
                                                                 const Dims& chunk) {
  fs::path file;
  {
    std::lock_guard lock(scratch_m_);
    std::string stem = plan_.nodes[i].id + "." + port;
    const int n = scratch_names_[stem]++;
    if (n > 0) stem += "." + std::to_string(n);
    std::error_code ec;
    fs::create_directories(plan_.scratch_dir, ec);
    file = resume_dir_.empty() ? temp_sibling(plan_.scratch_dir / (stem + ".scratch.h5"), files_.run_id())
                               : resume_dir_ / (stem + rank_suffix() + ".h5");
    scratch_files_.push_back(file);
  }
  std::shared_ptr<VolumeStore> store = create_volume_store(file, type_id, grid, chunk);
  {
    std::lock_guard lock(scratch_m_);
    if (auto j = journals_.find(i); j != journals_.end())
      store = j->second->wrap(file.filename().string(), voxel_bytes(type_id), grid.dims, std::move(store));
  }
  return std::make_shared<ChunkedVolume>(grid, type_id, std::move(store));
}

// ---- per-block resume (skel/block_journal.hpp)
// The journal of block-wise node i in the resume folder: an earlier killed run's committed blocks are
// kept (and said so); a journal that cannot be made is a warning, the stage then resumes per stage.
BlockJournalFile* Executor::Scheduler::open_journal(size_t i) {
  const std::string& id = plan_.nodes[i].id;
  try {
    auto j = std::make_unique<BlockJournalFile>(resume_dir_ / (id + rank_suffix() + ".blocks"), plan_.nodes[i].cache_key);
    if (const int64_t kept = j->kept_blocks(); kept > 0) {
      const std::string note = "resumed node '" + id + "' from " + std::to_string(kept) + " finished block(s)";
      std::lock_guard lock(m_);
      report_.notes.push_back(note);
      if (opt_.on_notice) opt_.on_notice(note);
    }
    std::lock_guard lock(scratch_m_);
    return (journals_[i] = std::move(j)).get();
  } catch (const Error& e) {
    if (opt_.on_warning) opt_.on_warning(id, std::string("blocks not kept for --resume: ") + e.what());
    return nullptr;
  }
}

// Drops node i's journal; `finished`: the node's outputs are kept (or it ran to its end), so its
// journal file goes too.
void Executor::Scheduler::close_journal(size_t i, bool finished) {
  std::unique_ptr<BlockJournalFile> j;
  {
    std::lock_guard lock(scratch_m_);
    auto it = journals_.find(i);
    if (it == journals_.end()) return;
    j = std::move(it->second);
    journals_.erase(it);
  }
  const fs::path f = j->file();
  j.reset();
  std::error_code ec;
  if (finished) fs::remove(f, ec);
}

// Removes the run's scratch files; `keep_live`: leave those whose volumes are still held (the GUI's
// cache): their stores remove them when the last user lets go.
void Executor::Scheduler::remove_scratch(bool keep_live) {
  std::lock_guard lock(scratch_m_);
  if (keep_live) return;
  for (const auto& f : scratch_files_) {
    std::error_code ec;
    fs::remove(f, ec);
  }
}

// Keeps what node i made for `--resume` (resume.hpp): its scratch volumes flushed, its in-memory
// volumes and tables written to the resume folder, then the manifest. Nodes that write files (their
// outputs are staged with the run's) and nodes with other outputs (graphs, meshes) are not kept:
// they run again when the run is resumed. A failure to keep them is a warning, not an error.
void Executor::Scheduler::checkpoint(size_t i, const NodeReport& nr) {
  const ResumeVolumeIo* io = resume_volume_io();
  if (!nr.outputs_written.empty() || !io) return;
  std::map<std::string, DataPtr> outs;
  {
    std::lock_guard lock(m_);
    outs = results_[i];
  }
  const std::string& id = plan_.nodes[i].id;
  detail::ResumeNode rn;
  rn.key = plan_.nodes[i].cache_key;
  try {
    for (const auto& [port, d] : outs) {
      if (!d) return;
      // Dropped when the node is done (node_done): nothing resumed reads it.
      if (drops_unread_outputs(i) && !output_read(i, port)) continue;
      detail::ResumeOutput o;
      o.port = port;
      if (const auto* c = dynamic_cast<const ChunkedVolume*>(d.get())) {
        const fs::path f = c->store()->file();
        if (f.parent_path() != resume_dir_ || f.filename().string().rfind(id + ".", 0) != 0) return;  // not its own
        io->flush(BlockJournalFile::unwrap(*c->store()));
        o.kind = "volume";
        o.file = f.filename().string();
        o.type_id = c->type_id();
        o.grid = c->grid();
      } else if (voxel_bytes(d->type_id()) > 0) {
        o.kind = "volume";
        o.file = id + "." + port + rank_suffix() + ".memory.h5";
        o.type_id = d->type_id();
        o.grid = any_volume_grid(*d, "output '" + port + "'");
        io->save(resume_dir_ / o.file, *d);
      } else if (const auto* t = dynamic_cast<const Table*>(d.get())) {
        o.kind = "table";
        o.file = id + "." + port + rank_suffix() + ".table";
        detail::save_table(resume_dir_ / o.file, *t);
      } else {
        return;
      }
      rn.outputs.push_back(std::move(o));
    }
    std::lock_guard lock(manifest_m_);
    manifest_.done[id] = std::move(rn);
    write_file_atomically(resume_dir_ / detail::resume_manifest_name(communicator().rank(), communicator().size()),
                          detail::manifest_text(manifest_));
  } catch (const std::exception& e) {
    if (opt_.on_warning) opt_.on_warning(id, std::string("not kept for --resume: ") + e.what());
  }
}

// Several ranks: the folder is the job's; rank 0 removes it once every rank is done with its files.
void Executor::Scheduler::remove_resume_dir() {
  if (resume_dir_.empty()) return;
  if (communicator().size() > 1) {
    try {
      sync_ranks();
    } catch (const std::exception&) {
      return;  // the ranks are out of step: the folder stays for a later run to remove
    }
    if (communicator().rank() != 0) return;
  }
  std::error_code ec;
  fs::remove_all(resume_dir_, ec);
}

// Caches what ran when outputs are kept (GUI); headless runs free intermediates instead.
void Executor::Scheduler::store_in_cache() {
  std::lock_guard lock(im_.cache_mutex);
  for (size_t i = 0; i < n_; ++i) {
    if (plan_.nodes[i].cached) continue;
    Impl::CacheEntry e;
    for (const auto& nr : report_.nodes)
      if (nr.id == plan_.nodes[i].id) e.files = nr.outputs_written;
    if (opt_.keep_outputs) e.outputs = results_[i];
    if (opt_.keep_outputs) im_.cache[plan_.nodes[i].cache_key] = std::move(e);
  }
  im_.last = report_;
}

// Several ranks (skelflow-mpi, skel/distributed.hpp): every rank says how its run ended and what
// its collectives cost; a rank whose run succeeded takes the first failed rank's error as its own
// (so rank 0 reports it at the node's place and writes nothing), and the report lists every rank.
void Executor::Scheduler::agree_with_ranks(bool& cancelled) {
  RankOutcome mine;
  mine.ok = !first_error_ && !cancelled;
  mine.seconds = report_.seconds;
  if (!mine.ok) {
    mine.node = first_error_node_;
    mine.error = "cancelled";
    if (first_error_) try {
        std::rethrow_exception(first_error_);
      } catch (const Cancelled&) {
      } catch (const std::exception& e) {
        mine.error = e.what();
      }
  }
  const std::vector<RankOutcome> all = agree_outcome(mine);
  for (size_t r = 0; r < all.size(); ++r) {
    const RankOutcome& o = all[r];
    RankReport rr;
    rr.rank = static_cast<int>(r);
    rr.ok = o.ok;
    rr.seconds = o.seconds;
    rr.seconds_blocks = o.stats.seconds_blocks;
    rr.seconds_waiting = o.stats.seconds_waiting;
    rr.blocks = o.stats.blocks;
    rr.collectives = o.stats.collectives;
    rr.bytes_sent = o.stats.bytes_sent;
    rr.bytes_received = o.stats.bytes_received;
    rr.seconds_io = o.stats.seconds_io;
    rr.bytes_read = o.stats.bytes_read;
    rr.bytes_written = o.stats.bytes_written;
    report_.ranks.push_back(rr);
  }
  if (!mine.ok) return;
  for (size_t r = 0; r < all.size(); ++r)
    if (!all[r].ok) {
      first_error_ = std::make_exception_ptr(RankFailed(static_cast<int>(r), all[r].error));
      first_error_node_ = all[r].node;
      if (all[r].error == "cancelled") cancelled = true;
      return;
    }
}

void Executor::Scheduler::conclude(double seconds) {
  report_.seconds = seconds;
  report_.peak_rss_mib = peak_rss_mib();
  bool cancelled = im_.cancel.load() || (opt_.cancel && opt_.cancel->load());
  if (communicator().reports_ranks()) agree_with_ranks(cancelled);
  if (!first_error_ && !cancelled) {
    std::vector<std::string> notes;
    try {
      // Several ranks (skelflow-mpi): every rank ran the pipeline; rank 0 alone writes the outputs.
      if (communicator().rank() == 0) files_.commit(&notes);
      else files_.rollback();
    } catch (const std::exception& e) {
      report_.ok = false;
      report_.error = e.what();
      report_.notes.insert(report_.notes.end(), notes.begin(), notes.end());
      {
        std::lock_guard lock(im_.cache_mutex);
        im_.last = report_;
      }
      // Several ranks: rank 0's outputs failed after the others concluded; it meets their
      // collectives below (the shared stores' closing, then remove_resume_dir's wait) in their order,
      // and keeps the resume folder.
      if (communicator().size() > 1 && plan_.memory_budget > 0) try {
          if (!opt_.keep_outputs) results_.clear();
          if (!resume_dir_.empty()) sync_ranks();
        } catch (const std::exception&) {
        }
      throw;
    }
    report_.ok = true;
    store_in_cache();
    if (plan_.memory_budget > 0) {
      if (!opt_.keep_outputs) results_.clear();  // drops the on-disk volumes: their stores remove their files
      remove_scratch(opt_.keep_outputs);
      remove_resume_dir();
    }
    return;
  }
  files_.rollback();
  if (plan_.memory_budget > 0) {
    results_.clear();
    remove_scratch(false);
    remove_resume_dir();
  }
  for (size_t i = 0; i < n_; ++i)
    if (state_[i] == NodeState::Waiting) status(i, NodeState::Cancelled, 0.0, {});
  report_.ok = false;
  // The error to throw: a node's error at the node's place in the pipeline file.
  std::exception_ptr err = first_error_;
  if (err && first_error_node_ >= 0) {
    const PipelineNode& n = *node_of_[static_cast<size_t>(first_error_node_)];
    try {
      std::rethrow_exception(err);
    } catch (...) {
      try {
        rethrow_at(ErrorSite{plan_.pipeline.file(), n.pos.line, n.pos.column, n.id, n.module, {}});
      } catch (...) {
        err = std::current_exception();
      }
    }
  }
  try {
    if (err) std::rethrow_exception(err);
    throw Cancelled();
  } catch (const Cancelled&) {
    report_.error = "cancelled";
  } catch (const std::exception& e) {
    report_.error = e.what();
  }
  {
    std::lock_guard lock(im_.cache_mutex);
    im_.last = report_;
  }
  if (!err) throw Cancelled();
  std::rethrow_exception(err);
}

// ---------------------------------------------------------------- run: the phases in order
RunReport Executor::run(const Pipeline& pipeline, const ExecOptions& opt) {
  std::lock_guard run_lock(impl_->run_mutex);
  Impl& im = *impl_;
  im.cancel.store(false);
  const auto t_start = std::chrono::steady_clock::now();

  ExecutionPlan plan = im.make_plan(pipeline, opt);
  check_outputs(plan);
  RunReport report;
  report.pipeline = plan.pipeline.file();
  report.threads = plan.threads;
  report.notes = remove_stale_outputs(plan);
  // Several ranks (skelflow-mpi): no rank makes files before every rank has removed the leftovers of
  // dead runs (on a cluster another node's live process looks dead).
  if (communicator().size() > 1) sync_ranks();
  auto results = im.lookup_cache(plan);
  fs::path resume_dir;
  detail::ResumeManifest manifest = im.prepare_resume(plan, opt, results, report.notes, resume_dir);
  if (opt.on_notice)
    for (const auto& n : report.notes) opt.on_notice(n);
  Scheduler run(im, plan, opt, std::move(results), modules_run_, report);
  run.set_resume(std::move(resume_dir), std::move(manifest));
  run.run_all();
  run.conclude(std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count());
  return report;
}

}  // namespace skel
