// TIFF as a VolumeFormat, through libtiff: multi-page stacks, folders (or file-name patterns) of
// single-slice files sorted naturally, 8/16/32/64-bit unsigned, signed and float samples, BigTIFF,
// strips and tiles, every compression libtiff decodes, ImageJ calibration and OME-TIFF metadata;
// read by boxes (only the pages and strips/tiles a box touches are decoded). Written as a multi-page
// TIFF with ImageJ calibration (OME-XML for names ending in .ome.tif), BigTIFF above 4 GiB, deflate
// optional.
#include <tiffio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstring>
#include <fnmatch.h>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>

#include "io/volume_format.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/out_of_core.hpp"
#include "skel/text.hpp"

namespace fs = std::filesystem;

namespace skel::io {
namespace {

// The canonical spelling of micrometres: ImageJ writes "micron", "um" or "\u00B5m", OME "µm".
constexpr const char* kMicrometre = "\u00b5m";

// ------------------------------------------------------------------ libtiff errors
thread_local std::string g_tiff_error;

void on_tiff_error(const char*, const char* fmt, va_list ap) {
  char buf[512];
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  g_tiff_error = buf;
}

void install_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    TIFFSetErrorHandler(on_tiff_error);
    TIFFSetWarningHandler(nullptr);  // unknown private tags are common and harmless
  });
}

// " (libtiff: ...)" for the last error of this thread, or "".
std::string tiff_reason() {
  std::string r;
  r.swap(g_tiff_error);
  return r.empty() ? std::string() : " (libtiff: " + r + ")";
}

struct TiffCloser {
  void operator()(TIFF* t) const {
    if (t) TIFFClose(t);
  }
};
using TiffPtr = std::unique_ptr<TIFF, TiffCloser>;

std::string show(const fs::path& p) { return display_path(p).string(); }

TiffPtr open_tiff(const fs::path& file) {
  install_handlers();
  std::error_code ec;
  if (!fs::exists(file, ec)) throw InputError(show(file) + ": file not found");
  if (!fs::is_regular_file(file, ec)) throw InputError(show(file) + ": not a regular file");
  char magic[4] = {0, 0, 0, 0};
  {
    std::ifstream in(file, std::ios::binary);
    in.read(magic, 4);
    if (in.gcount() < 4) throw InputError(show(file) + ": not a TIFF file (shorter than a TIFF header)");
  }
  const bool ok = (magic[0] == 'I' && magic[1] == 'I' && (magic[2] == 42 || magic[2] == 43) && magic[3] == 0) ||
                  (magic[0] == 'M' && magic[1] == 'M' && magic[2] == 0 && (magic[3] == 42 || magic[3] == 43));
  if (!ok) throw InputError(show(file) + ": not a TIFF file (wrong magic bytes)");
  g_tiff_error.clear();
  TIFF* t = TIFFOpen(file.c_str(), "rm");
  if (!t) throw InputError(show(file) + ": cannot read the TIFF header: the file is truncated or corrupt" + tiff_reason());
  return TiffPtr(t);
}

// ------------------------------------------------------------------ sample types
enum class Stored { u8, u16, u32, u64, i8, i16, i32, i64, f32, f64 };

const char* stored_name(Stored s) {
  switch (s) {
    case Stored::u8: return "uint8";
    case Stored::u16: return "uint16";
    case Stored::u32: return "uint32";
    case Stored::u64: return "uint64";
    case Stored::i8: return "int8";
    case Stored::i16: return "int16";
    case Stored::i32: return "int32";
    case Stored::i64: return "int64";
    case Stored::f32: return "float32";
    case Stored::f64: return "float64";
  }
  return "?";
}

template <class F>
decltype(auto) with_stored(Stored s, F&& f) {
  switch (s) {
    case Stored::u8: return f(uint8_t{});
    case Stored::u16: return f(uint16_t{});
    case Stored::u32: return f(uint32_t{});
    case Stored::u64: return f(uint64_t{});
    case Stored::i8: return f(int8_t{});
    case Stored::i16: return f(int16_t{});
    case Stored::i32: return f(int32_t{});
    case Stored::i64: return f(int64_t{});
    case Stored::f32: return f(float{});
    case Stored::f64: return f(double{});
  }
  return f(uint8_t{});
}

// The layout of one page (an image file directory).
struct PageFormat {
  int64_t width = 0, height = 0;
  uint16_t bits = 0, sample_format = SAMPLEFORMAT_UINT, spp = 1, planar = PLANARCONFIG_CONTIG, compression = 1;
  bool tiled = false;
  uint32_t tile_w = 0, tile_h = 0, rows_per_strip = 0;
  Stored stored = Stored::u8;
  [[nodiscard]] bool same_layout(const PageFormat& o) const {
    return width == o.width && height == o.height && bits == o.bits && sample_format == o.sample_format &&
           spp == o.spp && planar == o.planar;
  }
};

std::string compression_name(uint16_t c) {
  switch (c) {
    case COMPRESSION_NONE: return "none";
    case COMPRESSION_LZW: return "LZW";
    case COMPRESSION_ADOBE_DEFLATE:
    case COMPRESSION_DEFLATE: return "deflate";
    case COMPRESSION_PACKBITS: return "PackBits";
    case COMPRESSION_JPEG: return "JPEG";
    case COMPRESSION_LZMA: return "LZMA";
    case COMPRESSION_ZSTD: return "zstd";
    case COMPRESSION_WEBP: return "WebP";
    default: return "code " + std::to_string(c);
  }
}

