#include "skel/executor.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <sstream>
#include <thread>
#include <unordered_map>

#include <sys/resource.h>

#include "context.hpp"
#include "skel/parallel.hpp"
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

std::string RunReport::to_json() const {
  std::ostringstream o;
  o << "{\n  \"pipeline\": \"" << json_escape(pipeline) << "\",\n  \"ok\": " << (ok ? "true" : "false")
    << ",\n  \"error\": \"" << json_escape(error) << "\",\n  \"seconds\": " << num(seconds)
    << ",\n  \"peak_rss_mib\": " << num(peak_rss_mib) << ",\n  \"threads\": " << threads << ",\n  \"nodes\": [";
  for (size_t i = 0; i < nodes.size(); ++i) {
    const auto& n = nodes[i];
    o << (i ? ",\n" : "\n") << "    {\"id\": \"" << json_escape(n.id) << "\", \"module\": \"" << json_escape(n.module)
      << "\", \"cached\": " << (n.cached ? "true" : "false") << ", \"seconds\": " << num(n.seconds)
      << ", \"peak_rss_mib\": " << num(n.peak_rss_mib) << ", \"rss_mib\": " << num(n.rss_mib) << ", \"output_bytes\": {";
    size_t k = 0;
    for (const auto& [port, b] : n.output_bytes)
      o << (k++ ? ", " : "") << "\"" << json_escape(port) << "\": " << b;
    o << "}, \"files\": [";
    for (size_t j = 0; j < n.outputs_written.size(); ++j)
      o << (j ? ", " : "") << "\"" << json_escape(n.outputs_written[j]) << "\"";
    o << "], \"warnings\": [";
    for (size_t j = 0; j < n.warnings.size(); ++j)
      o << (j ? ", " : "") << "\"" << json_escape(n.warnings[j]) << "\"";
    o << "]}";
  }
  o << "\n  ]\n}\n";
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

RunReport Executor::run(const Pipeline& pipeline_in, const ExecOptions& opt) {
  std::lock_guard run_lock(impl_->run_mutex);
  Impl& im = *impl_;
  im.cancel.store(false);
  const auto t_start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };

  // Apply overrides to a copy, then validate everything before any work.
  Pipeline p = pipeline_in;
  for (const auto& [node, params] : opt.overrides) {
    if (!p.find(node)) throw InputError("--set: no node '" + node + "' in " + p.file());
    for (const auto& [name, v] : params) p.set_param(node, name, v);
  }
  for (const auto& t : opt.targets)
    if (!p.find(t)) throw InputError("no node '" + t + "' in " + p.file());
  validate_or_throw(p, im.registry);
  const std::vector<std::string> order_all = p.topological_order();
  const std::set<std::string> wanted = p.upstream_closure(opt.targets);
  std::vector<std::string> order;
  for (const auto& id : order_all)
    if (wanted.count(id)) order.push_back(id);
  const auto keys = im.keys(p, order_all, nullptr);
  const int threads = effective_threads(opt.threads);
  const fs::path input_base = p.base_dir();
  const fs::path output_base = opt.output_dir.empty() ? p.base_dir() : fs::absolute(opt.output_dir);

  RunReport report;
  report.pipeline = p.file();
  report.threads = threads;

  // Dependency bookkeeping.
  const size_t n_nodes = order.size();
  std::vector<const PipelineNode*> node_of(n_nodes);
  {
    std::unordered_map<std::string, const PipelineNode*> by_id;
    for (const auto& n : p.nodes()) by_id[n.id] = &n;
    for (size_t i = 0; i < n_nodes; ++i) node_of[i] = by_id.at(order[i]);
  }
  std::unordered_map<std::string, size_t> idx;
  for (size_t i = 0; i < n_nodes; ++i) idx[order[i]] = i;
  std::vector<std::vector<size_t>> users(n_nodes);
  std::vector<int> pending(n_nodes, 0), consumers(n_nodes, 0);
  for (size_t i = 0; i < n_nodes; ++i) {
    std::set<size_t> deps;
    for (const auto& [port, ref] : node_of[i]->inputs) deps.insert(idx.at(ref.node));
    for (size_t d : deps) {
      users[d].push_back(i);
      ++pending[i];
      ++consumers[d];
    }
  }

  std::mutex m;
  std::condition_variable cv;
  std::deque<size_t> ready;
  std::vector<std::map<std::string, DataPtr>> results(n_nodes);
  std::vector<double> progress(n_nodes, 0.0);
  std::vector<NodeState> state(n_nodes, NodeState::Waiting);
  size_t finished = 0, running = 0;
  std::exception_ptr first_error;
  std::string first_error_node;
  detail::OutputFiles files;

  auto status = [&](size_t i, NodeState s, double prog, const std::string& msg) {
    if (opt.on_status) opt.on_status(order[i], NodeStatus{s, prog, msg});
  };
  auto overall = [&]() {  // call with m held
    if (!opt.on_progress || n_nodes == 0) return;
    double sum = 0;
    for (size_t i = 0; i < n_nodes; ++i)
      sum += (state[i] == NodeState::Done || state[i] == NodeState::Cached) ? 1.0 : progress[i];
    opt.on_progress(sum / static_cast<double>(n_nodes));
  };

  // Nodes whose results are cached (and whose output files still exist) do not run.
  std::vector<bool> from_cache(n_nodes, false);
  {
    std::lock_guard lock(im.cache_mutex);
    for (size_t i = 0; i < n_nodes; ++i) {
      auto c = im.cache.find(keys.at(order[i]));
      if (c == im.cache.end()) continue;
      bool files_ok = std::all_of(c->second.files.begin(), c->second.files.end(),
                                  [](const std::string& f) { return fs::exists(f); });
      if (!files_ok) continue;
      from_cache[i] = true;
      results[i] = c->second.outputs;
    }
  }
  for (size_t i = 0; i < n_nodes; ++i) {
    status(i, NodeState::Waiting, 0.0, {});
    if (pending[i] == 0) ready.push_back(i);
  }

  auto release_inputs = [&](size_t i) {  // m held; headless: drop results nobody needs any more
    for (const auto& [port, ref] : node_of[i]->inputs) {
      size_t d = idx.at(ref.node);
      (void)port;
      if (--consumers[d] == 0 && !opt.keep_outputs && std::find(opt.targets.begin(), opt.targets.end(), order[d]) == opt.targets.end())
        results[d].clear();
    }
  };

  auto run_node = [&](size_t i) {
    const PipelineNode& node = *node_of[i];
    const ModuleSpec& spec = *im.registry.find(node.module);
    NodeReport nr;
    nr.id = node.id;
    nr.module = node.module;
    const auto t0 = std::chrono::steady_clock::now();
    try {
      std::map<std::string, DataPtr> inputs;
      {
        std::lock_guard lock(m);
        for (const auto& [port, ref] : node.inputs) {
          const auto& r = results[idx.at(ref.node)];
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
      }
      if (from_cache[i]) {
        nr.cached = true;
      } else {
        ParamMap eff = effective_params(node, spec);
        auto last_report = std::make_shared<std::atomic<int64_t>>(0);
        Interrupter intr(
            [&, i, last_report](double f) {
              const int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                                      std::chrono::steady_clock::now().time_since_epoch()).count();
              int64_t prev = last_report->load();
              if (now - prev < 50 && f < 1.0) return;
              last_report->store(now);
              std::lock_guard lock(m);
              progress[i] = f;
              status(i, NodeState::Running, f, {});
              overall();
            },
            &im.cancel);
        std::vector<std::string> warnings;
        detail::NodeContext ctx(spec, node.id, std::move(inputs), std::move(eff), threads, intr, input_base,
                                output_base, files, [&, i](const std::string& w) {
                                  if (opt.on_warning) opt.on_warning(order[i], w);
                                });
        status(i, NodeState::Running, 0.0, {});
        auto mod = im.registry.create(node.module);
        ++modules_run_;
        mod->run(ctx);
        intr.check();
        std::lock_guard lock(m);
        results[i] = std::move(ctx.outputs());
        nr.warnings = ctx.warnings();
        nr.outputs_written = ctx.written();
      }
      nr.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      nr.peak_rss_mib = peak_rss_mib();
      // Reading /proc costs ~10 µs: skip it for nodes too short to change the resident set much.
      if (nr.seconds > 0.01) nr.rss_mib = current_rss_mib();
      std::lock_guard lock(m);
      for (const auto& [port, d] : results[i])
        if (d) nr.output_bytes[port] = d->bytes();
      state[i] = from_cache[i] ? NodeState::Cached : NodeState::Done;
      progress[i] = 1.0;
      status(i, state[i], 1.0, nr.warnings.empty() ? std::string() : nr.warnings.back());
      report.nodes.push_back(std::move(nr));
      release_inputs(i);
      for (size_t u : users[i])
        if (--pending[u] == 0) ready.push_back(u);
      overall();
    } catch (...) {
      std::lock_guard lock(m);
      bool cancelled = false;
      try {
        throw;
      } catch (const Cancelled&) {
        cancelled = true;
      } catch (...) {
      }
      state[i] = cancelled ? NodeState::Cancelled : NodeState::Error;
      std::string msg;
      try {
        throw;
      } catch (const std::exception& e) {
        msg = e.what();
      } catch (...) {
        msg = "unknown error";
      }
      status(i, state[i], progress[i], msg);
      if (!first_error || (!cancelled && first_error_node.empty())) {
        if (!cancelled || !first_error) {
          first_error = std::current_exception();
          first_error_node = cancelled ? std::string() : node.id;
        }
      }
      im.cancel.store(true);  // stop the others
    }
  };

  // Scheduler: a pool of `node_workers` threads pulls ready nodes; each node gets the whole thread
  // budget (TBB's global scheduler keeps the total number of busy threads at the hardware count).
  const size_t node_workers = std::min<size_t>(static_cast<size_t>(std::clamp(threads, 1, 4)), std::max<size_t>(n_nodes, 1));
  std::vector<std::thread> pool;
  auto stop_now = [&] { return im.cancel.load(); };
  for (size_t w = 0; w < node_workers; ++w) {
    pool.emplace_back([&] {
      std::unique_lock lock(m);
      for (;;) {
        cv.wait(lock, [&] { return finished == n_nodes || stop_now() || !ready.empty(); });
        if (finished == n_nodes || stop_now()) return;
        size_t i = ready.front();
        ready.pop_front();
        ++running;
        lock.unlock();
        run_node(i);
        lock.lock();
        --running;
        ++finished;
        cv.notify_all();
      }
    });
  }
  {
    std::unique_lock lock(m);
    while (finished < n_nodes && !(stop_now() && running == 0)) {
      if (opt.cancel && opt.cancel->load()) im.cancel.store(true);
      if (stop_now()) cv.notify_all();
      cv.wait_for(lock, std::chrono::milliseconds(50));
    }
    cv.notify_all();
  }
  for (auto& t : pool) t.join();

  report.seconds = elapsed();
  report.peak_rss_mib = peak_rss_mib();
  const bool cancelled = im.cancel.load() || (opt.cancel && opt.cancel->load());
  if (first_error || cancelled) {
    files.rollback();
    for (size_t i = 0; i < n_nodes; ++i)
      if (state[i] == NodeState::Waiting) status(i, NodeState::Cancelled, 0.0, {});
    report.ok = false;
    std::exception_ptr err = first_error;
    try {
      if (err) std::rethrow_exception(err);
      throw Cancelled();
    } catch (const Cancelled& e) {
      report.error = "cancelled";
    } catch (const std::exception& e) {
      report.error = e.what();
    }
    {
      std::lock_guard lock(im.cache_mutex);
      im.last = report;
    }
    if (!err) throw Cancelled();
    try {
      std::rethrow_exception(err);
    } catch (...) {
      if (first_error_node.empty()) throw;
      const PipelineNode* n = p.find(first_error_node);
      rethrow_with_context("node '" + first_error_node + "' (" + n->module + ")");
    }
  }
  files.commit();
  report.ok = true;
  {
    std::lock_guard lock(im.cache_mutex);
    // Cache what ran when outputs are kept (GUI); headless runs free intermediates instead.
    for (size_t i = 0; i < n_nodes; ++i) {
      const uint64_t key = keys.at(order[i]);
      if (from_cache[i]) continue;
      Impl::CacheEntry e;
      for (const auto& nr : report.nodes)
        if (nr.id == order[i]) e.files = nr.outputs_written;
      if (opt.keep_outputs) e.outputs = results[i];
      if (opt.keep_outputs) im.cache[key] = std::move(e);
    }
    im.last = report;
  }
  return report;
}

}  // namespace skel
