#pragma once
// The data of VTK XML files (.vtp, .vtu, .vti, ...): DataArray contents in every encoding VTK,
// ParaView, VMTK and Slicer write — ASCII, inline binary (base64), appended raw or base64 — each
// optionally zlib-compressed in blocks, with UInt32 or UInt64 size headers, little- or big-endian.
// The XML around them is parsed by the caller (expat); raw appended data is cut off first
// (split_appended), since its bytes are not XML.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace skel::io::vtk {

// How the arrays of one file are stored, from the attributes of <VTKFile>.
struct Encoding {
  bool header64 = false;    // header_type="UInt64" (else UInt32, also for version 0.1 files)
  bool big_endian = false;  // byte_order="BigEndian"
  bool zlib = false;        // compressor="vtkZLibDataCompressor"
};
// Throws InputError naming `src` for an unknown header type or byte order and for compressors other
// than zlib (vtkLZ4DataCompressor, vtkLZMADataCompressor: "unsupported compression").
Encoding parse_encoding(const std::string& header_type, const std::string& byte_order, const std::string& compressor,
                        const std::string& src);

// A file split at <AppendedData ...>_ : `xml` is the file up to that tag, closed again
// ("</AppendedData></VTKFile>"), `appended` the bytes after '_' up to the last </AppendedData>.
struct SplitFile {
  std::string xml;
  std::string appended;
  bool has_appended = false;
};
SplitFile split_appended(const std::string& text, const std::string& src);

// One binary array block as VTK stores it, at b[off..]: a size header and the payload, or (zlib) a
// compression header — number of blocks, block size, size of the last block (0: a full block), the
// compressed size of every block — followed by the zlib blocks. The one decoder of such blocks, for
// graphs (.vtp) and volumes (.vti).
struct BlockMessages {
  std::string src;                        // start of every message: the file, or "f.vtp: DataArray 'Points'"
  std::string data = "the array's data";  // what the payload is called ("the voxel data")
  std::string need_by = "the caller";     // with a required size: what requires it ("WholeExtent and type")
};
// Checks the block's headers against the bytes present (and the payload size against `need`, when
// given) without allocating or inflating anything; returns the payload size. InputError starting
// with m.src for a truncated block, an inconsistent header, a size other than `need`, or a header
// that claims more than zlib can expand from the compressed bytes.
uint64_t check_block(std::string_view b, uint64_t off, const Encoding& enc, const BlockMessages& m,
                     std::optional<uint64_t> need = std::nullopt);
// Checks the block as check_block(…, bytes) and decodes its payload into `dst` (exactly `bytes`
// bytes; a zlib block that inflates to another size is an InputError naming the block).
void decode_block(std::string_view b, uint64_t off, const Encoding& enc, const BlockMessages& m, char* dst, uint64_t bytes);

// The payload bytes of one array (size header removed, blocks decompressed), checked against the
// sizes the headers declare. `what` starts error messages ("file: DataArray 'Points'").
std::string decode_inline(const std::string& base64_text, const Encoding& enc, const std::string& what);
// Appended data: the array's bytes start at `offset` (bytes for raw, characters for base64) and end
// before `end` (the next array's offset or the end of the data).
std::string decode_appended(const std::string& appended, bool base64, uint64_t offset, uint64_t end, const Encoding& enc,
                            const std::string& what);

// The values of payload bytes of VTK type `type` (Int8 .. UInt64, Float32, Float64) as doubles.
std::vector<double> to_doubles(const std::string& bytes, const std::string& type, const Encoding& enc,
                               const std::string& what);

// Writing: the appended-data block of one array: UInt64 header(s) and the payload, zlib-compressed
// in blocks of 32 KiB when `compress` (VTK's layout: nblocks, block size, last block size, compressed
// sizes), else the byte count and the raw payload.
std::string encode_array(const void* data, uint64_t bytes, bool compress);

}  // namespace skel::io::vtk