PageFormat page_format(TIFF* t, const fs::path& file, int64_t page) {
  PageFormat f;
  const std::string where = show(file) + ": page " + std::to_string(page) + ": ";
  uint32_t w = 0, h = 0;
  if (!TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w) || !TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h) || w == 0 || h == 0)
    throw InputError(where + "no image width/length");
  f.width = w;
  f.height = h;
  TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &f.bits);
  TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &f.sample_format);
  TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &f.spp);
  TIFFGetFieldDefaulted(t, TIFFTAG_PLANARCONFIG, &f.planar);
  TIFFGetFieldDefaulted(t, TIFFTAG_COMPRESSION, &f.compression);
  f.tiled = TIFFIsTiled(t) != 0;
  if (f.tiled) {
    TIFFGetField(t, TIFFTAG_TILEWIDTH, &f.tile_w);
    TIFFGetField(t, TIFFTAG_TILELENGTH, &f.tile_h);
    if (f.tile_w == 0 || f.tile_h == 0) throw InputError(where + "tiles of size 0");
  } else {
    TIFFGetFieldDefaulted(t, TIFFTAG_ROWSPERSTRIP, &f.rows_per_strip);
    f.rows_per_strip = std::min<uint32_t>(std::max<uint32_t>(f.rows_per_strip, 1), h);
  }
  if (f.spp == 0) throw InputError(where + "0 samples per pixel");
  if (!TIFFIsCODECConfigured(f.compression))
    throw InputError(where + "unsupported compression (" + compression_name(f.compression) +
                     "); libtiff here decodes none, LZW, deflate, PackBits and what it was built with");
  const int b = f.bits;
  const std::string kind = f.sample_format == SAMPLEFORMAT_UINT ? "unsigned" : f.sample_format == SAMPLEFORMAT_INT ? "signed"
                           : f.sample_format == SAMPLEFORMAT_IEEEFP ? "float"
                           : f.sample_format == SAMPLEFORMAT_COMPLEXINT || f.sample_format == SAMPLEFORMAT_COMPLEXIEEEFP ? "complex"
                                                                       : "sample format " + std::to_string(f.sample_format);
  if (f.sample_format == SAMPLEFORMAT_UINT || f.sample_format == SAMPLEFORMAT_VOID) {
    if (b == 8) f.stored = Stored::u8;
    else if (b == 16) f.stored = Stored::u16;
    else if (b == 32) f.stored = Stored::u32;
    else if (b == 64) f.stored = Stored::u64;
    else throw InputError(where + "unsupported sample type (" + std::to_string(b) + "-bit " + kind + "); 8, 16, 32 and 64-bit samples are read");
  } else if (f.sample_format == SAMPLEFORMAT_INT) {
    if (b == 8) f.stored = Stored::i8;
    else if (b == 16) f.stored = Stored::i16;
    else if (b == 32) f.stored = Stored::i32;
    else if (b == 64) f.stored = Stored::i64;
    else throw InputError(where + "unsupported sample type (" + std::to_string(b) + "-bit " + kind + "); 8, 16, 32 and 64-bit samples are read");
  } else if (f.sample_format == SAMPLEFORMAT_IEEEFP && (b == 32 || b == 64)) {
    f.stored = b == 32 ? Stored::f32 : Stored::f64;
  } else {
    throw InputError(where + "unsupported sample type (" + std::to_string(b) + "-bit " + kind +
                     "); unsigned, signed and float samples are read");
  }
  if (f.compression == COMPRESSION_JPEG || f.compression == COMPRESSION_OJPEG)
    throw InputError(where + "JPEG-compressed (lossy) images are not read; convert the stack to lossless TIFF");
  return f;
}

// ------------------------------------------------------------------ metadata
// One "key=value" of an ImageJ description, or "".
std::string imagej_value(const std::string& desc, const std::string& key) {
  for (const auto& line : text::split_lines(desc))
    if (line.size() > key.size() && line.compare(0, key.size(), key) == 0 && line[key.size()] == '=')
      return text::trim(line.substr(key.size() + 1));
  return {};
}

// ImageJ writes non-ASCII characters as "\uXXXX"; units as "micron", "um", "µm"...
std::string canonical_unit(std::string u) {
  for (size_t i = u.find("\\u"); i != std::string::npos && i + 6 <= u.size(); i = u.find("\\u", i + 1)) {
    const unsigned long cp = std::strtoul(u.substr(i + 2, 4).c_str(), nullptr, 16);
    std::string utf8;
    if (cp < 0x80) utf8 = std::string(1, static_cast<char>(cp));
    else if (cp < 0x800) {
      utf8 += static_cast<char>(0xC0 | (cp >> 6));
      utf8 += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
      utf8 += static_cast<char>(0xE0 | (cp >> 12));
      utf8 += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      utf8 += static_cast<char>(0x80 | (cp & 0x3F));
    }
    u.replace(i, 6, utf8);
  }
  const std::string l = text::to_lower(u);
  if (l == "micron" || l == "microns" || l == "um" || l == "\u00b5m" || l == "\u03bcm" || l == "micrometer" ||
      l == "micrometre")
    return kMicrometre;
  if (l == "nanometer" || l == "nanometre") return "nm";
  if (l == "millimeter" || l == "millimetre") return "mm";
  if (l == "pixel" || l == "pixels" || l == "inch" || l.empty()) return {};  // ImageJ: uncalibrated
  return u;
}

