#include "skel/pipeline.hpp"
#include "skel/out_of_core.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <system_error>

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace fs = std::filesystem;

namespace skel {

std::optional<PortRef> parse_port_ref(const std::string& text) {
  auto dot = text.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == text.size()) return std::nullopt;
  return PortRef{text.substr(0, dot), text.substr(dot + 1)};
}

std::string Diagnostic::format() const {
  std::string s = location_prefix(file, pos.line, pos.column);
  if (!node.empty()) s += "node '" + node + "': ";
  return s + message;
}

// ---------------------------------------------------------------- scalar parsing / formatting
namespace {

SourcePos pos_of(const YAML::Node& n) {
  const YAML::Mark m = n.Mark();
  if (m.line < 0) return {};
  return {m.line + 1, m.column + 1};
}

[[noreturn]] void fail(const std::string& file, SourcePos pos, const std::string& msg) {
  // Without a file (a value given alone, as by --set) a line:column would be one inside the value.
  Diagnostic d{file, file.empty() ? SourcePos{} : pos, "", msg};
  throw InputError(d.format());
}

// YAML scalars may carry a leading '+' (the text helpers take none).
std::string_view without_plus(const std::string& s) {
  std::string_view v = s;
  if (!v.empty() && v.front() == '+') v.remove_prefix(1);
  return v;
}

bool parse_int(const std::string& s, int64_t& out) { return text::parse_int(without_plus(s), out); }

bool parse_double(const std::string& s, double& out) {
  if (s == ".inf" || s == ".Inf" || s == "+.inf" || s == "inf") { out = std::numeric_limits<double>::infinity(); return true; }
  if (s == "-.inf" || s == "-.Inf" || s == "-inf") { out = -std::numeric_limits<double>::infinity(); return true; }
  if (s == ".nan" || s == ".NaN" || s == "nan") { out = std::numeric_limits<double>::quiet_NaN(); return true; }
  return text::parse_double(without_plus(s), out);
}

bool parse_bool(const std::string& s, bool& out) {
  if (s == "true" || s == "True" || s == "TRUE" || s == "yes" || s == "on") { out = true; return true; }
  if (s == "false" || s == "False" || s == "FALSE" || s == "no" || s == "off") { out = false; return true; }
  return false;
}

// The `execution:` section: {memory_budget: SIZE, block: [x, y, z]}, each optional.
ExecutionSettings parse_execution(const YAML::Node& n, const std::string& file) {
  ExecutionSettings e;
  if (n.IsNull()) return e;
  if (!n.IsMap()) fail(file, pos_of(n), "'execution' must be a mapping (memory_budget, block)");
  std::set<std::string> seen;
  for (const auto& kv : n) {
    const std::string k = kv.first.Scalar();
    if (!seen.insert(k).second) fail(file, pos_of(kv.first), "execution: '" + k + "' given twice");
    if (k == "memory_budget") {
      if (!kv.second.IsScalar()) fail(file, pos_of(kv.second), "execution: memory_budget must be a size such as 2GiB");
      try {
        e.memory_budget = parse_byte_size(kv.second.Scalar(), "execution: memory_budget");
      } catch (const InputError& err) {
        fail(file, pos_of(kv.second), err.what());
      }
      e.memory_budget_text = kv.second.Scalar();
      e.memory_budget_pos = pos_of(kv.second);
    } else if (k == "block") {
      const std::string help = "execution: block must be a list of three whole numbers >= 1 (x, y, z), e.g. [64, 64, 64]";
      if (!kv.second.IsSequence() || kv.second.size() != 3) fail(file, pos_of(kv.second), help);
      for (size_t a = 0; a < 3; ++a) {
        int64_t v = 0;
        if (!kv.second[a].IsScalar() || !parse_int(kv.second[a].Scalar(), v) || v < 1 || v > (int64_t{1} << 30))
          fail(file, pos_of(kv.second[a]), help);
        e.block[a] = v;
      }
      e.block_pos = pos_of(kv.second);
    } else {
      fail(file, pos_of(kv.first), "execution: unknown key '" + k + "' (expected memory_budget, block)");
    }
  }
  return e;
}

// A plain scalar's most specific value: bool, int, float, else string. Quoted scalars are strings.
ParamValue guess_scalar(const YAML::Node& n) {
  const std::string& s = n.Scalar();
  if (n.Tag() == "!") return s;  // quoted
  bool b;
  int64_t i;
  double d;
  if (parse_bool(s, b)) return b;
  if (parse_int(s, i)) return i;
  if (parse_double(s, d)) return d;
  return s;
}

std::string fmt_double(double d) {
  if (std::isnan(d)) return ".nan";
  if (std::isinf(d)) return d > 0 ? ".inf" : "-.inf";
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, d);
  std::string s(buf, r.ptr);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

// Would a plain scalar with this text read back as something other than this string?
bool needs_quotes(const std::string& s) {
  if (s.empty()) return true;
  bool b;
  int64_t i;
  double d;
  if (parse_bool(s, b) || parse_int(s, i) || parse_double(s, d)) return true;
  if (s == "null" || s == "~" || s == "Null" || s == "NULL") return true;
  return false;
}

void emit_value(YAML::Emitter& out, const ParamValue& v) {
  std::visit(
      [&](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) out << (x ? "true" : "false");
        else if constexpr (std::is_same_v<T, int64_t>) out << std::to_string(x);
        else if constexpr (std::is_same_v<T, double>) out << fmt_double(x);
        else if constexpr (std::is_same_v<T, std::string>) {
          if (needs_quotes(x)) out << YAML::DoubleQuoted << x;
          else out << x;
        } else {
          out << YAML::Flow << YAML::BeginSeq;
          for (const auto& e : x) {
            if constexpr (std::is_same_v<T, std::vector<double>>) out << fmt_double(e);
            else out << std::to_string(e);
          }
          out << YAML::EndSeq;
        }
      },
      v);
}

