// Volume and table file modules (io.read_volume / io.write_volume through the volume format registry,
// CSV tables) and the volume inspector of `skelflow info`.

#include "io/volume_format.hpp"
#include "io/names.hpp"
#include "skel/distributed.hpp"
#include "skel/fs.hpp"
#include "skel/module.hpp"
#include "skel/out_of_core.hpp"
#include "skel/table.hpp"
#include "volume/convert.hpp"

namespace skel::io {
namespace {

std::string format_list() {
  std::string s;
  for (const auto& f : volume_formats()) {
    s += "- **" + f.name + "** (";
    for (size_t i = 0; i < f.extensions.size(); ++i) s += (i ? ", " : "") + f.extensions[i];
    s += std::string(")") + (f.write ? ": read and write" : ": read") + "\n";
  }
  return s;
}

// The reader's options from the node's checked parameters (as validate() sees them).
VolumeReadOptions read_options(const ParamMap& params) {
  VolumeReadOptions o;
  o.dataset = std::get<std::string>(params.at("dataset"));
  o.level = static_cast<int>(std::get<int64_t>(params.at("level")));
  o.spacing = std::get<std::vector<double>>(params.at("spacing"));
  o.unit = std::get<std::string>(params.at("unit"));
  o.channel = static_cast<int>(std::get<int64_t>(params.at("channel")));
  o.raw.dims = std::get<std::vector<int64_t>>(params.at("raw_dims"));
  o.raw.type = std::get<std::string>(params.at("raw_type"));
  if (o.raw.type == "none") o.raw.type.clear();
  o.raw.big_endian = std::get<std::string>(params.at("raw_byte_order")) == "big";
  o.raw.header_bytes = std::get<int64_t>(params.at("raw_header_bytes"));
  return o;
}

class ReadVolume final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_volume, "Read a volume from an image file (format chosen by extension)")
        .add_output("volume", all_volume_types(), "the volume with spacing, origin and unit from the file (or the parameters)")
        .path("path", "", PathRole::Input,
              "volume file, or a folder or file-name pattern (slices/z*.tif) of TIFF slices; relative to the pipeline's folder")
        .extensions(readable_volume_extensions())
        .accepts_folder()
        .param("dataset", &VolumeReadOptions::dataset,
               "HDF5 dataset / Zarr array inside the file; empty: the format's default (/volume for HDF5)")
        .optional_value()
        .param("level", &VolumeReadOptions::level, "multiscale level (OME-Zarr); 0 = full resolution").min(0)
        .param("spacing", &VolumeReadOptions::spacing,
               "voxel spacing (x, y, z) replacing the file's; empty: the file's (1 if it states none)")
        .length(3).optional_value()
        .param("unit", &VolumeReadOptions::unit,
               "physical unit of spacing and origin (\"mm\", \"nm\", ...) replacing the file's; empty: the file's")
        .optional_value()
        .param("channel", &VolumeReadOptions::channel,
               "multi-channel or RGB files: the channel to read (0-based); -1: the file must have one channel")
        .min(-1)
        .param<std::vector<int64_t>>("raw_dims", {}, "raw files: dims (x, y, z) in voxels")
        .length(3).optional_value()
        .choice("raw_type", {"none", "uint8", "int8", "uint16", "int16", "uint32", "int32", "uint64", "int64", "float32", "float64"},
                "none", "raw files: the stored voxel type")
        .choice("raw_byte_order", {"little", "big"}, "little", "raw files: byte order of multi-byte voxels")
        .param<int64_t>("raw_header_bytes", 0, "raw files: bytes to skip before the first voxel").min(0)
        .choice("dtype", {"keep", "uint8", "uint16", "uint32", "int32", "float32", "float64"}, "keep",
                "convert the voxels to this type (clamped), or keep the file's type")
        .output_type_from("volume", [](const OutputTypeQuery& q) {
          const std::string dt = std::get<std::string>(q.params.at("dtype"));
          const std::filesystem::path path = q.input_path("path");
          const VolumeHeader h = read_volume_header(path, read_options(q.params));
          if (dt != "keep") return DeducedOutput{{volume_type_for_dtype(dt)}, "converted to " + dt};
          std::string why = path.string();  // built by appending: GCC 12 warns falsely (-Wrestrict) on "'" + s
          why.insert(why.begin(), '\'');
          why += "' holds " + h.dtype + " voxels";
          return DeducedOutput{{volume_type_for_dtype(h.dtype)}, why};
        })
        .blockwise(0, 16)
        .details(R"(Reads a three-dimensional image; the format is chosen by the file's extension (or,
for an unknown extension, by its first bytes). Formats:

)" + format_list() + R"(
`skelflow info FILE` shows what a file holds (voxel type, dims, spacing, unit, compression).
HDF5: before a file is opened, its structure (groups, attributes, dataset layout, chunk index) is
read once in a separate process (the helper `skelflow-hdf5-probe`, built with AddressSanitizer) with
1 GiB of address space and a 60 s limit, because the HDF5 library can crash or corrupt memory on
damaged files; a file that crashes it, makes a memory error or exceeds it is refused naming the file.
`SKEL_HDF5_PROBE=0` skips this for trusted data, `SKEL_HDF5_PROBE_TIMEOUT` sets the seconds,
`SKEL_HDF5_PROBE_MEMORY_MB` the memory (MiB), `SKEL_HDF5_PROBE_HELPER` names the helper
(docs/reliability.md). The file is then read in that helper too (dataset, attributes and voxels,
handed over through shared memory 64 MiB at a time), so the HDF5 library never decodes a user's file
in Skelflow's own process.
Chunked datasets compressed with deflate (with shuffle and Fletcher32 or not) are decoded by
Skelflow's own code on the reader's threads, which refuses a damaged chunk naming it (x, y, z index)
instead of letting the HDF5 library overrun a buffer; `SKEL_HDF5_OWN_CHUNKS=0` reads them through the
HDF5 library instead. Other filters (szip, scale-offset, n-bit, plugins) are decoded by the HDF5 library.
TIFF: a multi-page stack, or a folder of single-slice files (or a pattern such as `slices/z*.tif`)
sorted naturally (z2 before z10); 8/16/32/64-bit unsigned, signed and float samples, BigTIFF,
strips or tiles, any compression libtiff decodes (none, LZW, deflate, PackBits); only the pages and
strips a box touches are decoded. RGB and multi-channel files (samples per pixel, ImageJ or OME
channels) need `channel`.

raw (`.raw`): voxels x fastest, without a header or after `raw_header_bytes`; `raw_dims`,
`raw_type` and `spacing` are required (`unit` and `raw_byte_order` optional); the file's size must
equal the header plus the voxels, checked before anything is allocated.

Spacing, origin and unit come from the file's own metadata (HDF5: attributes `spacing`, `origin`
(x, y, z) and `unit`, or Fiji/BigDataViewer/ilastik's `element_size_um`; TIFF: ImageJ calibration
(XResolution/YResolution, `spacing=` and `unit=` in the description) or OME-XML
(PhysicalSizeX/Y/Z and their units)); a file that states none
gets spacing 1, origin 0 and the unit )" + std::string(kDefaultUnit) + R"(. The parameters `spacing` and `unit` replace what the file
says (the origin keeps its position in voxels). uint8/16/32/64, float32 and float64 are kept as
they are, int8/int16/int32 become int32, int64 becomes float64. `skelflow validate` reads the file's
header, so a missing, truncated or foreign file and a voxel type the next node does not take are
reported before anything runs. Memory: the volume itself (its voxel size in bytes per voxel; with
`dtype`, the converted copy too).

Block-wise under a memory budget: files whose format reads a box without decoding the rest (TIFF
pages and strips, Zarr chunks, HDF5, raw, uncompressed NRRD and MetaImage) are read box by box
straight into an on-disk volume: slabs of whole slices taking a quarter of the budget (or the
`block` of `execution:`), each converted to `dtype` on its own; memory per box: the stored voxel
size plus, with `dtype`, the converted one, in bytes per voxel. Other files (gzip NRRD, compressed
MetaImage, NIfTI, VTK image, Amira) are read whole when they fit the budget; otherwise the run stops
with an error naming the file and its format.)");
  }
  void run(RunContext& ctx) override {
    const auto path = ctx.input_path("path");
    ParamMap params;
    for (const auto& p : ctx.spec().params()) params[p.name] = ctx.param_value(p.name);
    VolumeReadOptions o = read_options(params);
    o.threads = ctx.threads();
    const std::string dt = ctx.param<std::string>("dtype");
    auto convert = [&](DataPtr v) {
      if (dt == "keep") return v;
      volume::ConvertOptions c;
      c.dtype = dt;
      c.threads = ctx.threads();
      return volume::convert_volume_type(*v, c);
    };
    if (const BlockPlan* blocks = ctx.blocks()) {
      if (reads_boxes_cheaply(path, o)) {
        ctx.output("volume", DataPtr(read_into_scratch(ctx, *blocks, path, o, dt, convert)));
        return;
      }
      // No box reader for this file: the whole volume, when it fits the budget.
      const VolumeHeader h = read_volume_header(path, o);
      const uint64_t n = static_cast<uint64_t>(h.grid.voxel_count());
      const uint64_t bytes = n * static_cast<uint64_t>(voxel_bytes(volume_type_for_dtype(h.dtype))) +
                             (dt == "keep" ? 0 : n * static_cast<uint64_t>(voxel_bytes(volume_type_for_dtype(dt))));
      if (bytes > blocks->memory_budget)
        throw InputError(path.string() + ": " + volume_format_for_read(path).name + " file (" + h.dtype + " " +
                         std::to_string(h.grid.dims[0]) + "x" + std::to_string(h.grid.dims[1]) + "x" +
                         std::to_string(h.grid.dims[2]) + ", " + format_byte_size(bytes) + " in memory" +
                         (dt == "keep" ? "" : " with the converted copy") +
                         ") cannot be read box by box (compressed or encoded as a whole) and does not fit the memory "
                         "budget of " + format_byte_size(blocks->memory_budget) +
                         "; convert it to TIFF, Zarr, HDF5 or an uncompressed NRRD/MetaImage/raw file, or raise --memory-budget");
    }
    ctx.output("volume", convert(read_any_volume(path, o)));
  }

