#pragma once
// One home for volume file formats: each format (HDF5, TIFF, NRRD, ...) lives in its own file
// modules/io/volume_<format>.cpp and describes itself as a VolumeFormat (name, extensions, magic
// bytes, header reader, reader, optional box reader and writer, describer). volume_formats() holds
// them all in one list (volume_formats.cpp: a new format = one file + one line there + its round-trip
// test). io.read_volume / io.write_volume, `skelflow info`, `skelflow validate` and the GUI's file
// dialogs ask this registry; nothing else names a volume format.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "skel/data.hpp"
#include "skel/volume.hpp"

namespace skel::io {

// What a reader knows without reading the voxels.
struct VolumeHeader {
  Grid grid;                  // dims (x, y, z), spacing, origin, unit, direction
  std::string dtype;          // voxel type as stored: uint8, int8, uint16, int16, uint32, int32, uint64,
                              // int64, float32, float64
  bool has_spacing = false;   // the file states the spacing (else 1)
  bool has_origin = false;    // the file states the origin (else 0)
  bool has_unit = false;      // the file states the unit (else kDefaultUnit)
  std::vector<std::string> details;  // extra "key: value" lines for `skelflow info` (compression, chunks, pages...)
};

struct VolumeReadOptions {
  std::string dataset;  // HDF5 dataset / Zarr array path inside the file; "" = the format's default
  int level = 0;        // multiscale level (OME-Zarr), 0 = full resolution
  int threads = 0;      // decompression threads; <= 0: all hardware threads
  int channel = -1;     // multi-channel / RGB files: the channel to read (0-based); -1: the file must have one
  // Raw files (.raw) state nothing: their layout is given here. dims (x, y, z) and the stored type
  // (uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32, float64) are required.
  struct Raw {
    std::vector<int64_t> dims;
    std::string type;
    bool big_endian = false;
    int64_t header_bytes = 0;  // bytes before the first voxel
  } raw;
  // Overrides of what the file says, applied by read_volume_header / read_any_volume /
  // read_any_volume_box after the format's reader (formats ignore them): 3 values (x, y, z) > 0, or
  // empty; a unit, or empty.
  std::vector<double> spacing;
  std::string unit;
};

struct VolumeWriteOptions {
  std::string dataset;   // HDF5 dataset / Zarr array path; "" = the format's default
  int compression = 1;   // format-specific level; 0 = none
  int threads = 0;       // compression threads; <= 0: all hardware threads
};

// A volume handed to a writer box by box (an on-disk volume under a memory budget): its grid, its
// port type id ("volume.u8", ...) and a reader of boxes [begin, begin + size) as Volume<T> of that
// type. Writers ask for slabs or bands of whole chunks of at most max_box_bytes where they can (at
// least one row of chunks or one slice), in their own order, and never hold the whole volume.
struct VolumeBoxSource {
  Grid grid;
  std::string type_id;
  uint64_t max_box_bytes = 0;  // 0: no limit
  std::function<DataPtr(Dims begin, Dims size)> read;
};

struct VolumeFormat {
  std::string name;                     // "TIFF", "NRRD", ... as shown to users
  std::vector<std::string> extensions;  // lower case, with the dot; compound ones allowed (".nii.gz")
  // Reads a folder of single-slice files with these extensions (sorted naturally: z2 before z10), or
  // a file-name pattern ("slices/z*.tif"), as one volume.
  bool slice_folders = false;
  // True when the file's first bytes (up to 512) are this format's; null: known by extension only.
  std::function<bool(std::string_view head)> sniff;
  // Required. Throws InputError naming the file and what is wrong.
  std::function<VolumeHeader(const std::filesystem::path&, const VolumeReadOptions&)> read_header;
  // Required. Returns a Volume<T> of the stored type (int8/int16 widen to int32, int64 to float64,
  // as HDF5 does) with the header's grid.
  std::function<DataPtr(const std::filesystem::path&, const VolumeReadOptions&)> read;
  // Optional: a box [begin, begin + size) (x, y, z) as Volume<T>, for streaming into block-wise
  // stages without reading the whole file.
  std::function<DataPtr(const std::filesystem::path&, const VolumeReadOptions&, Dims begin, Dims size)> read_box;
  // Optional: whether read_box of this file reads only what the box touches (NRRD and MetaImage:
  // only uncompressed data; a gzip stream would be inflated whole for every box). Null: always, when
  // read_box is set. io.read_volume streams a file into the block-wise engine only when this holds.
  std::function<bool(const std::filesystem::path&, const VolumeReadOptions&)> boxes_are_cheap;
  // Optional (null: read-only). Writes `volume` (any Volume<T>) to exactly `path` (the engine stages
  // outputs under a temporary name and renames them; a writer that cannot store the voxel type,
  // unit or direction throws InputError saying so).
  std::function<void(const std::filesystem::path&, const DataObject& volume, const VolumeWriteOptions&)> write;
  // Optional: writes a volume given box by box (HDF5 by bands of chunks, Zarr by chunks, TIFF by
  // pages), the same file `write` makes of the whole volume, staged the same way.
  std::function<void(const std::filesystem::path&, const VolumeBoxSource& volume, const VolumeWriteOptions&)> write_boxes;
  // Optional: a multi-line description for `skelflow info`; null: made from read_header.
  std::function<std::string(const std::filesystem::path&)> describe;
};

// Every volume format, in a fixed order.
const std::vector<VolumeFormat>& volume_formats();

// The format of `path` for reading: by its extension (the longest matching one, any case); when no
// extension matches, by the file's first bytes; a folder or a file-name pattern (*, ?) by the
// extensions of the files in it, for formats with slice_folders. Throws InputError naming the file and listing the
// known extensions.
const VolumeFormat& volume_format_for_read(const std::filesystem::path& path);
// The format that writes `path` (or, for the engine's temporary, its final path), by extension only. Throws InputError naming the file and listing
// the extensions that can be written.
const VolumeFormat& volume_format_for_write(const std::filesystem::path& path);
// Extensions that can be read / written, for ModuleSpec::extensions and file dialogs.
std::vector<std::string> readable_volume_extensions();
std::vector<std::string> writable_volume_extensions();

// Convenience: header / volume of any supported file.
VolumeHeader read_volume_header(const std::filesystem::path& path, const VolumeReadOptions& options = {});
DataPtr read_any_volume(const std::filesystem::path& path, const VolumeReadOptions& options = {});
// A box [begin, begin + size) (x, y, z) of any supported file: the format's read_box, or (for formats
// without one) the whole volume read and cut. Throws InputError when the box is outside the volume.
DataPtr read_any_volume_box(const std::filesystem::path& path, const VolumeReadOptions& options, Dims begin, Dims size);
// True when the format of `path` reads a box without decoding the whole volume (read_box set and
// boxes_are_cheap null or true): io.read_volume streams such files under a memory budget.
bool reads_boxes_cheaply(const std::filesystem::path& path, const VolumeReadOptions& options);
// The box [begin, begin + size) of a grid's voxels stored uncompressed, x fastest, from byte `offset`
// of `file` (raw, NRRD raw, MetaImage raw): seeks to each row (one read per slice for whole rows).
// `dtype` as in VolumeHeader; the result as VolumeFormat::read gives it, with the box's origin.
DataPtr read_raw_voxel_box(const std::filesystem::path& file, uint64_t offset, const Grid& grid, const std::string& dtype,
                           bool big_endian, Dims begin, Dims size);
// The box [begin, begin + size) of an in-memory volume (a box reader's fallback for encodings it
// cannot read in place); the box's origin keeps its physical position.
DataPtr crop_volume_box(const DataObject& whole, Dims begin, Dims size);
// The port type id ("volume.u16", ...) a reader gives for a stored dtype (int8/int16 -> volume.i32,
// int64 -> volume.f64). Throws InputError for an unknown dtype.
std::string volume_type_for_dtype(const std::string& dtype);
void write_any_volume(const std::filesystem::path& path, const DataObject& volume, const VolumeWriteOptions& options = {});
// Writes a volume box by box through the format's write_boxes; InputError naming the file and the
// format when it has none.
void write_any_volume_boxes(const std::filesystem::path& path, const VolumeBoxSource& volume,
                            const VolumeWriteOptions& options = {});
// How many whole units (slices of `unit_bytes`, rows of chunks, ...) a writer reads at once from
// `source`: as many as max_box_bytes holds, at least 1, at most `count`.
int64_t units_per_box(const VolumeBoxSource& source, uint64_t unit_bytes, int64_t count);
// `skelflow info` text of a volume file (the format's describe, or one made from its header).
std::string describe_volume_file(const std::filesystem::path& path);

}  // namespace skel::io
