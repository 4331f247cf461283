// NIfTI-1 volumes (.nii, .nii.gz): round trips of every voxel type with spacing, origin, unit and
// direction; files written by nibabel (plain save; big-endian, scaled, sform + qform); our files
// read by nibabel; bad files.
#include <gtest/gtest.h>

#include "io/volume_bytes.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;

TEST(VolumeNifti, RoundTripEveryTypeNiiAndNiiGz) {
  for (const char* ext : {".nii", ".nii.gz"}) {
    for_every_voxel_type([&](auto t) {
      using T = decltype(t);
      const auto v = random_volume<T>(Dims{13, 7, 5}, 7, "mm");
      expect_round_trip(v, scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + ext));
    });
  }
  EXPECT_EQ(io::read_volume_header(scratch() / "rt_uint8.nii.gz").details.back(), "compression: gzip");
}

TEST(VolumeNifti, RoundTripRotatedAndMirroredDirectionsAndUnits) {
  // float32 in the file: directions come back to float precision.
  auto v = random_volume<uint16_t>(Dims{6, 5, 4}, 3, kDefaultUnit, true);
  expect_round_trip(v, scratch() / "rot.nii", {}, 1e-6);
  v.set_direction({-1, 0, 0, 0, 0, 1, 0, 1, 0});  // a reflection: qfac -1
  v.set_unit("m");
  expect_round_trip(v, scratch() / "mirror.nii.gz", {}, 1e-6);
  v.set_unit("nm");
  const std::string e = error_of([&] { io::write_any_volume(scratch() / "nm.nii", v); });
  EXPECT_NE(e.find("nm.nii: NIfTI-1 stores lengths in m, mm or µm only; this volume's unit is 'nm'"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(scratch() / "nm.nii"));
}

TEST(VolumeNifti, ReadsFilesWrittenByNibabel) {
  const fs::path d = scratch();
  const int rc = run_python(d, R"(
try:
    import nibabel as nib
except ImportError:
    sys.exit(77)
import gzip
out = sys.argv[0].replace("make.py", "")
a = (numpy.arange(24, dtype=numpy.int16) * 100 - 1000).reshape((4, 3, 2), order="F")
aff = numpy.array([[0, -0.25, 0, 10], [0.5, 0, 0, -20], [0, 0, 2, 30.5], [0, 0, 0, 1]])
# 1. nib.save of a uint16 image, qform and sform, in mm.
img = nib.Nifti1Image(a.astype(numpy.uint16) + 1000, aff)
img.header.set_xyzt_units("mm")
nib.save(img, out + "plain.nii")
# 2. A big-endian int16 header made by nibabel with scl_slope 0.5, scl_inter 3, sform only, gzip.
h = nib.Nifti1Header(endianness=">")
h.set_data_shape((4, 3, 2)); h.set_data_dtype(numpy.int16); h.set_sform(aff, code="aligned")
h.set_xyzt_units("micron"); h.set_slope_inter(0.5, 3); h["vox_offset"] = 352
with gzip.open(out + "scaled.nii.gz", "wb") as f:
    f.write(h.binaryblock); f.write(b"\0" * 4); f.write(a.astype(">i2").tobytes(order="F"))
s = nib.load(out + "scaled.nii.gz").get_fdata()
assert abs(s[1, 0, 0] - ((-900) * 0.5 + 3)) < 1e-9, s[1, 0, 0]
# 3. qform only, with a reflection (qfac -1).
aff2 = numpy.array([[-0.5, 0, 0, 1], [0, 0, 0.75, 2], [0, 2, 0, 3], [0, 0, 0, 1]])
img = nib.Nifti1Image(a.astype(numpy.float32), None)
img.set_qform(aff2, code="scanner"); img.set_sform(None, code="unknown")
nib.save(img, out + "qform.nii")
)");
  if (rc == 77) GTEST_SKIP() << "python3-nibabel is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";

  const auto p = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(d / "plain.nii"));
  ASSERT_TRUE(p);
  EXPECT_EQ(p->dims(), (Dims{4, 3, 2}));
  EXPECT_EQ(p->unit(), "mm");
  EXPECT_EQ(p->spacing(), (Vec3{0.5, 0.25, 2}));
  EXPECT_EQ(p->origin(), (Vec3{10, -20, 30.5}));
  EXPECT_EQ(p->grid().direction, (Direction{0, -1, 0, 1, 0, 0, 0, 0, 1}));
  for (int i = 0; i < 24; ++i) EXPECT_EQ((*p)[i], i * 100);

  const auto s = std::dynamic_pointer_cast<const VolumeF32>(io::read_any_volume(d / "scaled.nii.gz"));
  ASSERT_TRUE(s) << "scaled data reads as float32";
  EXPECT_EQ(s->unit(), kDefaultUnit);
  EXPECT_EQ(s->grid().direction, (Direction{0, -1, 0, 1, 0, 0, 0, 0, 1}));
  for (int i = 0; i < 24; ++i) EXPECT_FLOAT_EQ((*s)[i], static_cast<float>((i * 100 - 1000) * 0.5 + 3));
  const io::VolumeHeader sh = io::read_volume_header(d / "scaled.nii.gz");
  EXPECT_EQ(sh.dtype, "float32");
  EXPECT_NE(io::describe_volume_file(d / "scaled.nii.gz").find("scaling: value * 0.5 + 3"), std::string::npos);

  const auto q = std::dynamic_pointer_cast<const VolumeF32>(io::read_any_volume(d / "qform.nii"));
  ASSERT_TRUE(q);
  EXPECT_EQ(q->spacing(), (Vec3{0.5, 2, 0.75}));
  EXPECT_EQ(q->origin(), (Vec3{1, 2, 3}));
  const Direction want{-1, 0, 0, 0, 0, 1, 0, 1, 0};
  for (size_t i = 0; i < 9; ++i) EXPECT_NEAR(q->grid().direction[i], want[i], 1e-6) << i;
  EXPECT_NE(io::describe_volume_file(d / "qform.nii").find("orientation: qform"), std::string::npos);
}

