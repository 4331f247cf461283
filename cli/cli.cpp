// skelflow: the headless command line. Runs and validates YAML pipelines, documents modules and
// describes data files.
//
// Exit codes: 0 done, 2 invalid pipeline or input, 1 failure while running, 130 interrupted.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "skel/distributed.hpp"
#include "skel/error.hpp"
#include "skel/executor.hpp"
#include "skel/fs.hpp"
#include "skel/module.hpp"
#include "skel/pipeline.hpp"
#include "skel/plugin.hpp"
#include "skel/table.hpp"
#include "skel/text.hpp"
#include "cli.hpp"
#include "cli_options.hpp"
#include "render_command.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

std::atomic<bool> g_interrupted{false};
extern "C" void on_sigint(int) { g_interrupted.store(true); }

constexpr int kOk = 0, kFailed = 1, kInvalid = 2, kInterrupted = 130;

#ifndef SKELFLOW_VERSION
#define SKELFLOW_VERSION "unknown"
#endif

// One entry per command: `skelflow COMMAND --help` prints its usage, options and an example; the
// overview (`skelflow --help`) is made of the same texts.
struct Command {
  const char* name;
  const char* usage;    // the synopsis line(s)
  const char* text;     // what it does and its options
  const char* example;  // one command line
  std::vector<std::string> options;  // for "unknown option" suggestions and completion
};