// The start tag of the first <Pixels> element of an OME-XML description: its attributes.
std::map<std::string, std::string> ome_pixels(const std::string& xml) {
  std::map<std::string, std::string> attrs;
  size_t p = std::string::npos;
  for (size_t i = xml.find("Pixels"); i != std::string::npos; i = xml.find("Pixels", i + 1)) {
    if (i > 0 && (xml[i - 1] == '<' || xml[i - 1] == ':') && i + 6 < xml.size() &&
        (xml[i + 6] == ' ' || xml[i + 6] == '\n' || xml[i + 6] == '\t' || xml[i + 6] == '\r')) {
      p = i + 6;
      break;
    }
  }
  if (p == std::string::npos) return attrs;
  const size_t end = xml.find('>', p);
  const std::string tag = xml.substr(p, end == std::string::npos ? std::string::npos : end - p);
  size_t i = 0;
  while (i < tag.size()) {
    while (i < tag.size() && std::isspace(static_cast<unsigned char>(tag[i]))) ++i;
    const size_t eq = tag.find('=', i);
    if (eq == std::string::npos) break;
    const std::string name = text::trim(tag.substr(i, eq - i));
    size_t q = eq + 1;
    while (q < tag.size() && std::isspace(static_cast<unsigned char>(tag[q]))) ++q;
    if (q >= tag.size() || (tag[q] != '"' && tag[q] != '\'')) break;
    const size_t close = tag.find(tag[q], q + 1);
    if (close == std::string::npos) break;
    attrs[name] = tag.substr(q + 1, close - q - 1);
    i = close + 1;
  }
  return attrs;
}

// "z2" before "z10": digit runs compare as numbers.
bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      size_t i2 = i, j2 = j;
      while (i2 < a.size() && std::isdigit(static_cast<unsigned char>(a[i2]))) ++i2;
      while (j2 < b.size() && std::isdigit(static_cast<unsigned char>(b[j2]))) ++j2;
      std::string x = a.substr(i, i2 - i), y = b.substr(j, j2 - j);
      x.erase(0, std::min(x.find_first_not_of('0'), x.size()));
      y.erase(0, std::min(y.find_first_not_of('0'), y.size()));
      if (x.size() != y.size()) return x.size() < y.size();
      if (x != y) return x < y;
      i = i2;
      j = j2;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

bool is_pattern(const fs::path& p) { return p.filename().string().find_first_of("*?[") != std::string::npos; }

bool has_tiff_extension(const fs::path& p) {
  const std::string e = text::to_lower(p.extension().string());
  return e == ".tif" || e == ".tiff" || e == ".btf" || e == ".tf8";
}

// The files of a folder of slices (every TIFF in it) or of a pattern ("slices/z*.tif"), in natural order.
std::vector<fs::path> slice_files(const fs::path& path) {
  std::vector<fs::path> files;
  std::error_code ec;
  if (is_pattern(path)) {
    const fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
    if (!fs::is_directory(dir, ec)) throw InputError(path.string() + ": folder " + dir.string() + " not found");
    const std::string pat = path.filename().string();
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.is_regular_file() && fnmatch(pat.c_str(), e.path().filename().c_str(), 0) == 0) files.push_back(e.path());
    if (files.empty()) throw InputError(path.string() + ": no file matches the pattern");
  } else {
    for (const auto& e : fs::directory_iterator(path, ec))
      if (e.is_regular_file() && has_tiff_extension(e.path()) && e.path().filename().string()[0] != '.')
        files.push_back(e.path());
    if (files.empty()) throw InputError(path.string() + ": folder holds no TIFF file (.tif, .tiff)");
  }
  std::sort(files.begin(), files.end(),
            [](const fs::path& a, const fs::path& b) { return natural_less(a.filename().string(), b.filename().string()); });
  return files;
}

// ------------------------------------------------------------------ the stack
struct Slice {
  size_t file = 0;   // index into Stack::files
  tdir_t page = 0;   // directory in that file
};

struct Stack {
  std::vector<fs::path> files;
  std::vector<Slice> slices;  // one per z
  PageFormat format;
  uint16_t sample = 0;        // sample (channel) read from each pixel when spp > 1
  VolumeHeader header;
};

std::string pages_word(size_t n) { return std::to_string(n) + (n == 1 ? " page" : " pages"); }

// The main pages (no reduced-resolution subfiles) of one file, checked against `ref` (set from the
// first page when null).
// Adds each page's voxel bytes to `claimed_bytes` and keeps the largest tile of any page (bytes, as
// decoded) in `largest_tile`: a tile may be larger than its page, so the voxels alone do not bound the
// buffer a read needs.
std::vector<tdir_t> main_pages(TIFF* t, const fs::path& file, PageFormat& ref, bool& have_ref, std::string& first_desc,
                               uint64_t& claimed_bytes, double& largest_tile) {
  std::vector<tdir_t> pages;
  tdir_t dir = 0;
  do {
    uint32_t subfile = 0;
    TIFFGetFieldDefaulted(t, TIFFTAG_SUBFILETYPE, &subfile);
    if ((subfile & FILETYPE_REDUCEDIMAGE) == 0) {
      const PageFormat f = page_format(t, file, static_cast<int64_t>(dir));
      if (!have_ref) {
        ref = f;
        have_ref = true;
        char* desc = nullptr;
        if (TIFFGetField(t, TIFFTAG_IMAGEDESCRIPTION, &desc) && desc) first_desc = desc;
      } else if (!f.same_layout(ref)) {
        throw InputError(show(file) + ": page " + std::to_string(dir) + " is " + std::to_string(f.width) + "x" +
                         std::to_string(f.height) + " " + stored_name(f.stored) + " (" + std::to_string(f.spp) +
                         " sample(s) per pixel), but the first page is " + std::to_string(ref.width) + "x" +
                         std::to_string(ref.height) + " " + stored_name(ref.stored) + " (" + std::to_string(ref.spp) +
                         "): every page of a stack must have the same size and type");
      }
      claimed_bytes += static_cast<uint64_t>(f.width) * static_cast<uint64_t>(f.height) * f.spp * (f.bits / 8u);
      if (f.tiled)
        largest_tile = std::max(largest_tile, static_cast<double>(f.tile_w) * static_cast<double>(f.tile_h) *
                                                  (f.planar == PLANARCONFIG_CONTIG ? f.spp : 1) * (f.bits / 8));
      pages.push_back(dir);
    }
    ++dir;
  } while (TIFFReadDirectory(t));
  // The chain of pages ends where the file says it does; an error on the way means a page the file
  // names but no longer holds.
  if (!g_tiff_error.empty())
    throw InputError(show(file) + ": cannot read page " + std::to_string(dir) + " (after " + pages_word(pages.size()) +
                     "): the file is truncated or corrupt" + tiff_reason());
  return pages;
}

