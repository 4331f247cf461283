// Amira lattice volumes (.am): round trips of the types Amira stores (binary and HxZip) with
// spacing, origin and unit; hand-written files as Amira writes them (big-endian binary, ASCII,
// HxByteRLE, a second lattice block before the voxels); what cannot be written; bad files.
#include <gtest/gtest.h>

#include "io/volume_bytes.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;

namespace {
template <class T>
void amira_round_trip(int c) {
  const auto v = random_volume<T>(Dims{13, 7, 5}, 21, "mm");
  io::VolumeWriteOptions o;
  o.compression = c;
  // The bounding box stores origin + spacing * (n - 1): spacing comes back to rounding.
  expect_round_trip(v, scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + "_" + std::to_string(c) + ".am"), o, 1e-12);
}
const char* kHeader =
    "define Lattice 3 2 2\n\nParameters {\n    Units {\n        Coordinates \"nm\"\n    }\n"
    "    Content \"3x2x2 short, uniform coordinates\",\n    BoundingBox 10 11 -5 -3 0 8,\n    CoordType \"uniform\"\n}\n\n";
}  // namespace

TEST(VolumeAmira, RoundTripStoredTypesBinaryAndHxZip) {
  for (int c : {0, 6}) {
    amira_round_trip<uint8_t>(c);
    amira_round_trip<uint16_t>(c);
    amira_round_trip<int32_t>(c);
    amira_round_trip<float>(c);
    amira_round_trip<double>(c);
  }
  const io::VolumeHeader h = io::read_volume_header(scratch() / "rt_uint16_6.am");
  EXPECT_EQ(h.grid.spacing[0], 0.5);
  EXPECT_EQ(h.grid.unit, "mm");
  EXPECT_EQ(h.details.back(), "encoding: binary, little endian, HxZip");
}