private:
  // The boxes read under a budget: the user's block shape, else slabs of whole slices (whole rows, or
  // parts of a row, when one slice is too large) taking a quarter of the budget at `bytes_per_voxel`,
  // as thick as a multiple of the scratch chunks (32) where they are thicker than one.
  static Dims read_shape(const Dims& d, uint64_t budget, int64_t bytes_per_voxel) {
    const int64_t quota = static_cast<int64_t>(std::min<uint64_t>(budget / 4, uint64_t{1} << 62));
    auto fit = [](int64_t n, int64_t cap) {
      n = std::min(n, cap);
      return n >= 32 ? n - n % 32 : n;
    };
    const int64_t slice = d[0] * d[1] * bytes_per_voxel, row = d[0] * bytes_per_voxel;
    if (quota / slice >= 1) return {d[0], d[1], fit(quota / slice, d[2])};
    if (quota / row >= 1) return {d[0], fit(quota / row, d[1]), 1};
    return {std::max<int64_t>(1, quota / bytes_per_voxel), 1, 1};
  }

  template <class Convert>
  static std::shared_ptr<ChunkedVolume> read_into_scratch(RunContext& ctx, const BlockPlan& blocks,
                                                           const std::filesystem::path& path, const VolumeReadOptions& o,
                                                           const std::string& dt, Convert&& convert) {
    const VolumeHeader h = read_volume_header(path, o);
    const std::string stored = volume_type_for_dtype(h.dtype);
    const std::string type = dt == "keep" ? stored : volume_type_for_dtype(dt);
    const DistributedStage stage;  // skelflow-mpi: each rank reads its slabs into one shared volume
    auto out = ctx.scratch_volume("volume", type, h.grid);
    const int64_t bpv = voxel_bytes(stored) + (dt == "keep" ? 0 : voxel_bytes(type));
    const Dims shape = blocks.block_from_user ? blocks.block : read_shape(h.grid.dims, blocks.memory_budget, bpv);
    for_each_owned_block(BlockLayout(h.grid.dims, shape), ctx.progress(), "read", [&](const Block& b) {
      const DataPtr box = convert(read_any_volume_box(path, o, b.begin, b.size));
      visit_volume(*box, "volume", [&](const auto& v) { out->write(v, b.begin); });
    });
    return out;
  }
};
SKEL_REGISTER_MODULE(ReadVolume);