Stack open_stack(const fs::path& path, const VolumeReadOptions& o) {
  Stack s;
  std::error_code ec;
  const bool folder = fs::is_directory(path, ec) || is_pattern(path);
  s.files = folder ? slice_files(path) : std::vector<fs::path>{path};
  bool have = false;
  std::string desc;
  std::vector<Slice> pages;
  uint64_t claimed = 0, file_bytes = 0;
  for (size_t i = 0; i < s.files.size(); ++i) {
    TiffPtr t = open_tiff(s.files[i]);
    double tile = 0;
    for (tdir_t p : main_pages(t.get(), s.files[i], s.format, have, desc, claimed, tile)) pages.push_back({i, p});
    const uint64_t bytes = fs::file_size(s.files[i], ec);
    file_bytes += bytes;
    // A tile is decoded whole into one buffer: one that decodes to more than its file can hold
    // (deflate's ~1000:1 again) is a corrupt tile size, refused before that buffer is allocated.
    if (tile / 1032 > static_cast<double>(bytes + 4096))
      throw InputError(show(s.files[i]) + ": a tile of " + std::to_string(static_cast<uint64_t>(tile)) +
                       " bytes is more than " + std::to_string(bytes) +
                       " bytes of file can hold: the file is truncated or corrupt");
  }
  const PageFormat& f = s.format;
  // No format compresses voxels more than ~1000:1 (deflate's limit): a header that claims more
  // describes a file that is truncated or corrupt; refuse it before allocating.
  if (claimed / 1032 > file_bytes + 4096)
    throw InputError(path.string() + ": the header claims " + std::to_string(claimed) + " bytes of voxels, more than " +
                     std::to_string(file_bytes) + " bytes of file can hold: the file is truncated or corrupt");
  VolumeHeader& h = s.header;
  Grid& g = h.grid;
  g.dims = {f.width, f.height, 0};
  int64_t channels = f.spp;
  // The pages of channel `c` at z (t = 0): ImageJ hyperstacks interleave channels (czt order), OME
  // follows DimensionOrder.
  int64_t z_count = static_cast<int64_t>(pages.size()), page_channels = 1;
  std::function<int64_t(int64_t z, int64_t c)> page_of = [](int64_t z, int64_t) { return z; };
  const bool imagej = desc.rfind("ImageJ=", 0) == 0;
  const bool ome = !imagej && desc.find("<OME") != std::string::npos;
  // In a folder of slices each file's description speaks of that file: only its calibration counts.
  if (imagej) {
    int64_t nc = 1, nz = 0, nt = 1;
    double v = 0;
    if (auto c = imagej_value(desc, "channels"); !c.empty()) text::parse_int(c, nc);
    if (auto z = imagej_value(desc, "slices"); !z.empty()) text::parse_int(z, nz);
    if (auto t = imagej_value(desc, "frames"); !t.empty()) text::parse_int(t, nt);
    if (nz <= 0) nz = static_cast<int64_t>(pages.size()) / std::max<int64_t>(nc * nt, 1);
    if (nt > 1 && nz == 1) {  // a time series of 2D images: read the frames as z (as ImageJ shows them)
      nz = nt;
      nt = 1;
    }
    if (nt > 1 && !folder)
      throw InputError(path.string() + ": an ImageJ hyperstack of " + std::to_string(nt) +
                       " time frames; Skelflow reads one 3D volume (save one frame as its own file)");
    if (!folder && nc >= 1 && nz >= 1 && nc * nz <= static_cast<int64_t>(pages.size())) {
      z_count = nz;
      page_channels = nc;
      page_of = [nc](int64_t z, int64_t c) { return z * nc + c; };
    }
    const std::string unit = canonical_unit(imagej_value(desc, "unit"));
    float xr = 0, yr = 0;
    TiffPtr t0 = open_tiff(s.files[0]);
    if (!unit.empty()) {
      g.unit = unit;
      h.has_unit = true;
      if (TIFFGetField(t0.get(), TIFFTAG_XRESOLUTION, &xr) && xr > 0) g.spacing[0] = 1.0 / xr;
      if (TIFFGetField(t0.get(), TIFFTAG_YRESOLUTION, &yr) && yr > 0) g.spacing[1] = 1.0 / yr;
      if (auto sp = imagej_value(desc, "spacing"); !sp.empty() && text::parse_double(sp, v) && v > 0) g.spacing[2] = v;
      h.has_spacing = true;
      for (int k = 0; k < 3; ++k) {
        const char* key = k == 0 ? "xorigin" : k == 1 ? "yorigin" : "zorigin";
        if (auto org = imagej_value(desc, key); !org.empty() && text::parse_double(org, v)) {
          g.origin[static_cast<size_t>(k)] = -v * g.spacing[static_cast<size_t>(k)];  // ImageJ: in pixels
          h.has_origin = true;
        }
      }
    }
    h.details.push_back("metadata: ImageJ" + (nc > 1 ? ", " + std::to_string(nc) + " channels" : std::string()));
  } else if (ome) {
    const auto a = ome_pixels(desc);
    auto num = [&](const char* k, double& out) {
      auto it = a.find(k);
      return it != a.end() && text::parse_double(it->second, out);
    };
    double sx = 0, sy = 0, sz = 0, zc = 0, cc = 0, tc = 0;
    if (num("SizeZ", zc) && num("SizeC", cc) && num("SizeT", tc)) {
      const auto nz = static_cast<int64_t>(zc), nc = static_cast<int64_t>(cc), nt = static_cast<int64_t>(tc);
      std::string order = a.count("DimensionOrder") ? a.at("DimensionOrder") : "XYZCT";
      // RGB samples in one page count in SizeC but not in the pages.
      const int64_t pc = nc % f.spp == 0 ? nc / f.spp : nc;
      if (!folder && nz >= 1 && pc >= 1 && nz * pc <= static_cast<int64_t>(pages.size()) && order.size() == 5) {
        int64_t stride_z = 1, stride_c = 1, stride = 1;
        for (char d : order.substr(2)) {
          if (d == 'Z') stride_z = stride, stride *= nz;
          else if (d == 'C') stride_c = stride, stride *= pc;
          else if (d == 'T') stride *= nt;
        }
        z_count = nz;
        page_channels = pc;
        page_of = [stride_z, stride_c](int64_t z, int64_t c) { return z * stride_z + c * stride_c; };
      }
    }
    auto unit_of = [&](const char* k) {
      auto it = a.find(k);
      return it == a.end() ? std::string(kMicrometre) : canonical_unit(it->second);  // OME's default: µm
    };
    bool any = false;
    if (num("PhysicalSizeX", sx) && sx > 0) g.spacing[0] = sx, any = true;
    if (num("PhysicalSizeY", sy) && sy > 0) g.spacing[1] = sy, any = true;
    if (num("PhysicalSizeZ", sz) && sz > 0) g.spacing[2] = sz, any = true;
    if (any) {
      const std::string ux = unit_of("PhysicalSizeXUnit"), uy = unit_of("PhysicalSizeYUnit"), uz = unit_of("PhysicalSizeZUnit");
      if (ux != uy || (sz > 0 && ux != uz))
        throw InputError(path.string() + ": OME PhysicalSize units differ between axes (" + ux + ", " + uy + ", " + uz +
                         "); set `spacing` and `unit` to read it");
      g.unit = ux.empty() ? std::string(kDefaultUnit) : ux;
      h.has_spacing = true;
      h.has_unit = !ux.empty();
    }
    h.details.push_back("metadata: OME-TIFF" + (page_channels > 1 ? ", " + std::to_string(page_channels) + " channels" : std::string()));
  }
  if (page_channels > 1) channels = page_channels;
  if (page_channels > 1 && f.spp > 1)
    throw InputError(path.string() + ": both " + std::to_string(page_channels) + " channel pages and " +
                     std::to_string(f.spp) + " samples per pixel; Skelflow reads one channel of one of them");
  if (channels > 1) {
    if (o.channel < 0)
      throw InputError(path.string() + ": " + std::to_string(channels) +
                       (f.spp > 1 ? " samples per pixel (RGB or multi-channel)" : " channels") +
                       "; set the parameter `channel` (0.." + std::to_string(channels - 1) + ") to read one");
    if (o.channel >= channels)
      throw InputError(path.string() + ": channel " + std::to_string(o.channel) + " asked, the file has " +
                       std::to_string(channels) + " (0.." + std::to_string(channels - 1) + ")");
  }
  const int64_t c = std::max(o.channel, 0);
  if (f.spp > 1) s.sample = static_cast<uint16_t>(c);
  for (int64_t z = 0; z < z_count; ++z) s.slices.push_back(pages[static_cast<size_t>(page_of(z, page_channels > 1 ? c : 0))]);
  g.dims[2] = z_count;
  h.dtype = stored_name(f.stored);
  h.details.push_back(std::string(folder ? "files: " + std::to_string(s.files.size()) + ", " : "") + pages_word(pages.size()) +
                      ", " + (f.tiled ? "tiles " + std::to_string(f.tile_w) + "x" + std::to_string(f.tile_h)
                                      : "strips of " + std::to_string(f.rows_per_strip) + " rows") +
                      ", compression " + compression_name(f.compression) +
                      (f.spp > 1 ? ", " + std::to_string(f.spp) + " samples per pixel" : std::string()));
  {
    TiffPtr t0 = open_tiff(s.files[0]);
    if (TIFFIsBigEndian(t0.get())) h.details.push_back("byte order: big-endian");
    if (TIFFIsBigTIFF(t0.get())) h.details.push_back("BigTIFF");
  }
  return s;
}

