// The readers' HDF5 attributes (spacing, origin, unit, element_size_um, encoding) come from the
// structure probe's walk, not from libhdf5's attribute decoding in the reader's own process: libhdf5
// 1.10.8 reads out of bounds in H5Aexists -> H5O__attr_exists on some damaged object headers,
// depending on the heap's history, so no probe can refuse those files in advance
// (docs/reliability.md). This binary interposes H5Aexists and H5Aopen to count the calls made in this
// process; the values and errors must be those of the in-process reading (SKEL_HDF5_PROBE=0).
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <hdf5.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "io/hdf5_chunks.hpp"
#include "io/hdf5_probe.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/data.hpp"
#include "skel/error.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
std::atomic<int64_t> g_exists{0}, g_open{0}, g_file_open{0}, g_dataset_open{0};
}

// Interposed too: every open of a file or dataset in this process.
extern "C" hid_t H5Fopen(const char* name, unsigned flags, hid_t fapl) {
  ++g_file_open;
  using Fn = hid_t (*)(const char*, unsigned, hid_t);
  static const Fn next = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "H5Fopen"));
  return next(name, flags, fapl);
}
extern "C" hid_t H5Dopen2(hid_t file, const char* name, hid_t dapl) {
  ++g_dataset_open;
  using Fn = hid_t (*)(hid_t, const char*, hid_t);
  static const Fn next = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "H5Dopen2"));
  return next(file, name, dapl);
}

// Interposed: calls from this process (the readers in skel_io) land here, then go to libhdf5.
extern "C" htri_t H5Aexists(hid_t obj, const char* name) {
  ++g_exists;
  using Fn = htri_t (*)(hid_t, const char*);
  static const Fn next = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "H5Aexists"));
  return next(obj, name);
}
extern "C" hid_t H5Aopen(hid_t obj, const char* name, hid_t aapl) {
  ++g_open;
  using Fn = hid_t (*)(hid_t, const char*, hid_t);
  static const Fn next = reinterpret_cast<Fn>(dlsym(RTLD_NEXT, "H5Aopen"));
  return next(obj, name, aapl);
}

