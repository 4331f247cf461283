#pragma once
// Module API: a module declares ports and parameters once, in a ModuleSpec (which feeds the YAML
// validator, the CLI docs and the GUI panel), and implements run(RunContext&).
#include <array>
#include <atomic>
#include <concepts>
#include <utility>
#include <limits>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/enum_names.hpp"
#include "skel/error.hpp"
#include "skel/interrupter.hpp"
#include "skel/out_of_core.hpp"
#include "skel/param.hpp"
#include "skel/volume.hpp"

namespace skel {

// Maps a C++ data type to its port type ids (used by ModuleSpec::input<T>/output<T>).
template <class T> struct PortTypes { static std::vector<std::string> ids() { return {T{}.type_id()}; } };
template <class T> struct PortTypes<Volume<T>> {
  static std::vector<std::string> ids() { return {VoxelTraits<T>::id}; }
};
// Marker types for ports accepting several types.
struct AnyVolume {};
struct AnyIntegerVolume {};
template <> struct PortTypes<AnyVolume> { static std::vector<std::string> ids() { return all_volume_types(); } };
template <> struct PortTypes<AnyIntegerVolume> {
  static std::vector<std::string> ids() { return integer_volume_types(); }
};

using ParamMap = std::map<std::string, ParamValue>;

// What the function of ModuleSpec::output_type_from sees at validation: the node's parameters
// (defaults applied, every value already checked against its spec) and its input file paths
// resolved against the pipeline's folder (each one exists).
struct OutputTypeQuery {
  const ParamMap& params;
  std::function<std::filesystem::path(const std::string& param)> input_path;
};
// The types an output will have for these parameters and files (a subset of the port's declared
// types) and why, for messages ("'ve.tif' holds uint16 voxels"; may be empty).
struct DeducedOutput {
  std::vector<std::string> types;
  std::string reason;
};
using OutputTypeFn = std::function<DeducedOutput(const OutputTypeQuery&)>;

struct PortSpec {
  std::string name;
  std::vector<std::string> types;  // accepted (inputs) or possible (outputs) type ids
  std::string doc;
  bool required = true;            // inputs only
  // Outputs only, optional: narrows `types` from the parameters and input files before anything
  // runs (ModuleSpec::output_type_from). Throws InputError naming the file when it cannot tell.
  OutputTypeFn deduce_types;
};

template <class T> struct ParamTypeOf;
template <> struct ParamTypeOf<bool> { static constexpr ParamType value = ParamType::Bool; };
template <> struct ParamTypeOf<int64_t> { static constexpr ParamType value = ParamType::Int; };
template <> struct ParamTypeOf<int> { static constexpr ParamType value = ParamType::Int; };
template <> struct ParamTypeOf<double> { static constexpr ParamType value = ParamType::Float; };
template <> struct ParamTypeOf<std::string> { static constexpr ParamType value = ParamType::String; };
template <> struct ParamTypeOf<std::vector<int64_t>> { static constexpr ParamType value = ParamType::IntList; };
template <> struct ParamTypeOf<std::vector<double>> { static constexpr ParamType value = ParamType::FloatList; };


namespace detail {
template <class T> struct IsStdVector : std::false_type {};
template <class T, class A> struct IsStdVector<std::vector<T, A>> : std::true_type {};
template <class T> struct IsStdArray : std::false_type {};
template <class T, size_t N> struct IsStdArray<std::array<T, N>> : std::true_type {};

// Converts one scalar parameter value to a member of type M (the value already passed
// ParamSpec::check). Integers that do not fit M are input errors naming the parameter.
template <class M>
M scalar_from(const ParamValue& v, const std::string& name) {
  if constexpr (std::is_same_v<M, bool>) {
    return std::get<bool>(v);
  } else if constexpr (NamedEnum<M>) {
    return parse_enum<M>(std::get<std::string>(v), "parameter '" + name + "'");
  } else if constexpr (std::is_integral_v<M>) {
    const int64_t x = std::get<int64_t>(v);
    if (!std::in_range<M>(x))
      throw InputError("parameter '" + name + "': value " + std::to_string(x) + " is out of range");
    return static_cast<M>(x);
  } else if constexpr (std::is_floating_point_v<M>) {
    if (auto* i = std::get_if<int64_t>(&v)) return static_cast<M>(*i);
    return static_cast<M>(std::get<double>(v));
  } else {
    static_assert(std::is_same_v<M, std::string>, "unsupported parameter member type");
    return std::get<std::string>(v);
  }
}

// Converts a list parameter value to std::vector<E> (E integral or floating point).
template <class E>
std::vector<E> list_from(const ParamValue& v, const std::string& name) {
  std::vector<E> r;
  if (auto* iv = std::get_if<std::vector<int64_t>>(&v)) {
    for (int64_t x : *iv) r.push_back(scalar_from<E>(ParamValue(x), name));
  } else {
    for (double x : std::get<std::vector<double>>(v)) r.push_back(scalar_from<E>(ParamValue(x), name));
  }
  return r;
}

template <class M>
void assign_member(M& member, const ParamValue& v, const std::string& name) {
  if constexpr (IsStdVector<M>::value) {
    member = list_from<typename M::value_type>(v, name);
  } else if constexpr (IsStdArray<M>::value) {
    const auto xs = list_from<typename M::value_type>(v, name);
    if (xs.size() != member.size())
      throw InputError("parameter '" + name + "': expected a list of " + std::to_string(member.size()) + " values");
    std::copy(xs.begin(), xs.end(), member.begin());
  } else {
    member = scalar_from<M>(v, name);
  }
}

// Type, default value, choices and list length of a parameter bound to a member of type M whose
// default (the options struct's default member initialiser) is `def`.
template <class M>
void describe_member(ParamSpec& p, const M& def) {
  if constexpr (IsStdVector<M>::value || IsStdArray<M>::value) {
    using E = typename M::value_type;
    static_assert(std::is_arithmetic_v<E> && !std::is_same_v<E, bool>, "lists hold numbers");
    if constexpr (std::is_integral_v<E>) {
      p.type = ParamType::IntList;
      p.default_value = std::vector<int64_t>(def.begin(), def.end());
    } else {
      p.type = ParamType::FloatList;
      p.default_value = std::vector<double>(def.begin(), def.end());
    }
    if constexpr (IsStdArray<M>::value) p.list_length = static_cast<int>(std::tuple_size_v<M>);
  } else if constexpr (std::is_same_v<M, bool>) {
    p.type = ParamType::Bool;
    p.default_value = def;
  } else if constexpr (NamedEnum<M>) {
    p.type = ParamType::Choice;
    p.choices = enum_choices<M>();
    p.default_value = std::string(enum_name(def));
  } else if constexpr (std::is_integral_v<M>) {
    p.type = ParamType::Int;
    p.default_value = static_cast<int64_t>(def);
  } else if constexpr (std::is_floating_point_v<M>) {
    p.type = ParamType::Float;
    p.default_value = static_cast<double>(def);
  } else {
    static_assert(std::is_same_v<M, std::string>, "unsupported parameter member type");
    p.type = ParamType::String;
    p.default_value = def;
  }
}
}  // namespace detail

class ModuleSpec {
public:
  ModuleSpec() = default;
  // name: "family.name" in snake_case; doc: one line; the long description goes in details().
  ModuleSpec(std::string name, std::string doc) : name_(std::move(name)), doc_(std::move(doc)) {}

