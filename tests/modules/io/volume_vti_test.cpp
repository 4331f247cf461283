// VTK image data (.vti): round trips of every voxel type with spacing, origin, unit and direction;
// files written by vtkXMLImageDataWriter in every mode (appended raw/base64, inline binary, ascii,
// zlib or not, UInt32/UInt64 headers, an extent not starting at 0, a direction); our files read by
// VTK; bad files.
#include <gtest/gtest.h>

#include <cstring>

#include "io/volume_bytes.hpp"
#include "io/vtk_xml_data.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;

TEST(VolumeVti, RoundTripEveryTypeRawAndZlib) {
  for (int c : {0, 6}) {
    for_every_voxel_type([&](auto t) {
      using T = decltype(t);
      const auto v = random_volume<T>(Dims{13, 7, 5}, 17, "mm", c > 0);
      io::VolumeWriteOptions o;
      o.compression = c;
      expect_round_trip(v, scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + "_" + std::to_string(c) + ".vti"), o);
    });
  }
  // More than one 1 MiB zlib block.
  const auto big = random_volume<uint16_t>(Dims{300, 200, 11}, 2, kDefaultUnit);
  expect_round_trip(big, scratch() / "big.vti");
}

TEST(VolumeVti, ReadsFilesWrittenByVtkInEveryMode) {
  const fs::path d = scratch();
  const int rc = run_python(d, R"(
try:
    import vtk
    from vtk.util import numpy_support as ns
except ImportError:
    sys.exit(77)
out = sys.argv[0].replace("make.py", "")
im = vtk.vtkImageData(); im.SetExtent(2, 5, 0, 2, 1, 2); im.SetSpacing(0.5, 0.25, 2); im.SetOrigin(1, 2, 3)
im.SetDirectionMatrix(0, -1, 0, 1, 0, 0, 0, 0, 1)
im.GetPointData().SetScalars(ns.numpy_to_vtk(numpy.arange(24, dtype=numpy.int16) * 100 - 1000, deep=1))
extra = ns.numpy_to_vtk(numpy.zeros(24, dtype=numpy.float64), deep=1); extra.SetName("other"); im.GetPointData().AddArray(extra)
modes = [("appended_zlib32", "appended", False, True, 32), ("appended_b64_64", "appended", True, False, 64),
         ("appended_b64_zlib", "appended", True, True, 64), ("binary_zlib", "binary", None, True, 32),
         ("binary_raw64", "binary", None, False, 64), ("ascii", "ascii", None, False, 32)]
for name, mode, enc, zlib, header in modes:
    w = vtk.vtkXMLImageDataWriter(); w.SetInputData(im); w.SetFileName(out + name + ".vti")
    {"appended": w.SetDataModeToAppended, "binary": w.SetDataModeToBinary, "ascii": w.SetDataModeToAscii}[mode]()
    if enc is not None: w.SetEncodeAppendedData(enc)
    w.SetCompressorTypeToZLib() if zlib else w.SetCompressorTypeToNone()
    w.SetHeaderTypeToUInt32() if header == 32 else w.SetHeaderTypeToUInt64()
    w.SetBlockSize(16)  # several blocks
    w.Write()
)");
  if (rc == 77) GTEST_SKIP() << "python3-vtk9 is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  for (const char* name : {"appended_zlib32", "appended_b64_64", "appended_b64_zlib", "binary_zlib", "binary_raw64", "ascii"}) {
    const fs::path f = d / (std::string(name) + ".vti");
    const auto v = std::dynamic_pointer_cast<const VolumeI32>(io::read_any_volume(f));  // int16 -> int32
    ASSERT_TRUE(v) << name;
    EXPECT_EQ(v->dims(), (Dims{4, 3, 2})) << name;
    EXPECT_EQ(v->spacing(), (Vec3{0.5, 0.25, 2})) << name;
    // Voxel (0,0,0) is extent index (2, 0, 1): origin + D * (2*0.5, 0, 1*2) = (1, 2, 3) + (0, 1, 2).
    EXPECT_EQ(v->origin(), (Vec3{1, 3, 5})) << name;
    EXPECT_EQ(v->grid().direction, (Direction{0, -1, 0, 1, 0, 0, 0, 0, 1})) << name;
    EXPECT_EQ(v->unit(), kDefaultUnit) << name;
    for (int i = 0; i < 24; ++i) ASSERT_EQ((*v)[i], i * 100 - 1000) << name << " voxel " << i;
    EXPECT_EQ(io::read_volume_header(f).dtype, "int16") << name;
  }
}

