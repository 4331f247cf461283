// io.read_volume and io.write_volume under a memory budget (issue 16/19): a file of every format
// with a box reader (HDF5, TIFF, Zarr, raw, uncompressed NRRD and MetaImage) streams box by box into
// an on-disk volume equal byte for byte to the in-memory read, with tiny budgets and odd block
// shapes; an on-disk volume is written box by box to HDF5 (compressed or not), Zarr and TIFF and
// reads back equal to the in-memory write; files without a box reader or writer are read or written
// whole when they fit the budget, and otherwise stop naming the file and its format.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>

#include "io/volume_format.hpp"
#include "skel/executor.hpp"
#include "skel/out_of_core.hpp"
#include "skel/pipeline.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("out_of_core_io_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A uint16 volume with every voxel different along short runs, a non-trivial grid and unit.
VolumeU16 test_volume(Dims d) {
  VolumeU16 v(Grid(d, {0.5, 0.75, 2.0}, {1.0, -2.0, 3.5}, "mm"));
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) v(x, y, z) = static_cast<uint16_t>((x * 7 + y * 131 + z * 1031) % 65521);
  return v;
}

// Same grid (dims, spacing, origin, unit; `grid` false: dims only) and the same voxel bytes.
void expect_same_volume(const DataObject& a, const DataObject& b, const std::string& what, bool grid = true) {
  ASSERT_EQ(a.type_id(), b.type_id()) << what;
  visit_volume(a, what, [&](const auto& va) {
    using V = std::decay_t<decltype(va)>;
    const auto* vb = dynamic_cast<const V*>(&b);
    ASSERT_NE(vb, nullptr) << what;
    EXPECT_EQ(va.dims(), vb->dims()) << what;
    if (grid) {
      EXPECT_EQ(va.grid().spacing, vb->grid().spacing) << what;
      EXPECT_EQ(va.grid().origin, vb->grid().origin) << what;
      EXPECT_EQ(va.grid().unit, vb->grid().unit) << what;
    }
    ASSERT_EQ(va.size(), vb->size()) << what;
    EXPECT_EQ(std::memcmp(va.data(), vb->data(), static_cast<size_t>(va.size()) * sizeof(typename V::value_type)), 0) << what;
  });
}

struct Captured {
  DataPtr in_memory;  // the read node's output, loaded while the run still holds its scratch file
  bool on_disk = false;
};

// Runs `yaml` with `budget` and `block`; captures node `node`'s output port `port`.
Captured run_capturing(const std::string& yaml, const fs::path& dir, uint64_t budget, Dims block, const std::string& node,
                       const std::string& port) {
  const Pipeline p = Pipeline::parse(yaml, (dir / "p.yaml").string());
  ExecOptions o;
  o.output_dir = dir;
  o.memory_budget = budget;
  o.block = block;
  o.scratch_dir = dir / "scratch";
  o.threads = 2;
  Captured c;
  std::mutex m;
  o.on_outputs = [&](const std::string& n, const std::map<std::string, DataPtr>& outputs) {
    if (n != node) return;
    std::lock_guard lock(m);
    const DataPtr& d = outputs.at(port);
    c.on_disk = is_on_disk(*d);
    c.in_memory = materialize(d);
  };
  Executor ex;
  ex.run(p, o);
  return c;
}

std::string read_node(const fs::path& file, const std::string& extra = "") {
  return "skelflow: 1\nnodes:\n  read: {module: io.read_volume, params: {path: \"" + file.string() + "\"" + extra +
         "}}\n  save: {module: io.write_volume, inputs: {volume: read.volume}, params: {path: out/copy.h5}}\n";
}

const char* kRawParams = ", raw_dims: [29, 23, 17], raw_type: uint16, spacing: [0.5, 0.75, 2.0], unit: mm";

// Files of the test volume in every format whose boxes are read in place.
std::vector<std::pair<fs::path, std::string>> box_readable_files(const fs::path& dir, const VolumeU16& v) {
  std::vector<std::pair<fs::path, std::string>> files;
  io::VolumeWriteOptions raw;
  raw.compression = 0;
  for (const char* name : {"v.h5", "v.tif", "v.zarr", "v.nrrd", "v.mha"}) {
    io::write_any_volume(dir / name, v, raw);
    files.emplace_back(dir / name, "");
  }
  io::VolumeWriteOptions deflate;  // compressed TIFF strips and HDF5 chunks are read by box too
  for (const char* name : {"deflate.tif", "deflate.h5"}) {
    io::write_any_volume(dir / name, v, deflate);
    files.emplace_back(dir / name, "");
  }
  {
    std::ofstream out(dir / "v.raw", std::ios::binary);
    out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * 2));
  }
  files.emplace_back(dir / "v.raw", kRawParams);
  return files;
}

}  // namespace