const std::vector<Command>& commands() {
  static const std::vector<Command> cs = {
      {"run",
       "run PIPELINE [--set node.param=value]... [--threads N] [--output-dir D] [--report run.json]\n"
       "               [--target NODE]... [--quiet] [--allow-outside-output-dir]\n"
       "               [--memory-budget SIZE] [--scratch DIR] [--resume] [--no-block-resume]",
       "Runs a pipeline. Relative paths resolve against the pipeline file's folder; output paths\n"
       "resolve against --output-dir when given. Outputs appear only when the whole run succeeds.\n"
       "With --output-dir, every output must lie inside D: absolute paths, '..' and symbolic links\n"
       "that lead out of D are refused before anything runs, unless --allow-outside-output-dir.\n"
       "options:\n"
       "  --set node.param=value      override a parameter of a node (repeatable)\n"
       "  --threads N                 worker threads, 0 = all cores\n"
       "  --output-dir D              write outputs below D\n"
       "  --allow-outside-output-dir  allow outputs outside --output-dir\n"
       "  --report FILE               write a JSON report of the run (also when it fails)\n"
       "  --target NODE               run only what NODE needs (repeatable)\n"
       "  --quiet, -q                 no progress line and no summary\n"
       "  --memory-budget SIZE        run the block-wise stages block by block with their volumes in\n"
       "                              scratch files (512MiB, 2GiB, ...); a stage that would load more\n"
       "                              than SIZE stops the run; as `execution: {memory_budget: ...}`\n"
       "  --scratch DIR               folder of the scratch files (default: next to the first output)\n"
       "  --resume                    continue a run under a memory budget that was killed, from the\n"
       "                              stages it finished (refused when the pipeline, a parameter, an\n"
       "                              input file, the budget or the block shape changed) and, inside\n"
       "                              the stage it was in, from its finished blocks\n"
       "  --no-block-resume           keep no per-block journal: a killed stage starts again from its\n"
       "                              first block on --resume (saves the journal's time and disk, up to\n"
       "                              twice the stage's scratch volumes)",
       "skelflow run pipelines/vessel_network.yaml --set phantom.seed=7 --threads 4 --output-dir out",
       {"--set", "--threads", "--output-dir", "--allow-outside-output-dir", "--report", "--target", "--quiet", "-q",
        "--memory-budget", "--scratch", "--resume", "--no-block-resume", "--help", "-h"}},
      {"validate", "validate PIPELINE [--output-dir D] [--allow-outside-output-dir]",
       "Checks a pipeline without running it: modules, parameters, connections, types, cycles, input\n"
       "files that do not exist, output extensions, two outputs into one file, outputs outside D.\n"
       "Lists the stages that run block-wise under a memory budget.\n"
       "options:\n"
       "  --output-dir D              check outputs as `run --output-dir D` would write them\n"
       "  --allow-outside-output-dir  allow outputs outside --output-dir",
       "skelflow validate pipelines/vessel_network.yaml", {"--output-dir", "--allow-outside-output-dir", "--help", "-h"}},
      {"render",
       "render PIPELINE --node NODE.PORT [--node NODE.PORT]... -o FILE.png [--size WxH]\n"
       "               [--color-by ATTR] [--camera iso|x|y|z] [--volume-mode MODE]\n"
       "               [--set node.param=value]... [--threads N] [--quiet]",
       "Draws node outputs (volumes, graphs, meshes) into a PNG as the GUI's 3D view shows them, without\n"
       "a window: runs only what the nodes need, then renders off-screen with VTK. Several --node are\n"
       "drawn together (e.g. a graph over its volume). VTK on Debian renders through X only (no OSMesa or\n"
       "EGL): without DISPLAY a private Xvfb is started for the rendering (package xvfb), or run the\n"
       "command under xvfb-run.\n"
       "options:\n"
       "  --node NODE.PORT     an output to draw (repeatable; drawn in the GUI's colours in this order)\n"
       "  -o, --output FILE    the PNG to write\n"
       "  --size WxH           image size in pixels (default 1280x800)\n"
       "  --color-by ATTR      colour graphs and meshes by this attribute (a graph's point/edge attribute;\n"
       "                       a mesh's NAME or vertex:/triangle:/line:NAME); default as in the GUI: radius,\n"
       "                       the triangles' manifold class\n"
       "  --camera VIEW        iso (three-quarter view, default) or along the x, y or z axis\n"
       "  --volume-mode MODE   volumes as slices, mip, iso, volume or voxels (default: voxels for masks,\n"
       "                       slices otherwise)\n"
       "  --set node.param=value  override a parameter of a node (repeatable)\n"
       "  --threads N          worker threads, 0 = all cores\n"
       "  --quiet, -q          do not print the file written",
       "skelflow render pipelines/vessel_network.yaml --node graph.graph --node seg.mask -o network.png",
       {"--node", "-o", "--output", "--size", "--color-by", "--camera", "--volume-mode", "--set", "--threads", "--quiet",
        "-q", "--help", "-h"}},
      {"modules", "modules [--markdown | --names] [NAME]",
       "Lists the modules, or documents one (or all, with --markdown) in full.\n"
       "options:\n"
       "  --markdown  document every module in Markdown (docs/modules.md)\n"
       "  --names     only the module names, one a line (for shell completion)",
       "skelflow modules thinning.doht", {"--markdown", "--names", "--help", "-h"}},
      {"info", "info FILE", "Describes what a volume, graph or pipeline file holds.", "skelflow info out/vessels/network.am",
       {"--help", "-h"}},
      {"help", "help [COMMAND]", "Shows the overview, or the help of one command.", "skelflow help run", {}},
  };
  return cs;
}

const Command* find_command(const std::string& name) {
  for (const auto& c : commands())
    if (name == c.name) return &c;
  return nullptr;
}

std::vector<std::string> command_names() {
  std::vector<std::string> v;
  for (const auto& c : commands()) v.emplace_back(c.name);
  return v;
}

std::string indent(const std::string& text, const std::string& pad) {
  std::string out = pad;
  for (char ch : text) {
    out += ch;
    if (ch == '\n') out += pad;
  }
  return out;
}

std::string usage_text() {
  std::string s = "usage: skelflow <command> [options]\n       skelflow --version\n\ncommands:\n";
  for (const auto& c : commands()) {
    s += "  " + std::string(c.usage) + "\n";
    std::string t = c.text;
    if (auto o = t.find("options:\n"); o != std::string::npos) t = t.substr(0, o ? o - 1 : 0);
    s += indent(t, "      ") + "\n";
  }
  s += "\n'skelflow COMMAND --help' shows a command's options and an example.\n\n"
       "exit codes: 0 done, 2 invalid pipeline or input (an unwritable output included: found before\n"
       "anything runs), 1 failure while running, 130 interrupted (SIGINT, SIGTERM, SIGHUP, SIGQUIT).\n";
  return s;
}

