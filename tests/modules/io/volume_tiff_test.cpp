// TIFF volumes: round trips of every voxel type (data, spacing, origin, unit), files written by
// tifffile (ImageJ, OME-TIFF, tiles, BigTIFF, big-endian, RGB, channels), LZW and PackBits written by
// libtiff, folders and patterns of slices in natural order, boxes, and a clear error naming the file
// for each way a file can be wrong.
#include <gtest/gtest.h>
#include <tiffio.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>

#include "io/volume_format.hpp"
#include "skel/pipeline.hpp"
#include "skel/run_module.hpp"
#include "volume_test_util.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
using skel::test::scratch;  // one folder per test (volume_test_util.hpp)

template <class T>
Volume<T> ramp_volume(Dims d, Vec3 spacing = {0.5, 0.75, 2.0}, Vec3 origin = {-3.0, 1.5, 10.0}) {
  Volume<T> v(d, T{}, spacing, origin);
  int64_t i = 0;
  for (auto& x : v) {
    x = static_cast<T>((i * 7919) % 251);
    if constexpr (std::is_signed_v<T>) x = static_cast<T>(x - 120);
    ++i;
  }
  return v;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// tifffile's files (make_tiffs.py), written once per test process; empty when tifffile is missing.
fs::path tifffile_dir() {
  static const fs::path d = [] {
    const fs::path dir = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "io_tiff" /
                         ("tifffile_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string cmd = "/usr/bin/python3 " + std::string(SKEL_SOURCE_DIR) + "/tests/modules/io/make_tiffs.py " + dir.string();
    const int st = std::system(cmd.c_str());
    if (WIFEXITED(st) && WEXITSTATUS(st) == 77) return fs::path();
    EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0) << cmd;
    return dir;
  }();
  return d;
}
#define NEED_TIFFFILE()                                                          \
  if (tifffile_dir().empty()) GTEST_SKIP() << "python3-tifffile is not installed"

// The ramp of make_tiffs.py at voxel index i (x fastest), as stored.
int64_t ramp(int64_t i, bool is_signed = false) { return (i * 7919) % 251 - (is_signed ? 120 : 0); }

template <class T>
std::shared_ptr<const Volume<T>> read_as(const fs::path& f, io::VolumeReadOptions o = {}) {
  auto d = io::read_any_volume(f, o);
  auto v = std::dynamic_pointer_cast<const Volume<T>>(d);
  EXPECT_TRUE(v) << f << ": got " << d->type_id();
  return v;
}

// A volume written with libtiff's own encoder (LZW, PackBits: tifffile needs imagecodecs for them).
void write_with_libtiff(const fs::path& f, const VolumeU8& v, uint16_t compression, uint32_t rows_per_strip) {
  TIFF* t = TIFFOpen(f.c_str(), "w");
  ASSERT_NE(t, nullptr);
  for (int64_t z = 0; z < v.nz(); ++z) {
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, static_cast<uint32_t>(v.nx()));
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, static_cast<uint32_t>(v.ny()));
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 8);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(t, TIFFTAG_COMPRESSION, compression);
    TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, rows_per_strip);
    for (int64_t y = 0; y < v.ny(); ++y)
      ASSERT_GE(TIFFWriteScanline(t, const_cast<uint8_t*>(&v(0, y, z)), static_cast<uint32_t>(y), 0), 0);
    TIFFWriteDirectory(t);
  }
  TIFFClose(t);
}
}  // namespace

namespace {
template <class T>
void round_trip(int compression) {
  auto v = ramp_volume<T>(Dims{19, 11, 4});
  v.set_unit("mm");
  const std::string name = std::string(VoxelTraits<T>::name) + "_" + std::to_string(compression);
  const fs::path f = scratch() / (name + ".tif");
  io::VolumeWriteOptions o;
  o.compression = compression;
  io::write_any_volume(f, v, o);
  auto back = read_as<T>(f);
  ASSERT_TRUE(back) << name;
  EXPECT_TRUE(std::equal(back->begin(), back->end(), v.begin())) << name;
  EXPECT_EQ(back->dims(), v.dims()) << name;
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(back->spacing()[k], v.spacing()[k], 1e-6 * v.spacing()[k]) << name;  // x/y as float resolutions
    EXPECT_NEAR(back->origin()[k], v.origin()[k], 1e-5) << name;
  }
  EXPECT_EQ(back->unit(), "mm") << name;
}
}  // namespace