ParamValue parse_param_value(const YAML::Node& n, const std::string& file, const std::string& what) {
  if (n.IsScalar()) return guess_scalar(n);
  if (n.IsNull()) return std::string();
  if (n.IsSequence()) {
    std::vector<int64_t> ints;
    std::vector<double> reals;
    bool all_int = true;
    for (const auto& e : n) {
      if (!e.IsScalar()) fail(file, pos_of(e), what + ": list elements must be numbers");
      ParamValue g = guess_scalar(e);
      if (auto* i = std::get_if<int64_t>(&g)) {
        ints.push_back(*i);
        reals.push_back(static_cast<double>(*i));
      } else if (auto* d = std::get_if<double>(&g)) {
        all_int = false;
        reals.push_back(*d);
      } else {
        fail(file, pos_of(e), what + ": list elements must be numbers, got '" + e.Scalar() + "'");
      }
    }
    if (all_int) return ints;
    return reals;
  }
  fail(file, pos_of(n), what + ": expected a value or a list of numbers, got a mapping");
}

bool valid_id(const std::string& id) {
  if (id.empty()) return false;
  if (!(std::isalpha(static_cast<unsigned char>(id[0])) || id[0] == '_')) return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
}

}  // namespace

ParamValue parse_param_text(const std::string& text) {
  YAML::Node n;
  try {
    n = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError("cannot read the value '" + text + "': " + e.msg);
  }
  if (!n.IsDefined() || n.IsNull()) return std::string();
  return parse_param_value(n, "", "value '" + text + "'");
}

std::optional<ParamValue> coerce_param(const ParamSpec& spec, const ParamValue& v) {
  switch (spec.type) {
    case ParamType::Bool:
      if (std::holds_alternative<bool>(v)) return v;
      return std::nullopt;
    case ParamType::Int:
      if (std::holds_alternative<int64_t>(v)) return v;
      if (auto* d = std::get_if<double>(&v)) {
        if (std::isfinite(*d) && std::floor(*d) == *d && std::abs(*d) < 9e15) return static_cast<int64_t>(*d);
      }
      return std::nullopt;
    case ParamType::Float:
      if (std::holds_alternative<double>(v)) return v;
      if (auto* i = std::get_if<int64_t>(&v)) return static_cast<double>(*i);
      return std::nullopt;
    case ParamType::String:
    case ParamType::Choice:
    case ParamType::Path:
      if (std::holds_alternative<std::string>(v)) return v;
      // A plain scalar such as `yes` or `12` meant as text.
      if (spec.type != ParamType::Path && !std::holds_alternative<std::vector<int64_t>>(v) &&
          !std::holds_alternative<std::vector<double>>(v)) {
        if (auto* b = std::get_if<bool>(&v)) return std::string(*b ? "true" : "false");
        if (auto* i = std::get_if<int64_t>(&v)) return std::to_string(*i);
      }
      return std::nullopt;
    case ParamType::IntList:
      if (std::holds_alternative<std::vector<int64_t>>(v)) return v;
      if (auto* s = std::get_if<std::string>(&v); s && s->empty() && spec.optional_value)
        return std::vector<int64_t>{};
      if (auto* i = std::get_if<int64_t>(&v)) return std::vector<int64_t>{*i};
      return std::nullopt;
    case ParamType::FloatList:
      if (std::holds_alternative<std::vector<double>>(v)) return v;
      if (auto* iv = std::get_if<std::vector<int64_t>>(&v))
        return std::vector<double>(iv->begin(), iv->end());
      if (auto* s = std::get_if<std::string>(&v); s && s->empty() && spec.optional_value)
        return std::vector<double>{};
      if (auto* d = std::get_if<double>(&v)) return std::vector<double>{*d};
      if (auto* i = std::get_if<int64_t>(&v)) return std::vector<double>{static_cast<double>(*i)};
      return std::nullopt;
  }
  return std::nullopt;
}

ParamMap effective_params(const PipelineNode& node, const ModuleSpec& spec) {
  ParamMap eff;
  for (const auto& p : spec.params()) eff[p.name] = p.default_value;
  for (const auto& [name, value] : node.params) {
    const ParamSpec* p = spec.find_param(name);
    if (!p) continue;
    auto c = coerce_param(*p, value);
    eff[p->name] = c ? *c : value;
  }
  return eff;
}

// ---------------------------------------------------------------- load
Pipeline Pipeline::load_file(const fs::path& path) {
  // What is not a regular file (/dev/zero, a FIFO, a folder) or is huge is refused before reading.
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) throw InputError(path.string() + ": pipeline file not found");
  if (!fs::is_regular_file(st))
    throw InputError(path.string() + ": not a regular file (a pipeline is a YAML file)");
  const uintmax_t size = fs::file_size(path, ec);
  auto too_large = [&] {
    return InputError(path.string() + ": the file is larger than the " + std::to_string(kMaxPipelineFileBytes >> 20) +
                      " MiB a pipeline file may have");
  };
  if (!ec && size > kMaxPipelineFileBytes) throw too_large();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot read the pipeline file");
  // At most the limit (and one byte more to notice a file that grew meanwhile).
  std::string text(static_cast<size_t>(kMaxPipelineFileBytes) + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  if (text.size() > kMaxPipelineFileBytes) throw too_large();
  fs::path base = fs::absolute(path).parent_path();
  Pipeline p = parse(text, path.string(), base);
  return p;
}

namespace {
// A first pass over the YAML events, before building the tree: refuses nesting deeper than
// kMaxYamlDepth (yaml-cpp's own guard, at 500 levels, says only "bad file") and a second document.
class StructureCheck final : public YAML::EventHandler {
public:
  explicit StructureCheck(const std::string& file) : file_(file) {}
  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents_ > 1)
      fail(file_, {mark.line + 1, mark.column + 1},
           "a second YAML document (after '---'); a pipeline file holds one document");
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    enter(mark);
  }
  void OnSequenceEnd() override { --depth_; }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    enter(mark);
  }
  void OnMapEnd() override { --depth_; }