class WriteVolume final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_volume, "Write a volume to an image file (format chosen by extension)")
        .add_input("volume", all_volume_types(), "volume to write", true)
        .path("path", "", PathRole::Output,
              "volume file to create; written to a temporary file and renamed when the run succeeds")
        .extensions(writable_volume_extensions())
        .param("dataset", &VolumeWriteOptions::dataset, "HDF5 dataset / Zarr array name (groups are created); empty: /volume")
        .optional_value()
        .param("compression", &VolumeWriteOptions::compression,
               "compression level (0 = none); HDF5: deflate level, 1 is fast and compresses masks ~20x").range(0, 9)
        .details(R"(Writes the volume in the format its path's extension names, with its spacing, origin
and unit. HDF5: a dataset of shape [z][y][x] in the volume's own voxel type with attributes `spacing`
and `origin` (x, y, z) and `unit`; chunks hold about 1 MiB and are as cube-like as the dims allow
(128x128x64 for uint8, 64x64x64 for float32): whole-volume reads stay fast and an aligned 64³ block
touches one chunk; compression adds the shuffle filter for multi-byte types and runs on the node's
threads. TIFF: one page per z slice with ImageJ calibration (pixel width/height as resolution,
`spacing=` and `unit=` in the description; OME-XML instead for names ending in .ome.tif), BigTIFF
when the voxels exceed 4 GiB, deflate at `compression` > 0 (0: uncompressed, for readers without
deflate); a volume with direction cosines is refused (TIFF cannot store them). The file is written
under a temporary name and renamed only when the whole pipeline run succeeds. Memory: no copy of the
volume (0 bytes per voxel).

Block-wise under a memory budget: a volume on disk is written box by box, never assembled in memory:
HDF5 by bands of whole rows of chunks in chunk order (compressed as above), Zarr chunk by chunk,
TIFF by slabs of whole pages; each box takes at most a quarter of the budget (at least one row of
chunks or one slice). Other formats load the volume when it fits the budget, and otherwise stop
with an error naming the file.)")
        .blockwise(0, 1);
  }
  void run(RunContext& ctx) override {
    const auto path = ctx.output_path("path");
    const DataPtr volume = ctx.input_data("volume");
    VolumeWriteOptions o = ctx.options<VolumeWriteOptions>();
    o.threads = ctx.threads();
    const auto* on_disk = dynamic_cast<const ChunkedVolume*>(volume.get());
    const BlockPlan* blocks = ctx.blocks();
    if (!on_disk || !blocks) {
      write_any_volume(path, *volume, o);
      return;
    }
    const VolumeFormat& f = volume_format_for_write(path);
    if (f.write_boxes) {
      VolumeBoxSource source;
      source.grid = on_disk->grid();
      source.type_id = on_disk->type_id();
      source.max_box_bytes = blocks->memory_budget / 4;
      source.read = [&](Dims begin, Dims size) {
        ctx.progress().check();  // cancellation between boxes
        return visit_voxel_type(on_disk->type_id(), "input 'volume'",
                                [&](auto t) -> DataPtr { return std::make_shared<Volume<decltype(t)>>(on_disk->read<decltype(t)>(begin, size)); });
      };
      write_any_volume_boxes(path, source, o);
      return;
    }
    // A format written from a whole volume: in memory, when it fits the budget.
    if (on_disk->voxel_data_bytes() > blocks->memory_budget)
      throw InputError(ctx.final_output_path("path").string() + ": " + f.name + " files are written from a whole volume in memory, and the " +
                       on_disk->describe() + " (" + format_byte_size(on_disk->voxel_data_bytes()) +
                       ") does not fit the memory budget of " + format_byte_size(blocks->memory_budget) +
                       "; write .h5, .zarr or .tif (written block by block), or raise --memory-budget");
    write_any_volume(path, *materialize(volume), o);
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

SKEL_REGISTER_INSPECTOR("volume file", readable_volume_extensions(),
                        [](const std::filesystem::path& p) { return describe_volume_file(p); },
                        [](const std::filesystem::path& p) {  // folders and patterns of slices, magic bytes
                          try {
                            (void)volume_format_for_read(p);
                            return true;
                          } catch (const Error&) {
                            return false;
                          }
                        });

}  // namespace
}  // namespace skel::io