TEST(Tiff, RoundTripEveryVoxelTypeWithSpacingOriginAndUnit) {
  for (int c : {0, 1}) {
    round_trip<uint8_t>(c);
    round_trip<uint16_t>(c);
    round_trip<uint32_t>(c);
    round_trip<uint64_t>(c);
    round_trip<int32_t>(c);
    round_trip<float>(c);
    round_trip<double>(c);
  }
  // µm is written as ImageJ writes it ("micron") and read back as µm; a non-ASCII unit survives.
  auto v = ramp_volume<uint8_t>(Dims{4, 3, 2});
  io::write_any_volume(scratch() / "um.tif", v);
  EXPECT_EQ(read_as<uint8_t>(scratch() / "um.tif")->unit(), kDefaultUnit);
  v.set_unit("\u00c5");
  io::write_any_volume(scratch() / "angstrom.tif", v);
  EXPECT_EQ(read_as<uint8_t>(scratch() / "angstrom.tif")->unit(), "\u00c5");
}

TEST(Tiff, ReadsImageJFilesOfTifffile) {
  NEED_TIFFFILE();
  const fs::path d = tifffile_dir();
  auto v = read_as<uint16_t>(d / "imagej_u16.tif");
  ASSERT_TRUE(v);
  EXPECT_EQ(v->dims(), (Dims{40, 35, 5}));
  EXPECT_EQ(v->spacing(), (Vec3{0.5, 0.25, 2.0}));
  EXPECT_EQ(v->unit(), kDefaultUnit);  // "um"
  for (int64_t i = 0; i < v->size(); ++i) ASSERT_EQ((*v)[i], ramp(i)) << i;
  auto mm = read_as<float>(d / "imagej_f32_mm.tif");
  ASSERT_TRUE(mm);
  EXPECT_EQ(mm->unit(), "mm");
  EXPECT_NEAR(mm->spacing()[0], 0.01, 1e-8);
  EXPECT_DOUBLE_EQ(mm->spacing()[2], 0.02);
  EXPECT_FLOAT_EQ((*mm)[7], static_cast<float>(ramp(7)) / 4);
  // Two channels: an error naming the file and the count, unless `channel` picks one.
  const std::string e = error_of([&] { io::read_any_volume(d / "imagej_2ch.tif"); });
  EXPECT_NE(e.find("imagej_2ch.tif: 2 channels; set the parameter `channel` (0..1)"), std::string::npos) << e;
  io::VolumeReadOptions o;
  o.channel = 1;
  auto c1 = read_as<uint8_t>(d / "imagej_2ch.tif", o);
  ASSERT_TRUE(c1);
  EXPECT_EQ(c1->dims(), (Dims{40, 35, 5}));
  for (int64_t i = 0; i < c1->size(); ++i) ASSERT_EQ((*c1)[i], ramp(i) / 2) << i;
  o.channel = 2;
  EXPECT_NE(error_of([&] { io::read_any_volume(d / "imagej_2ch.tif", o); }).find("channel 2 asked, the file has 2"), std::string::npos);
}

TEST(Tiff, ReadsOmeTiffOfTifffile) {
  NEED_TIFFFILE();
  const fs::path d = tifffile_dir();
  auto v = read_as<float>(d / "ome_f32.ome.tif");
  ASSERT_TRUE(v);
  EXPECT_EQ(v->dims(), (Dims{40, 35, 5}));
  EXPECT_EQ(v->spacing(), (Vec3{8.0, 8.0, 30.0}));
  EXPECT_EQ(v->unit(), "nm");
  for (int64_t i = 0; i < v->size(); ++i) ASSERT_EQ((*v)[i], static_cast<float>(ramp(i))) << i;
  io::VolumeReadOptions o;
  o.channel = 1;
  auto c1 = read_as<uint16_t>(d / "ome_2ch.ome.tif", o);
  ASSERT_TRUE(c1);
  EXPECT_EQ(c1->dims(), (Dims{40, 35, 5}));
  EXPECT_EQ(c1->spacing(), (Vec3{0.3, 0.3, 1.5}));
  EXPECT_EQ(c1->unit(), kDefaultUnit);  // OME's default unit: µm
  for (int64_t i = 0; i < c1->size(); ++i) ASSERT_EQ((*c1)[i], ramp(i) + 1) << i;
}