// ------------------------------------------------------------------ reading boxes
template <class T, class S>
void copy_row(T* dst, const unsigned char* src, int64_t n, int64_t step) {
  for (int64_t i = 0; i < n; ++i) {
    S v;
    std::memcpy(&v, src + i * step * static_cast<int64_t>(sizeof(S)), sizeof(S));
    dst[i] = static_cast<T>(v);
  }
}

template <class T>
Volume<T> read_stack_box(const Stack& s, Dims begin, Dims size) {
  const PageFormat& f = s.format;
  Grid g = s.header.grid;
  g.dims = size;
  for (size_t k = 0; k < 3; ++k) g.origin[k] += static_cast<double>(begin[k]) * g.spacing[k];
  Volume<T> v = Volume<T>::uninitialized(g);
  const int64_t bps = f.bits / 8;
  const bool contig = f.planar == PLANARCONFIG_CONTIG;
  const int64_t step = contig ? f.spp : 1;                          // samples between pixels
  const int64_t first = contig ? s.sample : 0;                      // sample offset in a pixel
  const uint16_t plane = contig ? 0 : s.sample;                     // plane of separate planes
  TiffPtr t;
  size_t open_file = SIZE_MAX;
  int64_t current = -1;  // the page libtiff is on
  std::vector<unsigned char> buf;
  for (int64_t z = 0; z < size[2]; ++z) {
    const Slice& sl = s.slices[static_cast<size_t>(begin[2] + z)];
    const fs::path& file = s.files[sl.file];
    if (sl.file != open_file) {
      t = open_tiff(file);
      open_file = sl.file;
      current = 0;
    }
    // Forward by the next-page links (TIFFSetDirectory walks the chain from the first page).
    bool ok = true;
    if (static_cast<int64_t>(sl.page) > current && static_cast<int64_t>(sl.page) - current < 64) {
      while (ok && current < static_cast<int64_t>(sl.page)) {
        ok = TIFFReadDirectory(t.get()) != 0;
        ++current;
      }
    } else if (static_cast<int64_t>(sl.page) != current) {
      ok = TIFFSetDirectory(t.get(), sl.page) != 0;
      current = sl.page;
    }
    if (!ok) throw InputError(show(file) + ": cannot read page " + std::to_string(sl.page) + tiff_reason());
    // The page's own tiles or strips: they may differ from the first page's (same_layout compares
    // the voxels only) and decide the layout of what libtiff decodes.
    const PageFormat pf = page_format(t.get(), file, sl.page);
    if (!pf.same_layout(f))
      throw InputError(show(file) + ": page " + std::to_string(sl.page) + " changed size or type");
    const std::string where = show(file) + ": page " + std::to_string(sl.page) + ": ";
    with_stored(f.stored, [&](auto tag) {
      using S = decltype(tag);
      if (!pf.tiled) {
        buf.resize(static_cast<size_t>(TIFFStripSize(t.get())));
        const int64_t rps = pf.rows_per_strip;
        const int64_t row_bytes = f.width * bps * step;
        for (int64_t s0 = begin[1] / rps; s0 * rps < begin[1] + size[1]; ++s0) {
          const uint32_t strip = TIFFComputeStrip(t.get(), static_cast<uint32_t>(s0 * rps), plane);
          const tmsize_t got = TIFFReadEncodedStrip(t.get(), strip, buf.data(), static_cast<tmsize_t>(buf.size()));
          if (got < 0) throw InputError(where + "cannot decode strip " + std::to_string(strip) + ": the file is truncated or corrupt" + tiff_reason());
          const int64_t y0 = std::max(begin[1], s0 * rps), y1 = std::min(begin[1] + size[1], (s0 + 1) * rps);
          for (int64_t y = y0; y < y1; ++y) {
            const int64_t off = (y - s0 * rps) * row_bytes + (begin[0] * step + first) * bps;
            if (off + ((size[0] - 1) * step + 1) * bps > got)
              throw InputError(where + "strip " + std::to_string(strip) + " is shorter than its rows: the file is truncated or corrupt");
            copy_row<T, S>(&v(0, y - begin[1], z), buf.data() + off, size[0], step);
          }
        }
      } else {
        buf.resize(static_cast<size_t>(TIFFTileSize(t.get())));
        const int64_t tw = pf.tile_w, th = pf.tile_h;
        const int64_t row_bytes = tw * bps * step;
        for (int64_t ty = begin[1] / th; ty * th < begin[1] + size[1]; ++ty)
          for (int64_t tx = begin[0] / tw; tx * tw < begin[0] + size[0]; ++tx) {
            const uint32_t tile = TIFFComputeTile(t.get(), static_cast<uint32_t>(tx * tw), static_cast<uint32_t>(ty * th), 0, plane);
            const tmsize_t got = TIFFReadEncodedTile(t.get(), tile, buf.data(), static_cast<tmsize_t>(buf.size()));
            if (got < 0) throw InputError(where + "cannot decode tile " + std::to_string(tile) + ": the file is truncated or corrupt" + tiff_reason());
            const int64_t y0 = std::max(begin[1], ty * th), y1 = std::min(begin[1] + size[1], (ty + 1) * th);
            const int64_t x0 = std::max(begin[0], tx * tw), x1 = std::min(begin[0] + size[0], (tx + 1) * tw);
            for (int64_t y = y0; y < y1; ++y) {
              const int64_t off = (y - ty * th) * row_bytes + ((x0 - tx * tw) * step + first) * bps;
              if (off + ((x1 - x0 - 1) * step + 1) * bps > got)
                throw InputError(where + "tile " + std::to_string(tile) + " is shorter than its rows: the file is truncated or corrupt");
              copy_row<T, S>(&v(x0 - begin[0], y - begin[1], z), buf.data() + off, x1 - x0, step);
            }
          }
      }
    });
  }
  return v;
}

