#pragma once
// Names of enum values, declared once next to the enum, for parameters with a fixed set of choices.
//
//   enum class ThinningVariant { Basic, Smooth };
//   constexpr auto enum_names(ThinningVariant) {
//     return std::to_array<skel::EnumName<ThinningVariant>>({{ThinningVariant::Basic, "basic"},
//                                                            {ThinningVariant::Smooth, "smooth"}});
//   }
//
// `enum_names` is found by argument-dependent lookup, so it lives in the enum's own namespace. A
// ModuleSpec parameter bound to such a member becomes a choice parameter with these names, and the
// value is converted when the module fills its options (skel::parse_enum).
#include <algorithm>
#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "skel/error.hpp"

namespace skel {

template <class E>
struct EnumName {
  E value;
  const char* name;
};

template <class E>
concept NamedEnum = std::is_enum_v<E> && requires(E e) { enum_names(e); };

// All names in declaration order.
template <NamedEnum E>
std::vector<std::string> enum_choices() {
  std::vector<std::string> r;
  for (const auto& n : enum_names(E{})) r.emplace_back(n.name);
  return r;
}

template <NamedEnum E>
const char* enum_name(E value) {
  for (const auto& n : enum_names(E{}))
    if (n.value == value) return n.name;
  return "?";
}

// The value named `text`; throws InputError "<what>: 'x' is not one of: a b c" otherwise.
template <NamedEnum E>
E parse_enum(std::string_view text, const std::string& what) {
  for (const auto& n : enum_names(E{}))
    if (text == n.name) return n.value;
  std::string msg = what + ": '" + std::string(text) + "' is not one of:";
  for (const auto& n : enum_names(E{})) msg += std::string(" ") + n.name;
  throw InputError(msg);
}

}  // namespace skel
