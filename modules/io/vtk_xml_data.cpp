#include "io/vtk_xml_data.hpp"

#include "skel/text.hpp"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <limits>

#include "io/volume_bytes.hpp"
#include "skel/error.hpp"

namespace skel::io::vtk {

namespace {

constexpr uint64_t kBlock = 32768;  // VTK's default compression block size

uint64_t read_uint(std::string_view b, uint64_t pos, const Encoding& enc) {
  const size_t n = enc.header64 ? 8 : 4;
  uint64_t v = 0;
  for (size_t i = 0; i < n; ++i) {
    const auto byte = static_cast<uint64_t>(static_cast<unsigned char>(b[pos + i]));
    v |= enc.big_endian ? byte << (8 * (n - 1 - i)) : byte << (8 * i);
  }
  return v;
}

// Payload from header + data bytes.
std::string payload(const std::string& b, const Encoding& enc, const std::string& what) {
  const BlockMessages m{what};
  std::string out(check_block(b, 0, enc, m), '\0');
  decode_block(b, 0, enc, m, out.data(), out.size());
  return out;
}

template <class T>
void convert(const std::string& b, bool swap, std::vector<double>& out) {
  const size_t n = b.size() / sizeof(T);
  out.resize(n);
  std::array<char, sizeof(T)> buf{};
  for (size_t i = 0; i < n; ++i) {
    std::memcpy(buf.data(), b.data() + i * sizeof(T), sizeof(T));
    if (swap) std::reverse(buf.begin(), buf.end());
    T v;
    std::memcpy(&v, buf.data(), sizeof(T));
    out[i] = static_cast<double>(v);
  }
}

}  // namespace

uint64_t check_block(std::string_view b, uint64_t off, const Encoding& enc, const BlockMessages& m,
                     std::optional<uint64_t> need) {
  const uint64_t hs = enc.header64 ? 8 : 4;
  const uint64_t avail = b.size() > off ? b.size() - off : 0;
  if (!enc.zlib) {
    volbytes::check_available(m.src, avail, hs, "the data array's header");
    const uint64_t n = read_uint(b, off, enc);
    if (need && n != *need)
      throw InputError(m.src + ": the data array holds " + std::to_string(n) + " bytes but " + m.need_by + " need " +
                       std::to_string(*need));
    volbytes::check_available(m.src, avail - hs, n, m.data);
    return n;
  }
  volbytes::check_available(m.src, avail, 3 * hs, "the compressed array's header");
  const uint64_t nb = read_uint(b, off, enc);
  const uint64_t bs = read_uint(b, off + hs, enc);
  uint64_t last = read_uint(b, off + 2 * hs, enc);
  if (nb > avail / hs)
    throw InputError(m.src + ": the compressed array's header claims " + std::to_string(nb) +
                     " blocks, more than the file can hold (truncated or corrupt)");
  volbytes::check_available(m.src, avail, (nb + 3) * hs, "the compressed array's block table");
  if (last == 0) last = bs;
  std::string layout = "(";  // built by appending: GCC 12 warns falsely (-Wrestrict) on "(" + s
  layout += std::to_string(nb) + " blocks of " + std::to_string(bs) + " bytes, last " + std::to_string(last) + ")";
  // The payload size without overflow: (nb − 1) full blocks and the last one.
  const bool fits = nb == 0 || (bs > 0 && last <= bs && nb - 1 <= (UINT64_MAX - last) / bs);
  if (!fits) throw InputError(m.src + ": the compressed array's header " + layout + " is inconsistent");
  const uint64_t total = nb == 0 ? 0 : (nb - 1) * bs + last;
  if (need && total != *need)
    throw InputError(m.src + ": the compressed array's header " + layout + " does not give the " + std::to_string(*need) +
                     " bytes " + m.need_by + " need");
  uint64_t pos = off + (nb + 3) * hs, compressed = 0;
  for (uint64_t i = 0; i < nb; ++i) {
    const uint64_t cs = read_uint(b, off + (3 + i) * hs, enc);
    volbytes::check_available(m.src, b.size() > pos ? b.size() - pos : 0, cs, "compressed block " + std::to_string(i));
    compressed += cs;  // each <= the file's size: no overflow
  }
  volbytes::check_available(m.src, b.size() > pos ? b.size() - pos : 0, compressed, "the compressed blocks");
  volbytes::check_compressed(m.src, compressed, total, "the compressed data array");
  return total;
}

void decode_block(std::string_view b, uint64_t off, const Encoding& enc, const BlockMessages& m, char* dst, uint64_t bytes) {
  check_block(b, off, enc, m, bytes);
  const uint64_t hs = enc.header64 ? 8 : 4;
  if (!enc.zlib) {
    if (bytes > 0) std::memcpy(dst, b.data() + off + hs, bytes);
    return;
  }
  const uint64_t nb = read_uint(b, off, enc), bs = read_uint(b, off + hs, enc);
  uint64_t last = read_uint(b, off + 2 * hs, enc);
  if (last == 0) last = bs;
  uint64_t pos = off + (nb + 3) * hs, out = 0;
  for (uint64_t i = 0; i < nb; ++i) {
    const uint64_t cs = read_uint(b, off + (3 + i) * hs, enc);
    const uint64_t us = i + 1 == nb ? last : bs;
    volbytes::inflate_into(m.src, "compressed block " + std::to_string(i), b.data() + pos, cs, dst + out, us);
    pos += cs;
    out += us;
  }
}

Encoding parse_encoding(const std::string& header_type, const std::string& byte_order, const std::string& compressor,
                        const std::string& src) {
  Encoding e;
  if (header_type == "UInt64") e.header64 = true;
  else if (!header_type.empty() && header_type != "UInt32")
    throw InputError(src + ": <VTKFile> header_type '" + header_type + "' is not UInt32 or UInt64");
  if (byte_order == "BigEndian") e.big_endian = true;
  else if (!byte_order.empty() && byte_order != "LittleEndian")
    throw InputError(src + ": <VTKFile> byte_order '" + byte_order + "' is not LittleEndian or BigEndian");
  if (compressor == "vtkZLibDataCompressor") e.zlib = true;
  else if (!compressor.empty())
    throw InputError(src + ": unsupported compression '" + compressor +
                     "' (only vtkZLibDataCompressor; save with zlib or without compression)");
  return e;
}

SplitFile split_appended(const std::string& text, const std::string& src) {
  SplitFile f;
  const size_t tag = text.find("<AppendedData");
  if (tag == std::string::npos) {
    f.xml = text;
    return f;
  }
  const size_t gt = text.find('>', tag);
  const size_t us = gt == std::string::npos ? gt : text.find('_', gt);
  if (us == std::string::npos) throw InputError(src + ": <AppendedData> has no '_' before its data");
  size_t end = text.rfind("</AppendedData>");
  if (end == std::string::npos || end < us) end = text.size();  // a truncated file: the offsets will tell
  f.xml = text.substr(0, gt + 1) + "</AppendedData></VTKFile>\n";
  f.appended = text.substr(us + 1, end - us - 1);
  f.has_appended = true;
  return f;
}

std::string decode_inline(const std::string& t, const Encoding& enc, const std::string& what) {
  return payload(text::base64_decode(t, what), enc, what);
}

std::string decode_appended(const std::string& a, bool base64, uint64_t offset, uint64_t end, const Encoding& enc,
                            const std::string& what) {
  if (offset >= a.size())
    throw InputError(what + ": offset " + std::to_string(offset) + " is past the end of the appended data (" +
                     std::to_string(a.size()) + (base64 ? " characters)" : " bytes)"));
  end = std::min<uint64_t>(std::max(end, offset), a.size());
  if (base64) return payload(text::base64_decode(std::string_view(a).substr(offset, end - offset), what), enc, what);
  return payload(a.substr(offset, end - offset), enc, what);
}

std::vector<double> to_doubles(const std::string& b, const std::string& type, const Encoding& enc, const std::string& what) {
  const bool swap = enc.big_endian != (std::endian::native == std::endian::big);
  std::vector<double> v;
  auto go = [&]<class T>(T) {
    if (b.size() % sizeof(T) != 0)
      throw InputError(what + ": " + std::to_string(b.size()) + " bytes is not a whole number of " + type + " values");
    convert<T>(b, swap, v);
  };
  if (type == "Int8" || type == "Char") go(int8_t{});
  else if (type == "UInt8" || type == "UnsignedChar") go(uint8_t{});
  else if (type == "Int16") go(int16_t{});
  else if (type == "UInt16") go(uint16_t{});
  else if (type == "Int32") go(int32_t{});
  else if (type == "UInt32") go(uint32_t{});
  else if (type == "Int64" || type == "IdType") go(int64_t{});
  else if (type == "UInt64") go(uint64_t{});
  else if (type == "Float32") go(float{});
  else if (type == "Float64") go(double{});
  else throw InputError(what + ": unsupported data type '" + type + "'");
  return v;
}

std::string encode_array(const void* data, uint64_t bytes, bool compress) {
  auto put64 = [](std::string& s, uint64_t v) {
    for (int i = 0; i < 8; ++i) s += static_cast<char>((v >> (8 * i)) & 0xFF);
  };
  std::string out;
  const auto* p = static_cast<const Bytef*>(data);
  if (!compress) {
    put64(out, bytes);
    out.append(reinterpret_cast<const char*>(p), bytes);
    return out;
  }
  const uint64_t nblocks = (bytes + kBlock - 1) / kBlock;
  std::string blocks;
  std::vector<uint64_t> sizes;
  std::vector<Bytef> buf(compressBound(kBlock));
  for (uint64_t k = 0; k < nblocks; ++k) {
    const uint64_t n = std::min(kBlock, bytes - k * kBlock);
    uLongf cs = static_cast<uLongf>(buf.size());
    if (compress2(buf.data(), &cs, p + k * kBlock, static_cast<uLong>(n), 6) != Z_OK) throw Error("zlib: compression failed");
    blocks.append(reinterpret_cast<const char*>(buf.data()), cs);
    sizes.push_back(cs);
  }
  put64(out, nblocks);
  put64(out, kBlock);
  put64(out, bytes % kBlock);
  for (uint64_t s : sizes) put64(out, s);
  return out + blocks;
}

}  // namespace skel::io::vtk
