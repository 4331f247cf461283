#pragma once
// Physical units of data and parameters. A volume's grid and a graph carry the unit of their
// coordinates (Grid::unit, SpatialGraph::unit: kDefaultUnit when a file names none); tables,
// files and the report derive every unit from it ("mm", "mm²", "mm³", "mm⁻²").
#include <string>

namespace skel::units {

// Parameter unit of a length given in the physical unit of the module's input (the grid's or the
// graph's unit: whatever the file says). Areas and volumes likewise.
inline constexpr const char* length = "input unit";
inline constexpr const char* area = "input unit²";
inline constexpr const char* volume = "input unit³";

// `unit` raised to `power` (-9..9, 0 gives ""): "mm" → "mm²", "mm³", "mm⁻²". A unit that already
// has a product or quotient in it is bracketed ("(px·s)²").
std::string power(const std::string& unit, int power);

// Throws InputError "WHAT_A and WHAT_B: units differ ('mm' and 'µm')" unless a == b: data of two
// inputs measured in different units are never combined.
void check_same(const std::string& a, const std::string& what_a, const std::string& b, const std::string& what_b);

}  // namespace skel::units