TEST(Tiff, ReadsTilesStripsBigTiffBigEndianSignedAndRgb) {
  NEED_TIFFFILE();
  const fs::path d = tifffile_dir();
  auto tiled = read_as<uint16_t>(d / "tiled_deflate.tif");
  ASSERT_TRUE(tiled);
  for (int64_t i = 0; i < tiled->size(); ++i) ASSERT_EQ((*tiled)[i], ramp(i)) << i;
  EXPECT_NE(io::describe_volume_file(d / "tiled_deflate.tif").find("tiles 16x16, compression deflate"), std::string::npos);
  auto strips = read_as<uint8_t>(d / "strips3.tif");
  ASSERT_TRUE(strips);
  for (int64_t i = 0; i < strips->size(); ++i) ASSERT_EQ((*strips)[i], ramp(i)) << i;
  auto big = read_as<int32_t>(d / "bigtiff.tif");  // int16 widens to int32
  ASSERT_TRUE(big);
  for (int64_t i = 0; i < big->size(); ++i) ASSERT_EQ((*big)[i], ramp(i, true)) << i;
  EXPECT_NE(io::describe_volume_file(d / "bigtiff.tif").find("BigTIFF"), std::string::npos);
  auto be = read_as<double>(d / "big_endian.tif");
  ASSERT_TRUE(be);
  for (int64_t i = 0; i < be->size(); ++i) ASSERT_EQ((*be)[i], static_cast<double>(ramp(i))) << i;
  auto i8 = read_as<int32_t>(d / "int8.tif");
  ASSERT_TRUE(i8);
  for (int64_t i = 0; i < i8->size(); ++i) ASSERT_EQ((*i8)[i], static_cast<int8_t>(ramp(i, true))) << i;
  auto u32 = read_as<uint32_t>(d / "uint32.tif");
  ASSERT_TRUE(u32);
  EXPECT_EQ((*u32)[100], ramp(100));
  for (const char* rgb : {"rgb.tif", "rgb_planar.tif"}) {
    const std::string e = error_of([&] { io::read_any_volume(d / rgb); });
    EXPECT_NE(e.find(std::string(rgb) + ": 3 samples per pixel (RGB or multi-channel); set the parameter `channel` (0..2)"),
              std::string::npos)
        << e;
    io::VolumeReadOptions o;
    o.channel = 2;
    auto blue = read_as<uint8_t>(d / rgb, o);
    ASSERT_TRUE(blue);
    EXPECT_EQ(blue->dims(), (Dims{40, 35, 5}));
    for (int64_t i = 0; i < blue->size(); ++i) ASSERT_EQ((*blue)[i], ramp(i) / 5) << rgb << " " << i;
  }
}

TEST(Tiff, ReadsLzwAndPackBitsOfLibtiff) {
  const auto v = ramp_volume<uint8_t>(Dims{33, 17, 3});
  for (auto [name, c] : {std::pair{"lzw.tif", COMPRESSION_LZW}, std::pair{"packbits.tif", COMPRESSION_PACKBITS}}) {
    write_with_libtiff(scratch() / name, v, static_cast<uint16_t>(c), 4);
    auto back = read_as<uint8_t>(scratch() / name);
    ASSERT_TRUE(back);
    EXPECT_TRUE(std::equal(back->begin(), back->end(), v.begin())) << name;
  }
}

