// Volume and table file modules (HDF5 volumes, CSV tables) and the HDF5 inspector for `skelflow info`.

#include "io/hdf5_volume.hpp"
#include "io/names.hpp"
#include "skel/fs.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"
#include "volume/convert.hpp"

namespace skel::io {
namespace {

class ReadVolume final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_volume, "Read a volume from an HDF5 file")
        .add_output("volume", all_volume_types(), "the volume, spacing and origin from the file's attributes")
        .path("path", "", PathRole::Input, "HDF5 file (.h5, .hdf5); relative to the pipeline's folder")
        .param<std::string>("dataset", "/volume", "dataset holding the volume, shape [z][y][x]")
        .choice("dtype", {"keep", "uint8", "uint16", "uint32", "int32", "float32", "float64"}, "keep",
                "convert the voxels to this type (clamped), or keep the file's type")
        .details(R"(Reads a three-dimensional integer or float dataset stored C-order as [z][y][x] (x
fastest). Attributes `spacing` and `origin` (3 numbers each, as (x, y, z), physical units) give the
grid; missing attributes mean spacing 1 and origin 0. uint8/16/32/64, float32 and float64 are kept as
they are, int8/int16/int32 become int32, int64 becomes float64. A missing file, a file that is not HDF5
or is truncated, a missing dataset (the message lists those present), a dataset that is not 3D and an
unsupported type are errors naming the file. Memory: the volume itself; chunked datasets are read
with a 256 MiB chunk cache.)");
  }
  void run(RunContext& ctx) override {
    const auto path = ctx.input_path("path");
    DataPtr v = io::read_volume(path, ctx.param<std::string>("dataset"));
    const std::string dt = ctx.param<std::string>("dtype");
    if (dt != "keep") {
      volume::ConvertOptions o;
      o.dtype = dt;
      o.threads = ctx.threads();
      v = volume::convert_volume_type(*v, o);
    }
    ctx.output("volume", v);
  }
};
SKEL_REGISTER_MODULE(ReadVolume);

class WriteVolume final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_volume, "Write a volume to an HDF5 file")
        .add_input("volume", all_volume_types(), "volume to write", true)
        .path("path", "", PathRole::Output, "HDF5 file to create (.h5); written to a temporary file and renamed when the run succeeds")
        .extensions({".h5", ".hdf5"})
        .param<std::string>("dataset", "/volume", "dataset name (groups are created)")
        .param("compression", &io::WriteOptions::compression, "deflate level (0 = none; 1 is fast and compresses masks ~20x)").range(0, 9)
        .details(R"(Writes the volume as a dataset of shape [z][y][x] in its own voxel type, with attributes
`spacing` and `origin` as (x, y, z). Chunks hold about 1 MiB and are as cube-like as the dims allow
(128x128x64 for uint8, 64x64x64 for float32): whole-volume reads stay fast (HDF5's small automatic
chunks read at only ~300 MB/s) and an aligned 64³ block touches one chunk; compression adds the shuffle filter for multi-byte types and runs on
the node's threads (chunks compressed in parallel, stored as HDF5's own filters would). The file is
written under a temporary name and renamed only when the whole pipeline run succeeds. Memory: no copy
of the volume.)");
  }
  void run(RunContext& ctx) override {
    io::write_volume(ctx.output_path("path"), *ctx.input_data("volume"), ctx.param<std::string>("dataset"),
                     ctx.options<io::WriteOptions>());
  }
};
SKEL_REGISTER_MODULE(WriteVolume);

class WriteTable final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_table, "Write a table to a CSV file")
        .input<Table>("table", "table to write")
        .path("path", "", PathRole::Output, "CSV file to create; written to a temporary file and renamed when the run succeeds")
        .extensions({".csv"})
        .details(R"(Comma-separated values with one header line; a column with a unit is headed
"name [unit]". Text containing commas or quotes is quoted. Numbers are written with full precision
(17 significant digits for floats), so reading them back is lossless.)");
  }
  void run(RunContext& ctx) override {
    write_file_atomically(ctx.output_path("path"), ctx.input<Table>("table")->to_csv());
  }
};
SKEL_REGISTER_MODULE(WriteTable);

SKEL_REGISTER_INSPECTOR("HDF5 file", {".h5", ".hdf5", ".he5"},
                        [](const std::filesystem::path& p) { return io::describe_file(p); });

}  // namespace
}  // namespace skel::io
