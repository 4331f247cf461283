#pragma once
// HDF5 volumes: datasets of shape [z][y][x] with attributes `spacing` and `origin` as (x, y, z) and
// `unit` (a string; Fiji/BigDataViewer/ilastik's `element_size_um` [z][y][x] on the dataset or its
// group is read as the spacing in µm when `spacing` is absent),
// chunked and compressed on write, any integer or float type on read, sub-boxes by hyperslab for
// block-wise algorithms. Every HDF5 problem becomes an InputError naming the file and dataset.
// Debian's HDF5 is not thread-safe: all calls are serialised by one process-wide mutex.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/out_of_core.hpp"
#include "skel/volume.hpp"

namespace skel::io {

struct VolumeInfo {
  Dims dims{0, 0, 0};          // (x, y, z)
  std::string dtype;           // uint8, uint16, uint32, uint64, int8, int16, int32, int64, float32, float64
  std::array<int64_t, 3> chunks{0, 0, 0};  // (x, y, z), 0 when contiguous
  std::vector<std::string> filters;        // e.g. "deflate", "shuffle"
  Vec3 spacing{1, 1, 1}, origin{0, 0, 0};
  std::string unit{kDefaultUnit};  // attribute `unit`; µm with `element_size_um`; else kDefaultUnit
  bool has_spacing = false, has_origin = false, has_unit = false;
};

// Chunking: automatic chunks hold about 1 MiB, as cube-like as the dims allow (128x128x64 for
// uint8, 64x64x64 for float32): a full read touches each chunk once, an aligned 64³ block (the
// out-of-core algorithms' unit) one or two chunks, and 1 MiB chunks read far faster than HDF5's small
// default chunks.
// Compression: deflate at `compression` (0 = none); multi-byte types also get the shuffle filter.
// write_volume compresses the chunks itself on `threads` threads (shuffle + zlib, the exact byte
// layout of HDF5's shuffle and deflate filters) and stores them with H5Dwrite_chunk: the file is
// the same as one written through HDF5's (single-threaded) filter pipeline, readable by any HDF5
// reader. Edge chunks are stored full-size, zero-padded, as HDF5 stores them.
struct WriteOptions {
  int compression = 1;           // deflate level 0..9 (0 = none)
  std::array<int64_t, 3> chunks{0, 0, 0};  // (x, y, z); 0 = automatic (~1 MiB, cube-like chunks)
  int threads = 0;               // compression threads of write_volume; <= 0: all hardware threads
};

// Chunk shape (x, y, z) that write_volume / create_volume_dataset use for these dims and voxel size.
std::array<int64_t, 3> automatic_chunks(Dims dims, int64_t bytes_per_voxel);

// Reads any supported dataset as its own voxel type (int8/int16 become int32, int64 becomes
// float64 unless it fits... see read_volume_as for conversion). Throws InputError. Chunked datasets
// with only shuffle / deflate / Fletcher32 filters are decoded by our code on `threads` threads (<= 0:
// all hardware threads), which refuses a damaged chunk naming it (hdf5_chunks.hpp;
// SKEL_HDF5_OWN_CHUNKS=0 reads through H5Dread instead); other datasets through H5Dread.
DataPtr read_volume(const std::filesystem::path& file, const std::string& dataset = "/volume", int threads = 0);
// Reads a box [begin, begin + size) of the dataset (x, y, z) as Volume<T> (converted by HDF5, or
// decoded chunk by chunk as read_volume does: only the chunks the box touches).
template <class T>
Volume<T> read_box(const std::filesystem::path& file, const std::string& dataset, Dims begin, Dims size);
VolumeInfo read_volume_info(const std::filesystem::path& file, const std::string& dataset = "/volume");
// Writes `volume` (any Volume<T>) to `file` as `dataset`. The file is written to a temporary sibling
// and renamed into place (an existing file is replaced; nothing partial is ever left under `file`).
void write_volume(const std::filesystem::path& file, const DataObject& volume, const std::string& dataset = "/volume",
                  const WriteOptions& options = {});
struct VolumeBoxSource;  // volume_format.hpp

// write_volume of a volume given box by box (under a memory budget): bands of whole rows of chunks
// (x whole, as many chunk rows as source.max_box_bytes holds) are read from the source and written
// in chunk order, compressed as write_volume does. The file holds the same dataset and attributes.
void write_volume_boxes(const std::filesystem::path& file, const VolumeBoxSource& source,
                        const std::string& dataset = "/volume", const WriteOptions& options = {});
// Block-wise (out-of-core) writing: create_volume_dataset creates `file` (replacing it) with an
// empty dataset of `dtype` (uint8, uint16, uint32, uint64, int32, float32, float64) and `grid`
// (dims, spacing, origin attributes); write_box then writes a block whose voxel (0,0,0) goes to
// dataset position `begin` (x, y, z). Unwritten voxels read as 0. These write in place (not
// atomically): write to a temporary path and rename it when all blocks are written.
void create_volume_dataset(const std::filesystem::path& file, const std::string& dataset, const std::string& dtype,
                           const Grid& grid, const WriteOptions& options = {});
template <class T>
void write_box(const std::filesystem::path& file, const std::string& dataset, const Volume<T>& block, Dims begin);

// The on-disk store of out-of-core runs (skel/out_of_core.hpp): an uncompressed HDF5 file at `file`
// with one dataset of `type_id` ("volume.u8", ...), chunked by `chunk` (x, y, z), every voxel 0 until
// written, open while the store lives and removed when it is destroyed; each open store keeps a
// 16 MiB chunk cache (a fixed overhead outside the memory budget). Registered at start-up as the
// framework's VolumeStoreFactory.
std::shared_ptr<VolumeStore> create_scratch_store(const std::filesystem::path& file, const std::string& type_id,
                                                  const Grid& grid, const Dims& chunk);

// One line per dataset of the file (name, shape (x, y, z), dtype, chunks, filters, spacing, origin;
// the `encoding` attribute when a dataset has one, e.g. a grid cell complex).
std::string describe_file(const std::filesystem::path& file);

// A string attribute of a dataset: written in place into an existing file (Error naming the file when
// that fails); read as "" when absent (InputError when the file or dataset cannot be opened).
void write_string_attribute(const std::filesystem::path& file, const std::string& dataset, const std::string& name,
                            const std::string& value);
std::string read_string_attribute(const std::filesystem::path& file, const std::string& dataset, const std::string& name);

}  // namespace skel::io
