#include "skel/module.hpp"
#include "registry_capture.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

namespace skel {

// ---------------------------------------------------------------- params
const char* to_string(ParamType t) {
  switch (t) {
    case ParamType::Bool: return "bool";
    case ParamType::Int: return "int";
    case ParamType::Float: return "float";
    case ParamType::String: return "string";
    case ParamType::Choice: return "choice";
    case ParamType::Path: return "path";
    case ParamType::IntList: return "int list";
    case ParamType::FloatList: return "float list";
  }
  return "?";
}

namespace {
std::string fmt_double(double d) {
  std::ostringstream s;
  s << d;
  std::string r = s.str();
  return r;
}
}  // namespace

std::string format_value(const ParamValue& v) {
  return std::visit(
      [](const auto& x) -> std::string {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) return x ? "true" : "false";
        else if constexpr (std::is_same_v<T, int64_t>) return std::to_string(x);
        else if constexpr (std::is_same_v<T, double>) return fmt_double(x);
        else if constexpr (std::is_same_v<T, std::string>) return x;
        else {
          std::string s = "[";
          for (size_t i = 0; i < x.size(); ++i) {
            if (i) s += ", ";
            if constexpr (std::is_same_v<T, std::vector<double>>) s += fmt_double(x[i]);
            else s += std::to_string(x[i]);
          }
          return s + "]";
        }
      },
      v);
}

std::string ParamSpec::check(const ParamValue& v) const {
  auto range_msg = [&](double x) -> std::string {
    if ((min && x < *min) || (max && x > *max) || std::isnan(x)) {
      std::ostringstream r;
      r << "value " << x << " is out of range [";
      if (min) r << *min; else r << "-inf";
      r << ", ";
      if (max) r << *max; else r << "inf";
      r << "]";
      if (!unit.empty()) r << " " << unit;
      return r.str();
    }
    return {};
  };
  switch (type) {
    case ParamType::Bool:
      return std::holds_alternative<bool>(v) ? "" : "expected true or false";
    case ParamType::Int:
      if (!std::holds_alternative<int64_t>(v)) return "expected an integer";
      return range_msg(static_cast<double>(std::get<int64_t>(v)));
    case ParamType::Float:
      if (!std::holds_alternative<double>(v)) return "expected a number";
      return range_msg(std::get<double>(v));
    case ParamType::String:
    case ParamType::Path:
      if (!std::holds_alternative<std::string>(v)) return "expected a string";
      if (type == ParamType::Path && std::get<std::string>(v).empty() && !optional_value)
        return "a path is required";
      return {};
    case ParamType::Choice: {
      if (!std::holds_alternative<std::string>(v)) return "expected one of the choices";
      const auto& s = std::get<std::string>(v);
      if (std::find(choices.begin(), choices.end(), s) != choices.end()) return {};
      std::string r = "'" + s + "' is not one of:";
      for (const auto& c : choices) r += " " + c;
      return r;
    }
    case ParamType::IntList:
    case ParamType::FloatList: {
      std::vector<double> xs;
      if (auto* iv = std::get_if<std::vector<int64_t>>(&v)) {
        for (auto x : *iv) xs.push_back(static_cast<double>(x));
      } else if (auto* dv = std::get_if<std::vector<double>>(&v)) {
        if (type == ParamType::IntList) return "expected a list of integers";
        xs = *dv;
      } else {
        return type == ParamType::IntList ? "expected a list of integers" : "expected a list of numbers";
      }
      if (xs.empty() && optional_value) return {};
      if (list_length >= 0 && static_cast<int>(xs.size()) != list_length)
        return "expected a list of " + std::to_string(list_length) + " values, got " +
               std::to_string(xs.size());
      for (double x : xs) {
        auto m = range_msg(x);
        if (!m.empty()) return m;
      }
      return {};
    }
  }
  return {};
}

