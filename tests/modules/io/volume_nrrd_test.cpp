// NRRD volumes (.nrrd, .nhdr + detached data): round trips of every voxel type with spacing,
// origin, unit and direction; hand-written headers as other tools write them (big endian, gzip,
// ascii, detached raw.gz, spacings + units); bad files.
#include <gtest/gtest.h>

#include <bit>

#include "io/volume_bytes.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;

TEST(VolumeNrrd, RoundTripEveryTypeRawAndGzip) {
  for (int c : {0, 6}) {
    for_every_voxel_type([&](auto t) {
      using T = decltype(t);
      const auto v = random_volume<T>(Dims{13, 7, 5}, 11, "mm");
      const fs::path f = scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + "_" + std::to_string(c) + ".nrrd");
      io::VolumeWriteOptions o;
      o.compression = c;
      expect_round_trip(v, f, o);
    });
  }
}

TEST(VolumeNrrd, RoundTripRotatedDirectionAndUnit) {
  const auto v = random_volume<uint16_t>(Dims{6, 5, 4}, 3, "nm", true);
  expect_round_trip(v, scratch() / "rot.nrrd", {}, 1e-12);
  const io::VolumeHeader h = io::read_volume_header(scratch() / "rot.nrrd");
  EXPECT_TRUE(h.has_spacing && h.has_origin && h.has_unit);
  EXPECT_EQ(h.grid.unit, "nm");
}

TEST(VolumeNrrd, ReadsHandWrittenBigEndianWithSpacingsAndUnits) {
  // As teem's unu writes it: spacings (no space), per-axis units, big-endian int16.
  std::string s = "NRRD0004\n# made by hand\ntype: short\ndimension: 3\nsizes: 3 2 2\nspacings: 0.5 0.5 2\n"
                  "units: \"um\" \"um\" \"um\"\nendian: big\nencoding: raw\nkey:=value\n\n";
  for (int i = 0; i < 12; ++i) {
    const int16_t v = static_cast<int16_t>(i * 1000 - 6000);
    s += static_cast<char>((static_cast<uint16_t>(v) >> 8) & 0xff);
    s += static_cast<char>(static_cast<uint16_t>(v) & 0xff);
  }
  const fs::path f = scratch() / "be.nrrd";
  write_bytes(f, s);
  const auto v = std::dynamic_pointer_cast<const VolumeI32>(io::read_any_volume(f));  // int16 widens to int32
  ASSERT_TRUE(v);
  EXPECT_EQ(v->dims(), (Dims{3, 2, 2}));
  EXPECT_EQ(v->spacing(), (Vec3{0.5, 0.5, 2}));
  EXPECT_EQ(v->unit(), kDefaultUnit);  // "um" is µm
  for (int i = 0; i < 12; ++i) EXPECT_EQ((*v)[i], i * 1000 - 6000);
  const io::VolumeHeader h = io::read_volume_header(f);
  EXPECT_EQ(h.dtype, "int16");
  EXPECT_FALSE(h.has_origin);
  EXPECT_NE(io::describe_volume_file(f).find("format: NRRD"), std::string::npos);
}

TEST(VolumeNrrd, ReadsDetachedGzipAndAsciiAndSlicerStyleSpace) {
  // Slicer style: space + space directions + space origin, detached .raw.gz data.
  std::string data;
  for (int i = 0; i < 24; ++i) data += static_cast<char>(i * 10);
  write_bytes(scratch() / "vol.raw.gz", io::volbytes::deflate(data.data(), data.size(), 6, true));
  write_bytes(scratch() / "vol.nhdr",
              "NRRD0005\ntype: unsigned char\ndimension: 3\nspace: left-posterior-superior\nsizes: 4 3 2\n"
              "space directions: (0,0.5,0) (-0.25,0,0) (0,0,3)\nkinds: domain domain domain\n"
              "endian: little\nencoding: gzip\nspace units: \"mm\" \"mm\" \"mm\"\n"
              "space origin: (10,-20,30.5)\ndata file: vol.raw.gz\n");
  const auto v = std::dynamic_pointer_cast<const VolumeU8>(io::read_any_volume(scratch() / "vol.nhdr"));
  ASSERT_TRUE(v);
  EXPECT_EQ(v->spacing(), (Vec3{0.5, 0.25, 3}));
  EXPECT_EQ(v->origin(), (Vec3{10, -20, 30.5}));
  EXPECT_EQ(v->unit(), "mm");
  EXPECT_EQ(v->grid().direction, (Direction{0, -1, 0, 1, 0, 0, 0, 0, 1}));
  for (int i = 0; i < 24; ++i) EXPECT_EQ((*v)[i], i * 10);
  EXPECT_NE(io::describe_volume_file(scratch() / "vol.nhdr").find("left-posterior-superior"), std::string::npos);

  write_bytes(scratch() / "a.nrrd", "NRRD0001\ntype: float\ndimension: 2\nsizes: 3 2\nencoding: ascii\n\n"
                                    "1.5 2 -3\n4e2 5 6\n");
  const auto a = std::dynamic_pointer_cast<const VolumeF32>(io::read_any_volume(scratch() / "a.nrrd"));
  ASSERT_TRUE(a);
  EXPECT_EQ(a->dims(), (Dims{3, 2, 1}));
  EXPECT_EQ(std::vector<float>(a->begin(), a->end()), (std::vector<float>{1.5f, 2, -3, 400, 5, 6}));
}

