// The helpers shared by the raw-block volume formats (volume_bytes.hpp): zlib/gzip with
// exact sizes, byte order, type widening, unit names, size checks.
#include <gtest/gtest.h>

#include "io/volume_bytes.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;
namespace vb = skel::io::volbytes;

TEST(VolumeBytes, InflateChecksTheExactSize) {
  const std::string data(1000, 'a');
  for (bool gzip : {false, true}) {
    const std::string z = vb::deflate(data.data(), data.size(), 6, gzip);
    std::string out(1000, '\0');
    vb::inflate_into("f", "w", z.data(), z.size(), out.data(), out.size());
    EXPECT_EQ(out, data);
    std::string small(999, '\0');
    std::string e = error_of([&] { vb::inflate_into("f", "w", z.data(), z.size(), small.data(), small.size()); });
    EXPECT_NE(e.find("f: w: compressed data holds more than 999 bytes"), std::string::npos) << e;
    std::string big(1001, '\0');
    e = error_of([&] { vb::inflate_into("f", "w", z.data(), z.size(), big.data(), big.size()); });
    EXPECT_NE(e.find("f: w: compressed data holds 1000 of 1001 bytes"), std::string::npos) << e;
    e = error_of([&] { vb::inflate_into("f", "w", z.data(), z.size() / 2, big.data(), big.size()); });
    EXPECT_NE(e.find("(truncated)"), std::string::npos) << e;
  }
}

TEST(VolumeBytes, DecodeSwapsAndWidens) {
  const Grid g(Dims{2, 1, 1});
  const char be16[] = {'\xff', '\xfe', '\x01', '\x00'};  // int16 big endian: -2, 256
  const auto v = std::dynamic_pointer_cast<const VolumeI32>(
      vb::decode(g, "int16", true, [&](char* dst, uint64_t n) { std::memcpy(dst, be16, n); }));
  ASSERT_TRUE(v);
  EXPECT_EQ((*v)[0], -2);
  EXPECT_EQ((*v)[1], 256);
  const auto f = std::dynamic_pointer_cast<const VolumeF64>(vb::decode(g, "int64", false, [&](char* dst, uint64_t n) {
    const int64_t x[2] = {-5, int64_t{1} << 40};
    std::memcpy(dst, x, n);
  }));
  ASSERT_TRUE(f);
  EXPECT_EQ((*f)[0], -5.0);
  EXPECT_EQ((*f)[1], 1099511627776.0);
  VolumeU16 u(Dims{2, 1, 1}, 0);
  u[0] = 0x0102;
  EXPECT_EQ(vb::encode(u, true).substr(0, 2), std::string("\x01\x02", 2));
  EXPECT_EQ(vb::encode(u, false).substr(0, 2), std::string("\x02\x01", 2));
}

TEST(VolumeBytes, UnitsAndSizeChecks) {
  EXPECT_EQ(vb::normalize_unit("um"), kDefaultUnit);
  EXPECT_EQ(vb::normalize_unit("micrometer"), kDefaultUnit);
  EXPECT_EQ(vb::normalize_unit("\xce\xbcm"), kDefaultUnit);  // Greek mu
  EXPECT_EQ(vb::normalize_unit("\xb5m"), kDefaultUnit);  // Latin-1
  EXPECT_EQ(vb::normalize_unit(" millimeter "), "mm");
  EXPECT_EQ(vb::normalize_unit("nanometer"), "nm");
  EXPECT_EQ(vb::normalize_unit("pixel"), "pixel");
  std::string e = error_of([] { vb::checked_bytes("f.nrrd", Dims{int64_t{1} << 40, int64_t{1} << 20, 8}, 2); });
  EXPECT_NE(e.find("f.nrrd: sizes 1099511627776 x 1048576 x 8 are too large"), std::string::npos) << e;
  EXPECT_EQ(vb::checked_bytes("f", Dims{3, 4, 5}, 8), 480u);
  e = error_of([] { vb::check_compressed("f", 1000, 2000000, "data"); });
  EXPECT_NE(e.find("f: data claims 2000000 bytes but its compressed data is only 1000 bytes"), std::string::npos) << e;
  EXPECT_NO_THROW(vb::check_compressed("f", 1000, 1000000, "data"));
}