std::string command_help(const Command& c) {
  return "usage: skelflow " + std::string(c.usage) + "\n\n" + c.text + "\n\nexample:\n  " + c.example + "\n";
}

bool is_help(const std::string& a) { return a == "--help" || a == "-h"; }

// "run: unknown option '--thread' (did you mean '--threads'?); see 'skelflow run --help'"
[[noreturn]] void unknown_option(const std::string& cmd, const std::string& a) {
  const Command* c = find_command(cmd);
  std::vector<std::string> opts = c ? c->options : std::vector<std::string>{};
  const std::string option = a.substr(0, a.find('='));
  throw InputError(cmd + ": unknown option '" + option + "'" + did_you_mean(option, opts) + "; see 'skelflow " + cmd +
                   " --help'");
}

// ---------------------------------------------------------------- progress display
}  // namespace

// Short durations for the progress line: "7s", "3m05s", "2h04m".
std::string format_duration(double seconds) {
  if (!(seconds >= 0)) seconds = 0;
  const auto s = static_cast<long long>(seconds + 0.5);
  char buf[32];
  if (s < 60) std::snprintf(buf, sizeof buf, "%llds", s);
  else if (s < 3600) std::snprintf(buf, sizeof buf, "%lldm%02llds", s / 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%lldh%02lldm", s / 3600, (s % 3600) / 60);
  return buf;
}

namespace {
class Progress {
public:
  explicit Progress(bool quiet)
      : quiet_(quiet), tty_(isatty(STDERR_FILENO) != 0), start_(std::chrono::steady_clock::now()) {}

  void status(const std::string& node, const NodeStatus& s) {
    std::lock_guard lock(m_);
    if (quiet_) return;
    if (s.state == NodeState::Running) {
      current_ = s.message.empty() ? node : node + ": " + s.message;  // e.g. "dist: chamfer 37/512 blocks"
      return;
    }
    if (s.state == NodeState::Done || s.state == NodeState::Cached || s.state == NodeState::Error) {
      clear_line();
      if (s.state == NodeState::Error) std::fprintf(stderr, "  %-24s error\n", node.c_str());
      else std::fprintf(stderr, "  %-24s %s\n", node.c_str(), to_string(s.state));
      draw();
    }
  }
  void overall(double f) {
    std::lock_guard lock(m_);
    fraction_ = f;
    if (quiet_) return;
    auto now = std::chrono::steady_clock::now();
    if (tty_) {
      if (now - last_ < std::chrono::milliseconds(100) && f < 1.0) return;
      last_ = now;
      draw();
    } else if (now - last_ >= std::chrono::seconds(5)) {  // plain lines for logs, not too many
      last_ = now;
      std::fprintf(stderr, "progress %3.0f%% %s (%s)\n", f * 100.0, times(now).c_str(), current_.c_str());
    }
  }
  void warning(const std::string& node, const std::string& msg) {
    std::lock_guard lock(m_);
    clear_line();
    std::fprintf(stderr, "warning: node '%s': %s\n", node.c_str(), msg.c_str());
    draw();
  }
  void notice(const std::string& msg) {
    std::lock_guard lock(m_);
    clear_line();
    std::fprintf(stderr, "skelflow: %s\n", msg.c_str());
    draw();
  }
  void finish() {
    std::lock_guard lock(m_);
    clear_line();
  }

private:
  void clear_line() {
    if (tty_ && drawn_) std::fprintf(stderr, "\r\033[K");
    drawn_ = false;
  }
  void draw() {
    if (!tty_ || quiet_) return;
    const int width = 30;
    int filled = static_cast<int>(fraction_ * width + 0.5);
    std::string bar(static_cast<size_t>(filled), '#');
    bar.resize(width, '-');
    std::fprintf(stderr, "\r\033[K[%s] %3.0f%% %s %s", bar.c_str(), fraction_ * 100.0,
                 times(std::chrono::steady_clock::now()).c_str(), current_.c_str());
    std::fflush(stderr);
    drawn_ = true;
  }
  // "12s" or "12s, ~40s left": the estimate only once the run reports a fraction worth extrapolating.
  std::string times(std::chrono::steady_clock::time_point now) const {
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    std::string t = format_duration(elapsed);
    if (fraction_ >= 0.01 && fraction_ < 1.0 && elapsed >= 1.0)
      t += ", ~" + format_duration(elapsed * (1.0 - fraction_) / fraction_) + " left";
    return t;
  }
  std::mutex m_;
  bool quiet_, tty_;
  std::chrono::steady_clock::time_point start_;
  bool drawn_ = false;
  double fraction_ = 0;
  std::string current_;
  std::chrono::steady_clock::time_point last_{};
};

// ---------------------------------------------------------------- module docs
std::string default_text(const ParamSpec& p) {
  std::string v = format_value(p.default_value);
  if (v.empty()) return p.optional_value ? "(not set)" : "(required)";
  return v;
}

std::string range_text(const ParamSpec& p) {
  std::ostringstream s;
  if (!p.choices.empty()) {
    for (size_t i = 0; i < p.choices.size(); ++i) s << (i ? " \\| " : "") << p.choices[i];
    return s.str();
  }
  if (p.min || p.max) {
    s << "[" << (p.min ? format_value(*p.min) : std::string("-inf")) << ", "
      << (p.max ? format_value(*p.max) : std::string("inf")) << "]";
  }
  if (p.list_length >= 0) s << (s.str().empty() ? "" : ", ") << p.list_length << " values";
  for (size_t i = 0; i < p.extensions.size(); ++i) s << (i ? " \\| " : "") << p.extensions[i];
  if (!p.extensions.empty() && !p.extensions_unless.empty()) s << " (" << p.extensions_unless << ": auto)";
  return s.str();
}

std::string types_text(const std::vector<std::string>& ts) {
  if (ts == all_volume_types()) return "any volume";
  if (ts == integer_volume_types()) return "integer volume";
  std::string s;
  for (const auto& t : ts) {
    if (!s.empty()) s += ", ";
    s += t;
  }
  return s;
}

void print_markdown(const ModuleSpec& m, std::ostream& o) {
  o << "### `" << m.name() << "`\n\n" << m.doc() << "\n\n";
  if (!m.inputs().empty()) {
    o << "| input | type | required | description |\n|---|---|---|---|\n";
    for (const auto& p : m.inputs())
      o << "| `" << p.name << "` | " << types_text(p.types) << " | " << (p.required ? "yes" : "no") << " | "
        << p.doc << " |\n";
    o << "\n";
  }
  if (!m.outputs().empty()) {
    o << "| output | type | description |\n|---|---|---|\n";
    for (const auto& p : m.outputs()) o << "| `" << p.name << "` | " << types_text(p.types) << " | " << p.doc << " |\n";
    o << "\n";
  }
  if (!m.params().empty()) {
    o << "| parameter | type | default | range | unit | description |\n|---|---|---|---|---|---|\n";
    for (const auto& p : m.params())
      o << "| `" << p.name << "` | " << to_string(p.type) << " | `" << default_text(p) << "` | " << range_text(p)
        << " | " << p.unit << " | " << p.doc << " |\n";
    o << "\n";
  }
  if (!m.details().empty()) o << m.details() << "\n\n";
}

// ---------------------------------------------------------------- plugins
// Loads the plugins (SKELFLOW_PLUGIN_PATH, the user folder) before any command; a refused plugin is
// a warning naming its file and why, and the command goes on without it.
void load_plugins_for_cli() {
  for (const auto& e : load_plugins().errors) std::fprintf(stderr, "skelflow: warning: %s\n", e.c_str());
}

// `skelflow --version`'s lines about plugins: the ABI tag a plugin must carry and every plugin loaded.
void print_plugins() {
  std::printf("plugin ABI: %s\n", plugin_abi_tag().c_str());
  if (loaded_plugins().empty()) std::printf("plugins: none loaded (SKELFLOW_PLUGIN_PATH, ~/.local/share/skelflow/plugins)\n");
  for (const auto& p : loaded_plugins()) {
    std::printf("plugin: %s:", p.file.c_str());
    for (const auto& m : p.modules) std::printf(" %s", m.c_str());
    std::printf("\n");
  }
}

// "  [plugin FILE]" after a module that came from a plugin, in `skelflow modules`.
std::string plugin_note(const std::string& module) {
  const std::string file = plugin_of_module(module);
  return file.empty() ? std::string() : "  [plugin " + file + "]";
}

int cmd_modules(const std::vector<std::string>& args) {
  bool markdown = false, names_only = false;
  std::string name;
  for (const auto& a : args) {
    if (a == "--markdown") markdown = true;
    else if (a == "--names") names_only = true;
    else if (!a.empty() && a[0] == '-') unknown_option("modules", a);
    else name = a;
  }
  const auto& reg = Registry::instance();
  if (names_only) {
    for (const auto* m : reg.specs()) std::printf("%s\n", m->name().c_str());
    return kOk;
  }
  if (!name.empty()) {
    const ModuleSpec* m = reg.find(name);
    if (!m) {
      std::vector<std::string> known;
      for (const auto* s : reg.specs()) known.push_back(s->name());
      throw InputError("unknown module '" + name + "'" + did_you_mean(name, known) +
                       "; 'skelflow modules' lists them");
    }
    print_markdown(*m, std::cout);
    return kOk;
  }
  if (markdown) {
    std::cout << "# Skelflow modules\n\nGenerated by `skelflow modules --markdown`. Every module reads its inputs "
                 "from other nodes' outputs (`node.port` in YAML) and takes the parameters listed.\n\n";
    std::string family;
    for (const auto* m : reg.specs()) {
      if (m->family() != family) {
        family = m->family();
        std::cout << "## " << family << "\n\n";
      }
      print_markdown(*m, std::cout);
    }
    return kOk;
  }
  for (const auto* m : reg.specs())
    std::printf("%-34s %s%s\n", m->name().c_str(), m->doc().c_str(), plugin_note(m->name()).c_str());
  return kOk;
}

// ---------------------------------------------------------------- info
int cmd_info(const std::vector<std::string>& args) {
  if (args.size() == 1 && args[0].size() > 1 && args[0][0] == '-' && !fs::exists(args[0])) unknown_option("info", args[0]);
  if (args.size() != 1) throw InputError("info: expected one FILE");
  fs::path f = args[0];
  std::error_code ec;
  const FileInspector* claimed = nullptr;  // by content or as a folder/pattern, when no extension matches
  for (const auto& ins : Registry::instance().inspectors())
    if (!claimed && ins.claims && ins.claims(f)) claimed = &ins;
  if (!fs::exists(f, ec) && !claimed) throw InputError(f.string() + ": file not found");
  const std::string ext = text::to_lower(f.extension().string());
  if (ext == ".yaml" || ext == ".yml") {
    Pipeline p = Pipeline::load_file(f);
    std::cout << f.string() << ": Skelflow pipeline, " << p.nodes().size() << " nodes\n";
    for (const auto& n : p.nodes()) {
      std::cout << "  " << n.id << ": " << n.module;
      for (const auto& [port, ref] : n.inputs) std::cout << "  " << port << "<-" << ref.str();
      std::cout << "\n";
    }
    auto ds = validate(p);
    for (const auto& d : ds) std::cout << "  problem: " << d.format() << "\n";
    return ds.empty() ? kOk : kInvalid;
  }
  // The inspectors whose extension is the longest suffix of the name (".nii.gz" before ".gz"); several
  // kinds of data share some extensions (Amira `.am`: volumes and spatial graphs; `.vtp`: graphs and
  // meshes), so each of them is tried in turn and the first that reads the file describes it.
  const std::string name = text::to_lower(f.filename().string());
  std::vector<const FileInspector*> candidates;
  size_t best_len = 0;
  for (const auto& ins : Registry::instance().inspectors())
    for (const auto& e : ins.extensions)
      if (e.size() >= best_len && name.size() > e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0) {
        if (e.size() > best_len) candidates.clear();
        best_len = e.size();
        if (std::find(candidates.begin(), candidates.end(), &ins) == candidates.end()) candidates.push_back(&ins);
      }
  if (candidates.empty() && claimed) candidates.push_back(claimed);
  std::vector<std::string> failures;
  for (const FileInspector* ins : candidates) {
    try {
      std::string description = ins->describe(f);  // first: a file it cannot read prints only the error
      if (!description.empty() && description.back() != '\n') description += '\n';
      std::cout << f.string() << ": " << ins->name << "\n" << description;
      return kOk;
    } catch (const InputError& e) {
      if (candidates.size() == 1) throw;
      failures.push_back("as " + ins->name + ": " + e.what());
    }
  }
  if (!failures.empty()) {
    std::string msg = f.string() + ": cannot be read";
    for (const auto& fl : failures) msg += "\n  " + fl;
    throw InputError(msg);
  }
  std::string known;
  for (const auto& ins : Registry::instance().inspectors())
    for (const auto& e : ins.extensions) known += " " + e;
  throw InputError(f.string() + ": unknown file type " + (ext.empty() ? std::string("(no extension)") : "'" + ext + "'") +
                   " (known: .yaml" + known + ")");
}

// ---------------------------------------------------------------- validate / run
int cmd_validate(const std::vector<std::string>& args) {
  std::string file;
  PathPolicy paths;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--output-dir") {
      if (i + 1 >= args.size()) throw InputError("validate: --output-dir needs a value");
      paths.output_dir = args[++i];
    } else if (a == "--allow-outside-output-dir") {
      paths.allow_outside = true;
    } else if (!a.empty() && a[0] == '-') {
      unknown_option("validate", a);
    } else if (file.empty()) {
      file = a;
    } else {
      throw InputError("validate: expected one PIPELINE file");
    }
  }
  if (file.empty()) throw InputError("validate: expected one PIPELINE file");
  Pipeline p = Pipeline::load_file(file);
  validate_or_throw(p, Registry::instance(), paths);
  std::printf("%s: valid (%zu nodes)\n", file.c_str(), p.nodes().size());
  std::string blockwise;
  for (const auto& n : p.nodes())
    if (Registry::instance().find(n.module)->block_support().blockwise) blockwise += (blockwise.empty() ? "" : ", ") + n.id;
  if (p.execution().memory_budget > 0)
    std::printf("memory budget %s: block-wise: %s\n", format_byte_size(p.execution().memory_budget).c_str(),
                blockwise.empty() ? "none" : blockwise.c_str());
  else
    std::printf("block-wise under --memory-budget: %s\n", blockwise.empty() ? "none" : blockwise.c_str());
  return kOk;
}

