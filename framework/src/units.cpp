#include "skel/units.hpp"

#include <cstdlib>

#include "skel/error.hpp"

namespace skel::units {

std::string power(const std::string& unit, int p) {
  if (p == 0 || unit.empty()) return {};
  if (p == 1) return unit;
  static const char* const digits[] = {"⁰", "¹", "²", "³", "⁴", "⁵", "⁶", "⁷", "⁸", "⁹"};
  // Compound units ("N m", "m/s", "kg·m") get parentheses. Search whole characters: "·" is two
  // bytes in UTF-8, the first of which µ shares (a byte-wise find_first_of made "µm³" "(µm)³").
  bool compound = unit.find_first_of(" */^") != std::string::npos || unit.find("·") != std::string::npos;
  std::string s = compound ? "(" + unit + ")" : unit;
  if (p < 0) s += "⁻";
  s += digits[std::abs(p) % 10];
  return s;
}

void check_same(const std::string& a, const std::string& what_a, const std::string& b, const std::string& what_b) {
  if (a != b)
    throw InputError(what_a + " and " + what_b + ": units differ ('" + a + "' and '" + b +
                     "'); convert one of them (io.read_graph: scale and unit; io.read_volume: spacing and unit)");
}

}  // namespace skel::units