  // --- ports ---
  template <class T>
  ModuleSpec& input(std::string name, std::string doc) {
    return add_input(std::move(name), PortTypes<T>::ids(), std::move(doc), true);
  }
  template <class T>
  ModuleSpec& optional_input(std::string name, std::string doc) {
    return add_input(std::move(name), PortTypes<T>::ids(), std::move(doc), false);
  }
  template <class T>
  ModuleSpec& output(std::string name, std::string doc) {
    return add_output(std::move(name), PortTypes<T>::ids(), std::move(doc));
  }
  ModuleSpec& add_input(std::string name, std::vector<std::string> types, std::string doc, bool required);
  ModuleSpec& add_output(std::string name, std::vector<std::string> types, std::string doc);
  // Lets validate() know the type of output `port` from the parameters and the input files (e.g. a
  // reader looks at a file's header): `fn` returns the types it will have, and validate() checks the
  // connections from that port against them, naming the reason. An InputError `fn` throws (missing
  // or unreadable header) is reported at the node's input file parameter. validate() calls `fn` only
  // when the node's parameters are valid and its input files exist; it must be cheap (a header, not
  // the data) and must not write anything.
  ModuleSpec& output_type_from(const std::string& port, OutputTypeFn fn);

  // --- parameters (modifiers below apply to the last one added) ---
  // A parameter the module reads itself with ctx.param<T>(name) (choices: an enum with enum_names).
  template <class T>
  ModuleSpec& param(std::string name, T default_value, std::string doc) {
    ParamSpec p;
    p.name = std::move(name);
    if constexpr (NamedEnum<T>) {
      detail::describe_member<T>(p, default_value);
    } else {
      p.type = ParamTypeOf<T>::value;
      if constexpr (std::is_same_v<T, int>) p.default_value = static_cast<int64_t>(default_value);
      else p.default_value = std::move(default_value);
    }
    p.doc = std::move(doc);
    return add_param(std::move(p));
  }
  ModuleSpec& param(std::string name, const char* default_value, std::string doc) {
    return param<std::string>(std::move(name), std::string(default_value), std::move(doc));
  }
  // A parameter bound to a member of an algorithm's options struct: its type, default (the
  // struct's default member initialiser), choices (enums with enum_names) and list length (arrays)
  // come from the member; ctx.options<Opt>() fills the struct. Declare ranges, units and docs here,
  // and nowhere else.
  template <class Opt, class M>
    requires std::is_class_v<Opt>
  ModuleSpec& param(std::string name, M Opt::*member, std::string doc) {
    ParamSpec p;
    p.name = std::move(name);
    p.doc = std::move(doc);
    detail::describe_member<M>(p, Opt{}.*member);
    p.bound_to = typeid(Opt);
    p.assign = [member, n = p.name](void* options, const ParamValue& v) {
      detail::assign_member(static_cast<Opt*>(options)->*member, v, n);
    };
    return add_param(std::move(p));
  }
  // A parameter that sets an options struct through `setter(Opt&, const V&)`, for values that
  // are not one member (e.g. three chamfer weights expanded to seven).
  template <class Opt, class V, class F>
  ModuleSpec& param_fn(std::string name, V default_value, F setter, std::string doc) {
    ParamSpec p;
    p.name = std::move(name);
    p.doc = std::move(doc);
    detail::describe_member<V>(p, default_value);
    p.bound_to = typeid(Opt);
    p.assign = [setter, n = p.name](void* options, const ParamValue& v) {
      V value{};
      detail::assign_member(value, v, n);
      setter(*static_cast<Opt*>(options), value);
    };
    return add_param(std::move(p));
  }
  ModuleSpec& choice(std::string name, std::vector<std::string> choices, std::string default_value,
                     std::string doc);
  ModuleSpec& path(std::string name, std::string default_value, PathRole role, std::string doc);
  ModuleSpec& range(double min, double max);
  ModuleSpec& min(double min);
  ModuleSpec& max(double max);
  ModuleSpec& unit(std::string unit);
  ModuleSpec& length(int n);          // lists: exact length
  ModuleSpec& optional_value();       // empty string / empty list means "not given"
  ModuleSpec& accepts_folder();       // input paths: a folder or a file-name pattern ("z*.tif") too
  // A Path parameter's accepted file extensions (".h5", any case in the path), checked at
  // validation for outputs; with `unless_param`, only while that choice parameter is "auto".
  ModuleSpec& extensions(std::vector<std::string> exts, std::string unless_param = {});
  ModuleSpec& renamed_from(std::string old_name);
  // Overrides the default of the last parameter (a bound parameter whose module default differs
  // from the algorithm's, e.g. a pipeline-friendly default).
  ModuleSpec& default_value(ParamValue value);
  ModuleSpec& add_param(ParamSpec p);