TEST(Tiff, BoxesDecodeOnlyTheirPagesAndEqualTheCrop) {
  const auto v = ramp_volume<uint16_t>(Dims{37, 29, 9});
  io::write_any_volume(scratch() / "v.tif", v);
  for (auto [b, s] : {std::pair{Dims{0, 0, 0}, Dims{37, 29, 9}}, std::pair{Dims{5, 7, 2}, Dims{20, 13, 4}},
                      std::pair{Dims{36, 28, 8}, Dims{1, 1, 1}}}) {
    auto box = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume_box(scratch() / "v.tif", {}, b, s));
    ASSERT_TRUE(box);
    EXPECT_EQ(box->dims(), s);
    EXPECT_DOUBLE_EQ(box->origin()[2], v.origin()[2] + static_cast<double>(b[2]) * v.spacing()[2]);
    for (int64_t z = 0; z < s[2]; ++z)
      for (int64_t y = 0; y < s[1]; ++y)
        for (int64_t x = 0; x < s[0]; ++x) ASSERT_EQ((*box)(x, y, z), v(x + b[0], y + b[1], z + b[2]));
  }
  // Only the box's pages are decoded: with page 0's compressed strip damaged (it follows the 8-byte
  // header), a box of the other pages reads and the whole volume fails, naming the file and page.
  io::VolumeWriteOptions wo;
  wo.compression = 1;
  io::write_any_volume(scratch() / "damaged.tif", v, wo);
  {
    std::fstream f(scratch() / "damaged.tif", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(8);
    const std::string junk(64, '\x5a');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  auto rest = std::dynamic_pointer_cast<const VolumeU16>(
      io::read_any_volume_box(scratch() / "damaged.tif", {}, Dims{0, 0, 1}, Dims{37, 29, 8}));
  ASSERT_TRUE(rest);
  EXPECT_EQ((*rest)(3, 4, 5), v(3, 4, 6));
  const std::string whole = error_of([&] { io::read_any_volume(scratch() / "damaged.tif"); });
  EXPECT_NE(whole.find((scratch() / "damaged.tif").string() + ": page 0: cannot decode strip 0: the file is truncated or corrupt"),
            std::string::npos)
      << whole;
  NEED_TIFFFILE();
  auto tiled = std::dynamic_pointer_cast<const VolumeU16>(
      io::read_any_volume_box(tifffile_dir() / "tiled_deflate.tif", {}, Dims{10, 14, 1}, Dims{25, 20, 3}));
  ASSERT_TRUE(tiled);
  for (int64_t z = 0; z < 3; ++z)
    for (int64_t y = 0; y < 20; ++y)
      for (int64_t x = 0; x < 25; ++x) ASSERT_EQ((*tiled)(x, y, z), ramp((x + 10) + 40 * ((y + 14) + 35 * (z + 1))));
}

TEST(Tiff, FoldersAndPatternsOfSlicesInNaturalOrder) {
  const fs::path dir = scratch() / "slices";
  fs::create_directories(dir);
  const auto v = ramp_volume<uint8_t>(Dims{12, 7, 12}, {0.5, 0.5, 1.0}, {0, 0, 0});
  for (int64_t z = 0; z < v.nz(); ++z) {
    VolumeU8 s(Dims{12, 7, 1}, 0, {0.5, 0.5, 1.0});
    std::copy_n(&v(0, 0, z), 12 * 7, s.data());
    std::string name = std::to_string(z);  // appended: GCC 12 warns falsely (-Wrestrict) on "z" + s
    name.insert(name.begin(), 'z');
    name += ".tif";
    io::write_any_volume(dir / name, s);
  }
  std::ofstream(dir / "notes.txt") << "not a slice";
  auto back = read_as<uint8_t>(dir);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->dims(), v.dims());
  EXPECT_TRUE(std::equal(back->begin(), back->end(), v.begin()));  // z2 before z10
  EXPECT_EQ(back->spacing()[0], 0.5);
  // A pattern picks some of the files: z1, z10, z11 (natural order).
  auto some = read_as<uint8_t>(dir / "z1*.tif");
  ASSERT_TRUE(some);
  ASSERT_EQ(some->nz(), 3);
  EXPECT_EQ((*some)(3, 2, 1), v(3, 2, 10));
  // The module and validate take folders and patterns.
  auto r = run_module("io.read_volume", {}, {{"path", std::string("slices/z1*.tif")}}, {.threads = 1, .base_dir = scratch()});
  EXPECT_EQ(r.get<VolumeU8>("volume")->nz(), 3);
  const std::string yaml = "skelflow: 1\nnodes:\n  a: {module: io.read_volume, params: {path: slices}}\n"
                           "  b: {module: io.read_volume, params: {path: nowhere/z*.tif}}\n"
                           "  c: {module: io.read_volume, params: {path: slices/q*.tif}}\n";
  const auto ds = validate(Pipeline::parse(yaml, "p.yaml", scratch()));
  ASSERT_EQ(ds.size(), 2u);
  EXPECT_NE(ds[0].format().find("node 'b': param 'path': folder '" + (scratch() / "nowhere").string() + "' of the pattern not found"),
            std::string::npos)
      << ds[0].format();
  EXPECT_NE(ds[1].format().find("node 'c': param 'path': " + (scratch() / "slices" / "q*.tif").string() + ": no file matches"),
            std::string::npos)
      << ds[1].format();
  // A slice of another size names its file.
  io::write_any_volume(dir / "z12.tif", VolumeU8(Dims{12, 8, 1}));
  const std::string e = error_of([&] { io::read_any_volume(dir); });
  EXPECT_NE(e.find("z12.tif: page 0 is 12x8 uint8"), std::string::npos) << e;
}

