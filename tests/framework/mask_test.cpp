// The mask rule (framework/skel/mask.hpp): any integer volume, voxel > 0 is object; float volumes
// are an error naming the port. (Moved from the distance tests, where binary_mask lived.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "skel/error.hpp"
#include "skel/mask.hpp"

namespace skel {
namespace {

TEST(Mask, BinaryMaskRules) {
  VolumeU16 u16({3, 2, 1}, 0);
  u16[1] = 700;
  VolumeU8 b = to_mask(u16, "mask");
  EXPECT_EQ(1, b[1]);
  EXPECT_EQ(0, b[0]);
  VolumeI32 i32({3, 2, 1}, -5);
  i32[2] = 3;
  b = to_mask(i32, "mask");
  EXPECT_EQ(0, b[0]);  // negative values are background (voxel > 0 is object)
  EXPECT_EQ(1, b[2]);
  VolumeF32 f({3, 2, 1}, 0.5f);
  try {
    (void)to_mask(f, "seeds");
    FAIL() << "float mask accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("seeds"), std::string::npos) << e.what();
  }
}

TEST(Mask, SharedMaskKeepsUint8AndConvertsOthers) {
  auto u8 = std::make_shared<VolumeU8>(Dims{2, 2, 1}, uint8_t{0});
  (*u8)[3] = 255;
  auto same = shared_mask(u8, "mask");
  EXPECT_EQ(same.get(), u8.get());  // no copy, values as they are
  auto u16 = std::make_shared<VolumeU16>(Dims{2, 2, 1}, uint16_t{0});
  (*u16)[2] = 9;
  auto conv = shared_mask(u16, "mask");
  EXPECT_EQ(1, (*conv)[2]);
  EXPECT_EQ(0, (*conv)[0]);
  EXPECT_EQ(conv->grid().dims, u16->grid().dims);
  EXPECT_THROW((void)shared_mask(std::make_shared<VolumeF64>(Dims{1, 1, 1}, 1.0), "mask"), InputError);
}

// A grey image in a mask port is "all object" where it is > 0: a volume holding values other than 0
// and 1 gives a warning naming the port (and saying so when every voxel is > 0); 0/1 masks give none.
TEST(Mask, ValuesOtherThanZeroAndOneGiveAWarning) {
  std::string w = "stale";
  VolumeU16 grey({4, 3, 2}, 0);
  for (int64_t i = 0; i < grey.size(); ++i) grey[i] = static_cast<uint16_t>(100 + i);  // every voxel > 0
  VolumeU8 m = to_mask(grey, "input 'mask'", &w);
  EXPECT_EQ(m[0], 1);
  EXPECT_NE(w.find("input 'mask': a mask holds 0 and 1, but this volume holds values from 100 to 123"),
            std::string::npos) << w;
  EXPECT_NE(w.find("here all of them"), std::string::npos) << w;

  VolumeI32 labels({4, 3, 2}, 0);
  labels[5] = -1;  // negative: not 0/1 either, though background
  (void)to_mask(labels, "input 'mask'", &w);
  EXPECT_NE(w.find("from -1 to 0"), std::string::npos) << w;
  EXPECT_EQ(w.find("all of them"), std::string::npos) << w;

  VolumeU16 binary({4, 3, 2}, 0);
  binary[7] = 1;
  (void)to_mask(binary, "input 'mask'", &w);
  EXPECT_TRUE(w.empty()) << w;

  auto u8 = std::make_shared<VolumeU8>(Dims{70000, 1, 1}, uint8_t{1});
  (void)shared_mask(u8, "seeds", &w);
  EXPECT_TRUE(w.empty()) << w;
  (*u8)[69999] = 200;  // past the first block of the blocked passes
  auto same = shared_mask(u8, "seeds", &w);
  EXPECT_EQ(same.get(), u8.get());
  EXPECT_NE(w.find("seeds: a mask holds 0 and 1, but this volume holds values from 1 to 200"), std::string::npos) << w;
  auto grey16 = std::make_shared<VolumeU16>(Dims{70000, 1, 1}, uint16_t{0});
  (*grey16)[69999] = 2;
  (void)shared_mask(grey16, "seeds", &w);
  EXPECT_NE(w.find("from 0 to 2"), std::string::npos) << w;
  // Without a place for the warning, nothing is checked and the result is the same.
  EXPECT_EQ(to_mask(grey, "input 'mask'")[3], 1);
}

// How much the check costs is measured by bench/engine (bench_engine, "mask value check"), not here.

}  // namespace
}  // namespace skel