// ---------------------------------------------------------------- ModuleSpec
ModuleSpec& ModuleSpec::add_input(std::string name, std::vector<std::string> types, std::string doc,
                                  bool required) {
  inputs_.push_back({std::move(name), std::move(types), std::move(doc), required, {}});
  return *this;
}
ModuleSpec& ModuleSpec::add_output(std::string name, std::vector<std::string> types, std::string doc) {
  outputs_.push_back({std::move(name), std::move(types), std::move(doc), true, {}});
  return *this;
}
ModuleSpec& ModuleSpec::add_param(ParamSpec p) {
  params_.push_back(std::move(p));
  return *this;
}
ModuleSpec& ModuleSpec::choice(std::string name, std::vector<std::string> choices,
                               std::string default_value, std::string doc) {
  ParamSpec p;
  p.name = std::move(name);
  p.type = ParamType::Choice;
  p.choices = std::move(choices);
  p.default_value = std::move(default_value);
  p.doc = std::move(doc);
  return add_param(std::move(p));
}
ModuleSpec& ModuleSpec::path(std::string name, std::string default_value, PathRole role, std::string doc) {
  ParamSpec p;
  p.name = std::move(name);
  p.type = ParamType::Path;
  p.default_value = std::move(default_value);
  p.path_role = role;
  p.doc = std::move(doc);
  return add_param(std::move(p));
}
static ParamSpec& last(std::vector<ParamSpec>& ps, const char* what) {
  if (ps.empty()) throw Error(std::string("ModuleSpec::") + what + " called before any param");
  return ps.back();
}
ModuleSpec& ModuleSpec::range(double lo, double hi) {
  auto& p = last(params_, "range");
  p.min = lo;
  p.max = hi;
  return *this;
}
ModuleSpec& ModuleSpec::min(double lo) { last(params_, "min").min = lo; return *this; }
ModuleSpec& ModuleSpec::max(double hi) { last(params_, "max").max = hi; return *this; }
ModuleSpec& ModuleSpec::unit(std::string u) { last(params_, "unit").unit = std::move(u); return *this; }
ModuleSpec& ModuleSpec::length(int n) { last(params_, "length").list_length = n; return *this; }
ModuleSpec& ModuleSpec::optional_value() { last(params_, "optional_value").optional_value = true; return *this; }
ModuleSpec& ModuleSpec::accepts_folder() { last(params_, "accepts_folder").folder_ok = true; return *this; }
ModuleSpec& ModuleSpec::extensions(std::vector<std::string> exts, std::string unless_param) {
  auto& p = last(params_, "extensions");
  if (p.type != ParamType::Path) throw Error("ModuleSpec::extensions: parameter '" + p.name + "' is not a path");
  for (auto& e : exts) {
    if (e.size() < 2 || e[0] != '.') throw Error("ModuleSpec::extensions: '" + e + "' must start with '.'");
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  }
  p.extensions = std::move(exts);
  p.extensions_unless = std::move(unless_param);
  return *this;
}
ModuleSpec& ModuleSpec::renamed_from(std::string old_name) {
  last(params_, "renamed_from").old_names.push_back(std::move(old_name));
  return *this;
}
ModuleSpec& ModuleSpec::default_value(ParamValue value) {
  last(params_, "default_value").default_value = std::move(value);
  return *this;
}
ModuleSpec& ModuleSpec::details(std::string text) {
  details_ = std::move(text);
  return *this;
}
ModuleSpec& ModuleSpec::blockwise(int64_t halo, int64_t bytes_per_voxel) {
  if (halo < 0 || bytes_per_voxel < 1) throw Error(name_ + ": blockwise() needs halo >= 0 and bytes_per_voxel >= 1");
  block_support_ = {true, halo, bytes_per_voxel};
  return *this;
}
ModuleSpec& ModuleSpec::in_place(const std::string& input_port, const std::string& output_port) {
  const PortSpec* in = find_input(input_port);
  const PortSpec* out = find_output(output_port);
  if (!in || !out)
    throw Error(name_ + ": in_place('" + input_port + "', '" + output_port + "') names an undeclared " +
                (in ? "output" : "input") + " port");
  in_place_.push_back({input_port, output_port});
  return *this;
}
const PortSpec* ModuleSpec::find_input(const std::string& n) const {
  for (const auto& p : inputs_)
    if (p.name == n) return &p;
  return nullptr;
}
ModuleSpec& ModuleSpec::output_type_from(const std::string& port, OutputTypeFn fn) {
  for (auto& o : outputs_)
    if (o.name == port) {
      o.deduce_types = std::move(fn);
      return *this;
    }
  throw Error("module " + name_ + ": output_type_from: no output port '" + port + "'");
}

const PortSpec* ModuleSpec::find_output(const std::string& n) const {
  for (const auto& p : outputs_)
    if (p.name == n) return &p;
  return nullptr;
}
const ParamSpec* ModuleSpec::find_param(const std::string& n) const {
  for (const auto& p : params_)
    if (p.name == n) return &p;
  for (const auto& p : params_)
    if (std::find(p.old_names.begin(), p.old_names.end(), n) != p.old_names.end()) return &p;
  return nullptr;
}

// ---------------------------------------------------------------- Registry
namespace {
// Set by the plugin loader (registry_capture.hpp) while a plugin's code runs.
Registry* g_capture = nullptr;
}  // namespace
void detail::set_registry_capture(Registry* capture) { g_capture = capture; }

Registry& Registry::instance() {
  static Registry r;
  return r;
}
void Registry::add(ModuleSpec spec, Factory factory) {
  if (g_capture && this == &instance()) return g_capture->add(std::move(spec), std::move(factory));
  const std::string name = spec.name();
  if (name.find('.') == std::string::npos) throw Error("module name '" + name + "' must be family.name");
  if (entries_.count(name)) throw Error("module '" + name + "' is registered twice");
  entries_.emplace(name, Entry{std::move(spec), std::move(factory)});
}
void Registry::add_inspector(FileInspector inspector) {
  if (g_capture && this == &instance()) return g_capture->add_inspector(std::move(inspector));
  inspectors_.push_back(std::move(inspector));
}
const ModuleSpec* Registry::find(const std::string& name) const {
  auto it = entries_.find(name);
  return it == entries_.end() ? nullptr : &it->second.spec;
}
std::unique_ptr<Module> Registry::create(const std::string& name) const {
  auto it = entries_.find(name);
  if (it == entries_.end()) throw InputError("unknown module '" + name + "'");
  return it->second.factory();
}
std::vector<const ModuleSpec*> Registry::specs() const {
  std::vector<const ModuleSpec*> r;
  for (const auto& [n, e] : entries_) r.push_back(&e.spec);
  return r;
}

}  // namespace skel
