#pragma once
// Shared by the volume format tests (volume_<format>_test.cpp): a scratch folder per test, volumes
// of every voxel type with a non-trivial grid, error capture, and running the Python tools users
// have (nibabel, VTK, zarr) to make reference files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>

#include "io/volume_format.hpp"
#include "skel/volume.hpp"

namespace skel::test {

namespace fs = std::filesystem;

// One folder per test (ctest runs the tests of a binary as parallel processes).
inline fs::path scratch() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "volume";
  fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "volume_formats" / name;
  static fs::path made;
  if (made != p) {
    fs::remove_all(p);
    fs::create_directories(p);
    made = p;
  }
  return p;
}

// A rotation about z by 30 degrees (row-major, column k = direction of voxel axis k).
inline Direction rotated_direction() {
  const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
  return {c, -s, 0, s, c, 0, 0, 0, 1};
}

template <class T>
Volume<T> random_volume(Dims d, uint64_t seed, const std::string& unit = "mm", bool rotated = false) {
  Grid g(d, {0.5, 0.75, 2.0}, {-3.0, 1.5, 10.0}, unit);
  if (rotated) g.direction = rotated_direction();
  Volume<T> v(g, T{});
  std::mt19937_64 rng(seed);
  for (auto& x : v) {
    if constexpr (std::is_floating_point_v<T>) x = static_cast<T>(static_cast<double>(rng() % 100000) / 7.0 - 5000.0);
    else if constexpr (std::is_signed_v<T>) x = static_cast<T>(static_cast<int64_t>(rng() % 2000001) - 1000000);
    else x = static_cast<T>(rng());  // the whole range of the type
  }
  return v;
}

inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("(not an InputError) ") + e.what();
  }
  return "(no InputError)";
}

// Grids equal up to `tol` in spacing, origin and direction (directions written as axis vectors
// come back through a normalisation).
inline void expect_grid_near(const Grid& a, const Grid& b, double tol, const std::string& what) {
  EXPECT_EQ(a.dims, b.dims) << what;
  EXPECT_EQ(a.unit, b.unit) << what;
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(a.spacing[i], b.spacing[i], tol) << what << " spacing " << i;
    EXPECT_NEAR(a.origin[i], b.origin[i], tol) << what << " origin " << i;
  }
  for (size_t i = 0; i < 9; ++i) EXPECT_NEAR(a.direction[i], b.direction[i], tol) << what << " direction " << i;
}

// Writes `v` to `file` through the registry, reads it back and checks type, voxels and grid.
template <class T>
void expect_round_trip(const Volume<T>& v, const fs::path& file, const io::VolumeWriteOptions& o = {},
                       double tol = 0.0) {
  io::write_any_volume(file, v, o);
  const auto back = std::dynamic_pointer_cast<const Volume<T>>(io::read_any_volume(file));
  ASSERT_TRUE(back) << file << ": read back as another type (" << io::read_any_volume(file)->type_id() << ")";
  const std::string what = file.filename().string();
  if (tol == 0.0) {
    EXPECT_EQ(back->grid(), v.grid()) << what;
  } else {
    expect_grid_near(back->grid(), v.grid(), tol, what);
  }
  ASSERT_EQ(back->size(), v.size());
  EXPECT_TRUE(std::equal(v.begin(), v.end(), back->begin())) << what << ": voxels differ";
  const io::VolumeHeader h = io::read_volume_header(file);
  EXPECT_EQ(h.grid.dims, v.dims()) << what;
  EXPECT_EQ(h.dtype, VoxelTraits<T>::name) << what;
}

template <class F>
void for_every_voxel_type(F&& f) {
  f(uint8_t{});
  f(uint16_t{});
  f(uint32_t{});
  f(uint64_t{});
  f(int32_t{});
  f(float{});
  f(double{});
}

inline void write_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Runs /usr/bin/python3 with `script` (the Python code, written to a file in `dir`). Returns the
// exit status; 77 means a module the script imports is missing (the test then skips).
inline int run_python(const fs::path& dir, const std::string& script) {
  const fs::path py = dir / "make.py";
  std::ofstream(py) << "import sys\ntry:\n    import numpy\nexcept ImportError:\n    sys.exit(77)\n" << script;
  const std::string cmd = "/usr/bin/python3 " + py.string() + " > " + (dir / "python.log").string() + " 2>&1";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

}  // namespace skel::test
