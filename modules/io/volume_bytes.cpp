#include "io/volume_bytes.hpp"

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cctype>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <system_error>
#include <vector>

#include "skel/error.hpp"
#include "skel/text.hpp"

namespace skel::io::volbytes {

size_t dtype_bytes(const std::string& t) {
  if (t == "uint8" || t == "int8") return 1;
  if (t == "uint16" || t == "int16") return 2;
  if (t == "uint32" || t == "int32" || t == "float32") return 4;
  if (t == "uint64" || t == "int64" || t == "float64") return 8;
  return 0;
}

std::string volume_dtype(const DataObject& volume) {
  return visit_volume(volume, "volume", [](const auto& v) {
    return std::string(VoxelTraits<typename std::decay_t<decltype(v)>::value_type>::name);
  });
}

namespace {

void swap_bytes(char* p, uint64_t bytes, size_t width) {
  if (width <= 1) return;
  for (uint64_t i = 0; i + width <= bytes; i += width) std::reverse(p + i, p + i + width);
}

bool needs_swap(bool big_endian) { return big_endian != (std::endian::native == std::endian::big); }

template <class T>
DataPtr direct(const Grid& grid, bool big_endian, const std::function<void(char*, uint64_t)>& fill) {
  auto v = std::make_shared<Volume<T>>(Volume<T>::uninitialized(grid));
  const uint64_t n = static_cast<uint64_t>(v->size()) * sizeof(T);
  fill(reinterpret_cast<char*>(v->data()), n);
  if (needs_swap(big_endian)) swap_bytes(reinterpret_cast<char*>(v->data()), n, sizeof(T));
  return v;
}

template <class S, class T>
DataPtr widened(const Grid& grid, bool big_endian, const std::function<void(char*, uint64_t)>& fill) {
  auto v = std::make_shared<Volume<T>>(Volume<T>::uninitialized(grid));
  const uint64_t count = static_cast<uint64_t>(v->size());
  std::vector<S> tmp(count);
  fill(reinterpret_cast<char*>(tmp.data()), count * sizeof(S));
  if (needs_swap(big_endian)) swap_bytes(reinterpret_cast<char*>(tmp.data()), count * sizeof(S), sizeof(S));
  T* d = v->data();
  for (uint64_t i = 0; i < count; ++i) d[i] = static_cast<T>(tmp[i]);
  return v;
}

}  // namespace

DataPtr decode(const Grid& grid, const std::string& t, bool big_endian,
               const std::function<void(char*, uint64_t)>& fill) {
  if (t == "uint8") return direct<uint8_t>(grid, big_endian, fill);
  if (t == "uint16") return direct<uint16_t>(grid, big_endian, fill);
  if (t == "uint32") return direct<uint32_t>(grid, big_endian, fill);
  if (t == "uint64") return direct<uint64_t>(grid, big_endian, fill);
  if (t == "int32") return direct<int32_t>(grid, big_endian, fill);
  if (t == "float32") return direct<float>(grid, big_endian, fill);
  if (t == "float64") return direct<double>(grid, big_endian, fill);
  if (t == "int8") return widened<int8_t, int32_t>(grid, big_endian, fill);
  if (t == "int16") return widened<int16_t, int32_t>(grid, big_endian, fill);
  if (t == "int64") return widened<int64_t, double>(grid, big_endian, fill);
  throw Error("volbytes::decode: unknown voxel type '" + t + "'");
}

namespace {
template <class T>
bool store_int(std::string_view tok, char* dst) {
  T v{};
  if constexpr (std::is_same_v<T, uint64_t>) {
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (r.ec != std::errc() || r.ptr != tok.data() + tok.size()) return false;
  } else {
    int64_t x = 0;
    if (!text::parse_int(tok, x) || x < static_cast<int64_t>(std::numeric_limits<T>::min()) ||
        (x > 0 && static_cast<uint64_t>(x) > static_cast<uint64_t>(std::numeric_limits<T>::max())))
      return false;
    v = static_cast<T>(x);
  }
  std::memcpy(dst, &v, sizeof v);
  return true;
}
}  // namespace

bool store_text_value(std::string_view tok, const std::string& t, char* dst) {
  if (t == "uint8") return store_int<uint8_t>(tok, dst);
  if (t == "int8") return store_int<int8_t>(tok, dst);
  if (t == "uint16") return store_int<uint16_t>(tok, dst);
  if (t == "int16") return store_int<int16_t>(tok, dst);
  if (t == "uint32") return store_int<uint32_t>(tok, dst);
  if (t == "int32") return store_int<int32_t>(tok, dst);
  if (t == "uint64") return store_int<uint64_t>(tok, dst);
  if (t == "int64") return store_int<int64_t>(tok, dst);
  double v = 0;
  if (!text::parse_double(tok, v)) return false;
  if (t == "float32") {
    if (std::isfinite(v) && std::abs(v) > static_cast<double>(std::numeric_limits<float>::max())) return false;
    const auto f = static_cast<float>(v);
    std::memcpy(dst, &f, sizeof f);
    return true;
  }
  std::memcpy(dst, &v, sizeof v);
  return true;
}

std::string encode(const DataObject& volume, bool big_endian) {
  return visit_volume(volume, "volume", [&](const auto& v) {
    using T = typename std::decay_t<decltype(v)>::value_type;
    std::string out(static_cast<size_t>(v.size()) * sizeof(T), '\0');
    if (!out.empty()) std::memcpy(out.data(), v.data(), out.size());
    if (needs_swap(big_endian)) swap_bytes(out.data(), out.size(), sizeof(T));
    return out;
  });
}

uint64_t checked_bytes(const std::string& file, const Dims& dims, size_t voxel_bytes) {
  constexpr uint64_t limit = uint64_t{1} << 62;
  uint64_t n = voxel_bytes;
  for (int i = 0; i < 3; ++i) {
    if (dims[static_cast<size_t>(i)] < 0)
      throw InputError(file + ": size " + std::to_string(dims[static_cast<size_t>(i)]) + " of axis " +
                       "xyz"[i] + " is negative");
    const auto d = static_cast<uint64_t>(dims[static_cast<size_t>(i)]);
    if (d != 0 && n > limit / d)
      throw InputError(file + ": sizes " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) + " x " +
                       std::to_string(dims[2]) + " are too large (more than 2^62 bytes)");
    n *= d;
  }
  return n;
}

