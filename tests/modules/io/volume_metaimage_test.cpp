// MetaImage volumes (.mha, .mhd + raw/zraw): round trips of every voxel type with spacing, origin,
// unit and direction; files written by VTK's vtkMetaImageWriter; our files read by VTK; bad files.
#include <gtest/gtest.h>

#include "io/volume_bytes.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;

TEST(VolumeMetaImage, RoundTripEveryTypeRawAndCompressed) {
  for (int c : {0, 6}) {
    for_every_voxel_type([&](auto t) {
      using T = decltype(t);
      const auto v = random_volume<T>(Dims{13, 7, 5}, 5, "mm");
      const fs::path f = scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + "_" + std::to_string(c) + ".mha");
      io::VolumeWriteOptions o;
      o.compression = c;
      expect_round_trip(v, f, o);
    });
  }
}

TEST(VolumeMetaImage, RoundTripRotatedDirectionAndDefaultUnit) {
  const auto v = random_volume<float>(Dims{6, 5, 4}, 3, kDefaultUnit, true);
  expect_round_trip(v, scratch() / "rot.mha");  // direction written as numbers, exact
  const io::VolumeHeader h = io::read_volume_header(scratch() / "rot.mha");
  EXPECT_TRUE(h.has_spacing && h.has_origin && h.has_unit);
}

TEST(VolumeMetaImage, ReadsFilesWrittenByVtk) {
  const fs::path d = scratch();
  const int rc = run_python(d, R"(
try:
    import vtk
    from vtk.util import numpy_support as ns
except ImportError:
    sys.exit(77)
im = vtk.vtkImageData(); im.SetDimensions(4, 3, 2); im.SetSpacing(0.5, 0.25, 2); im.SetOrigin(1, 2, 3)
im.GetPointData().SetScalars(ns.numpy_to_vtk(numpy.arange(24, dtype=numpy.int16) * 100 - 1000, deep=1))
for name, comp in (("vtk.mhd", True), ("vtk.mha", False)):
    w = vtk.vtkMetaImageWriter(); w.SetInputData(im); w.SetFileName(sys.argv[0].replace("make.py", name))
    w.SetCompression(comp); w.Write()
)");
  if (rc == 77) GTEST_SKIP() << "python3-vtk9 is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  for (const char* name : {"vtk.mhd", "vtk.mha"}) {
    const auto v = std::dynamic_pointer_cast<const VolumeI32>(io::read_any_volume(d / name));  // int16 -> int32
    ASSERT_TRUE(v) << name;
    EXPECT_EQ(v->dims(), (Dims{4, 3, 2})) << name;
    EXPECT_EQ(v->spacing(), (Vec3{0.5, 0.25, 2})) << name;
    EXPECT_EQ(v->origin(), (Vec3{1, 2, 3})) << name;
    EXPECT_EQ(v->unit(), kDefaultUnit) << name;  // MetaIO names no unit
    for (int i = 0; i < 24; ++i) EXPECT_EQ((*v)[i], i * 100 - 1000) << name;
    EXPECT_EQ(io::read_volume_header(d / name).dtype, "int16");
  }
  EXPECT_EQ(io::volume_format_for_read(d / "vtk.mhd").name, "MetaImage (detached header)");
}

TEST(VolumeMetaImage, VtkReadsOurFiles) {
  const fs::path d = scratch();
  Grid g(Dims{5, 4, 3}, {0.5, 0.25, 2}, {-1, 2, 7.5}, "mm");
  VolumeU16 v(g, 0);
  for (int64_t i = 0; i < v.size(); ++i) v[i] = static_cast<uint16_t>(i * 997);
  io::VolumeWriteOptions o;
  o.compression = 6;
  io::write_any_volume(d / "ours.mha", v, o);
  const int rc = run_python(d, R"(
try:
    import vtk
    from vtk.util import numpy_support as ns
except ImportError:
    sys.exit(77)
r = vtk.vtkMetaImageReader(); r.SetFileName(sys.argv[0].replace("make.py", "ours.mha")); r.Update()
im = r.GetOutput()
a = ns.vtk_to_numpy(im.GetPointData().GetScalars())
with open(sys.argv[0].replace("make.py", "out.txt"), "w") as f:
    f.write("%s %s %s %s %d\n" % (im.GetDimensions(), im.GetSpacing(), im.GetOrigin(), a.dtype, int(a.astype(numpy.int64).sum())))
)");
  if (rc == 77) GTEST_SKIP() << "python3-vtk9 is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  std::ifstream in(d / "out.txt");
  std::string line;
  std::getline(in, line);
  int64_t sum = 0;
  for (int64_t i = 0; i < v.size(); ++i) sum += v[i];
  EXPECT_EQ(line, "(5, 4, 3) (0.5, 0.25, 2.0) (-1.0, 2.0, 7.5) uint16 " + std::to_string(sum));
}

