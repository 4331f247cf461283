// skel::text: the shared trim / split / number helpers (C locale, whole-string numbers).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "skel/error.hpp"
#include "skel/text.hpp"

namespace skel::text {
namespace {

using Strings = std::vector<std::string>;

TEST(Text, TrimAndLower) {
  EXPECT_EQ(trim("  a b \t\r\n"), "a b");
  EXPECT_EQ(trim(" \t "), "");
  EXPECT_EQ(trim(""), "");
  EXPECT_EQ(to_lower(".LandmarkAscii"), ".landmarkascii");
  EXPECT_EQ(to_lower("µm X"), "µm x");  // bytes >= 0x80 untouched
}

TEST(Text, SplitKeepsEmptyFields) {
  EXPECT_EQ(split("a,b,,c", ','), (Strings{"a", "b", "", "c"}));
  EXPECT_EQ(split("", ','), (Strings{""}));
  EXPECT_EQ(split(",", ','), (Strings{"", ""}));
  EXPECT_EQ(split("a b\r", ','), (Strings{"a b\r"}));
}

TEST(Text, SplitLines) {
  EXPECT_EQ(split_lines("a\r\nb\n\nc"), (Strings{"a", "b", "", "c"}));
  EXPECT_EQ(split_lines("a\n"), (Strings{"a"}));
  EXPECT_EQ(split_lines(""), Strings{});
}

TEST(Text, WholeStringNumbers) {
  int64_t i = 0;
  EXPECT_TRUE(parse_int("-42", i));
  EXPECT_EQ(i, -42);
  EXPECT_TRUE(parse_int("9223372036854775807", i));
  EXPECT_EQ(i, std::numeric_limits<int64_t>::max());
  for (const char* bad : {"", "+1", " 1", "1 ", "1.0", "0x10", "9223372036854775808"}) EXPECT_FALSE(parse_int(bad, i)) << bad;
  double d = 0;
  EXPECT_TRUE(parse_double("1.5e-3", d));
  EXPECT_EQ(d, 1.5e-3);
  EXPECT_TRUE(parse_double("-7", d));
  EXPECT_EQ(d, -7.0);
  EXPECT_TRUE(parse_double("inf", d));
  EXPECT_TRUE(std::isinf(d));
  EXPECT_TRUE(parse_double("nan", d));
  EXPECT_TRUE(std::isnan(d));
  for (const char* bad : {"", "+1", " 1", "1,5", "1.5x", "e3", "."}) EXPECT_FALSE(parse_double(bad, d)) << bad;
}

TEST(Text, FormatAsPrintfG) {
  EXPECT_EQ(format_double(0.1, 17), "0.10000000000000001");
  EXPECT_EQ(format_double(0.1, 9), "0.1");
  EXPECT_EQ(format_double(static_cast<double>(0.1f), 9), "0.100000001");
  EXPECT_EQ(format_double(1e21, 9), "1e+21");
  EXPECT_EQ(format_double(-2.5, 6), "-2.5");
  EXPECT_EQ(format_double(123456789.0, 6), "1.23457e+08");
  EXPECT_EQ(format_double(std::numeric_limits<double>::infinity(), 9), "inf");
  std::string s = "x=";
  append_double(s, 3.0, 17);
  EXPECT_EQ(s, "x=3");
  // Identical to snprintf("%.<n>g") in the C locale, over a spread of magnitudes.
  for (double v : {0.0, -0.0, 1.0 / 3.0, 6.02214076e23, 1e-310, 123.456, -9.999999999e-5, 2.0e9}) {
    for (int n : {6, 9, 17}) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.*g", n, v);
      EXPECT_EQ(format_double(v, n), std::string(buf)) << v << " " << n;
    }
  }
}

}  // namespace
}  // namespace skel::text

// Base64 exists once (skel/text.hpp), for VTK XML data of graphs and volumes and for the report's
// embedded PNG: round trips of every length, two padded streams back to back (VTK's compressed
// header, then its blocks) with white space, and clear errors.
TEST(Text, Base64RoundTripsAndConcatenatedStreams) {
  const std::string all = std::string("\x00\x01\xfe\xff", 4) + "Skelflow volumes";
  for (size_t n = 0; n <= all.size(); ++n) {
    const std::string e = skel::text::base64_encode(std::string_view(all).substr(0, n));
    EXPECT_EQ(e.size() % 4, 0u);
    EXPECT_EQ(skel::text::base64_decode(e, "w"), all.substr(0, n)) << n;
  }
  EXPECT_EQ(skel::text::base64_encode("Ma"), "TWE=");
  EXPECT_EQ(skel::text::base64_encode("abcd"), "YWJjZA==");
  EXPECT_EQ(skel::text::base64_decode("TWE=\n  TQ==", "w"), "MaM");
  auto error_of = [](std::string_view t) {
    try {
      (void)skel::text::base64_decode(t, "file.vti: inline data");
    } catch (const skel::InputError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(error_of("TW!="), "file.vti: inline data: '!' at character 2 is not base64");
  EXPECT_EQ(error_of("TWE"), "file.vti: inline data: base64 text ends in the middle of a group (truncated)");
  EXPECT_EQ(error_of("T==="), "file.vti: inline data: misplaced base64 padding at character 1");
}