  // Long documentation (markdown): algorithm, memory per voxel, conventions, references.
  ModuleSpec& details(std::string text);

  // Declares that the module runs block by block under a memory budget (see
  // docs/architecture.md, "Out-of-core execution"): `halo` voxels of context around every block,
  // `bytes_per_voxel` of block buffers (inputs + outputs + work per voxel of a block with halo).
  ModuleSpec& blockwise(int64_t halo, int64_t bytes_per_voxel);
  struct BlockSupport {
    bool blockwise = false;
    int64_t halo = 0, bytes_per_voxel = 1;
  };
  [[nodiscard]] const BlockSupport& block_support() const { return block_support_; }

  // Declares that run() can write output `output_port` into the buffer of input `input_port` when the
  // executor hands that buffer over (RunContext::take_input; docs/architecture.md, "In-place
  // execution"): the module then saves the output's allocation and the copy. Both ports must be
  // declared before; the module must give the same bytes either way (it runs out of place whenever
  // take_input returns nullptr).
  ModuleSpec& in_place(const std::string& input_port, const std::string& output_port);
  struct InPlace {
    std::string input, output;
  };
  [[nodiscard]] const std::vector<InPlace>& in_place_ports() const { return in_place_; }

  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] std::string family() const { return name_.substr(0, name_.find('.')); }
  [[nodiscard]] const std::string& doc() const { return doc_; }
  [[nodiscard]] const std::string& details() const { return details_; }
  [[nodiscard]] const std::vector<PortSpec>& inputs() const { return inputs_; }
  [[nodiscard]] const std::vector<PortSpec>& outputs() const { return outputs_; }
  [[nodiscard]] const std::vector<ParamSpec>& params() const { return params_; }
  [[nodiscard]] const PortSpec* find_input(const std::string& n) const;
  [[nodiscard]] const PortSpec* find_output(const std::string& n) const;
  // Finds a parameter by its name or one of its old names.
  [[nodiscard]] const ParamSpec* find_param(const std::string& n) const;

private:
  std::string name_, doc_, details_;
  std::vector<PortSpec> inputs_, outputs_;
  std::vector<ParamSpec> params_;
  BlockSupport block_support_;
  std::vector<InPlace> in_place_;
};