private:
  void enter(const YAML::Mark& mark) {
    if (++depth_ > kMaxYamlDepth)
      fail(file_, {mark.line + 1, mark.column + 1},
           "mappings and lists nested deeper than " + std::to_string(kMaxYamlDepth) + " levels");
  }
  const std::string& file_;
  int depth_ = 0, documents_ = 0;
};
}  // namespace

Pipeline Pipeline::parse(const std::string& text, const std::string& file, const fs::path& base_dir) {
  YAML::Node root;
  try {
    {
      std::istringstream in(text);
      YAML::Parser parser(in);
      StructureCheck check(file);
      while (parser.HandleNextDocument(check)) {
      }
    }
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    fail(file, {e.mark.line + 1, e.mark.column + 1}, "YAML syntax error: " + e.msg);
  } catch (const YAML::Exception& e) {
    fail(file, {e.mark.line + 1, e.mark.column + 1}, std::string("YAML error: ") + e.what());
  }
  Pipeline p;
  p.file_ = file;
  p.base_dir_ = base_dir;
  if (!root.IsMap()) fail(file, pos_of(root), "a pipeline must be a mapping with keys 'skelflow' and 'nodes'");
  bool have_version = false, have_nodes = false;
  // Keys given twice (yaml-cpp keeps both) are errors at the second one.
  auto once = [&](std::map<std::string, SourcePos>& seen, const YAML::Node& key, const std::string& what) {
    const SourcePos at = pos_of(key);
    auto [it, fresh] = seen.emplace(key.Scalar(), at);
    if (!fresh)
      fail(file, at, what + "'" + key.Scalar() + "' given twice (first at line " + std::to_string(it->second.line) + ")");
  };
  std::map<std::string, SourcePos> top_keys;
  for (const auto& kv : root) {
    const std::string key = kv.first.Scalar();
    once(top_keys, kv.first, "top-level key ");
    if (key == "skelflow") {
      have_version = true;
      int64_t v = 0;
      if (!kv.second.IsScalar() || !parse_int(kv.second.Scalar(), v) || v != 1)
        fail(file, pos_of(kv.second), "unsupported format version '" + (kv.second.IsScalar() ? kv.second.Scalar() : std::string("?")) +
                                          "' (this Skelflow reads version 1)");
    } else if (key == "nodes") {
      have_nodes = true;
      const YAML::Node& nodes = kv.second;
      if (nodes.IsNull()) continue;
      if (!nodes.IsMap()) fail(file, pos_of(nodes), "'nodes' must be a mapping of node id to node");
      for (const auto& nkv : nodes) {
        PipelineNode n;
        n.id = nkv.first.Scalar();
        n.pos = pos_of(nkv.first);
        if (!valid_id(n.id))
          fail(file, n.pos, "invalid node id '" + n.id + "' (letters, digits, '_' and '-'; starts with a letter)");
        if (p.find(n.id)) {
          const PipelineNode* first = p.find(n.id);
          fail(file, n.pos, "duplicate node id '" + n.id + "' (first defined at line " +
                                std::to_string(first->pos.line) + ")");
        }
        const YAML::Node& body = nkv.second;
        if (!body.IsMap()) fail(file, pos_of(body), "node '" + n.id + "' must be a mapping with 'module'");
        std::map<std::string, SourcePos> node_keys;
        for (const auto& f : body) {
          const std::string fk = f.first.Scalar();
          once(node_keys, f.first, "node '" + n.id + "': key ");
          if (fk == "module") {
            if (!f.second.IsScalar()) fail(file, pos_of(f.second), "node '" + n.id + "': 'module' must be a name");
            n.module = f.second.Scalar();
            n.module_pos = pos_of(f.second);
          } else if (fk == "params") {
            if (f.second.IsNull()) continue;
            if (!f.second.IsMap()) fail(file, pos_of(f.second), "node '" + n.id + "': 'params' must be a mapping");
            for (const auto& pk : f.second) {
              const std::string name = pk.first.Scalar();
              if (n.params.count(name))
                fail(file, pos_of(pk.first), "node '" + n.id + "': parameter '" + name + "' given twice");
              n.params[name] = parse_param_value(pk.second, file, "node '" + n.id + "': param '" + name + "'");
              n.param_pos[name] = pos_of(pk.second);
            }
          } else if (fk == "inputs") {
            if (f.second.IsNull()) continue;
            if (!f.second.IsMap()) fail(file, pos_of(f.second), "node '" + n.id + "': 'inputs' must be a mapping");
            for (const auto& ik : f.second) {
              const std::string port = ik.first.Scalar();
              if (!ik.second.IsScalar())
                fail(file, pos_of(ik.second), "node '" + n.id + "': input '" + port + "' must be 'node.port'");
              auto ref = parse_port_ref(ik.second.Scalar());
              if (!ref)
                fail(file, pos_of(ik.second), "node '" + n.id + "': input '" + port + "': '" +
                                                  ik.second.Scalar() + "' is not of the form node.port");
              if (n.inputs.count(port))
                fail(file, pos_of(ik.first), "node '" + n.id + "': input '" + port + "' given twice");
              n.inputs[port] = *ref;
              n.input_pos[port] = pos_of(ik.second);
            }
          } else {
            fail(file, pos_of(f.first), "node '" + n.id + "': unknown key '" + fk +
                                            "' (expected module, inputs, params)");
          }
        }
        if (n.module.empty()) fail(file, n.pos, "node '" + n.id + "' has no 'module'");
        p.nodes_.push_back(std::move(n));
      }
    } else if (key == "execution") {
      p.execution_ = parse_execution(kv.second, file);
    } else if (key == "gui") {
      if (!kv.second.IsNull()) {
        YAML::Emitter e;
        e << kv.second;
        p.gui_yaml_ = e.c_str();
      }
    } else {
      fail(file, pos_of(kv.first), "unknown top-level key '" + key + "' (expected skelflow, nodes, execution, gui)");
    }
  }
  if (!have_version) fail(file, pos_of(root), "missing 'skelflow: 1' (the format version)");
  if (!have_nodes) fail(file, pos_of(root), "missing 'nodes'");
  return p;
}