TEST(Tiff, BadFilesNameTheFileAndWhatIsWrong) {
  const fs::path d = scratch();
  io::write_any_volume(d / "good.tif", ramp_volume<uint16_t>(Dims{64, 64, 4}));
  std::ofstream(d / "text.tif") << "this is not a TIFF file at all";
  EXPECT_NE(error_of([&] { io::read_any_volume(d / "text.tif"); }).find("text.tif: not a TIFF file (wrong magic bytes)"),
            std::string::npos);
  std::ofstream(d / "tiny.tif") << "II";
  EXPECT_NE(error_of([&] { io::read_any_volume(d / "tiny.tif"); }).find("tiny.tif: not a TIFF file (shorter than a TIFF header)"),
            std::string::npos);
  // Truncated: the header names pages the file no longer holds, or strips are cut.
  for (uintmax_t keep : {uintmax_t{12}, fs::file_size(d / "good.tif") / 2}) {
    fs::copy_file(d / "good.tif", d / "cut.tif", fs::copy_options::overwrite_existing);
    fs::resize_file(d / "cut.tif", keep);
    const std::string e = error_of([&] { io::read_any_volume(d / "cut.tif"); });
    EXPECT_NE(e.find((d / "cut.tif").string() + ": "), std::string::npos) << e;
    EXPECT_TRUE(e.find("truncated") != std::string::npos || e.find("corrupt") != std::string::npos) << e;
  }
  EXPECT_NE(error_of([&] { io::read_any_volume(d / "missing.tif"); }).find("missing.tif: file not found"), std::string::npos);
  NEED_TIFFFILE();
  const std::string sizes = error_of([&] { io::read_any_volume(tifffile_dir() / "bad_sizes.tif"); });
  EXPECT_NE(sizes.find("bad_sizes.tif: page 1 is 41x35 uint8"), std::string::npos) << sizes;
  EXPECT_NE(sizes.find("every page of a stack must have the same size and type"), std::string::npos) << sizes;
  const std::string cplx = error_of([&] { io::read_any_volume(tifffile_dir() / "bad_complex.tif"); });
  EXPECT_NE(cplx.find("bad_complex.tif: page 0: unsupported sample type (64-bit complex)"), std::string::npos) << cplx;
}