// Everything run() may use: inputs, parameters, outputs, progress, cancellation, threads, paths.
class RunContext {
public:
  virtual ~RunContext() = default;

  // Input data, or nullptr for an unconnected optional input.
  [[nodiscard]] virtual DataPtr input_data(const std::string& port) const = 0;
  [[nodiscard]] bool has_input(const std::string& port) const { return input_data(port) != nullptr; }
  // Typed input; throws InputError naming the port when missing or of another type.
  template <class T>
  [[nodiscard]] std::shared_ptr<const T> input(const std::string& port) const {
    DataPtr d = input_data(port);
    if (!d) throw InputError("input '" + port + "' is not connected");
    auto t = std::dynamic_pointer_cast<const T>(d);
    if (!t) {
      throw InputError("input '" + port + "': expected " + PortTypes<T>::ids().front() + ", got " +
                       d->type_id());
    }
    return t;
  }
  // Optional typed input: nullptr when not connected.
  template <class T>
  [[nodiscard]] std::shared_ptr<const T> optional_input(const std::string& port) const {
    return has_input(port) ? input<T>(port) : nullptr;
  }

  // Input `port` for writing in place, when the executor handed its buffer over to this node: the spec
  // declares in_place(port, ...), this node is the last one reading that output, the output is no
  // target and is not kept for the GUI, the node reads it on no other port, and nothing else holds
  // the data (no cache entry, no caller's reference, no wrapped outside memory). nullptr otherwise,
  // and always outside the executor's in-memory runs: the module then computes out of place. A
  // second call returns nullptr. The data is the one input_data(port) returns.
  template <class T>
  [[nodiscard]] std::shared_ptr<T> take_input(const std::string& port) {
    auto t = std::dynamic_pointer_cast<T>(std::const_pointer_cast<DataObject>(take_input_data(port)));
    if constexpr (requires { t->wraps_external_memory(); })
      if (t && t->wraps_external_memory()) return nullptr;
    return t;
  }
  // The untyped form of take_input (nullptr when not handed over).
  [[nodiscard]] virtual DataPtr take_input_data(const std::string& /*port*/) { return nullptr; }
  // false when output `port` would be dropped unread as soon as the node is done (a headless run in
  // which no node reads it and the node is no target): the module may skip computing it and its
  // memory. true otherwise, and always outside the executor.
  [[nodiscard]] virtual bool output_wanted(const std::string& /*port*/) const { return true; }

  // Parameter value (defaults already applied). T must match the declared type (int64_t for Int,
  // double for Float, std::string for String/Choice/Path, vectors for lists).
  [[nodiscard]] virtual const ParamValue& param_value(const std::string& name) const = 0;
  template <class T>
  [[nodiscard]] T param(const std::string& name) const {
    const ParamValue& v = param_value(name);
    if constexpr (NamedEnum<T>) {
      return parse_enum<T>(std::get<std::string>(v), "parameter '" + name + "'");
    } else if constexpr (std::is_same_v<T, int>) {
      return static_cast<int>(std::get<int64_t>(v));
    } else {
      if (auto* p = std::get_if<T>(&v)) return *p;
      throw Error("parameter '" + name + "' requested with the wrong C++ type");
    }
  }

  // The options struct Opt filled from every parameter bound to it in the spec (see
  // ModuleSpec::param(name, &Opt::member, doc)), plus `threads` and `interrupter` when Opt has them.
  template <class Opt>
  [[nodiscard]] Opt options() const {
    Opt o{};
    fill(o);
    return o;
  }
  // An options struct that extends another names it `using OptionsBase = Base;`, and the
  // parameters bound to the base's members are filled too.
  template <class Opt>
  void fill(Opt& o) const {
    for (const ParamSpec& p : spec().params())
      if (p.bound_to == typeid(Opt)) p.assign(&o, param_value(p.name));
    if constexpr (requires { typename Opt::OptionsBase; })
      fill(static_cast<typename Opt::OptionsBase&>(o));
    if constexpr (requires { o.threads = 1; }) o.threads = threads();
    if constexpr (requires { o.interrupter = progress(); }) o.interrupter = progress();
  }
  // The specification of the running module.
  [[nodiscard]] virtual const ModuleSpec& spec() const = 0;