// ---------------------------------------------------------------- save
std::string Pipeline::to_yaml() const {
  const Registry& reg = Registry::instance();
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "skelflow" << YAML::Value << 1;
  out << YAML::Key << "nodes" << YAML::Value;
  if (nodes_.empty()) {
    out << YAML::Flow << YAML::BeginMap << YAML::EndMap;
  } else {
    out << YAML::BeginMap;
    for (const auto& n : nodes_) {
      out << YAML::Key << n.id << YAML::Value << YAML::BeginMap;
      out << YAML::Key << "module" << YAML::Value << n.module;
      const ModuleSpec* spec = reg.find(n.module);
      if (!n.inputs.empty()) {
        out << YAML::Key << "inputs" << YAML::Value << YAML::Flow << YAML::BeginMap;
        // Declared order when the module is known, then the rest.
        std::vector<std::string> order;
        if (spec)
          for (const auto& ps : spec->inputs())
            if (n.inputs.count(ps.name)) order.push_back(ps.name);
        for (const auto& [port, ref] : n.inputs)
          if (std::find(order.begin(), order.end(), port) == order.end()) order.push_back(port);
        for (const auto& port : order) out << YAML::Key << port << YAML::Value << n.inputs.at(port).str();
        out << YAML::EndMap;
      }
      if (!n.params.empty()) {
        out << YAML::Key << "params" << YAML::Value << YAML::Flow << YAML::BeginMap;
        std::vector<std::string> order;
        if (spec)
          for (const auto& ps : spec->params())
            if (n.params.count(ps.name)) order.push_back(ps.name);
        for (const auto& [name, v] : n.params)
          if (std::find(order.begin(), order.end(), name) == order.end()) order.push_back(name);
        for (const auto& name : order) {
          ParamValue v = n.params.at(name);
          if (spec)
            if (const ParamSpec* ps = spec->find_param(name))
              if (auto c = coerce_param(*ps, v)) v = *c;
          out << YAML::Key << name << YAML::Value;
          emit_value(out, v);
        }
        out << YAML::EndMap;
      }
      out << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  if (!execution_.empty()) {
    out << YAML::Key << "execution" << YAML::Value << YAML::Flow << YAML::BeginMap;
    if (execution_.memory_budget > 0)
      out << YAML::Key << "memory_budget" << YAML::Value
          << (execution_.memory_budget_text.empty() ? std::to_string(execution_.memory_budget) : execution_.memory_budget_text);
    if (execution_.block != Dims{0, 0, 0})
      out << YAML::Key << "block" << YAML::Value << YAML::Flow << YAML::BeginSeq << execution_.block[0]
          << execution_.block[1] << execution_.block[2] << YAML::EndSeq;
    out << YAML::EndMap;
  }
  if (!gui_yaml_.empty()) {
    out << YAML::Key << "gui" << YAML::Value << YAML::Load(gui_yaml_);
  }
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

void Pipeline::save(const fs::path& path) {
  const std::string text = to_yaml();
  write_atomically(path, [&](const fs::path& tmp) {
    std::ofstream o(tmp, std::ios::binary);
    o << text;
    if (!o.flush()) throw Error("cannot write " + tmp.string());
  });
  file_ = path.string();
  base_dir_ = fs::absolute(path).parent_path();
  // Positions now refer to the file just written, so that run-time errors point into it.
  Pipeline saved;
  try {
    saved = parse(text, file_, base_dir_);
  } catch (const Error&) {
  }
  for (auto& n : nodes_) {
    const PipelineNode* s = saved.find(n.id);
    n.pos = s ? s->pos : SourcePos{};
    n.module_pos = s ? s->module_pos : SourcePos{};
    n.param_pos = s ? s->param_pos : std::map<std::string, SourcePos>{};
    n.input_pos = s ? s->input_pos : std::map<std::string, SourcePos>{};
  }
}

// ---------------------------------------------------------------- editing
const PipelineNode* Pipeline::find(const std::string& id) const {
  for (const auto& n : nodes_)
    if (n.id == id) return &n;
  return nullptr;
}
PipelineNode* Pipeline::find(const std::string& id) {
  for (auto& n : nodes_)
    if (n.id == id) return &n;
  return nullptr;
}

PipelineNode& Pipeline::add_node(const std::string& id, const std::string& module) {
  if (!valid_id(id)) throw InputError("invalid node id '" + id + "'");
  if (find(id)) throw InputError("duplicate node id '" + id + "'");
  PipelineNode n;
  n.id = id;
  n.module = module;
  nodes_.push_back(std::move(n));
  return nodes_.back();
}

void Pipeline::remove_node(const std::string& id) {
  auto it = std::find_if(nodes_.begin(), nodes_.end(), [&](const PipelineNode& n) { return n.id == id; });
  if (it == nodes_.end()) throw InputError("unknown node '" + id + "'");
  nodes_.erase(it);
  for (auto& n : nodes_) {
    for (auto i = n.inputs.begin(); i != n.inputs.end();) {
      if (i->second.node == id) i = n.inputs.erase(i);
      else ++i;
    }
  }
}

void Pipeline::rename_node(const std::string& id, const std::string& new_id) {
  if (id == new_id) return;
  PipelineNode* n = find(id);
  if (!n) throw InputError("unknown node '" + id + "'");
  if (!valid_id(new_id)) throw InputError("invalid node id '" + new_id + "'");
  if (find(new_id)) throw InputError("duplicate node id '" + new_id + "'");
  n->id = new_id;
  for (auto& m : nodes_)
    for (auto& [port, ref] : m.inputs)
      if (ref.node == id) ref.node = new_id;
}

void Pipeline::set_param(const std::string& node, const std::string& param, ParamValue value) {
  PipelineNode* n = find(node);
  if (!n) throw InputError("unknown node '" + node + "'");
  n->params[param] = std::move(value);
}

void Pipeline::reset_param(const std::string& node, const std::string& param) {
  PipelineNode* n = find(node);
  if (!n) throw InputError("unknown node '" + node + "'");
  n->params.erase(param);
}

std::string Pipeline::connect(const PortRef& from, const std::string& to_node, const std::string& to_port,
                              const Registry& registry) {
  const PipelineNode* src = find(from.node);
  PipelineNode* dst = find(to_node);
  if (!src) return "unknown node '" + from.node + "'";
  if (!dst) return "unknown node '" + to_node + "'";
  if (from.node == to_node) return "a node cannot be connected to itself";
  const ModuleSpec* ss = registry.find(src->module);
  const ModuleSpec* ds = registry.find(dst->module);
  if (!ss) return "unknown module '" + src->module + "'";
  if (!ds) return "unknown module '" + dst->module + "'";
  const PortSpec* op = ss->find_output(from.port);
  const PortSpec* ip = ds->find_input(to_port);
  if (!op) return "module " + ss->name() + " has no output '" + from.port + "'";
  if (!ip) return "module " + ds->name() + " has no input '" + to_port + "'";
  bool compatible = false;
  for (const auto& t : op->types)
    if (std::find(ip->types.begin(), ip->types.end(), t) != ip->types.end()) compatible = true;
  if (!compatible) {
    std::string a, b;
    for (const auto& t : op->types) { if (!a.empty()) a += "|"; a += t; }
    for (const auto& t : ip->types) { if (!b.empty()) b += "|"; b += t; }
    return "type mismatch: " + from.str() + " gives " + a + " but " + to_node + "." + to_port + " takes " + b;
  }
  // Would it create a cycle? It does if to_node is upstream of from.node.
  std::set<std::string> up = upstream_closure({from.node});
  if (up.count(to_node)) return "connecting " + from.str() + " to " + to_node + "." + to_port + " would create a cycle";
  dst->inputs[to_port] = from;
  return {};
}

void Pipeline::disconnect(const std::string& to_node, const std::string& to_port) {
  PipelineNode* n = find(to_node);
  if (!n) throw InputError("unknown node '" + to_node + "'");
  n->inputs.erase(to_port);
}

std::string Pipeline::unique_id(const std::string& stem_in) const {
  std::string stem = stem_in;
  if (auto d = stem.rfind('.'); d != std::string::npos) stem = stem.substr(d + 1);
  if (!valid_id(stem)) stem = "node";
  if (!find(stem)) return stem;
  for (int i = 2;; ++i) {
    std::string c = stem + std::to_string(i);
    if (!find(c)) return c;
  }
}

std::set<std::string> Pipeline::upstream_closure(const std::vector<std::string>& targets) const {
  std::set<std::string> seen;
  if (targets.empty()) {
    for (const auto& n : nodes_) seen.insert(n.id);
    return seen;
  }
  std::vector<std::string> stack(targets.begin(), targets.end());
  while (!stack.empty()) {
    std::string id = stack.back();
    stack.pop_back();
    if (!seen.insert(id).second) continue;
    if (const PipelineNode* n = find(id))
      for (const auto& [port, ref] : n->inputs) stack.push_back(ref.node);
  }
  return seen;
}

namespace {
// Kahn's algorithm, picking the earliest node in file order among the ready ones. Returns node
// indices in order; `left` gets the nodes that never became ready (on or behind a cycle).
std::vector<size_t> kahn_order(const std::vector<PipelineNode>& nodes, std::vector<size_t>& left) {
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < nodes.size(); ++i) index[nodes[i].id] = i;
  std::vector<int> indeg(nodes.size(), 0);
  std::vector<std::vector<size_t>> users(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    std::set<size_t> deps;
    for (const auto& [port, ref] : nodes[i].inputs) {
      auto it = index.find(ref.node);
      if (it != index.end()) deps.insert(it->second);
    }
    for (size_t d : deps) {
      users[d].push_back(i);
      ++indeg[i];
    }
  }
  std::set<size_t> ready;
  for (size_t i = 0; i < nodes.size(); ++i)
    if (indeg[i] == 0) ready.insert(i);
  std::vector<size_t> order;
  while (!ready.empty()) {
    size_t i = *ready.begin();
    ready.erase(ready.begin());
    order.push_back(i);
    for (size_t u : users[i])
      if (--indeg[u] == 0) ready.insert(u);
  }
  left.clear();
  for (size_t i = 0; i < nodes.size(); ++i)
    if (indeg[i] > 0) left.push_back(i);
  return order;
}

// One cycle among the nodes Kahn's algorithm left (each of them reads from another one left, so
// following inputs inside that set must come back to a node already seen): the nodes on it in the
// direction data flows, starting with the one earliest in the file. Nodes merely downstream of a
// cycle are not on it.
std::vector<size_t> find_cycle(const std::vector<PipelineNode>& nodes, const std::vector<size_t>& left) {
  std::map<std::string, size_t> index;
  for (size_t i : left) index[nodes[i].id] = i;
  std::vector<size_t> path;
  std::map<size_t, size_t> at;  // node -> position in path
  size_t cur = left.front();
  while (!at.count(cur)) {
    at[cur] = path.size();
    path.push_back(cur);
    size_t next = cur;
    for (const auto& [port, ref] : nodes[cur].inputs)
      if (auto it = index.find(ref.node); it != index.end()) {
        next = it->second;
        break;
      }
    cur = next;
  }
  std::vector<size_t> cycle(path.begin() + static_cast<std::ptrdiff_t>(at[cur]), path.end());
  std::reverse(cycle.begin(), cycle.end());  // walked against the data flow
  std::rotate(cycle.begin(), std::min_element(cycle.begin(), cycle.end()), cycle.end());
  return cycle;
}

std::string cycle_message(const std::vector<PipelineNode>& nodes, const std::vector<size_t>& cycle) {
  std::string cyc;
  for (size_t i : cycle) cyc += "'" + nodes[i].id + "' -> ";
  return "the pipeline has a cycle: " + cyc + "'" + nodes[cycle.front()].id + "'";
}
}  // namespace

std::vector<std::string> Pipeline::topological_order() const {
  std::vector<size_t> left;
  const std::vector<size_t> order = kahn_order(nodes_, left);
  if (!left.empty()) {
    const std::vector<size_t> cycle = find_cycle(nodes_, left);
    const PipelineNode& first = nodes_[cycle.front()];
    throw InputError(Diagnostic{file_, first.pos, "", cycle_message(nodes_, cycle)}.format());
  }
  std::vector<std::string> ids;
  for (size_t i : order) ids.push_back(nodes_[i].id);
  return ids;
}

bool Pipeline::operator==(const Pipeline& o) const {
  if (nodes_.size() != o.nodes_.size()) return false;
  for (size_t i = 0; i < nodes_.size(); ++i) {
    const auto& a = nodes_[i];
    const auto& b = o.nodes_[i];
    if (a.id != b.id || a.module != b.module || a.inputs != b.inputs) return false;
    if (a.params.size() != b.params.size()) return false;
    const ModuleSpec* spec = Registry::instance().find(a.module);
    for (const auto& [k, v] : a.params) {
      auto it = b.params.find(k);
      if (it == b.params.end()) return false;
      ParamValue va = v, vb = it->second;
      if (spec)
        if (const ParamSpec* ps = spec->find_param(k)) {
          if (auto c = coerce_param(*ps, va)) va = *c;
          if (auto c = coerce_param(*ps, vb)) vb = *c;
        }
      if (!(va == vb)) return false;
    }
  }
  auto norm = [](const std::string& g) -> std::string {
    if (g.empty()) return {};
    YAML::Emitter e;
    e << YAML::Load(g);
    return e.c_str();
  };
  return execution_ == o.execution_ && norm(gui_yaml_) == norm(o.gui_yaml_);
}

// ---------------------------------------------------------------- validation
namespace {
size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}
// "a, b, c": the names an error lists (a module's ports).
std::string join_names(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) { if (!s.empty()) s += ", "; s += n; }
  return s;
}
std::vector<std::string> pipeline_node_ids(const Pipeline& p) {
  std::vector<std::string> ids;
  for (const auto& n : p.nodes()) ids.push_back(n.id);
  return ids;
}
// Port types as users read them: the common sets by name (as `skelflow modules` shows them).
std::string join_types(const std::vector<std::string>& ts) {
  if (ts == all_volume_types()) return "any volume";
  if (ts == integer_volume_types()) return "integer volume";
  std::string s;
  for (const auto& t : ts) { if (!s.empty()) s += "|"; s += t; }
  return s;
}
}  // namespace