TEST(VolumeNifti, NibabelReadsOurFiles) {
  const fs::path d = scratch();
  auto v = random_volume<int32_t>(Dims{5, 4, 3}, 9, "mm", true);
  io::write_any_volume(d / "ours.nii.gz", v);
  const int rc = run_python(d, R"(
try:
    import nibabel as nib
except ImportError:
    sys.exit(77)
img = nib.load(sys.argv[0].replace("make.py", "ours.nii.gz"))
a = numpy.asanyarray(img.dataobj)
q = img.get_qform(); s = img.get_sform()
with open(sys.argv[0].replace("make.py", "out.txt"), "w") as f:
    f.write("%s %s %s %d %d\n" % (a.shape, a.dtype, img.header.get_xyzt_units()[0], int(a.astype(numpy.int64).sum()),
                                  int(numpy.allclose(q, s, atol=1e-5))))
    f.write(" ".join("%.4f" % x for x in s[:3, :].ravel()) + "\n")
)");
  if (rc == 77) GTEST_SKIP() << "python3-nibabel is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  std::ifstream in(d / "out.txt");
  std::string l1, l2;
  std::getline(in, l1);
  std::getline(in, l2);
  int64_t sum = 0;
  for (auto x : v) sum += x;
  EXPECT_EQ(l1, "(5, 4, 3) int32 mm " + std::to_string(sum) + " 1");  // qform agrees with sform
  // affine = direction * diag(spacing) | origin, rotated 30 degrees about z.
  EXPECT_EQ(l2, "0.4330 -0.3750 0.0000 -3.0000 0.2500 0.6495 0.0000 1.5000 0.0000 0.0000 2.0000 10.0000");
}

TEST(VolumeNifti, BadFilesNameTheFileAndTheProblem) {
  const fs::path d = scratch();
  io::write_any_volume(d / "good.nii", random_volume<uint16_t>(Dims{4, 4, 4}, 1));
  const std::string good = io::volbytes::read_file(d / "good.nii");
  auto err = [&](const std::string& name, const std::string& content) {
    write_bytes(d / name, content);
    return error_of([&] { io::read_any_volume(d / name); });
  };
  auto patched = [&](size_t off, const void* v, size_t n) {
    std::string s = good;
    std::memcpy(s.data() + off, v, n);
    return s;
  };
  std::string e = err("short.nii", good.substr(0, 100));
  EXPECT_NE(e.find("short.nii: the NIfTI header needs 348 bytes but the file has only 100"), std::string::npos) << e;
  e = err("magic.nii", patched(344, "xx1\0", 4));
  EXPECT_NE(e.find("magic.nii: not a NIfTI-1 file (magic is not 'n+1')"), std::string::npos) << e;
  e = err("trunc.nii", good.substr(0, 352 + 100));
  EXPECT_NE(e.find("trunc.nii: the voxel data needs 128 bytes but the file has only 100"), std::string::npos) << e;
  const int16_t rgb = 128;
  e = err("rgb.nii", patched(70, &rgb, 2));
  EXPECT_NE(e.find("rgb.nii: unsupported NIfTI datatype 128"), std::string::npos) << e;
  const int16_t bitpix = 8;
  e = err("bitpix.nii", patched(72, &bitpix, 2));
  EXPECT_NE(e.find("bitpix.nii: NIfTI bitpix 8 does not match datatype uint16"), std::string::npos) << e;
  const int16_t four[2] = {4, 4};
  std::string s4 = patched(40, &four[0], 2);
  std::memcpy(s4.data() + 48, &four[1], 2);
  e = err("series.nii", s4);
  EXPECT_NE(e.find("series.nii: NIfTI dim[4] is 4: a series of volumes"), std::string::npos) << e;
  // 10^12 voxels claimed: refused before allocating, plain and gzip.
  const int16_t big[3] = {10000, 10000, 10000};
  const std::string huge = patched(42, big, 6);
  e = err("huge.nii", huge);
  EXPECT_NE(e.find("huge.nii: the voxel data needs 2000000000000 bytes but the file has only 128"), std::string::npos) << e;
  e = err("huge.nii.gz", io::volbytes::deflate(huge.data(), huge.size(), 6, true));
  EXPECT_NE(e.find("huge.nii.gz: the NIfTI data claims 2000000000352 bytes"), std::string::npos) << e;
  const std::string z = io::volbytes::deflate(good.data(), good.size(), 6, true);
  e = err("truncz.nii.gz", z.substr(0, z.size() - 40));
  EXPECT_NE(e.find("truncz.nii.gz: the voxel data ends after"), std::string::npos) << e;
}