TEST(VolumeVti, VtkReadsOurFiles) {
  const fs::path d = scratch();
  auto v = random_volume<float>(Dims{5, 4, 3}, 9, "mm", true);
  io::VolumeWriteOptions o;
  o.compression = 6;
  io::write_any_volume(d / "ours.vti", v, o);
  const int rc = run_python(d, R"(
try:
    import vtk
    from vtk.util import numpy_support as ns
except ImportError:
    sys.exit(77)
r = vtk.vtkXMLImageDataReader(); r.SetFileName(sys.argv[0].replace("make.py", "ours.vti")); r.Update()
im = r.GetOutput()
a = ns.vtk_to_numpy(im.GetPointData().GetScalars())
m = im.GetDirectionMatrix()
with open(sys.argv[0].replace("make.py", "out.txt"), "w") as f:
    f.write("%s %s %s %s %.6f %s\n" % (im.GetDimensions(), im.GetSpacing(), im.GetOrigin(), a.dtype, float(a.astype(numpy.float64).sum()),
                                     im.GetFieldData().GetAbstractArray("unit").GetValue(0)))
    f.write(" ".join("%.4f" % m.GetElement(i, j) for i in range(3) for j in range(3)) + "\n")
)");
  if (rc == 77) GTEST_SKIP() << "python3-vtk9 is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  std::ifstream in(d / "out.txt");
  std::string l1, l2;
  std::getline(in, l1);
  std::getline(in, l2);
  double sum = 0;
  for (float x : v) sum += static_cast<double>(x);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", sum);
  EXPECT_EQ(l1, "(5, 4, 3) (0.5, 0.75, 2.0) (-3.0, 1.5, 10.0) float32 " + std::string(buf) + " mm");
  EXPECT_EQ(l2, "0.8660 -0.5000 0.0000 0.5000 0.8660 0.0000 0.0000 0.0000 1.0000");
}

TEST(VolumeVti, BadFilesNameTheFileAndTheProblem) {
  const fs::path d = scratch();
  io::VolumeWriteOptions raw;
  raw.compression = 0;
  io::write_any_volume(d / "good.vti", random_volume<uint16_t>(Dims{4, 4, 4}, 1), raw);
  io::write_any_volume(d / "goodz.vti", random_volume<uint16_t>(Dims{4, 4, 4}, 1));
  const std::string good = io::volbytes::read_file(d / "good.vti");
  const std::string goodz = io::volbytes::read_file(d / "goodz.vti");
  auto err = [&](const std::string& name, const std::string& content) {
    write_bytes(d / name, content);
    return error_of([&] { io::read_any_volume(d / name); });
  };
  auto replace = [](std::string s, const std::string& a, const std::string& b) {
    const size_t p = s.find(a);
    EXPECT_NE(p, std::string::npos) << a;
    return s.replace(p, a.size(), b);
  };
  std::string e = err("magic.vti", "<?xml version=\"1.0\"?>\n<Other/>\n");
  EXPECT_NE(e.find("magic.vti: not a VTK XML file"), std::string::npos) << e;
  e = err("poly.vti", replace(good, "type=\"ImageData\"", "type=\"PolyData\""));
  EXPECT_NE(e.find("poly.vti: a VTK XML file of type 'PolyData', not ImageData"), std::string::npos) << e;
  e = err("trunc.vti", good.substr(0, good.find("   _") + 50));
  EXPECT_NE(e.find("trunc.vti: the voxel data needs 128 bytes but the file has only"), std::string::npos) << e;
  e = err("extent.vti", replace(replace(good, "WholeExtent=\"0 3 0 3 0 3\"", "WholeExtent=\"0 3 0 3 0 4\""),
                                "Extent=\"0 3 0 3 0 3\"", "Extent=\"0 3 0 3 0 4\""));
  EXPECT_NE(e.find("extent.vti: the data array holds 128 bytes but WholeExtent and type need 160"), std::string::npos) << e;
  e = err("lz4.vti", replace(goodz, "vtkZLibDataCompressor", "vtkLZ4DataCompressor"));
  EXPECT_NE(e.find("lz4.vti: unsupported compressor 'vtkLZ4DataCompressor'"), std::string::npos) << e;
  e = err("xml.vti", replace(good, "<PointData", "<PointData <"));
  EXPECT_NE(e.find("xml.vti:10: XML error: not well-formed"), std::string::npos) << e;
  const std::string ascii =
      "<VTKFile type=\"ImageData\" version=\"1.0\"><ImageData WholeExtent=\"0 1 0 0 0 0\" Origin=\"0 0 0\" Spacing=\"1 1 1\">"
      "<Piece Extent=\"0 1 0 0 0 0\"><PointData><DataArray type=\"Int16\" Name=\"a\" format=\"ascii\">";
  const std::string tail = "</DataArray></PointData></Piece></ImageData></VTKFile>";
  write_bytes(d / "ascii.vti", ascii + "-7 12" + tail);
  const auto av = std::dynamic_pointer_cast<const VolumeI32>(io::read_any_volume(d / "ascii.vti"));
  ASSERT_TRUE(av);
  EXPECT_EQ((*av)[0], -7);
  EXPECT_EQ((*av)[1], 12);
  e = err("asciirange.vti", ascii + "-7 99999" + tail);
  EXPECT_NE(e.find("asciirange.vti: ascii data value 1 is missing or not a int16 value"), std::string::npos) << e;
  // 10^12 voxels claimed by a small file: refused before anything is allocated.
  const std::string huge_ext = "0 9999 0 9999 0 9999";
  e = err("huge.vti", replace(replace(good, "WholeExtent=\"0 3 0 3 0 3\"", "WholeExtent=\"" + huge_ext + "\""),
                              "Extent=\"0 3 0 3 0 3\"", "Extent=\"" + huge_ext + "\""));
  EXPECT_NE(e.find("huge.vti: the data array holds 128 bytes but WholeExtent and type need 2000000000000"), std::string::npos) << e;
  e = err("hugez.vti", replace(replace(goodz, "WholeExtent=\"0 3 0 3 0 3\"", "WholeExtent=\"" + huge_ext + "\""),
                               "Extent=\"0 3 0 3 0 3\"", "Extent=\"" + huge_ext + "\""));
  EXPECT_NE(e.find("hugez.vti: the compressed array's header (1 blocks of 1048576 bytes, last 128) does not give the 2000000000000 bytes"),
            std::string::npos) << e;
}