std::string did_you_mean(const std::string& name, const std::vector<std::string>& candidates) {
  std::string best;
  size_t bd = 3;
  for (const auto& c : candidates) {
    size_t d = edit_distance(name, c);
    if (d < bd) { bd = d; best = c; }
  }
  return best.empty() ? std::string() : " (did you mean '" + best + "'?)";
}

namespace {
// As the executor resolves a path parameter (detail::resolve_path): against `base` unless absolute.
fs::path resolve_against(const fs::path& base, const std::string& value) {
  const fs::path path(value);
  if (path.is_absolute() || base.empty()) return path.lexically_normal();
  return (base / path).lexically_normal();
}
// The path with the symbolic links of its existing part resolved, absolute, without a trailing '/'.
fs::path real_path(const fs::path& path) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) r = fs::absolute(path, ec).lexically_normal();
  if (!r.has_filename() && r.has_parent_path() && r != r.root_path()) r = r.parent_path();
  return r;
}
bool is_inside(const fs::path& path, const fs::path& dir) {
  auto d = dir.begin(), p = path.begin();
  for (; d != dir.end(); ++d, ++p)
    if (p == path.end() || *p != *d) return false;
  return true;
}
std::string join_or(const std::vector<std::string>& xs) {
  std::string s;
  for (size_t i = 0; i < xs.size(); ++i) s += (i == 0 ? "" : i + 1 == xs.size() ? " or " : ", ") + xs[i];
  return s;
}

