// The volume format registry as users meet it: io.read_volume / io.write_volume choose the format by
// extension, `spacing` and `unit` override the file, HDF5 keeps the unit and reads Fiji's
// element_size_um, `skelflow info` describes any volume file, and `skelflow validate` reads headers
// (a voxel type the next node does not take, a missing or truncated header) before anything runs.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "io/hdf5_volume.hpp"
#include "io/volume_format.hpp"
#include "skel/pipeline.hpp"
#include "skel/run_module.hpp"
#include "volume_test_util.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
using skel::test::scratch;  // one folder per test (volume_test_util.hpp)

template <class T>
Volume<T> random_volume(Dims d, uint64_t seed) {
  Volume<T> v(d, T{}, {0.5, 0.75, 2.0}, {-3.0, 1.5, 10.0});
  std::mt19937_64 rng(seed);
  for (auto& x : v) x = static_cast<T>(rng() % 200);
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

// Runs the real `skelflow` with `args`; returns stdout + stderr and sets `code`.
std::string skelflow(const std::string& args, int& code) {
  const std::string cmd = std::string(SKELFLOW_BIN) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  std::array<char, 4096> buf{};
  while (size_t n = fread(buf.data(), 1, buf.size(), p)) out.append(buf.data(), n);
  const int st = pclose(p);
  code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return out;
}

const std::string kMicrometre = kDefaultUnit;
}  // namespace

TEST(VolumeFormats, Hdf5KeepsTheUnitAndTheRegistryChoosesByExtension) {
  auto v = random_volume<uint16_t>(Dims{9, 7, 5}, 1);
  v.set_unit("mm");
  const fs::path f = scratch() / "v.HDF5";  // extensions match in any case
  io::write_any_volume(f, v);
  EXPECT_EQ(io::volume_format_for_read(f).name, "HDF5");
  const io::VolumeHeader h = io::read_volume_header(f);
  EXPECT_EQ(h.dtype, "uint16");
  EXPECT_EQ(h.grid.unit, "mm");
  EXPECT_TRUE(h.has_unit && h.has_spacing && h.has_origin);
  EXPECT_EQ(h.grid.dims, v.dims());
  auto back = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(f));
  ASSERT_TRUE(back);
  EXPECT_TRUE(*back == v);
  EXPECT_EQ(back->unit(), "mm");
  EXPECT_EQ(back->spacing(), v.spacing());
  // A box, by hyperslab: the crop's voxels, its origin moved to the box corner.
  auto box = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume_box(f, {}, Dims{2, 1, 3}, Dims{4, 5, 2}));
  ASSERT_TRUE(box);
  EXPECT_EQ(box->unit(), "mm");
  EXPECT_DOUBLE_EQ(box->origin()[0], v.origin()[0] + 2 * v.spacing()[0]);
  for (int64_t z = 0; z < 2; ++z)
    for (int64_t y = 0; y < 5; ++y)
      for (int64_t x = 0; x < 4; ++x) ASSERT_EQ((*box)(x, y, z), v(x + 2, y + 1, z + 3));
  EXPECT_NE(error_of([&] { io::read_any_volume_box(f, {}, Dims{8, 0, 0}, Dims{2, 1, 1}); }).find("outside the volume"),
            std::string::npos);
  // A file Skelflow does not know names itself and the known extensions; so does one it cannot write.
  std::ofstream(scratch() / "notes.xyz") << "hello";
  const std::string e = error_of([&] { io::read_any_volume(scratch() / "notes.xyz"); });
  EXPECT_NE(e.find("notes.xyz: not a volume file"), std::string::npos) << e;
  EXPECT_NE(e.find(".h5"), std::string::npos) << e;
  const std::string w = error_of([&] { io::write_any_volume(scratch() / "out.xyz", v); });
  EXPECT_NE(w.find("out.xyz: cannot write a volume of this type"), std::string::npos) << w;
  // An HDF5 file under another name is recognised by its first bytes.
  fs::copy_file(f, scratch() / "v.data");
  EXPECT_EQ(io::volume_format_for_read(scratch() / "v.data").name, "HDF5");
}