TEST(VolumeAmira, RefusesWhatAmiraCannotStore) {
  const fs::path d = scratch();
  std::string e = error_of([&] { io::write_any_volume(d / "u32.am", random_volume<uint32_t>(Dims{2, 2, 2}, 1)); });
  EXPECT_NE(e.find("u32.am: Amira lattices store byte, short, ushort, int, float and double voxels, not uint32"), std::string::npos) << e;
  e = error_of([&] { io::write_any_volume(d / "rot.am", random_volume<uint8_t>(Dims{2, 2, 2}, 1, "mm", true)); });
  EXPECT_NE(e.find("rot.am: an Amira lattice stores no direction"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(d / "u32.am") || fs::exists(d / "rot.am"));
}

TEST(VolumeAmira, ReadsBigEndianAsciiRleAndSeveralBlocks) {
  const fs::path d = scratch();
  // Amira 5's default: "# AmiraMesh 3D BINARY 2.0" (big endian), short data.
  std::string be = std::string("# AmiraMesh 3D BINARY 2.0\n\n") + kHeader + "Lattice { short Data } @1\n\n# Data section follows\n@1\n";
  for (int i = 0; i < 12; ++i) {
    const auto u = static_cast<uint16_t>(static_cast<int16_t>(i * 1000 - 6000));
    be += static_cast<char>(u >> 8);
    be += static_cast<char>(u & 0xff);
  }
  write_bytes(d / "be.am", be + "\n");
  const auto v = std::dynamic_pointer_cast<const VolumeI32>(io::read_any_volume(d / "be.am"));
  ASSERT_TRUE(v);
  EXPECT_EQ(v->dims(), (Dims{3, 2, 2}));
  EXPECT_EQ(v->spacing(), (Vec3{0.5, 2, 8}));
  EXPECT_EQ(v->origin(), (Vec3{10, -5, 0}));
  EXPECT_EQ(v->unit(), "nm");
  for (int i = 0; i < 12; ++i) EXPECT_EQ((*v)[i], i * 1000 - 6000);

  write_bytes(d / "ascii.am", std::string("# AmiraMesh 3D ASCII 2.0\n\n") + kHeader +
                                  "Lattice { float Data } @1\n\n# Data section follows\n@1\n0 0.5 1\n1.5 2 2.5\n3 3.5 4\n4.5 5 5.5\n");
  const auto a = std::dynamic_pointer_cast<const VolumeF32>(io::read_any_volume(d / "ascii.am"));
  ASSERT_TRUE(a);
  for (int i = 0; i < 12; ++i) EXPECT_EQ((*a)[i], 0.5f * static_cast<float>(i));

  // HxByteRLE byte labels, after a 3-component float block @1 that is skipped.
  // Voxels: 5 x 7, then literals 1 2 3, then 4 x 9 = 12 bytes.
  const std::string rle = std::string("\x05\x07\x83\x01\x02\x03\x04\x09", 8);
  std::string two = std::string("# AmiraMesh BINARY-LITTLE-ENDIAN 2.1\n\n") + kHeader +
                    "Lattice { float[3] Vectors } @1\nLattice { byte Labels } @2(HxByteRLE," + std::to_string(rle.size()) +
                    ")\n\n# Data section follows\n@1\n" + std::string(12 * 12, '\x40') + "\n@2\n" + rle + "\n";
  write_bytes(d / "rle.am", two);
  const auto r = std::dynamic_pointer_cast<const VolumeU8>(io::read_any_volume(d / "rle.am"));
  ASSERT_TRUE(r);
  EXPECT_EQ(std::vector<uint8_t>(r->begin(), r->end()), (std::vector<uint8_t>{7, 7, 7, 7, 7, 1, 2, 3, 9, 9, 9, 9}));
  EXPECT_NE(io::describe_volume_file(d / "rle.am").find("HxByteRLE"), std::string::npos);
}

TEST(VolumeAmira, BadFilesNameTheFileAndTheProblem) {
  const fs::path d = scratch();
  auto err = [&](const std::string& name, const std::string& content) {
    write_bytes(d / name, content);
    return error_of([&] { io::read_any_volume(d / name); });
  };
  const std::string le = "# AmiraMesh BINARY-LITTLE-ENDIAN 2.1\n\n";
  std::string e = err("magic.am", "# Hyper\n");
  EXPECT_NE(e.find("magic.am: not an AmiraMesh file"), std::string::npos) << e;
  e = err("graph.am", "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 2\nVERTEX { float[3] VertexCoordinates } @1\n@1\n0 0 0\n1 1 1\n");
  EXPECT_NE(e.find("graph.am: no 'define Lattice nx ny nz'"), std::string::npos) << e;
  e = err("trunc.am", le + kHeader + "Lattice { short Data } @1\n@1\n" + std::string(10, 'x'));
  EXPECT_NE(e.find("trunc.am: the lattice data needs 24 bytes but the file has only 10"), std::string::npos) << e;
  e = err("type.am", le + kHeader + "Lattice { complex Data } @1\n@1\n");
  EXPECT_NE(e.find("type.am:14: unsupported lattice type 'complex'"), std::string::npos) << e;
  e = err("enc.am", le + kHeader + "Lattice { byte Data } @1(HxJPEG,4)\n@1\nabcd");
  EXPECT_NE(e.find("enc.am:14: unsupported AmiraMesh encoding 'HxJPEG'"), std::string::npos) << e;
  e = err("rect.am", le + "define Lattice 2 2 2\nParameters { CoordType \"rectilinear\" }\nLattice { byte Data } @1\n@1\n12345678");
  EXPECT_NE(e.find("rect.am: CoordType \"rectilinear\""), std::string::npos) << e;
  e = err("asciirange.am", "# AmiraMesh 3D ASCII 2.0\ndefine Lattice 2 1 1\nLattice { byte Data } @1\n@1\n5 1e30\n");
  EXPECT_NE(e.find("asciirange.am: ASCII lattice value 1 is missing or not a byte value"), std::string::npos) << e;
  std::string z = io::volbytes::deflate("abcdefgh", 8, 6, false);
  e = err("zip.am", le + kHeader + "Lattice { byte Data } @1(HxZip," + std::to_string(z.size()) + ")\n@1\n" + z + "\n");
  EXPECT_NE(e.find("zip.am: HxZip lattice data: compressed data holds 8 of 12 bytes"), std::string::npos) << e;
  // 10^12 voxels claimed by a small file: refused before anything is allocated.
  e = err("huge.am", le + "define Lattice 10000 10000 10000\nLattice { byte Data } @1\n@1\n" + std::string(1000, 'x'));
  EXPECT_NE(e.find("huge.am: the lattice data needs 1000000000000 bytes but the file has only 1000"), std::string::npos) << e;
  e = err("hugez.am", le + "define Lattice 10000 10000 10000\nLattice { byte Data } @1(HxZip," + std::to_string(z.size()) + ")\n@1\n" + z);
  EXPECT_NE(e.find("hugez.am: the HxZip lattice data claims 1000000000000 bytes"), std::string::npos) << e;
  e = err("hugerle.am", le + "define Lattice 10000 10000 10000\nLattice { byte Data } @1(HxByteRLE,4)\n@1\nabcd");
  EXPECT_NE(e.find("hugerle.am: the HxByteRLE lattice data claims 1000000000000 bytes from only 4"), std::string::npos) << e;
}