TEST(OutOfCoreIo, ReadVolumeStreamsEveryBoxFormatIntoTheSameBytes) {
  const fs::path dir = scratch("read");
  const VolumeU16 v = test_volume({29, 23, 17});
  for (const auto& [file, extra] : box_readable_files(dir, v)) {
    io::VolumeReadOptions ro;
    if (!extra.empty()) {
      ro.raw.dims = {29, 23, 17};
      ro.raw.type = "uint16";
      ro.spacing = {0.5, 0.75, 2.0};
      ro.unit = "mm";
    }
    EXPECT_TRUE(io::reads_boxes_cheaply(file, ro)) << file;
    const DataPtr in_core = io::read_any_volume(file, ro);
    // 4 KiB: boxes of 17 rows (a slice is 1.3 KiB, a quarter of the budget 1 KiB); then odd blocks.
    for (const auto& [budget, block] : {std::pair<uint64_t, Dims>{4096, Dims{0, 0, 0}}, {1 << 20, Dims{7, 5, 3}},
                                        {1 << 20, Dims{29, 23, 4}}}) {
      const fs::path run_dir = dir / ("run_" + file.filename().string() + "_" + std::to_string(block[0]));
      const Captured c = run_capturing(read_node(file, extra), run_dir, budget, block, "read", "volume");
      EXPECT_TRUE(c.on_disk) << file << " was not streamed";
      ASSERT_TRUE(c.in_memory) << file;
      expect_same_volume(*in_core, *c.in_memory, file.string());
      // ... and written box by box to HDF5, it reads back the same.
      expect_same_volume(*in_core, *io::read_any_volume(run_dir / "out/copy.h5"), file.string() + " -> copy.h5");
      EXPECT_FALSE(fs::exists(run_dir / "scratch") && !fs::is_empty(run_dir / "scratch")) << "scratch left behind";
    }
  }
  // The conversion of `dtype` happens box by box: the same voxels as converting in memory.
  const std::string yaml = read_node(dir / "v.tif", ", dtype: uint8");
  const Captured c = run_capturing(yaml, dir / "run_convert", 4096, {0, 0, 0}, "read", "volume");
  const Captured m = run_capturing(yaml, dir / "run_convert_in_core", 0, {0, 0, 0}, "read", "volume");
  EXPECT_TRUE(c.on_disk);
  EXPECT_FALSE(m.on_disk);
  expect_same_volume(*m.in_memory, *c.in_memory, "dtype uint8");
}

TEST(OutOfCoreIo, FilesWithoutBoxReaderAreReadWholeWhenTheyFitElseRefusedNamingTheFile) {
  const fs::path dir = scratch("whole");
  const VolumeU16 v = test_volume({29, 23, 17});  // 22.1 KiB
  io::write_any_volume(dir / "gz.nrrd", v);      // gzip: no box reader
  EXPECT_FALSE(io::reads_boxes_cheaply(dir / "gz.nrrd", {}));
  const Captured fits = run_capturing(read_node(dir / "gz.nrrd"), dir / "fits", 1 << 20, {0, 0, 0}, "read", "volume");
  EXPECT_FALSE(fits.on_disk);
  expect_same_volume(v, *fits.in_memory, "gzip NRRD in memory");
  try {
    run_capturing(read_node(dir / "gz.nrrd"), dir / "too_big", 16 << 10, {0, 0, 0}, "read", "volume");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("node 'read' (io.read_volume)"), std::string::npos) << msg;
    EXPECT_NE(msg.find((dir / "gz.nrrd").string() + ": NRRD file (uint16 29x23x17, 22.1 KiB in memory) cannot be read box "
                       "by box (compressed or encoded as a whole) and does not fit the memory budget of 16 KiB"),
              std::string::npos)
        << msg;
  }
  EXPECT_FALSE(fs::exists(dir / "too_big" / "out"));
}

TEST(OutOfCoreIo, WriteVolumeWritesAnOnDiskVolumeBoxByBox) {
  const fs::path dir = scratch("write");
  // 150x140x70 uint16 (2.8 MiB): HDF5/Zarr chunks 64³, several bands of chunk rows at a 64 KiB budget.
  const VolumeU16 v = test_volume({150, 140, 70});
  io::write_any_volume(dir / "src.h5", v);
  const std::string outputs[] = {"w.h5", "w_raw.h5", "w.zarr", "w.tif", "w_deflate.tif"};
  std::string yaml = "skelflow: 1\nnodes:\n  read: {module: io.read_volume, params: {path: \"" + (dir / "src.h5").string() + "\"}}\n";
  int k = 0;
  for (const auto& o : outputs) {
    const bool raw = o.find("raw") != std::string::npos || o == "w.tif";
    yaml += "  save_" + std::to_string(k++) + ": {module: io.write_volume, inputs: {volume: read.volume}, params: {path: out/" + o +
            (raw ? ", compression: 0" : "") + "}}\n";
  }
  const Captured streamed = run_capturing(yaml, dir / "budget", 64 << 10, {0, 0, 0}, "read", "volume");
  EXPECT_TRUE(streamed.on_disk);
  run_capturing(yaml, dir / "in_core", 0, {0, 0, 0}, "read", "volume");
  for (const auto& o : outputs) {
    const DataPtr a = io::read_any_volume(dir / "in_core/out" / o), b = io::read_any_volume(dir / "budget/out" / o);
    expect_same_volume(*a, *b, o);
    expect_same_volume(v, *b, o, o.find(".tif") == std::string::npos);  // TIFF: spacing as float32 resolutions
  }
  EXPECT_FALSE(fs::exists(dir / "budget" / "scratch") && !fs::is_empty(dir / "budget" / "scratch"));
  // A format written whole: a volume on disk larger than the budget is refused naming the file.
  const std::string to_nrrd = "skelflow: 1\nnodes:\n  read: {module: io.read_volume, params: {path: \"" + (dir / "src.h5").string() +
                              "\"}}\n  save: {module: io.write_volume, inputs: {volume: read.volume}, params: {path: out/w.nrrd}}\n";
  try {
    run_capturing(to_nrrd, dir / "nrrd", 64 << 10, {0, 0, 0}, "read", "volume");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("node 'save' (io.write_volume)"), std::string::npos) << msg;
    EXPECT_NE(msg.find("out/w.nrrd: NRRD files are written from a whole volume in memory"), std::string::npos) << msg;
    EXPECT_NE(msg.find("does not fit the memory budget of 64 KiB"), std::string::npos) << msg;
  }
  EXPECT_FALSE(fs::exists(dir / "nrrd" / "out" / "w.nrrd"));
}
