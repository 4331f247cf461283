// Unit strings: powers of simple and compound units, and the check that two inputs agree.
#include <gtest/gtest.h>

#include "skel/error.hpp"
#include "skel/units.hpp"

using namespace skel;

// "µm" is one unit, not a compound: µm³, not (µm)³ (before: a byte-wise search for "·" matched the
// first UTF-8 byte that µ and · share).
TEST(Units, PowersOfSimpleAndCompoundUnits) {
  EXPECT_EQ(units::power("µm", 3), "µm³");
  EXPECT_EQ(units::power("µm", -2), "µm⁻²");
  EXPECT_EQ(units::power("mm", 1), "mm");
  EXPECT_EQ(units::power("mm", 0), "");
  EXPECT_EQ(units::power("", 3), "");
  EXPECT_EQ(units::power("kg·m", 2), "(kg·m)²");
  EXPECT_EQ(units::power("m/s", 2), "(m/s)²");
  EXPECT_EQ(units::power("N m", 3), "(N m)³");
}

TEST(Units, DifferentUnitsAreRefusedNamingBothInputs) {
  EXPECT_NO_THROW(units::check_same("mm", "input 'a'", "mm", "input 'b'"));
  try {
    units::check_same("mm", "input 'a'", "µm", "input 'b'");
    FAIL();
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("input 'a' and input 'b'"), std::string::npos) << m;
    EXPECT_NE(m.find("'mm' and 'µm'"), std::string::npos) << m;
  }
}
