#pragma once
// Parameter values and their specifications (type, default, range, choices, unit, doc).
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <typeindex>
#include <typeinfo>
#include <variant>
#include <vector>

namespace skel {

enum class ParamType { Bool, Int, Float, String, Choice, Path, IntList, FloatList };
// "bool", "int", ... as written in docs and error messages.
const char* to_string(ParamType t);

using ParamValue =
    std::variant<bool, int64_t, double, std::string, std::vector<int64_t>, std::vector<double>>;

// Human-readable form of a value ("true", "3", "0.5", "rods", "[128, 128, 128]").
std::string format_value(const ParamValue& v);

enum class PathRole { None, Input, Output };  // how relative paths resolve; outputs are transactional

struct ParamSpec {
  std::string name;
  ParamType type = ParamType::Float;
  ParamValue default_value;
  std::string doc;
  std::string unit;                      // e.g. units::length (the input's unit), "voxels"; empty if unitless
  std::optional<double> min, max;        // inclusive range for numbers and list elements
  std::vector<std::string> choices;      // for Choice
  int list_length = -1;                  // for lists: required length, -1 = any
  PathRole path_role = PathRole::None;   // for Path
  bool optional_value = false;           // an empty string / list means "not given"
  bool folder_ok = false;                // Input paths: a folder or a file-name pattern (*, ?, [) is accepted
  // Output paths: the file extensions the writer accepts (lower case, with dot), checked by
  // validate(); empty = any. While the choice parameter `extensions_unless` is not "auto" (a format
  // given explicitly), any extension is accepted.
  std::vector<std::string> extensions;
  std::string extensions_unless;
  std::vector<std::string> old_names;    // renamed parameters still accepted when loading YAML
  // Binding to a member of an algorithm's options struct (ModuleSpec::param(name, &Opt::member, doc)):
  // the struct's type and a function that stores a checked value into that member of an Opt object.
  // RunContext::options<Opt>() fills a struct from every parameter bound to Opt.
  std::type_index bound_to = typeid(void);
  std::function<void(void* options, const ParamValue& value)> assign;

  // Checks type, range, choices, length; returns an error message or empty if `v` is acceptable.
  [[nodiscard]] std::string check(const ParamValue& v) const;
};

}  // namespace skel