// The one decoder of VTK binary blocks (io/vtk_xml_data.hpp), used by .vti volumes and .vtp graphs:
// an encoded array (several zlib blocks, and raw) decodes into a caller's buffer with its size
// checked first; the graph path (decode_appended) gives the same bytes; a short buffer size, a
// truncated block and a header promising more than zlib can expand are input errors naming `src`.
TEST(VtkBlocks, OneDecoderIntoTheCallersBufferWithSizeChecks) {
  std::vector<uint16_t> values(40000);
  for (size_t i = 0; i < values.size(); ++i) values[i] = static_cast<uint16_t>((i * 2654435761u) >> 7);
  const uint64_t bytes = values.size() * sizeof(uint16_t);
  for (bool compress : {false, true}) {
    const std::string block = io::vtk::encode_array(values.data(), bytes, compress);
    const io::vtk::Encoding enc{true, false, compress};
    const io::vtk::BlockMessages m{"b.vtp: DataArray 'a'", "the array's data", "the caller"};
    EXPECT_EQ(io::vtk::check_block(block, 0, enc, m), bytes);
    std::vector<uint16_t> out(values.size());
    io::vtk::decode_block(block, 0, enc, m, reinterpret_cast<char*>(out.data()), bytes);
    EXPECT_EQ(out, values);
    const std::string via_graph = io::vtk::decode_appended(block, false, 0, block.size(), enc, "b.vtp: DataArray 'a'");
    ASSERT_EQ(via_graph.size(), bytes);
    EXPECT_EQ(std::memcmp(via_graph.data(), values.data(), bytes), 0);
    auto error = [&](const std::string& b, std::optional<uint64_t> need) {
      try {
        io::vtk::check_block(b, 0, enc, m, need);
      } catch (const InputError& e) {
        return std::string(e.what());
      }
      return std::string("no error");
    };
    const std::string e = error(block, bytes - 2);
    EXPECT_NE(e.find(compress ? "b.vtp: DataArray 'a': the compressed array's header (" : "b.vtp: DataArray 'a': the data array holds 80000 bytes but the caller need 79998"),
              std::string::npos) << e;
    const std::string t = error(block.substr(0, block.size() - 10), std::nullopt);
    EXPECT_NE(t.find("b.vtp: DataArray 'a': "), std::string::npos) << t;
    EXPECT_NE(t.find("but the file has only"), std::string::npos) << t;
  }
  // One compressed block of 10 bytes claiming 2^40 bytes: refused before anything is inflated.
  std::string huge;
  auto put = [&](uint64_t v) { huge.append(reinterpret_cast<const char*>(&v), 8); };
  put(1); put(uint64_t{1} << 40); put(uint64_t{1} << 40); put(10);
  huge += std::string(10, 'x');
  try {
    io::vtk::check_block(huge, 0, io::vtk::Encoding{true, false, true}, {"h.vti"});
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("h.vti: the compressed data array claims 1099511627776 bytes but its compressed data is only 10 bytes"),
              std::string::npos) << e.what();
  }
}