TEST(VolumeFormats, Hdf5ReadsElementSizeUmOfFijiAndIlastik) {
  // As Fiji's HDF5 plugin and ilastik write it: the dataset in a group, element_size_um [z][y][x].
  const fs::path f = scratch() / "fiji.h5";
  for (bool on_group : {true, false}) {
    {
      hid_t file = H5Fcreate(f.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
      hid_t g = H5Gcreate2(file, "/t00000", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      const hsize_t dims[3] = {3, 4, 5};
      hid_t space = H5Screate_simple(3, dims, nullptr);
      hid_t d = H5Dcreate2(g, "data", H5T_NATIVE_UINT8, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      std::vector<uint8_t> voxels(60);
      for (size_t i = 0; i < voxels.size(); ++i) voxels[i] = static_cast<uint8_t>(i);
      H5Dwrite(d, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, voxels.data());
      const hsize_t three = 3;
      hid_t as = H5Screate_simple(1, &three, nullptr);
      hid_t a = H5Acreate2(on_group ? g : d, "element_size_um", H5T_IEEE_F32LE, as, H5P_DEFAULT, H5P_DEFAULT);
      const float zyx[3] = {2.0f, 0.5f, 0.25f};
      H5Awrite(a, H5T_NATIVE_FLOAT, zyx);
      H5Aclose(a);
      H5Sclose(as);
      H5Dclose(d);
      H5Sclose(space);
      H5Gclose(g);
      H5Fclose(file);
    }
    io::VolumeReadOptions o;
    o.dataset = "/t00000/data";
    auto v = std::dynamic_pointer_cast<const VolumeU8>(io::read_any_volume(f, o));
    ASSERT_TRUE(v);
    EXPECT_EQ(v->dims(), (Dims{5, 4, 3}));
    EXPECT_EQ(v->spacing(), (Vec3{0.25, 0.5, 2.0})) << "on group: " << on_group;
    EXPECT_EQ(v->unit(), kMicrometre);
    EXPECT_EQ((*v)(4, 3, 2), 59);
    const io::VolumeHeader h = io::read_volume_header(f, o);
    EXPECT_TRUE(h.has_spacing && h.has_unit);
    EXPECT_EQ(h.grid.spacing, (Vec3{0.25, 0.5, 2.0}));
  }
}

TEST(VolumeFormats, ReadVolumeModuleOverridesSpacingAndUnitAndWritesByExtension) {
  const fs::path dir = scratch();
  DataPtr v = std::make_shared<VolumeU8>(random_volume<uint8_t>(Dims{6, 5, 4}, 2));
  run_module("io.write_volume", {{"volume", v}}, {{"path", std::string("a/v.h5")}}, {.threads = 1, .base_dir = dir});
  auto same = run_module("io.read_volume", {}, {{"path", std::string("a/v.h5")}}, {.threads = 1, .base_dir = dir})
                  .get<VolumeU8>("volume");
  EXPECT_EQ(same->spacing(), (Vec3{0.5, 0.75, 2.0}));
  EXPECT_EQ(same->unit(), kMicrometre);
  auto r = run_module("io.read_volume", {},
                      {{"path", std::string("a/v.h5")},
                       {"spacing", std::vector<double>{0.1, 0.2, 0.3}},
                       {"unit", std::string("nm")}},
                      {.threads = 1, .base_dir = dir});
  auto u = r.get<VolumeU8>("volume");
  EXPECT_EQ(u->spacing(), (Vec3{0.1, 0.2, 0.3}));
  EXPECT_EQ(u->unit(), "nm");
  EXPECT_TRUE(std::equal(u->begin(), u->end(), same->begin()));
  // The origin keeps its place in voxels: -3 / 0.5 = -6 voxels -> -0.6 nm.
  EXPECT_DOUBLE_EQ(u->origin()[0], -0.6);
  const std::string e = error_of([&] {
    run_module("io.read_volume", {}, {{"path", std::string("a/v.h5")}, {"spacing", std::vector<double>{1, 0, 1}}},
               {.threads = 1, .base_dir = dir});
  });
  EXPECT_NE(e.find("must be > 0"), std::string::npos) << e;
  // The written unit goes back to the file.
  run_module("io.write_volume", {{"volume", u}}, {{"path", std::string("b/nm.h5")}}, {.threads = 1, .base_dir = dir});
  EXPECT_EQ(io::read_volume_header(dir / "b" / "nm.h5").grid.unit, "nm");
}

TEST(VolumeFormats, InfoDescribesVolumeFilesAndListsTheKnownExtensions) {
  auto v = random_volume<float>(Dims{4, 3, 2}, 3);
  v.set_unit("mm");
  io::write_any_volume(scratch() / "v.h5", v);
  int code = -1;
  const std::string out = skelflow("info " + (scratch() / "v.h5").string(), code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("format: HDF5"), std::string::npos) << out;
  EXPECT_NE(out.find("/volume: float32 4x3x2 (x,y,z)"), std::string::npos) << out;
  EXPECT_NE(out.find("mm"), std::string::npos) << out;
  std::ofstream(scratch() / "x.qqq") << "hello";
  const std::string bad = skelflow("info " + (scratch() / "x.qqq").string(), code);
  EXPECT_EQ(code, 2) << bad;
  EXPECT_NE(bad.find("x.qqq: unknown file type '.qqq'"), std::string::npos) << bad;
  for (const auto& ext : io::readable_volume_extensions()) EXPECT_NE(bad.find(ext), std::string::npos) << ext << ": " << bad;
  // A folder of TIFF slices and a pattern are described too (before: "unknown file type").
  fs::create_directories(scratch() / "slices");
  for (const char* z : {"s1.tif", "s2.tif", "s10.tif"}) io::write_any_volume(scratch() / "slices" / z, VolumeU8(Dims{5, 4, 1}));
  const std::string folder = skelflow("info " + (scratch() / "slices").string(), code);
  EXPECT_EQ(code, 0) << folder;
  EXPECT_NE(folder.find("voxels: uint8 5x4x3 (x,y,z)"), std::string::npos) << folder;
  EXPECT_NE(folder.find("files: 3"), std::string::npos) << folder;
  const std::string pattern = skelflow("info '" + (scratch() / "slices" / "s1*.tif").string() + "'", code);
  EXPECT_EQ(code, 0) << pattern;
  EXPECT_NE(pattern.find("voxels: uint8 5x4x2 (x,y,z)"), std::string::npos) << pattern;
}

namespace {
// A pipeline reading `file` into thinning.doht's uint8 `mask` port (its priority from a distance map
// of the same file).
std::string reader_into_mask(const std::string& file, const std::string& extra = "") {
  return "skelflow: 1\n"
         "nodes:\n"
         "  image: {module: io.read_volume, params: {path: " + file + extra + "}}\n"
         "  dist: {module: distance.euclidean, inputs: {mask: image.volume}}\n"
         "  thin: {module: thinning.doht, inputs: {mask: image.volume, priority: dist.distance}}\n";
}
std::vector<std::string> validate_text(const std::string& yaml, const fs::path& dir) {
  std::vector<std::string> r;
  for (const auto& d : validate(Pipeline::parse(yaml, "p.yaml", dir))) r.push_back(d.format());
  return r;
}
}  // namespace

TEST(VolumeFormats, ValidateReadsTheHeaderAndReportsAVoxelTypeTheNextNodeDoesNotTake) {
  const fs::path dir = scratch();
  io::write_any_volume(dir / "u16.h5", random_volume<uint16_t>(Dims{8, 8, 8}, 4));
  io::write_any_volume(dir / "u8.h5", random_volume<uint8_t>(Dims{8, 8, 8}, 5));
  // Before: "image.volume gives any volume" matched the uint8 port and the run failed later.
  const auto ds = validate_text(reader_into_mask("u16.h5"), dir);
  ASSERT_EQ(ds.size(), 1u);  // distance.euclidean takes any integer volume
  EXPECT_NE(ds[0].find("p.yaml:5:"), std::string::npos) << ds[0];
  EXPECT_NE(ds[0].find("node 'thin': input 'mask': type mismatch: image.volume gives volume.u16 ('" +
                       (dir / "u16.h5").string() + "' holds uint16 voxels), but 'mask' takes volume.u8"),
            std::string::npos)
      << ds[0];
  EXPECT_TRUE(validate_text(reader_into_mask("u8.h5"), dir).empty());
  // Converting in the reader fixes it.
  EXPECT_TRUE(validate_text(reader_into_mask("u16.h5", ", dtype: uint8"), dir).empty());
  // A missing dataset, a file that is not a volume and a truncated one are reported at the path.
  const auto md = validate_text(reader_into_mask("u8.h5", ", dataset: /nope"), dir);
  ASSERT_EQ(md.size(), 1u);
  EXPECT_NE(md[0].find("p.yaml:3:50: node 'image': param 'path': " + (dir / "u8.h5").string() + ": no dataset '/nope'"),
            std::string::npos)
      << md[0];
  {
    std::ifstream in(dir / "u8.h5", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(dir / "cut.h5", std::ios::binary).write(bytes.data(), 300);
  }
  const auto tr = validate_text(reader_into_mask("cut.h5"), dir);
  ASSERT_EQ(tr.size(), 1u);
  EXPECT_NE(tr[0].find("cut.h5: "), std::string::npos) << tr[0];
  // A missing file is reported once, as before (the header is not read).
  const auto mf = validate_text(reader_into_mask("missing.h5"), dir);
  ASSERT_EQ(mf.size(), 1u);
  EXPECT_NE(mf[0].find("input file '" + (dir / "missing.h5").string() + "' not found"), std::string::npos) << mf[0];
}

// Validation reads headers only: a file whose voxels are damaged passes validate and fails while
// running, naming the file (the GUI's run-time error test relies on such a file).
TEST(VolumeFormats, DamagedVoxelsPassValidationAndFailAtRunNamingTheFile) {
  const fs::path dir = scratch();
  Volume<uint8_t> v(Dims{64, 64, 64});
  std::mt19937 rng(7);
  for (auto& x : v) x = static_cast<uint8_t>(rng());
  io::VolumeWriteOptions wo;
  wo.compression = 1;
  io::write_any_volume(dir / "damaged.h5", v, wo);
  const auto size = static_cast<std::streamoff>(fs::file_size(dir / "damaged.h5"));
  {
    std::fstream f(dir / "damaged.h5", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(size / 2);
    const std::string junk(4096, '\xff');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  const std::string yaml = "skelflow: 1\nnodes:\n  image: {module: io.read_volume, params: {path: damaged.h5}}\n";
  EXPECT_TRUE(validate_text(yaml, dir).empty());
  const std::string e = error_of([&] {
    run_module("io.read_volume", {}, {{"path", std::string("damaged.h5")}}, {.threads = 1, .base_dir = dir});
  });
  // Read by our chunk decoding (io/hdf5_chunks.hpp), which names the damaged chunk.
  EXPECT_EQ(e.rfind((dir / "damaged.h5").string() + ": dataset '/volume': chunk (", 0), 0u) << e;
  EXPECT_NE(e.find("the file is damaged"), std::string::npos) << e;
}

// Raw volumes: the layout comes from the parameters; the file's size is checked against it before
// anything is allocated.
TEST(VolumeFormats, RawVolumesTakeTheirLayoutFromParameters) {
  const fs::path dir = scratch();
  const Dims d{7, 5, 3};
  std::vector<int16_t> voxels(7 * 5 * 3);
  for (size_t i = 0; i < voxels.size(); ++i) voxels[i] = static_cast<int16_t>(static_cast<int>(i) * 37 - 1000);
  {
    std::ofstream little(dir / "v.raw", std::ios::binary);
    little.write("HDR!", 4);  // a 4-byte header to skip
    little.write(reinterpret_cast<const char*>(voxels.data()), static_cast<std::streamsize>(voxels.size() * 2));
    std::ofstream big(dir / "big.raw", std::ios::binary);
    for (int16_t v : voxels) {
      const auto u = static_cast<uint16_t>(v);
      const char b[2] = {static_cast<char>(u >> 8), static_cast<char>(u & 0xFF)};
      big.write(b, 2);
    }
  }
  const ParamMap base{{"raw_dims", std::vector<int64_t>{7, 5, 3}},
                      {"raw_type", std::string("int16")},
                      {"spacing", std::vector<double>{0.3, 0.3, 1.2}},
                      {"unit", std::string("mm")}};
  ParamMap little = base;
  little["path"] = std::string("v.raw");
  little["raw_header_bytes"] = int64_t{4};
  auto v = run_module("io.read_volume", {}, little, {.threads = 1, .base_dir = dir}).get<VolumeI32>("volume");
  EXPECT_EQ(v->dims(), d);
  EXPECT_EQ(v->spacing(), (Vec3{0.3, 0.3, 1.2}));
  EXPECT_EQ(v->unit(), "mm");
  for (size_t i = 0; i < voxels.size(); ++i) ASSERT_EQ((*v)[static_cast<int64_t>(i)], voxels[i]) << i;
  ParamMap big = base;
  big["path"] = std::string("big.raw");
  big["raw_byte_order"] = std::string("big");
  auto b = run_module("io.read_volume", {}, big, {.threads = 1, .base_dir = dir}).get<VolumeI32>("volume");
  EXPECT_TRUE(std::equal(b->begin(), b->end(), v->begin()));
  // A box reads only its rows.
  io::VolumeReadOptions o;
  o.raw = {{7, 5, 3}, "int16", true, 0};
  o.spacing = {1, 1, 1};
  auto box = std::dynamic_pointer_cast<const VolumeI32>(io::read_any_volume_box(dir / "big.raw", o, Dims{2, 1, 1}, Dims{3, 2, 2}));
  ASSERT_TRUE(box);
  EXPECT_EQ((*box)(2, 1, 1), (*v)(4, 2, 2));
  // Wrong dims, a missing type or spacing: errors naming the file, at validate, before any allocation.
  const std::string yaml = "skelflow: 1\nnodes:\n"
                           "  a: {module: io.read_volume, params: {path: v.raw, raw_dims: [7, 5, 4], raw_type: int16, spacing: [1, 1, 1]}}\n"
                           "  b: {module: io.read_volume, params: {path: v.raw, raw_dims: [7, 5, 3], spacing: [1, 1, 1]}}\n"
                           "  c: {module: io.read_volume, params: {path: v.raw, raw_dims: [100000000000, 100000000000, 3], raw_type: float64, spacing: [1, 1, 1]}}\n"
                           "  d: {module: io.read_volume, params: {path: v.raw, raw_dims: [7, 5, 3], raw_type: int16}}\n";
  const auto ds = validate_text(yaml, dir);
  ASSERT_EQ(ds.size(), 4u);
  EXPECT_NE(ds[0].find((dir / "v.raw").string() + ": holds 214 bytes, but 7x5x4 voxels of int16 need 280: check `raw_dims`"),
            std::string::npos)
      << ds[0];
  EXPECT_NE(ds[1].find("a raw file states no voxel type: set `raw_type`"), std::string::npos) << ds[1];
  EXPECT_NE(ds[2].find("need more than 2^63"), std::string::npos) << ds[2];
  EXPECT_NE(ds[3].find("a raw file states no spacing: set `spacing`"), std::string::npos) << ds[3];
}