// "slices/z*.tif": a file-name pattern (input paths that accept folders accept those too).
bool is_file_pattern(const fs::path& f) { return f.filename().string().find_first_of("*?[") != std::string::npos; }

// Output types narrowed by ModuleSpec::output_type_from (a reader looking at its file's header), and
// the nodes whose files could not tell (reported at their first input file parameter).
struct Deductions {
  std::map<PortRef, DeducedOutput> types;
  struct Failure {
    std::string param, message;
  };
  std::map<std::string, Failure> errors;
};

Deductions deduce_output_types(const Pipeline& p, const Registry& registry) {
  Deductions r;
  for (const auto& n : p.nodes()) {
    const ModuleSpec* spec = registry.find(n.module);
    if (!spec) continue;
    bool any = false;
    for (const auto& o : spec->outputs()) any = any || static_cast<bool>(o.deduce_types);
    if (!any) continue;
    // Only for valid parameters and existing input files (other problems are reported as such).
    bool valid = true;
    for (const auto& [name, value] : n.params) {
      const ParamSpec* ps = spec->find_param(name);
      if (!ps) { valid = false; break; }
      auto c = coerce_param(*ps, value);
      if (!c || !ps->check(*c).empty()) { valid = false; break; }
    }
    if (!valid) continue;
    const ParamMap eff = effective_params(n, *spec);
    std::map<std::string, fs::path> files;
    std::string first_file;
    for (const auto& ps : spec->params()) {
      if (ps.type != ParamType::Path || ps.path_role != PathRole::Input) continue;
      const auto* value = std::get_if<std::string>(&eff.at(ps.name));
      if (!value || value->empty()) continue;
      const fs::path f = resolve_against(p.base_dir(), *value);
      std::error_code ec;
      const fs::file_status st = fs::status(f, ec);
      const bool pattern_ok = ps.folder_ok && is_file_pattern(f) && fs::is_directory(f.parent_path(), ec);
      if (!pattern_ok && (!fs::exists(st) || (fs::is_directory(st) && !ps.folder_ok))) { valid = false; break; }
      files[ps.name] = f;
      if (first_file.empty()) first_file = ps.name;
    }
    if (!valid) continue;
    const OutputTypeQuery q{eff, [&files](const std::string& name) {
                              auto it = files.find(name);
                              if (it == files.end()) throw InputError("parameter '" + name + "' names no input file");
                              return it->second;
                            }};
    for (const auto& o : spec->outputs()) {
      if (!o.deduce_types) continue;
      try {
        DeducedOutput d = o.deduce_types(q);
        r.types[PortRef{n.id, o.name}] = std::move(d);
      } catch (const Error& e) {
        r.errors[n.id] = {first_file, e.what()};
        break;
      }
    }
  }
  return r;
}

}  // namespace

