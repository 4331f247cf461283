// The mask rule (framework/skel/mask.hpp): any integer volume, voxel > 0 is object; float volumes
// are an error naming the port. (Moved from the distance tests, where binary_mask lived.)
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace skel