void check_available(const std::string& file, uint64_t available, uint64_t needed, const std::string& what) {
  if (available < needed)
    throw InputError(file + ": " + what + " needs " + std::to_string(needed) + " bytes but the file has only " +
                     std::to_string(available) + " (truncated, or the header's sizes or type are wrong)");
}

void check_compressed(const std::string& file, uint64_t compressed, uint64_t needed, const std::string& what) {
  if (needed / 1032 > compressed + 64)
    throw InputError(file + ": " + what + " claims " + std::to_string(needed) + " bytes but its compressed data is only " +
                     std::to_string(compressed) + " bytes, more than zlib can expand (truncated, or the header's sizes are wrong)");
}

void inflate_into(const std::string& file, const std::string& what, const char* src, uint64_t n, char* dst,
                  uint64_t expected) {
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) throw Error("zlib: cannot initialise inflate");
  uint64_t in_done = 0, out_done = 0;
  int rc = Z_OK;
  char probe = 0;
  bool probing = false;
  while (true) {
    if (z.avail_in == 0 && in_done < n) {
      const auto chunk = static_cast<uInt>(std::min<uint64_t>(n - in_done, 1u << 30));
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(src + in_done));
      z.avail_in = chunk;
      in_done += chunk;
    }
    if (z.avail_out == 0) {
      if (out_done < expected) {
        const auto chunk = static_cast<uInt>(std::min<uint64_t>(expected - out_done, 1u << 30));
        z.next_out = reinterpret_cast<Bytef*>(dst + out_done);
        z.avail_out = chunk;
        out_done += chunk;
      } else {
        // Everything expected arrived: one more byte would be too many.
        z.next_out = reinterpret_cast<Bytef*>(&probe);
        z.avail_out = 1;
        out_done += 1;
        probing = true;
      }
    }
    rc = inflate(&z, Z_NO_FLUSH);
    if (rc == Z_STREAM_END) break;
    if (probing && z.avail_out == 0) break;  // more data than expected
    if (rc == Z_BUF_ERROR && z.avail_in == 0 && in_done >= n) break;  // input ran out
    if (rc != Z_OK) {
      const std::string msg = z.msg ? z.msg : "error " + std::to_string(rc);
      inflateEnd(&z);
      throw InputError(file + ": " + what + ": corrupt compressed data (" + msg + ")");
    }
  }
  const uint64_t produced = out_done - z.avail_out;
  inflateEnd(&z);
  if (rc != Z_STREAM_END && produced < expected)
    throw InputError(file + ": " + what + ": compressed data ends after " + std::to_string(produced) + " of " +
                     std::to_string(expected) + " bytes (truncated)");
  if (produced != expected)
    throw InputError(file + ": " + what + ": compressed data holds " +
                     (produced > expected ? "more than " + std::to_string(expected)
                                          : std::to_string(produced) + " of " + std::to_string(expected)) +
                     " bytes (the header's sizes or type do not match the data)");
}