TEST(VolumeMetaImage, BadFilesNameTheFileAndTheProblem) {
  const fs::path d = scratch();
  auto err = [&](const std::string& name, const std::string& content) {
    write_bytes(d / name, content);
    return error_of([&] { io::read_any_volume(d / name); });
  };
  const std::string hdr = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_USHORT\n";
  std::string e = err("magic.mha", "\x89PNG\r\n\x1a\n");
  EXPECT_NE(e.find("magic.mha: not a MetaImage file"), std::string::npos) << e;
  e = err("trunc.mha", hdr + "ElementDataFile = LOCAL\n" + std::string(100, 'x'));
  EXPECT_NE(e.find("trunc.mha: the voxel data needs 128 bytes but the file has only 100"), std::string::npos) << e;
  e = err("noend.mha", hdr);
  EXPECT_NE(e.find("noend.mha: the MetaImage header has no 'ElementDataFile' line"), std::string::npos) << e;
  e = err("dims.mha", "ObjectType = Image\nNDims = 3\nDimSize = 4 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n");
  EXPECT_NE(e.find("dims.mha:3: 'DimSize' has 2 values; expected 3"), std::string::npos) << e;
  e = err("type.mha", "NDims = 3\nDimSize = 4 4 4\nElementType = MET_FLOAT_ARRAY\nElementDataFile = LOCAL\n");
  EXPECT_NE(e.find("type.mha:3: unsupported ElementType 'MET_FLOAT_ARRAY'"), std::string::npos) << e;
  e = err("list.mhd", hdr + "ElementDataFile = LIST\nslice0.raw\n");
  EXPECT_NE(e.find("list.mhd:5: ElementDataFile 'LIST' lists several files"), std::string::npos) << e;
  e = err("chan.mha", hdr + "ElementNumberOfChannels = 3\nElementDataFile = LOCAL\n");
  EXPECT_NE(e.find("chan.mha:5: ElementNumberOfChannels is 3"), std::string::npos) << e;
  // 10^12 voxels claimed by a 1 KB file: refused before allocating (raw and compressed).
  const std::string huge = "NDims = 3\nDimSize = 10000 10000 10000\nElementType = MET_UCHAR\n";
  e = err("huge.mha", huge + "ElementDataFile = LOCAL\n" + std::string(1000, '\0'));
  EXPECT_NE(e.find("huge.mha: the voxel data needs 1000000000000 bytes but the file has only 1000"), std::string::npos) << e;
  e = err("hugez.mha", huge + "CompressedData = True\nElementDataFile = LOCAL\n" + io::volbytes::deflate("abc", 3, 6, false));
  EXPECT_NE(e.find("hugez.mha: the compressed voxel data claims 1000000000000 bytes"), std::string::npos) << e;
  e = err("csize.mha", hdr + "CompressedData = True\nCompressedDataSize = 5000\nElementDataFile = LOCAL\nxyz");
  EXPECT_NE(e.find("csize.mha: CompressedDataSize needs 5000 bytes but the file has only 3"), std::string::npos) << e;
  // Tabs between values are white space too.
  write_bytes(d / "tabs.mha", "NDims = 3\nDimSize = 2\t1 1\nElementSpacing = 0.5\t0.5 2\nElementType = MET_UCHAR\n"
                              "ElementDataFile = LOCAL\nab");
  EXPECT_EQ(io::read_volume_header(d / "tabs.mha").grid.spacing, (Vec3{0.5, 0.5, 2}));
  e = err("nodata.mhd", hdr + "ElementDataFile = missing.raw\n");
  EXPECT_NE(e.find("missing.raw: cannot read"), std::string::npos) << e;
}