// `--report` must not overwrite the pipeline or one of its outputs (compared after resolving
// symbolic links and "..", so another spelling of the same file is caught too).
void refuse_report_over_outputs(const std::string& report, const std::string& pipeline, const ExecutionPlan& plan) {
  std::error_code ec;
  const fs::path r = fs::weakly_canonical(fs::absolute(report), ec);
  auto same = [&](const fs::path& p) {
    std::error_code e;
    return fs::weakly_canonical(fs::absolute(p), e) == r && !e;
  };
  if (same(pipeline)) throw InputError("--report " + report + ": this is the pipeline file; choose another file for the report");
  for (const auto& o : plan.outputs)
    if (same(o.path))
      throw InputError("--report " + report + ": this is an output of the pipeline (node '" + o.node + "', parameter '" +
                       o.param + "'); choose another file for the report");
}

// The one-row "summary" tables of a run (analysis.network_statistics and the like) as aligned
// "name  value  unit" lines under a "node.summary:" heading.
void print_summaries(const std::vector<std::pair<std::string, std::shared_ptr<const Table>>>& summaries) {
  for (const auto& [node, t] : summaries) {
    size_t w = 0;
    for (const auto& c : t->columns()) w = std::max(w, c.name.size());
    std::printf("%s.summary:\n", node.c_str());
    for (size_t c = 0; c < t->columns().size(); ++c) {
      const auto& col = t->columns()[c];
      std::string v = t->cell(c, 0);
      if (const auto* d = std::get_if<std::vector<double>>(&col.values)) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.6g", (*d)[0]);
        v = buf;
      }
      std::printf("  %-*s  %12s%s%s\n", static_cast<int>(w), col.name.c_str(), v.c_str(), col.unit.empty() ? "" : "  ",
                  col.unit.c_str());
    }
  }
}