std::string deflate(const char* src, uint64_t n, int level, bool gzip) {
  z_stream z{};
  if (deflateInit2(&z, std::clamp(level, 1, 9), Z_DEFLATED, gzip ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw Error("zlib: cannot initialise deflate");
  std::string out;
  out.resize(static_cast<size_t>(deflateBound(&z, static_cast<uLong>(std::min<uint64_t>(n, 1u << 30)))) + 64);
  uint64_t in_done = 0, out_done = 0;
  while (true) {
    if (z.avail_in == 0 && in_done < n) {
      const auto chunk = static_cast<uInt>(std::min<uint64_t>(n - in_done, 1u << 30));
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(src + in_done));
      z.avail_in = chunk;
      in_done += chunk;
    }
    if (out_done == out.size()) out.resize(out.size() * 2);
    z.next_out = reinterpret_cast<Bytef*>(out.data() + out_done);
    z.avail_out = static_cast<uInt>(std::min<uint64_t>(out.size() - out_done, 1u << 30));
    const uInt before = z.avail_out;
    const int rc = ::deflate(&z, in_done >= n && z.avail_in == 0 ? Z_FINISH : Z_NO_FLUSH);
    out_done += before - z.avail_out;
    if (rc == Z_STREAM_END) break;
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      deflateEnd(&z);
      throw Error("zlib: deflate failed (" + std::to_string(rc) + ")");
    }
  }
  deflateEnd(&z);
  out.resize(static_cast<size_t>(out_done));
  return out;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot read: " + std::generic_category().message(errno));
  std::string s;
  in.seekg(0, std::ios::end);
  const auto size = in.tellg();
  if (size < 0) throw InputError(path.string() + ": cannot read (not a regular file?)");
  s.resize(static_cast<size_t>(size));
  in.seekg(0);
  in.read(s.data(), size);
  if (in.gcount() != size) throw InputError(path.string() + ": cannot read all of it");
  return s;
}

void read_exact(const std::filesystem::path& path, uint64_t offset, char* dst, uint64_t n, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot read: " + std::generic_category().message(errno));
  in.seekg(static_cast<std::streamoff>(offset));
  uint64_t done = 0;
  while (done < n && in) {
    const auto chunk = static_cast<std::streamsize>(std::min<uint64_t>(n - done, uint64_t{1} << 30));
    in.read(dst + done, chunk);
    done += static_cast<uint64_t>(in.gcount());
  }
  if (done < n)
    throw InputError(path.string() + ": " + what + ": the file ends after " + std::to_string(done) + " of " +
                     std::to_string(n) + " data bytes (truncated)");
}

uint64_t file_size(const std::filesystem::path& path) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(path.string() + ": cannot read: " + ec.message());
  return n;
}

std::string normalize_unit(const std::string& unit) {
  const std::string u = text::trim(unit);
  const std::string l = text::to_lower(u);
  if (l == "um" || l == "micron" || l == "microns" || l == "micrometer" || l == "micrometre" ||
      l == "micrometers" || l == "micrometres" || u == "\xce\xbcm" /* Greek mu */ || u == "\xc2\xb5m" ||
      u == "\xb5m" /* Latin-1 micro sign (older Amira files) */)
    return kDefaultUnit;
  if (l == "millimeter" || l == "millimetre" || l == "millimeters" || l == "millimetres") return "mm";
  if (l == "nanometer" || l == "nanometre" || l == "nanometers" || l == "nanometres") return "nm";
  if (l == "meter" || l == "metre" || l == "meters" || l == "metres") return "m";
  return u;
}

bool split_axes(const std::array<Vec3, 3>& axes, Vec3& spacing, Direction& direction) {
  for (size_t k = 0; k < 3; ++k) {
    const Vec3& a = axes[k];
    const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(len > 0) || !std::isfinite(len)) return false;
    spacing[k] = len;
    for (size_t r = 0; r < 3; ++r) direction[r * 3 + k] = a[r] / len;
  }
  // Exact values for axis-aligned data (no 0.9999999999 from a normalisation).
  for (double& d : direction)
    for (double e : {-1.0, 0.0, 1.0})
      if (std::abs(d - e) < 1e-15) d = e;
  return true;
}

std::string join_numbers(const double* v, int n, const char* sep) {
  std::string s;
  for (int i = 0; i < n; ++i) {
    if (i) s += sep;
    text::append_double(s, v[i], 17);
  }
  return s;
}

}  // namespace skel::io::volbytes