  virtual void output(const std::string& port, DataPtr data) = 0;
  template <class T>
  void output(const std::string& port, T&& value) {
    output(port, DataPtr(std::make_shared<std::decay_t<T>>(std::forward<T>(value))));
  }

  [[nodiscard]] virtual const Interrupter& progress() const = 0;
  [[nodiscard]] bool cancelled() const { return progress().cancelled(); }
  [[nodiscard]] virtual int threads() const = 0;
  [[nodiscard]] virtual const std::string& node_id() const = 0;
  virtual void warn(const std::string& message) = 0;

  // Absolute path for an input file parameter (relative to the pipeline file's folder).
  [[nodiscard]] virtual std::filesystem::path input_path(const std::string& param_name) const = 0;
  // Temporary path to write an output file parameter to; the engine renames it to its final place
  // when the whole run succeeds and deletes it otherwise (no partial outputs). Directories are
  // created. The final path is returned by final_output_path().
  [[nodiscard]] virtual std::filesystem::path output_path(const std::string& param_name) = 0;
  [[nodiscard]] virtual std::filesystem::path final_output_path(const std::string& param_name) const = 0;

  // Under a memory budget, for a module whose spec declares blockwise(): the block shape and the
  // factory of on-disk output volumes; nullptr when the module runs in memory (no budget).
  [[nodiscard]] virtual const BlockPlan* blocks() const { return nullptr; }
  // An empty on-disk volume for output `port` (blocks() must be set); removed when the run ends.
  [[nodiscard]] std::shared_ptr<ChunkedVolume> scratch_volume(const std::string& port, const std::string& type_id,
                                                              const Grid& grid) const {
    if (!blocks() || !blocks()->scratch) throw Error("output '" + port + "': no scratch volumes outside a budgeted run");
    return blocks()->scratch(port, type_id, grid);
  }
};

class Module {
public:
  virtual ~Module() = default;
  virtual void run(RunContext& ctx) = 0;
};

// Inspects a file for `skelflow info` (registered by io modules, so framework names no format).
struct FileInspector {
  std::string name;                     // e.g. "HDF5 volume"
  std::vector<std::string> extensions;  // lower case, with dot: ".h5", ".hdf5"
  std::function<std::string(const std::filesystem::path&)> describe;
  // Optional: claims a path no extension matches (a folder of slices, a file-name pattern, a known
  // file under another name by its magic bytes).
  std::function<bool(const std::filesystem::path&)> claims{};
};

class Registry {
public:
  using Factory = std::function<std::unique_ptr<Module>()>;
  static Registry& instance();

  void add(ModuleSpec spec, Factory factory);  // throws Error on a duplicate name
  void add_inspector(FileInspector inspector);
  [[nodiscard]] const ModuleSpec* find(const std::string& name) const;
  [[nodiscard]] std::unique_ptr<Module> create(const std::string& name) const;  // throws if unknown
  // All specs sorted by name.
  [[nodiscard]] std::vector<const ModuleSpec*> specs() const;
  [[nodiscard]] const std::vector<FileInspector>& inspectors() const { return inspectors_; }

private:
  struct Entry {
    ModuleSpec spec;
    Factory factory;
  };
  std::map<std::string, Entry> entries_;
  std::vector<FileInspector> inspectors_;
};

namespace detail {
template <class M>
struct Registrar {
  Registrar() { Registry::instance().add(M::spec(), [] { return std::make_unique<M>(); }); }
};
struct InspectorRegistrar {
  explicit InspectorRegistrar(FileInspector i) { Registry::instance().add_inspector(std::move(i)); }
};
}  // namespace detail

#define SKEL_CONCAT_INNER(a, b) a##b
#define SKEL_CONCAT(a, b) SKEL_CONCAT_INNER(a, b)
// Registers module class M (with `static ModuleSpec spec()`) at static-initialisation time.
#define SKEL_REGISTER_MODULE(M) \
  static const ::skel::detail::Registrar<M> SKEL_CONCAT(skel_registrar_, __LINE__) {}
#define SKEL_REGISTER_INSPECTOR(...)                                                       \
  static const ::skel::detail::InspectorRegistrar SKEL_CONCAT(skel_inspector_, __LINE__) { \
    ::skel::FileInspector{__VA_ARGS__}                                                     \
  }

}  // namespace skel