// libFuzzer's reproducer (a seed of the tiff target now): a 24x18 page whose tiles claim to be
// 4294508560x16 pixels. The tile buffer (137 GB) was allocated before any check (std::bad_alloc, or
// an out-of-memory abort under ASan); the tile size is now checked against the file like the voxels.
TEST(Tiff, HugeTileIsRefusedBeforeItsBufferIsAllocated) {
  const fs::path path = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "tiff" / "huge_tile_width.tif";
  ASSERT_TRUE(fs::exists(path)) << path;
  for (const bool header_only : {true, false}) {
    const std::string e = error_of([&] {
      if (header_only) (void)io::read_volume_header(path);
      else (void)io::read_any_volume(path);
    });
    EXPECT_NE(e.find(path.string() + ": a tile of 137424273920 bytes is more than 1439 bytes of file can hold"),
              std::string::npos) << e;
    EXPECT_NE(e.find("truncated or corrupt"), std::string::npos) << e;
  }
  // Tiles larger than their page are legal and still read (16x16 tiles of a 5x3 page).
  const fs::path small = scratch() / "small_page_big_tile.tif";
  {
    TIFF* t = TIFFOpen(small.c_str(), "w");
    ASSERT_NE(t, nullptr);
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, 5u);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, 3u);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 8);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(t, TIFFTAG_TILEWIDTH, 16u);
    TIFFSetField(t, TIFFTAG_TILELENGTH, 16u);
    std::vector<unsigned char> tile(256, 0);
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 5; ++x) tile[static_cast<size_t>(y * 16 + x)] = static_cast<unsigned char>(10 * y + x);
    ASSERT_GE(TIFFWriteEncodedTile(t, 0, tile.data(), 256), 0);
    TIFFClose(t);
  }
  const DataPtr v = io::read_any_volume(small);
  const auto* u8 = dynamic_cast<const VolumeU8*>(v.get());
  ASSERT_NE(u8, nullptr);
  EXPECT_EQ(u8->dims(), (Dims{5, 3, 1}));
  EXPECT_EQ((*u8)(4, 2, 0), 24);
}

TEST(Tiff, WrittenFilesAreImageJStacksForTifffile) {
  NEED_TIFFFILE();
  auto v = ramp_volume<uint16_t>(Dims{9, 8, 3}, {0.25, 0.25, 1.5});
  io::write_any_volume(scratch() / "w.tif", v);
  const fs::path out = scratch() / "check.txt";
  const std::string cmd = "/usr/bin/python3 -c \"import tifffile; t = tifffile.TiffFile('" + (scratch() / "w.tif").string() +
                          "'); m = t.imagej_metadata; a = t.asarray(); print(t.is_imagej, m['unit'], m['spacing'], a.shape, a.dtype, int(a[2, 7, 8]))\" > " +
                          out.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream in(out);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "True micron 1.5 (3, 8, 9) uint16 " + std::to_string(v(8, 7, 2))) << line;
}

TEST(Tiff, OmeTiffNamesGetOmeXmlThatTifffileReads) {
  auto v = ramp_volume<uint16_t>(Dims{9, 8, 3}, {0.25, 0.5, 1.5}, {0, 0, 0});
  v.set_unit("nm");
  io::write_any_volume(scratch() / "w.ome.tif", v);
  auto back = read_as<uint16_t>(scratch() / "w.ome.tif");
  ASSERT_TRUE(back);
  EXPECT_TRUE(std::equal(back->begin(), back->end(), v.begin()));
  EXPECT_EQ(back->spacing(), v.spacing());
  EXPECT_EQ(back->unit(), "nm");
  EXPECT_NE(io::describe_volume_file(scratch() / "w.ome.tif").find("metadata: OME-TIFF"), std::string::npos);
  EXPECT_NE(error_of([&] { io::write_any_volume(scratch() / "u64.ome.tif", VolumeU64(Dims{2, 2, 2})); }).find("OME-TIFF has no uint64"),
            std::string::npos);
  NEED_TIFFFILE();
  const fs::path out = scratch() / "check.txt";
  const std::string cmd = "/usr/bin/python3 -c \"import tifffile; t = tifffile.TiffFile('" + (scratch() / "w.ome.tif").string() +
                          "'); a = t.asarray(); print(t.is_ome, t.series[0].axes, a.shape, int(a[2, 7, 8]))\" > " + out.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream in(out);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "True ZYX (3, 8, 9) " + std::to_string(v(8, 7, 2))) << line;
}
