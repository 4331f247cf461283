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

#include "io/hdf5_probe.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/error.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
std::atomic<int64_t> g_exists{0}, g_open{0};
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

fs::path scratch() {
  static fs::path d = [] {
    fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "io" / "Hdf5Attributes";
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
