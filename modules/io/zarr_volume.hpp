#pragma once
// Block-wise writing of Zarr / OME-Zarr stores, as create_volume_dataset / write_box do for HDF5
// (hdf5_volume.hpp), so out-of-core stages can write a result larger than memory chunk by chunk.
// Reading by boxes is the registry's read_box of the Zarr format (volume_format.hpp).
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>

#include "io/volume_format.hpp"
#include "skel/volume.hpp"

namespace skel::io {

// Creates `dir` (replacing it) as an OME-Zarr 0.4 group with one empty array (options.dataset, "0"
// by default) of `dtype` (uint8, uint16, uint32, uint64, int32, float32, float64) and `grid` (no
// direction: OME-Zarr has no rotation). chunks (x, y, z): 0 = automatic (~1 MiB, as HDF5's).
// options.compression > 0: blosc lz4 with byte shuffle at that level; 0: uncompressed. Voxels never
// written read as 0. Writes in place (not atomically): create under a temporary name and rename it
// when all blocks are written.
void create_zarr_volume(const std::filesystem::path& dir, const std::string& dtype, const Grid& grid,
                        const VolumeWriteOptions& options = {}, std::array<int64_t, 3> chunks = {0, 0, 0});
// Writes `block` with its voxel (0,0,0) at array voxel `begin` (x, y, z): the chunks it covers
// whole are written, the chunks it covers in part are read, patched and written again; chunks that
// end up all 0 are removed. Blocks on chunk boundaries may be written from several threads at once;
// blocks that share a chunk must not.
template <class T>
void write_zarr_box(const std::filesystem::path& dir, const Volume<T>& block, Dims begin,
                    const VolumeWriteOptions& options = {});

}  // namespace skel::io