TEST(VolumeNrrd, OneAndTwoAxisImagesGetAnOrthonormalFrame) {
  write_bytes(scratch() / "line.nrrd", "NRRD0004\ntype: uint8\ndimension: 1\nspace dimension: 3\nsizes: 3\n"
                                       "space directions: (0.6,0.8,0)\nencoding: raw\n\nabc");
  const io::VolumeHeader h = io::read_volume_header(scratch() / "line.nrrd");
  EXPECT_EQ(h.grid.dims, (Dims{3, 1, 1}));
  EXPECT_NEAR(h.grid.spacing[0], 1.0, 1e-15);
  const Direction& d = h.grid.direction;
  for (size_t i = 0; i < 3; ++i)
    for (size_t j = 0; j < 3; ++j) {
      double dot = 0;
      for (size_t r = 0; r < 3; ++r) dot += d[r * 3 + i] * d[r * 3 + j];
      EXPECT_NEAR(dot, i == j ? 1.0 : 0.0, 1e-12) << i << " " << j;
    }
  EXPECT_NEAR(d[0], 0.6, 1e-15);
  EXPECT_NEAR(d[3], 0.8, 1e-15);
}

TEST(VolumeNrrd, FoundByMagicBytesWithoutExtension) {
  io::write_any_volume(scratch() / "v.nrrd", random_volume<uint8_t>(Dims{2, 2, 2}, 1));
  fs::copy_file(scratch() / "v.nrrd", scratch() / "v.data");
  EXPECT_EQ(io::volume_format_for_read(scratch() / "v.data").name, "NRRD");
  EXPECT_EQ(io::volume_format_for_write(scratch() / "x.nrrd").name, "NRRD");
  EXPECT_THROW(io::volume_format_for_write(scratch() / "x.nhdr"), InputError);  // read-only
}

TEST(VolumeNrrd, BadFilesNameTheFileAndTheProblem) {
  const fs::path d = scratch();
  auto err = [&](const std::string& name, const std::string& content) {
    write_bytes(d / name, content);
    return error_of([&] { io::read_any_volume(d / name); });
  };
  const std::string hdr = "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 4 4\nendian: little\n";
  std::string e = err("magic.nrrd", "NRRX0004\ntype: uint8\n\n");
  EXPECT_NE(e.find("magic.nrrd: not a NRRD file"), std::string::npos) << e;
  e = err("trunc.nrrd", hdr + "encoding: raw\n\n" + std::string(100, 'x'));
  EXPECT_NE(e.find("trunc.nrrd: the voxel data needs 128 bytes but the file has only 100"), std::string::npos) << e;
  e = err("sizes.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4\nencoding: raw\n\n");
  EXPECT_NE(e.find("sizes.nrrd:4: 'sizes' has 2 values but 'dimension' is 3"), std::string::npos) << e;
  e = err("bz.nrrd", hdr + "encoding: bzip2\n\nBZh");
  EXPECT_NE(e.find("bz.nrrd:6: unsupported NRRD encoding 'bzip2'"), std::string::npos) << e;
  e = err("type.nrrd", "NRRD0004\ntype: block\ndimension: 3\n\n");
  EXPECT_NE(e.find("type.nrrd:2: unsupported NRRD type 'block'"), std::string::npos) << e;
  // A 1 KB file claiming 10^12 voxels is refused before anything is allocated (raw and gzip).
  const std::string huge = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10000 10000 10000\n";
  e = err("huge.nrrd", huge + "encoding: raw\n\n" + std::string(1000, '\0'));
  EXPECT_NE(e.find("huge.nrrd: the voxel data needs 1000000000000 bytes but the file has only 1000"), std::string::npos) << e;
  e = err("hugez.nrrd", huge + "encoding: gzip\n\n" + io::volbytes::deflate("abc", 3, 6, true));
  EXPECT_NE(e.find("hugez.nrrd: the gzip voxel data claims 1000000000000 bytes"), std::string::npos) << e;
  // Corrupt and short gzip data.
  std::string z = io::volbytes::deflate(std::string(64, '\1').data(), 64, 6, true);
  e = err("shortz.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 5\nencoding: gzip\n\n" + z);
  EXPECT_NE(e.find("shortz.nrrd: gzip voxel data: compressed data holds 64 of 80 bytes"), std::string::npos) << e;
  e = err("corrupt.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\n" + z.substr(0, 10) +
                              std::string(20, '\xff'));
  EXPECT_NE(e.find("corrupt.nrrd: gzip voxel data: corrupt compressed data"), std::string::npos) << e;
  e = err("range.nrrd", "NRRD0004\ntype: uint8\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1 300 2\n");
  EXPECT_NE(e.find("range.nrrd: ascii data value 1 '300' is not a uint8 value"), std::string::npos) << e;
  e = err("fl.nrrd", "NRRD0004\ntype: float\ndimension: 1\nsizes: 2\nencoding: ascii\n\n1 1e300\n");
  EXPECT_NE(e.find("fl.nrrd: ascii data value 1 '1e300' is not a float32 value"), std::string::npos) << e;
  e = err("nodata.nhdr", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: missing.raw\n");
  EXPECT_NE(e.find("missing.raw: cannot read"), std::string::npos) << e;
  e = err("negsp.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1 1 1\nspacings: 1 -2 1\nencoding: raw\n\nx");
  EXPECT_NE(e.find("negsp.nrrd:5: 'spacings': axis 1 has spacing -2 (must be > 0)"), std::string::npos) << e;
}