std::vector<Diagnostic> validate(const Pipeline& p, const Registry& registry, const PathPolicy& paths) {
  std::vector<Diagnostic> ds;
  auto add = [&](const PipelineNode& n, SourcePos pos, std::string msg) {
    ds.push_back({p.file(), pos.known() ? pos : n.pos, n.id, std::move(msg)});
  };
  // A parameter set outside the file (--set) is reported at its origin, not at the file's value.
  auto add_param = [&](const PipelineNode& n, const std::string& name, SourcePos pos, std::string msg) {
    auto o = n.param_origin.find(name);
    if (o == n.param_origin.end()) add(n, pos, std::move(msg));
    else ds.push_back({o->second, {}, n.id, std::move(msg)});
  };
  std::vector<std::string> module_names;
  for (const auto* s : registry.specs()) module_names.push_back(s->name());
  const Deductions deduced = deduce_output_types(p, registry);
  for (const auto& n : p.nodes()) {
    const ModuleSpec* spec = registry.find(n.module);
    if (!spec) {
      add(n, n.module_pos, "unknown module '" + n.module + "'" + did_you_mean(n.module, module_names) +
                               " (`skelflow modules` lists them)");
      continue;
    }
    // Parameters.
    std::vector<std::string> pnames;
    for (const auto& ps : spec->params()) pnames.push_back(ps.name);
    for (const auto& [name, value] : n.params) {
      SourcePos pos = n.param_pos.count(name) ? n.param_pos.at(name) : n.pos;
      const ParamSpec* ps = spec->find_param(name);
      if (!ps) {
        add_param(n, name, pos, "unknown parameter '" + name + "' of " + n.module + did_you_mean(name, pnames));
        continue;
      }
      auto c = coerce_param(*ps, value);
      if (!c) {
        add_param(n, name, pos, "param '" + name + "': expected " + to_string(ps->type) + ", got '" + format_value(value) + "'");
        continue;
      }
      std::string m = ps->check(*c);
      if (!m.empty()) add_param(n, name, pos, "param '" + name + "': " + m);
    }
    for (const auto& ps : spec->params()) {
      if (ps.type == ParamType::Path && !ps.optional_value && !n.params.count(ps.name) &&
          std::get<std::string>(ps.default_value).empty())
        add(n, n.pos, "param '" + ps.name + "' (a file path) is required");
    }
    // Inputs.
    std::vector<std::string> inames;
    for (const auto& ip : spec->inputs()) inames.push_back(ip.name);
    for (const auto& [port, ref] : n.inputs) {
      SourcePos pos = n.input_pos.count(port) ? n.input_pos.at(port) : n.pos;
      const PortSpec* ip = spec->find_input(port);
      if (!ip) {
        add(n, pos, "unknown input port '" + port + "' of " + n.module + did_you_mean(port, inames) + "; its inputs: " +
                        (inames.empty() ? std::string("none") : join_names(inames)));
        continue;
      }
      const PipelineNode* src = p.find(ref.node);
      if (!src) {
        add(n, pos, "input '" + port + "': no node '" + ref.node + "'" + did_you_mean(ref.node, pipeline_node_ids(p)));
        continue;
      }
      const ModuleSpec* ss = registry.find(src->module);
      if (!ss) continue;  // reported on that node
      const PortSpec* op = ss->find_output(ref.port);
      if (!op) {
        std::vector<std::string> onames;
        for (const auto& o : ss->outputs()) onames.push_back(o.name);
        add(n, pos, "input '" + port + "': node '" + ref.node + "' (" + src->module + ") has no output '" +
                        ref.port + "'" + did_you_mean(ref.port, onames) + "; its outputs: " +
                        (onames.empty() ? std::string("none") : join_names(onames)));
        continue;
      }
      const std::vector<std::string>* gives = &op->types;
      std::string why;
      if (auto d = deduced.types.find(ref); d != deduced.types.end()) {
        gives = &d->second.types;
        if (!d->second.reason.empty()) why = " (" + d->second.reason + ")";
      }
      bool ok = false;
      for (const auto& t : *gives)
        if (std::find(ip->types.begin(), ip->types.end(), t) != ip->types.end()) ok = true;
      if (!ok)
        add(n, pos, "input '" + port + "': type mismatch: " + ref.str() + " gives " + join_types(*gives) + why +
                        ", but '" + port + "' takes " + join_types(ip->types));
    }
    for (const auto& ip : spec->inputs())
      if (ip.required && !n.inputs.count(ip.name))
        add(n, n.pos, "required input '" + ip.name + "' (" + join_types(ip.types) + ") is not connected");
  }
  // Files: inputs that do not exist, outputs with an extension their writer does not know, outputs
  // outside --output-dir, two outputs into one file (compared with symbolic links resolved).
  const fs::path out_base = paths.output_dir.empty() ? p.base_dir() : fs::absolute(paths.output_dir);
  const fs::path confine = paths.output_dir.empty() || paths.allow_outside ? fs::path() : real_path(out_base);
  struct Writer {
    std::string node, param, where;
  };
  std::map<fs::path, Writer> writers;
  for (const auto& n : p.nodes()) {
    const ModuleSpec* spec = registry.find(n.module);
    if (!spec) continue;
    const ParamMap eff = effective_params(n, *spec);
    for (const auto& ps : spec->params()) {
      if (ps.type != ParamType::Path || ps.path_role == PathRole::None) continue;
      const auto* value = std::get_if<std::string>(&eff.at(ps.name));
      if (!value || value->empty()) continue;  // a bad value is reported above, a missing one too
      const SourcePos pos = n.param_pos.count(ps.name) ? n.param_pos.at(ps.name) : n.pos;
      const std::string param = "param '" + ps.name + "': ";
      if (ps.path_role == PathRole::Input) {
        const fs::path f = resolve_against(p.base_dir(), *value);
        std::error_code ec;
        const fs::file_status st = fs::status(f, ec);
        if (ps.folder_ok && is_file_pattern(f)) {
          if (!fs::is_directory(f.parent_path(), ec))
            add_param(n, ps.name, pos, param + "folder '" + f.parent_path().string() + "' of the pattern not found");
          else if (auto e = deduced.errors.find(n.id); e != deduced.errors.end() && e->second.param == ps.name)
            add_param(n, ps.name, pos, param + e->second.message);
        } else if (!fs::exists(st)) add_param(n, ps.name, pos, param + "input file '" + f.string() + "' not found");
        else if (fs::is_directory(st) && !ps.folder_ok) add_param(n, ps.name, pos, param + "'" + f.string() + "' is a folder, not a file");
        else if (auto e = deduced.errors.find(n.id); e != deduced.errors.end() && e->second.param == ps.name)
          add_param(n, ps.name, pos, param + e->second.message);
        continue;
      }
      const fs::path f = resolve_against(out_base, *value);
      if (!ps.extensions.empty()) {
        bool check = true;
        if (!ps.extensions_unless.empty())
          if (auto it = eff.find(ps.extensions_unless); it != eff.end())
            if (auto* c = std::get_if<std::string>(&it->second); c && *c != "auto") check = false;
        const std::string ext = text::to_lower(f.extension().string());
        // Compound extensions (".nii.gz") match as a suffix of the file name.
        const std::string fname = text::to_lower(f.filename().string());
        const bool known = std::any_of(ps.extensions.begin(), ps.extensions.end(), [&](const std::string& e) {
          return fname.size() > e.size() && fname.compare(fname.size() - e.size(), e.size(), e) == 0;
        });
        if (check && !known)
          add_param(n, ps.name, pos,
                    param + "'" + *value + "': " + (ext.empty() ? "no file extension" : "unknown extension '" + ext + "'") +
                        "; " + n.module + " writes " + join_or(ps.extensions) +
                        (ps.extensions_unless.empty() ? "" : " (or set '" + ps.extensions_unless + "')"));
      }
      const fs::path real = real_path(f);
      if (!confine.empty() && !is_inside(real, confine)) {
        add_param(n, ps.name, pos,
                  param + "output '" + *value + "' resolves to " + real.string() + ", outside the output folder " +
                      confine.string() + " (--allow-outside-output-dir allows it)");
        continue;
      }
      std::error_code ec;
      if (fs::is_directory(real, ec)) {
        add_param(n, ps.name, pos, param + "output '" + real.string() + "' is an existing folder");
        continue;
      }
      auto o = n.param_origin.find(ps.name);
      std::string where;
      if (o != n.param_origin.end()) where = o->second;
      else if (pos.known()) where = p.file() + ":" + std::to_string(pos.line) + ":" + std::to_string(pos.column);
      auto [it, fresh] = writers.emplace(real, Writer{n.id, ps.name, where});
      if (!fresh) {
        const Writer& w = it->second;
        add_param(n, ps.name, pos,
                  param + "writes the same file " + real.string() + " as node '" + w.node + "' param '" + w.param + "'" +
                      (w.where.empty() ? "" : " (" + w.where + ")"));
      }
    }
  }
  // A module that tells its output types from its parameters alone (no input file) and failed.
  for (const auto& [id, failure] : deduced.errors)
    if (failure.param.empty())
      if (const PipelineNode* n = p.find(id)) add(*n, n->pos, failure.message);
  // A cycle is reported at the first of its nodes in the file.
  std::vector<size_t> left;
  (void)kahn_order(p.nodes(), left);
  if (!left.empty()) {
    const std::vector<size_t> cycle = find_cycle(p.nodes(), left);
    ds.push_back({p.file(), p.nodes()[cycle.front()].pos, "", cycle_message(p.nodes(), cycle)});
  }
  return ds;
}

void validate_or_throw(const Pipeline& p, const Registry& registry, const PathPolicy& paths) {
  auto ds = validate(p, registry, paths);
  if (ds.empty()) return;
  std::string msg;
  for (const auto& d : ds) { if (!msg.empty()) msg += "\n"; msg += d.format(); }
  throw InputError(msg);
}

}  // namespace skel
