#pragma once
// Shared by the volume formats that store voxels as a raw byte block (NRRD, MetaImage, NIfTI, VTK
// image, Amira lattice): voxel type names and sizes, bytes <-> Volume<T> in either byte order, zlib
// / gzip streams, unit names and the size checks every reader makes before it allocates.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "skel/data.hpp"
#include "skel/volume.hpp"

namespace skel::io::volbytes {

// Bytes per voxel of a stored type (uint8, int8, uint16, int16, uint32, int32, uint64, int64,
// float32, float64); 0 for any other name.
size_t dtype_bytes(const std::string& dtype);

// The voxel type name of a Volume<T> (uint8, uint16, uint32, uint64, int32, float32, float64).
std::string volume_dtype(const DataObject& volume);

// Makes a volume of `grid` from `dtype` voxels stored x-fastest: `fill(dst, n)` writes the n stored
// bytes to dst. The result has the stored type, except int8/int16 (-> int32) and int64 (->
// float64), as the HDF5 reader does. `big_endian`: the bytes are most significant byte first.
DataPtr decode(const Grid& grid, const std::string& dtype, bool big_endian,
               const std::function<void(char* dst, uint64_t bytes)>& fill);

// Parses one ASCII voxel value `tok` and stores it at dst as native `dtype` bytes. False when `tok`
// is not a number, not an integer for an integer type, or outside the type's range (NaN and
// infinities are values of the float types).
bool store_text_value(std::string_view tok, const std::string& dtype, char* dst);

// The voxels of any volume as bytes of its own type (volume_dtype), in the given byte order.
std::string encode(const DataObject& volume, bool big_endian);

// Voxel count of `dims`, throwing InputError "FILE: ..." when a size is negative or the product
// overflows 2^62 bytes at `voxel_bytes` per voxel.
uint64_t checked_bytes(const std::string& file, const Dims& dims, size_t voxel_bytes);

// The bytes a reader may read (`available`) must hold `needed`: InputError "FILE: WHAT needs N bytes
// but the file has only M (truncated?)" otherwise.
void check_available(const std::string& file, uint64_t available, uint64_t needed, const std::string& what);
// Before inflating `compressed` bytes into `needed` bytes: deflate never shrinks data by more than
// 1032:1, so a header that claims more is refused before anything is allocated.
void check_compressed(const std::string& file, uint64_t compressed, uint64_t needed, const std::string& what);

// Inflates a zlib or gzip stream (detected from its first bytes) of exactly `expected` bytes into
// dst. InputError naming the file and `what` when the stream is corrupt, shorter or longer.
void inflate_into(const std::string& file, const std::string& what, const char* src, uint64_t n, char* dst,
                  uint64_t expected);
// A zlib (gzip = false) or gzip stream of `n` bytes at `level` (1..9).
std::string deflate(const char* src, uint64_t n, int level, bool gzip);

// The whole file; InputError "FILE: cannot read: REASON" when it cannot be opened.
std::string read_file(const std::filesystem::path& path);
// Exactly `n` bytes of `path` from `offset` into dst; InputError "FILE: WHAT: ... (truncated)" when the
// file is shorter.
void read_exact(const std::filesystem::path& path, uint64_t offset, char* dst, uint64_t n, const std::string& what);
// The size of a file; InputError naming it when it does not exist.
uint64_t file_size(const std::filesystem::path& path);

// One spelling per unit: "um", "micron", "micrometer", "μm" (Greek mu), a Latin-1 micro sign become
// "µm" (kDefaultUnit),
// "millimeter" "mm", "nanometer" "nm", "meter" "m"; any other name stays as written (trimmed).
std::string normalize_unit(const std::string& unit);

// Direction cosines and spacing from the three axis vectors (column k = physical step of voxel axis
// k). False when a vector has length 0.
bool split_axes(const std::array<Vec3, 3>& axes, Vec3& spacing, Direction& direction);


// "a b c" with 17 significant digits each.
std::string join_numbers(const double* v, int n, const char* sep = " ");

}  // namespace skel::io::volbytes