DataPtr read_box_any(const Stack& s, Dims begin, Dims size) {
  switch (s.format.stored) {
    case Stored::u8: return std::make_shared<VolumeU8>(read_stack_box<uint8_t>(s, begin, size));
    case Stored::u16: return std::make_shared<VolumeU16>(read_stack_box<uint16_t>(s, begin, size));
    case Stored::u32: return std::make_shared<VolumeU32>(read_stack_box<uint32_t>(s, begin, size));
    case Stored::u64: return std::make_shared<VolumeU64>(read_stack_box<uint64_t>(s, begin, size));
    case Stored::i8:
    case Stored::i16:
    case Stored::i32: return std::make_shared<VolumeI32>(read_stack_box<int32_t>(s, begin, size));
    case Stored::f32: return std::make_shared<VolumeF32>(read_stack_box<float>(s, begin, size));
    case Stored::i64:
    case Stored::f64: return std::make_shared<VolumeF64>(read_stack_box<double>(s, begin, size));
  }
  return nullptr;
}

// ------------------------------------------------------------------ writing
template <class T> constexpr uint16_t sample_format_of() {
  if constexpr (std::is_floating_point_v<T>) return SAMPLEFORMAT_IEEEFP;
  else if constexpr (std::is_signed_v<T>) return SAMPLEFORMAT_INT;
  else return SAMPLEFORMAT_UINT;
}