namespace {

// A folder of this test's own (ctest runs the tests of this program in parallel processes).
fs::path scratch() {
  static fs::path d = [] {
    fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "io" / "Hdf5Attributes" /
                 ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }();
  return d;
}

void attr_numbers(hid_t obj, const char* name, hid_t file_type, hid_t mem_type, const void* values, hsize_t n) {
  const hid_t s = H5Screate_simple(1, &n, nullptr);
  const hid_t a = H5Acreate2(obj, name, file_type, s, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(a, 0);
  H5Awrite(a, mem_type, values);
  H5Aclose(a);
  H5Sclose(s);
}

void attr_string(hid_t obj, const char* name, const std::string& value, bool variable) {
  const hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_cset(t, H5T_CSET_UTF8);
  const hid_t s = H5Screate(H5S_SCALAR);
  if (variable) {
    H5Tset_size(t, H5T_VARIABLE);
    const char* p = value.c_str();
    const hid_t a = H5Acreate2(obj, name, t, s, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, t, &p);
    H5Aclose(a);
  } else {
    H5Tset_size(t, value.size());
    const hid_t a = H5Acreate2(obj, name, t, s, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, t, value.data());
    H5Aclose(a);
  }
  H5Sclose(s);
  H5Tclose(t);
}

hid_t add_volume(hid_t where, const char* name) {
  const hsize_t dims[3] = {2, 3, 4};
  const hid_t s = H5Screate_simple(3, dims, nullptr);
  const hid_t d = H5Dcreate2(where, name, H5T_STD_U8LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  std::vector<uint8_t> v(24, 7);
  H5Dwrite(d, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Sclose(s);
  return d;
}

// Every way the readers' attributes can be stored: float and integer numbers, fixed and variable
// strings, UTF-8, element_size_um on the dataset and on its group, and the wrong ones.
fs::path make_file() {
  const fs::path file = scratch() / "attributes.h5";
  const hid_t f = H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t g = H5Gcreate2(f, "/fiji", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const float zyx[3] = {2.0f, 0.5f, 0.25f};
  attr_numbers(g, "element_size_um", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, zyx, 3);
  H5Dclose(add_volume(g, "volume"));  // spacing from the group's element_size_um
  hid_t d = add_volume(g, "own");     // its own element_size_um wins over the group's
  const double own[3] = {4, 5, 6};
  attr_numbers(d, "element_size_um", H5T_IEEE_F64BE, H5T_NATIVE_DOUBLE, own, 3);
  attr_string(d, "unit", "nm", true);
  H5Dclose(d);
  H5Gclose(g);
  d = add_volume(f, "full");
  const float spacing[3] = {0.5f, 0.25f, 2.0f};
  const int32_t origin[3] = {-1, 2, 3};
  attr_numbers(d, "spacing", H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, spacing, 3);
  attr_numbers(d, "origin", H5T_STD_I32BE, H5T_NATIVE_INT32, origin, 3);
  attr_string(d, "unit", "\u00b5m", false);
  attr_string(d, "encoding", "grid cells (test)", true);
  H5Dclose(d);
  d = add_volume(f, "plain");
  H5Dclose(d);
  d = add_volume(f, "two_values");
  attr_numbers(d, "spacing", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, own, 2);
  H5Dclose(d);
  d = add_volume(f, "number_unit");
  attr_numbers(d, "unit", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, own, 3);
  H5Dclose(d);
  d = add_volume(f, "negative");
  const double negative[3] = {1, -1, 1};
  attr_numbers(d, "spacing", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, negative, 3);
  H5Dclose(d);
  d = add_volume(f, "empty_unit");
  attr_string(d, "unit", "", true);
  H5Dclose(d);
  H5Fclose(f);
  return file;
}

// What a reader makes of one dataset: its geometry and encoding, or its error.
std::string describe(const fs::path& file, const std::string& dataset) {
  try {
    const io::VolumeInfo i = io::read_volume_info(file, dataset);
    std::string s;
    for (double v : i.spacing) s += std::to_string(v) + " ";
    for (double v : i.origin) s += std::to_string(v) + " ";
    s += i.unit + (i.has_spacing ? " S" : " -") + (i.has_origin ? "O" : "-") + (i.has_unit ? "U" : "-");
    return s + " encoding '" + io::read_string_attribute(file, dataset, "encoding") + "'";
  } catch (const Error& e) {
    return std::string("error: ") + e.what();
  }
}

const std::vector<std::string> kDatasets = {"/fiji/volume", "/fiji/own", "/full",       "/plain",
                                            "/two_values",  "/number_unit", "/negative", "/empty_unit"};

}  // namespace

TEST(Hdf5Attributes, TheReadersTakeTheProbesValuesAndDecodeNoAttributeThemselves) {
  if (io::detail::hdf5_probe_helper().empty()) GTEST_SKIP() << "skelflow-hdf5-probe not built";
  const fs::path file = make_file();
  // In this process, with the probe off: libhdf5 decodes the attributes here.
  setenv("SKEL_HDF5_PROBE", "0", 1);
  std::vector<std::string> in_process;
  g_exists = 0;
  for (const auto& d : kDatasets) in_process.push_back(describe(file, d));
  EXPECT_GT(g_exists.load(), 0);
  // With the probe (the default): the same values and errors, and no attribute decoded here.
  for (const char* mode : {"1", "fork"}) {
    setenv("SKEL_HDF5_PROBE", mode, 1);
    io::detail::forget_hdf5_probes();
    g_exists = 0;
    g_open = 0;
    for (size_t i = 0; i < kDatasets.size(); ++i) EXPECT_EQ(describe(file, kDatasets[i]), in_process[i]) << kDatasets[i] << " " << mode;
    EXPECT_EQ(g_exists.load(), 0) << mode;
    EXPECT_EQ(g_open.load(), 0) << mode;
  }
  unsetenv("SKEL_HDF5_PROBE");
  // The readings themselves.
  EXPECT_EQ(in_process[0].substr(0, in_process[0].find(" encoding")),
            "0.250000 0.500000 2.000000 0.000000 0.000000 0.000000 \u00b5m S-U");
  EXPECT_EQ(in_process[1].substr(0, in_process[1].find(" encoding")),
            "6.000000 5.000000 4.000000 0.000000 0.000000 0.000000 nm S-U");
  EXPECT_EQ(in_process[2], "0.500000 0.250000 2.000000 -1.000000 2.000000 3.000000 \u00b5m SOU encoding 'grid cells (test)'");
  EXPECT_NE(in_process[4].find("attribute 'spacing' must hold 3 numbers (x, y, z)"), std::string::npos) << in_process[4];
  EXPECT_NE(in_process[5].find("attribute 'unit' must be a string"), std::string::npos) << in_process[5];
  EXPECT_NE(in_process[6].find("the spacing must be > 0 on every axis"), std::string::npos) << in_process[6];
  EXPECT_NE(in_process[7].find("attribute 'unit' is empty"), std::string::npos) << in_process[7];
}

namespace {

// Everything the readers make of `file`: info, attributes, the description, the whole volume and
// boxes, as text (values as their bytes' hash) or the error.
std::string read_everything(const fs::path& file, const std::string& dataset) {
  std::string s;
  try {
    s += describe(file, dataset) + "\n" + io::describe_file(file);
    const DataPtr v = io::read_volume(file, dataset, 2);
    visit_volume(*v, "v", [&](const auto& a) {
      s += std::string(" ") + a.type_id() + " " + std::to_string(std::hash<std::string_view>{}(std::string_view(
                                                    reinterpret_cast<const char*>(a.data()), a.size() * sizeof(*a.data()))));
    });
    const io::VolumeInfo i = io::read_volume_info(file, dataset);
    const Dims b{i.dims[0] / 3, i.dims[1] / 4, i.dims[2] / 5}, n{i.dims[0] - i.dims[0] / 3 - 1, i.dims[1] / 2, i.dims[2] - i.dims[2] / 5};
    const Volume<double> box = io::read_box<double>(file, dataset, b, n);
    double sum = 0;
    for (int64_t k = 0; k < box.size(); ++k) sum += box.data()[k] * static_cast<double>(k % 7 + 1);
    s += " box " + std::to_string(sum) + " origin " + std::to_string(box.grid().origin[0]);
  } catch (const Error& e) {
    s += std::string(" error: ") + e.what();
  }
  return s;
}

}  // namespace

// With the helper (the default), users' files are opened and read only in the helper process
// (hdf5_read.hpp: libhdf5 1.10.8 reads freed memory under H5Dopen2 on some damaged object headers,
// depending on the heap's history, which no walk in a fresh process can foresee). The results are
// those of reading in this process (SKEL_HDF5_PROBE=0), also when a small shared window makes the
// reader ask for many boxes (chunk-aligned, contiguous, and chunks larger than the window).
TEST(Hdf5Attributes, WithTheHelperNoUsersFileIsOpenedInTheReadersProcess) {
  if (io::detail::hdf5_probe_helper().empty()) GTEST_SKIP() << "skelflow-hdf5-probe not built";
  const fs::path attributes = make_file();
  std::vector<std::pair<fs::path, std::string>> cases;
  for (const auto& d : kDatasets) cases.emplace_back(attributes, d);
  // Volumes of several types and layouts, read whole and by boxes.
  VolumeF32 f(Grid(Dims{37, 29, 23}, Vec3{0.5, 1, 2}, Vec3{1, 2, 3}, "mm"));
  for (int64_t k = 0; k < f.size(); ++k) f.data()[k] = static_cast<float>((k * 7919) % 1000) * 0.25f;
  VolumeU16 u(Grid(Dims{41, 17, 13}));
  for (int64_t k = 0; k < u.size(); ++k) u.data()[k] = static_cast<uint16_t>((k * 31) % 65000);
  int n = 0;
  for (const std::array<int64_t, 3> chunks : {std::array<int64_t, 3>{8, 8, 8}, std::array<int64_t, 3>{37, 29, 1}, std::array<int64_t, 3>{0, 0, 0}})
    for (int level : {0, 1}) {
      io::WriteOptions o;
      o.compression = level;
      o.chunks = chunks;
      const std::string id = std::to_string(n++);
      const fs::path a = scratch() / ("f" + id + ".h5"), b = scratch() / ("u" + id + ".h5");
      io::write_volume(a, f, "/volume", o);
      io::write_volume(b, u, "/g/v", o);
      cases.emplace_back(a, "/volume");
      cases.emplace_back(b, "/g/v");
    }
  {  // contiguous (not chunked), as h5py writes by default
    const fs::path c = scratch() / "f_contiguous.h5";
    const hid_t file = H5Fcreate(c.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hsize_t dims[3] = {10, 20, 30};
    const hid_t space = H5Screate_simple(3, dims, nullptr);
    const hid_t d = H5Dcreate2(file, "volume", H5T_STD_U16BE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    std::vector<uint16_t> v(6000);
    for (size_t k = 0; k < v.size(); ++k) v[k] = static_cast<uint16_t>(k * 13);
    H5Dwrite(d, H5T_NATIVE_UINT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Dclose(d);
    H5Sclose(space);
    H5Fclose(file);
    cases.emplace_back(c, "/volume");
  }
  cases.emplace_back(scratch() / "missing.h5", "/volume");
  cases.emplace_back(attributes, "/no/such");

  setenv("SKEL_HDF5_PROBE", "0", 1);
  std::vector<std::string> in_process;
  g_file_open = 0;
  for (const auto& [file, dataset] : cases) in_process.push_back(read_everything(file, dataset));
  EXPECT_GT(g_file_open.load(), 0);  // the interposition sees this process's opens
  unsetenv("SKEL_HDF5_PROBE");
  // The default window for every case; for the float volumes (each layout) and the contiguous one
  // also boxes of <= 5000 bytes (most chunks fit: aligned boxes); for the deflated 8³ chunks and the
  // contiguous one boxes of <= 700 bytes (no chunk fits).
  for (uint64_t window : {uint64_t{0}, uint64_t{5000}, uint64_t{700}}) {
    io::detail::set_hdf5_read_window(window);
    io::detail::forget_hdf5_probes();
    g_file_open = 0;
    g_dataset_open = 0;
    const int64_t decoded = io::detail::own_chunks_decoded();
    for (size_t i = 0; i < cases.size(); ++i) {
      const std::string name = cases[i].first.stem().string();
      const bool small = name == "f1" || name == "f_contiguous";
      if (window == 0 || (window == 5000 && name[0] == 'f') || small) {
        EXPECT_EQ(read_everything(cases[i].first, cases[i].second), in_process[i])
            << cases[i].first << " " << cases[i].second << " window " << window;
      }
    }
    EXPECT_EQ(g_file_open.load(), 0) << window;
    EXPECT_EQ(g_dataset_open.load(), 0) << window;
    EXPECT_GT(io::detail::own_chunks_decoded(), decoded) << "the helper's chunk counts reach this process";
  }
  io::detail::set_hdf5_read_window(0);
  EXPECT_NE(in_process[cases.size() - 2].find("file not found"), std::string::npos) << in_process[cases.size() - 2];
  EXPECT_NE(in_process.back().find("no dataset '/no/such'"), std::string::npos) << in_process.back();
}