int cmd_run(const std::vector<std::string>& args) {
  std::string file, report_path;
  ExecOptions opt;
  bool quiet = false;
  auto need = [&](size_t& i, const std::string& what) -> const std::string& {
    if (i + 1 >= args.size()) throw InputError("run: " + what + " needs a value");
    return args[++i];
  };
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--set") {
      cli::parse_set_option(need(i, "--set"), opt);
    } else if (a == "--threads") {
      cli::parse_threads_option(need(i, "--threads"), opt);
    } else if (a == "--output-dir") {
      opt.output_dir = need(i, "--output-dir");
    } else if (a == "--allow-outside-output-dir") {
      opt.allow_outside_output_dir = true;
    } else if (a == "--report") {
      report_path = need(i, "--report");
    } else if (a == "--target") {
      opt.targets.push_back(need(i, "--target"));
    } else if (a == "--memory-budget") {
      opt.memory_budget = parse_byte_size(need(i, "--memory-budget"), "--memory-budget");
    } else if (a == "--scratch") {
      opt.scratch_dir = need(i, "--scratch");
    } else if (a == "--resume") {
      opt.resume = true;
    } else if (a == "--no-block-resume") {
      opt.block_resume = false;
    } else if (a == "--quiet" || a == "-q") {
      quiet = true;
    } else if (!a.empty() && a[0] == '-') {
      unknown_option("run", a);
    } else if (file.empty()) {
      file = a;
    } else {
      throw InputError("run: more than one pipeline given");
    }
  }
  if (file.empty()) throw InputError("run: no PIPELINE given");
  Pipeline p = Pipeline::load_file(file);
  if (!opt.scratch_dir.empty() && opt.memory_budget == 0 && p.execution().memory_budget == 0)
    throw InputError("--scratch " + opt.scratch_dir.string() + ": scratch files are only made under a memory budget "
                     "(--memory-budget SIZE or execution: {memory_budget: SIZE} in the pipeline)");
  Executor ex;
  if (!report_path.empty()) refuse_report_over_outputs(report_path, file, ex.plan(p, opt));

  Progress progress(quiet);
  opt.cancel = &g_interrupted;
  opt.on_status = [&](const std::string& n, const NodeStatus& s) { progress.status(n, s); };
  opt.on_progress = [&](double f) { progress.overall(f); };
  opt.on_warning = [&](const std::string& n, const std::string& w) { progress.warning(n, w); };
  opt.on_notice = [&](const std::string& m) { progress.notice(m); };
  std::mutex summaries_mutex;
  std::vector<std::pair<std::string, std::shared_ptr<const Table>>> summaries;
  opt.on_outputs = [&](const std::string& n, const std::map<std::string, DataPtr>& outs) {
    auto it = outs.find("summary");
    if (it == outs.end()) return;
    auto t = std::dynamic_pointer_cast<const Table>(it->second);
    if (!t || t->rows() != 1) return;
    std::lock_guard lock(summaries_mutex);
    summaries.emplace_back(n, std::move(t));
  };

  auto write_report = [&](const RunReport& r) {
    // Several ranks (skelflow-mpi): rank 0 writes it (every rank's outcome is in it).
    if (report_path.empty() || communicator().rank() != 0) return;
    write_atomically(report_path, [&](const fs::path& tmp) {
      std::ofstream o(tmp);
      o << r.to_json();
      if (!o.flush()) throw Error("cannot write the report " + report_path);
    });
  };
  try {
    RunReport r = ex.run(p, opt);
    progress.finish();
    write_report(r);
    if (!quiet) {
      std::fprintf(stderr, "done in %.2f s, peak memory %.0f MiB\n", r.seconds, r.peak_rss_mib);
      for (const auto& n : r.nodes)
        for (const auto& f : n.outputs_written) std::printf("wrote %s\n", f.c_str());
      std::sort(summaries.begin(), summaries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      print_summaries(summaries);
    }
    return kOk;
  } catch (...) {
    progress.finish();
    RunReport r = ex.last_report();
    if (!r.pipeline.empty()) {
      try {
        write_report(r);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "skelflow: %s\n", e.what());
      }
    }
    throw;
  }
}

}  // namespace

