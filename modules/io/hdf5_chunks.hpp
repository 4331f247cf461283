#pragma once
// Our own decoding of an HDF5 dataset's chunks on the read path (io/hdf5_volume.cpp: read_volume,
// read_box). libhdf5 1.10.8 trusts a deflated chunk's inflated size when it copies voxels out in
// H5Dread (heap overflows and SEGVs in H5VM_memcpyvv on mutated files, docs/reliability.md); the
// structure probe reads the voxels of datasets up to 64 MiB only, so a damaged chunk in the middle of
// a larger dataset would reach that code in the user's process. Here libhdf5 only looks chunks up in
// the dataset's chunk index and hands over their stored bytes (H5Dget_chunk_info_by_coord,
// H5Dread_chunk); the filters are undone by our code: Fletcher32 checked, zlib inflated into a buffer
// of exactly the size the chunk must have, HDF5's shuffle undone, the element type converted. A chunk
// that inflates to more or fewer bytes, fails to inflate or fails its checksum is refused with an
// InputError naming the file, the dataset and the chunk's (x, y, z) index. Chunks are decoded in
// parallel (one libhdf5 call at a time, under a lock of the read, while the caller holds the
// process-wide HDF5 mutex), so a deflated read also gets faster than H5Dread where cores are free.
//
// Handled: chunked datasets with no filters, or whose filters are shuffle, deflate (at most one) and
// Fletcher32, in any order, each honoured or skipped by the chunk's filter mask (an unfiltered chunk
// must be stored in exactly its shape's bytes); stored types the standard little- or
// big-endian integers of 8..64 bits and IEEE float32/float64, read as a memory type that holds every
// value exactly (the same type, wider integers, float → double, integers → float64 as H5Dread's cast);
// chunks never written take the dataset's fill value. Everything else (other filters such as szip,
// scaleoffset, nbit or plugins, narrowing conversions, undefined fill values, contiguous and compact
// layouts) is read by H5Dread as before.
//
// Environment: SKEL_HDF5_OWN_CHUNKS=0 turns our decoding off (every read goes through H5Dread; for
// comparisons and as a fallback should a file be read differently).
#include <hdf5.h>

#include <filesystem>
#include <string>
#include <type_traits>

#include "skel/volume.hpp"

namespace skel::io::detail {

// HDF5's native memory type of T (the voxel types of skel::Volume).
template <class T>
hid_t native_type() {
  if constexpr (std::is_same_v<T, uint8_t>) return H5T_NATIVE_UINT8;
  else if constexpr (std::is_same_v<T, uint16_t>) return H5T_NATIVE_UINT16;
  else if constexpr (std::is_same_v<T, uint32_t>) return H5T_NATIVE_UINT32;
  else if constexpr (std::is_same_v<T, uint64_t>) return H5T_NATIVE_UINT64;
  else if constexpr (std::is_same_v<T, int32_t>) return H5T_NATIVE_INT32;
  else if constexpr (std::is_same_v<T, float>) return H5T_NATIVE_FLOAT;
  else {
    static_assert(std::is_same_v<T, double>, "no HDF5 memory type for this voxel type");
    return H5T_NATIVE_DOUBLE;
  }
}

// False when SKEL_HDF5_OWN_CHUNKS=0 (read each call).
bool own_chunk_decoding_enabled();

// Reads the box [begin, begin + size) (x, y, z) of the 3-D dataset `dset` (dims `dims`, x, y, z) into
// `out` (size[0] * size[1] * size[2] values, x fastest) as H5Dread to T's native type would, decoding
// the chunks on `threads` threads (<= 0: all hardware threads). Returns false, having read nothing,
// when the dataset is not one this decoder handles (see above): the caller reads it with H5Dread.
// Throws InputError naming `file`, `dataset` and the chunk for a damaged chunk. The caller holds the
// process-wide HDF5 mutex for the whole call; the workers call libhdf5 (chunk lookup and raw read)
// one at a time under a lock of their own, and inflate, unshuffle and copy outside it.
template <class T>
bool read_chunked_box(hid_t dset, const std::filesystem::path& file, const std::string& dataset, const Dims& dims,
                      const Dims& begin, const Dims& size, T* out, int threads);

// Counters (tests: which path a read took). Chunks decoded by read_chunked_box; reads it declined.
int64_t own_chunks_decoded();
int64_t own_chunk_reads_declined();
// Adds the counts of a read the probe helper made for this process (hdf5_read.hpp).
void count_remote_chunk_reads(int64_t decoded, int64_t declined);

// Turns libhdf5's error printing off for the calling thread, once per thread (Debian's libhdf5 is
// thread-safe: its error settings are per thread).
void quiet_hdf5_errors_on_this_thread();

}  // namespace skel::io::detail