// ImageJ writes non-ASCII characters of its description as \uXXXX.
std::string imagej_escape(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      out += static_cast<char>(c);
      ++i;
      continue;
    }
    unsigned cp = 0;
    int n = 0;
    if ((c & 0xE0) == 0xC0) cp = c & 0x1F, n = 1;
    else if ((c & 0xF0) == 0xE0) cp = c & 0x0F, n = 2;
    else cp = '?', n = 0;
    for (int k = 1; k <= n && i + static_cast<size_t>(k) < s.size(); ++k) cp = (cp << 6) | (static_cast<unsigned char>(s[i + static_cast<size_t>(k)]) & 0x3F);
    char buf[8];
    std::snprintf(buf, sizeof buf, "\\u%04X", cp & 0xFFFF);
    out += buf;
    i += static_cast<size_t>(n) + 1;
  }
  return out;
}

// Writes a stack of g.dims[2] pages; `page(z)` gives slice z (x fastest), asked for in z order.
template <class T>
void write_tiff_pages(const fs::path& path, const Grid& g, const VolumeWriteOptions& o,
                      const std::function<const T*(int64_t z)>& page) {
  install_handlers();
  {
    if (g.voxel_count() == 0) throw InputError(show(path) + ": cannot write an empty volume as TIFF");
    if (g.direction != kIdentityDirection)
      throw InputError(show(path) + ": TIFF cannot store the volume's direction cosines; write .nrrd, .mha or .nii");
    if (g.dims[0] > 0xFFFFFFFFll || g.dims[1] > 0xFFFFFFFFll || g.dims[2] > 0xFFFFll * 0xFFFF)
      throw InputError(show(path) + ": too large for TIFF");
    const uint64_t bytes = static_cast<uint64_t>(g.voxel_count()) * sizeof(T);
    const bool big = bytes + (64ull << 20) > (4ull << 30);
    // ImageJ calibration: spacing x/y as resolution (pixels per unit), z, unit and origin (in pixels) in
    // the description.
    std::string desc = "ImageJ=1.11a\nimages=" + std::to_string(g.dims[2]) + "\nslices=" + std::to_string(g.dims[2]) +
                       "\nunit=" + (g.unit == kMicrometre ? std::string("micron") : imagej_escape(g.unit)) +
                       "\nspacing=" + text::format_double(g.spacing[2], 17) + "\nloop=false\n";
    for (size_t k = 0; k < 3; ++k)
      if (g.origin[k] != 0)
        desc += std::string(k == 0 ? "xorigin=" : k == 1 ? "yorigin=" : "zorigin=") +
                text::format_double(-g.origin[k] / g.spacing[k], 17) + "\n";
    // A name ending in .ome.tif(f) gets OME-XML instead (one image, one channel, planes in z order).
    const std::string lname = text::to_lower(display_path(path).filename().string());
    if (lname.size() > 8 && (lname.ends_with(".ome.tif") || lname.ends_with(".ome.tiff"))) {
      const char* type = std::is_same_v<T, uint8_t> ? "uint8" : std::is_same_v<T, uint16_t> ? "uint16"
                       : std::is_same_v<T, uint32_t> ? "uint32" : std::is_same_v<T, int32_t> ? "int32"
                       : std::is_same_v<T, float> ? "float" : std::is_same_v<T, double> ? "double" : nullptr;
      if (!type) throw InputError(show(path) + ": OME-TIFF has no " + std::string(VoxelTraits<T>::name) + " pixels; write .tif");
      auto num = [](double x) { return text::format_double(x, 17); };
      std::string xml_unit;
      for (char ch : g.unit) xml_unit += ch == '"' ? std::string("&quot;") : ch == '&' ? std::string("&amp;") : ch == '<' ? std::string("&lt;") : std::string(1, ch);
      desc = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>"
             "<OME xmlns=\"http://www.openmicroscopy.org/Schemas/OME/2016-06\" Creator=\"Skelflow\">"
             "<Image ID=\"Image:0\"><Pixels ID=\"Pixels:0\" DimensionOrder=\"XYZCT\" Type=\"" + std::string(type) +
             "\" SizeX=\"" + std::to_string(g.dims[0]) + "\" SizeY=\"" + std::to_string(g.dims[1]) + "\" SizeZ=\"" +
             std::to_string(g.dims[2]) + "\" SizeC=\"1\" SizeT=\"1\" PhysicalSizeX=\"" + num(g.spacing[0]) +
             "\" PhysicalSizeXUnit=\"" + xml_unit + "\" PhysicalSizeY=\"" + num(g.spacing[1]) + "\" PhysicalSizeYUnit=\"" +
             xml_unit + "\" PhysicalSizeZ=\"" + num(g.spacing[2]) + "\" PhysicalSizeZUnit=\"" + xml_unit +
             "\"><Channel ID=\"Channel:0:0\" SamplesPerPixel=\"1\"/><TiffData IFD=\"0\" PlaneCount=\"" +
             std::to_string(g.dims[2]) + "\"/></Pixels></Image></OME>";
    }
    write_atomically(path, [&](const fs::path& tmp) {
      g_tiff_error.clear();
      TiffPtr t(TIFFOpen(tmp.c_str(), big ? "w8" : "w"));
      if (!t) throw Error("cannot write " + show(path) + ": cannot create the file" + tiff_reason());
      const auto fail = [&](const std::string& what) {
        throw Error("cannot write " + show(path) + ": " + what + tiff_reason());
      };
      const int64_t row_bytes = g.dims[0] * static_cast<int64_t>(sizeof(T));
      const auto rows = static_cast<uint32_t>(std::clamp<int64_t>((256 << 10) / std::max<int64_t>(row_bytes, 1), 1, g.dims[1]));
      for (int64_t z = 0; z < g.dims[2]; ++z) {
        TIFF* tf = t.get();
        TIFFSetField(tf, TIFFTAG_SUBFILETYPE, FILETYPE_PAGE);
        TIFFSetField(tf, TIFFTAG_IMAGEWIDTH, static_cast<uint32_t>(g.dims[0]));
        TIFFSetField(tf, TIFFTAG_IMAGELENGTH, static_cast<uint32_t>(g.dims[1]));
        TIFFSetField(tf, TIFFTAG_BITSPERSAMPLE, static_cast<uint16_t>(sizeof(T) * 8));
        TIFFSetField(tf, TIFFTAG_SAMPLEFORMAT, sample_format_of<T>());
        TIFFSetField(tf, TIFFTAG_SAMPLESPERPIXEL, static_cast<uint16_t>(1));
        TIFFSetField(tf, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        TIFFSetField(tf, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(tf, TIFFTAG_ROWSPERSTRIP, rows);
        TIFFSetField(tf, TIFFTAG_XRESOLUTION, static_cast<float>(1.0 / g.spacing[0]));
        TIFFSetField(tf, TIFFTAG_YRESOLUTION, static_cast<float>(1.0 / g.spacing[1]));
        TIFFSetField(tf, TIFFTAG_RESOLUTIONUNIT, RESUNIT_NONE);
        if (o.compression > 0) {
          TIFFSetField(tf, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
          TIFFSetField(tf, TIFFTAG_ZIPQUALITY, std::clamp(o.compression, 1, 9));
        } else {
          TIFFSetField(tf, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
        }
        if (z == 0) TIFFSetField(tf, TIFFTAG_IMAGEDESCRIPTION, desc.c_str());
        const T* slice = page(z);
        for (int64_t y = 0, strip = 0; y < g.dims[1]; y += rows, ++strip) {
          const int64_t n = std::min<int64_t>(rows, g.dims[1] - y);
          auto* p = const_cast<T*>(slice + y * g.dims[0]);  // libtiff's API is not const; it does not write the buffer
          if (TIFFWriteEncodedStrip(tf, static_cast<uint32_t>(strip), p, static_cast<tmsize_t>(n * row_bytes)) < 0)
            fail("page " + std::to_string(z));
        }
        if (!TIFFWriteDirectory(tf)) fail("page " + std::to_string(z));
      }
      TIFF* raw = t.release();
      TIFFFlush(raw);
      const bool flush_error = !g_tiff_error.empty();
      TIFFClose(raw);
      if (flush_error) fail("closing the file");
    });
  }
}

void write_tiff(const fs::path& path, const DataObject& data, const VolumeWriteOptions& o) {
  visit_volume(data, "volume", [&](const auto& v) {
    using T = typename std::decay_t<decltype(v)>::value_type;
    write_tiff_pages<T>(path, v.grid(), o, [&](int64_t z) { return &v(0, 0, z); });
  });
}

// write_tiff of a volume given box by box: slabs of whole slices (as many as the source's
// max_box_bytes holds, a multiple of 32 when more), one slab in memory at a time.
void write_tiff_boxes(const fs::path& path, const VolumeBoxSource& source, const VolumeWriteOptions& o) {
  visit_voxel_type(source.type_id, show(path), [&](auto t) {
    using T = decltype(t);
    const Dims n = source.grid.dims;
    int64_t depth = units_per_box(source, static_cast<uint64_t>(n[0] * n[1]) * sizeof(T), n[2]);
    if (depth > 32) depth -= depth % 32;  // whole chunks of the scratch files (32 deep)
    std::shared_ptr<const Volume<T>> slab;
    int64_t z0 = 0;
    write_tiff_pages<T>(path, source.grid, o, [&](int64_t z) {
      if (!slab || z >= z0 + slab->nz()) {
        slab.reset();  // one slab at a time
        z0 = z;
        const Dims size{n[0], n[1], std::min(depth, n[2] - z)};
        slab = std::dynamic_pointer_cast<const Volume<T>>(source.read(Dims{0, 0, z}, size));
        if (!slab || slab->dims() != size) throw Error(show(path) + ": the volume's box reader gave a wrong box");
      }
      return &(*slab)(0, 0, z - z0);
    });
  });
}

}  // namespace

VolumeFormat tiff_volume_format() {
  VolumeFormat f;
  f.name = "TIFF";
  f.extensions = {".tif", ".tiff", ".btf", ".tf8", ".ome.tif", ".ome.tiff"};
  f.slice_folders = true;
  f.sniff = [](std::string_view h) {
    return h.size() >= 4 && (h.substr(0, 4) == std::string_view("II*\0", 4) || h.substr(0, 4) == std::string_view("MM\0*", 4) ||
                             h.substr(0, 4) == std::string_view("II+\0", 4) || h.substr(0, 4) == std::string_view("MM\0+", 4));
  };
  f.read_header = [](const fs::path& p, const VolumeReadOptions& o) { return open_stack(p, o).header; };
  f.read = [](const fs::path& p, const VolumeReadOptions& o) {
    const Stack s = open_stack(p, o);
    return read_box_any(s, Dims{0, 0, 0}, s.header.grid.dims);
  };
  f.read_box = [](const fs::path& p, const VolumeReadOptions& o, Dims begin, Dims size) {
    return read_box_any(open_stack(p, o), begin, size);
  };
  f.write = write_tiff;
  f.write_boxes = write_tiff_boxes;
  return f;
}

}  // namespace skel::io