int skelflow_main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || (args[0] == "help" && args.size() == 1)) {
    std::fputs(usage_text().c_str(), args.empty() ? stderr : stdout);
    return args.empty() ? kInvalid : kOk;
  }
  load_plugins_for_cli();
  if (args[0] == "--version" || args[0] == "-V") {
    std::printf("skelflow %s\n", SKELFLOW_VERSION);
    print_plugins();
    return kOk;
  }
  {  // `skelflow help COMMAND` and `skelflow COMMAND --help`
    const bool help_cmd = args[0] == "help";
    const std::string name = help_cmd ? args[1] : args[0];
    const Command* c = find_command(name);
    if (c && (help_cmd || std::any_of(args.begin() + 1, args.end(), is_help))) {
      std::fputs(command_help(*c).c_str(), stdout);
      return kOk;
    }
    if (!c) {
      std::fprintf(stderr, "skelflow: unknown %s '%s'%s; 'skelflow --help' lists the commands\n",
                   (!name.empty() && name[0] == '-') ? "option" : "command", name.c_str(),
                   did_you_mean(name, (!name.empty() && name[0] == '-') ? std::vector<std::string>{"--help", "--version"}
                                                     : command_names()).c_str());
      return kInvalid;
    }
  }
  struct sigaction sa {};
  sa.sa_handler = on_sigint;
  sigemptyset(&sa.sa_mask);
  // Ctrl+C, kill, a closed terminal (SIGHUP) and Ctrl+\ (SIGQUIT) all cancel cleanly: the running
  // nodes stop, temporaries are removed, and the exit code is 130.
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) sigaction(sig, &sa, nullptr);

  const std::string cmd = args[0];
  std::vector<std::string> rest(args.begin() + 1, args.end());
  try {
    if (cmd == "run") return cmd_run(rest);
    if (cmd == "validate") return cmd_validate(rest);
    if (cmd == "modules") return cmd_modules(rest);
    if (cmd == "info") return cmd_info(rest);
    if (cmd == "render")
      return cli::cmd_render(rest, &g_interrupted, [](const std::string& a) { unknown_option("render", a); });
    std::fputs(usage_text().c_str(), stdout);  // "help" with more than one word
    return kOk;
  } catch (const Cancelled&) {
    std::fprintf(stderr, "skelflow: interrupted; no partial outputs were left\n");
    return kInterrupted;
  } catch (const InputError& e) {
    std::fprintf(stderr, "skelflow: %s\n", e.what());
    return kInvalid;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "skelflow: %s\n", e.what());
    return kFailed;
  }
}
