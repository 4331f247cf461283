// NIfTI-1 volumes: `.nii` and `.nii.gz` (single file, magic "n+1"), read through zlib's gz* API (a
// plain .nii reads the same way). Read: both byte orders; datatypes uint8, int8, int16, uint16,
// int32, uint32, int64, uint64, float32, float64; dims of up to 3 axes (a 4th of size 1); pixdim;
// xyzt_units -> unit (m, mm, µm; unknown: the default unit); scl_slope/scl_inter applied (the volume
// is then float32) unless they are 0/NaN or 1 and 0.
// Orientation: the sform when sform_code > 0, else the qform when qform_code > 0, else pixdim only.
// Coordinates are NIfTI's RAS+ world coordinates as stored (no flip to ITK's LPS): origin = the
// affine's translation, spacing = the length of its columns, direction = the normalised columns.
// Write: sform and qform (code 1, scanner) from spacing, origin and direction, xyzt_units from the
// unit (a unit NIfTI-1 cannot name is an error), vox_offset 352, `.nii.gz` gzip-compressed at the
// write options' level.
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <bit>
#include <cmath>
#include <cstring>
#include <memory>

#include "io/volume_bytes.hpp"
#include "io/volume_format.hpp"
#include "skel/error.hpp"
#include "skel/fs.hpp"
#include "skel/text.hpp"

namespace skel::io {

namespace {

namespace fs = std::filesystem;

constexpr size_t kHeader = 348;

struct Gz {
  gzFile f = nullptr;
  explicit Gz(const fs::path& p, const char* mode) : f(gzopen(p.c_str(), mode)) {}
  ~Gz() {
    if (f) gzclose(f);
  }
  Gz(const Gz&) = delete;
  Gz& operator=(const Gz&) = delete;
};

// Reads n bytes; returns how many arrived.
uint64_t gz_read(gzFile f, char* dst, uint64_t n) {
  uint64_t done = 0;
  while (done < n) {
    const auto chunk = static_cast<unsigned>(std::min<uint64_t>(n - done, 1u << 30));
    const int r = gzread(f, dst + done, chunk);
    if (r <= 0) break;
    done += static_cast<uint64_t>(r);
  }
  return done;
}

struct NiftiHeader {
  VolumeHeader header;
  std::string stored;  // datatype as stored
  bool big_endian = false;
  uint64_t vox_offset = 352;
  double slope = 1, inter = 0;
  bool scaled = false;
};

class Bytes {
public:
  Bytes(const char* p, bool swap) : p_(p), swap_(swap) {}
  template <class T>
  T get(size_t offset) const {
    char b[sizeof(T)];
    std::memcpy(b, p_ + offset, sizeof(T));
    if (swap_) std::reverse(b, b + sizeof(T));
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  }

private:
  const char* p_;
  bool swap_;
};

std::string datatype_name(int code) {
  switch (code) {
    case 2: return "uint8";
    case 4: return "int16";
    case 8: return "int32";
    case 16: return "float32";
    case 64: return "float64";
    case 256: return "int8";
    case 512: return "uint16";
    case 768: return "uint32";
    case 1024: return "int64";
    case 1280: return "uint64";
    default: return {};
  }
}

int datatype_code(const std::string& t) {
  if (t == "uint8") return 2;
  if (t == "int32") return 8;
  if (t == "float32") return 16;
  if (t == "float64") return 64;
  if (t == "uint16") return 512;
  if (t == "uint32") return 768;
  if (t == "uint64") return 1280;
  throw Error("NIfTI: no datatype code for " + t);
}

bool is_gz(const fs::path& p) { return text::to_lower(p.filename().string()).ends_with(".gz"); }

NiftiHeader parse_header(const fs::path& path) {
  const std::string file = path.string();
  if (!fs::exists(path)) throw InputError(file + ": cannot read: No such file or directory");
  Gz gz(path, "rb");
  if (!gz.f) throw InputError(file + ": cannot read");
  char raw[kHeader];
  const uint64_t got = gz_read(gz.f, raw, kHeader);
  if (got < kHeader)
    throw InputError(file + ": the NIfTI header needs 348 bytes but the " + (is_gz(path) ? "decompressed " : "") + "file has only " +
                     std::to_string(got) + " (truncated, or not a NIfTI file)");
  int32_t sizeof_hdr = 0;
  std::memcpy(&sizeof_hdr, raw, 4);
  bool swap = false;
  if (sizeof_hdr != 348) {
    uint32_t u = 0;
    std::memcpy(&u, raw, 4);
    u = (u >> 24) | ((u >> 8) & 0xff00u) | ((u << 8) & 0xff0000u) | (u << 24);
    const auto swapped = static_cast<int32_t>(u);
    if (swapped == 348) swap = true;
    else if (sizeof_hdr == 540 || swapped == 540)
      throw InputError(file + ": a NIfTI-2 file; Skelflow reads NIfTI-1");
    else
      throw InputError(file + ": not a NIfTI-1 file (sizeof_hdr is " + std::to_string(sizeof_hdr) + ", not 348)");
  }
  const Bytes b(raw, swap);
  NiftiHeader n;
  n.big_endian = swap != (std::endian::native == std::endian::big);
  if (std::memcmp(raw + 344, "n+1\0", 4) != 0) {
    if (std::memcmp(raw + 344, "ni1\0", 4) == 0)
      throw InputError(file + ": a NIfTI header of a .hdr/.img pair (magic 'ni1'); Skelflow reads single-file .nii");
    throw InputError(file + ": not a NIfTI-1 file (magic is not 'n+1')");
  }
  const int16_t ndim = b.get<int16_t>(40);
  if (ndim < 1 || ndim > 7) throw InputError(file + ": NIfTI dim[0] is " + std::to_string(ndim) + " (1 to 7)");
  Dims dims{1, 1, 1};
  for (int i = 1; i <= ndim; ++i) {
    const int16_t d = b.get<int16_t>(40 + 2 * static_cast<size_t>(i));
    if (d < 1) throw InputError(file + ": NIfTI dim[" + std::to_string(i) + "] is " + std::to_string(d) + " (must be >= 1)");
    if (i <= 3) dims[static_cast<size_t>(i - 1)] = d;
    else if (d != 1)
      throw InputError(file + ": NIfTI dim[" + std::to_string(i) + "] is " + std::to_string(d) +
                       ": a series of volumes; Skelflow reads one 3D volume");
  }
  const int16_t dt = b.get<int16_t>(70);
  n.stored = datatype_name(dt);
  if (n.stored.empty())
    throw InputError(file + ": unsupported NIfTI datatype " + std::to_string(dt) +
                     " (uint8, int8, int16, uint16, int32, uint32, int64, uint64, float32, float64)");
  const int16_t bitpix = b.get<int16_t>(72);
  if (bitpix != static_cast<int16_t>(8 * volbytes::dtype_bytes(n.stored)))
    throw InputError(file + ": NIfTI bitpix " + std::to_string(bitpix) + " does not match datatype " + n.stored);
  float pixdim[8];
  for (size_t i = 0; i < 8; ++i) pixdim[i] = b.get<float>(76 + 4 * i);
  const float vox = b.get<float>(108);
  if (!(vox >= 348) || vox != std::floor(vox) || vox > 1e12)
    throw InputError(file + ": NIfTI vox_offset " + text::format_double(vox, 9) + " is not a byte offset >= 348");
  n.vox_offset = static_cast<uint64_t>(vox);
  const float slope = b.get<float>(112), inter = b.get<float>(116);
  if (std::isfinite(slope) && slope != 0 && !(slope == 1 && (inter == 0 || !std::isfinite(inter)))) {
    n.scaled = true;
    n.slope = slope;
    n.inter = std::isfinite(inter) ? inter : 0.0;
  }
  VolumeHeader& h = n.header;
  Grid& g = h.grid;
  g.dims = dims;
  switch (static_cast<unsigned char>(raw[123]) & 0x07) {
    case 1: g.unit = "m"; h.has_unit = true; break;
    case 2: g.unit = "mm"; h.has_unit = true; break;
    case 3: g.unit = kDefaultUnit; h.has_unit = true; break;
    default: break;
  }
  const int16_t qcode = b.get<int16_t>(252), scode = b.get<int16_t>(254);
  auto pix = [&](size_t i) {
    const double p = std::abs(static_cast<double>(pixdim[i]));
    return p > 0 && std::isfinite(p) ? p : 1.0;
  };
  if (scode > 0) {
    double m[3][4];
    for (size_t r = 0; r < 3; ++r)
      for (size_t c = 0; c < 4; ++c) m[r][c] = b.get<float>(280 + 16 * r + 4 * c);
    std::array<Vec3, 3> axes;
    for (size_t k = 0; k < 3; ++k) axes[k] = {m[0][k], m[1][k], m[2][k]};
    if (!volbytes::split_axes(axes, g.spacing, g.direction))
      throw InputError(file + ": the NIfTI sform has a column of length 0 (sform_code " + std::to_string(scode) + ")");
    g.origin = {m[0][3], m[1][3], m[2][3]};
    h.details.push_back("orientation: sform (code " + std::to_string(scode) + "), RAS+ as stored");
  } else if (qcode > 0) {
    const double qb = b.get<float>(256), qc = b.get<float>(260), qd = b.get<float>(264);
    double qa = 1.0 - (qb * qb + qc * qc + qd * qd);
    double B = qb, C = qc, D = qd;
    if (qa < 1e-7) {  // numerically a 180-degree rotation: normalise (b, c, d)
      const double s = std::sqrt(qb * qb + qc * qc + qd * qd);
      B /= s, C /= s, D /= s;
      qa = 0;
    } else {
      qa = std::sqrt(qa);
    }
    const double a = qa;
    const double R[3][3] = {{a * a + B * B - C * C - D * D, 2 * B * C - 2 * a * D, 2 * B * D + 2 * a * C},
                            {2 * B * C + 2 * a * D, a * a + C * C - B * B - D * D, 2 * C * D - 2 * a * B},
                            {2 * B * D - 2 * a * C, 2 * C * D + 2 * a * B, a * a + D * D - C * C - B * B}};
    const double qfac = pixdim[0] < 0 ? -1.0 : 1.0;
    std::array<Vec3, 3> axes;
    for (size_t k = 0; k < 3; ++k) {
      const double s = pix(k + 1) * (k == 2 ? qfac : 1.0);
      axes[k] = {R[0][k] * s, R[1][k] * s, R[2][k] * s};
    }
    volbytes::split_axes(axes, g.spacing, g.direction);
    g.spacing = {pix(1), pix(2), pix(3)};  // exactly pixdim (the split only rounds them)
    g.origin = {b.get<float>(268), b.get<float>(272), b.get<float>(276)};
    h.details.push_back("orientation: qform (code " + std::to_string(qcode) + "), RAS+ as stored");
  } else {
    g.spacing = {pix(1), pix(2), pix(3)};
    h.details.push_back("orientation: none (sform_code and qform_code 0): pixdim only");
  }
  h.has_spacing = true;
  h.has_origin = scode > 0 || qcode > 0;
  for (double o : g.origin)
    if (!std::isfinite(o)) throw InputError(file + ": the NIfTI origin is not finite");
  h.dtype = n.scaled ? "float32" : n.stored;
  h.details.push_back("datatype: " + n.stored + (volbytes::dtype_bytes(n.stored) > 1 ? (swap ? " (byte-swapped)" : "") : ""));
  if (n.scaled)
    h.details.push_back("scaling: value * " + text::format_double(n.slope, 9) + " + " + text::format_double(n.inter, 9) +
                        " (read as float32)");
  char descrip[81] = {};
  std::memcpy(descrip, raw + 148, 80);
  if (descrip[0]) h.details.push_back("descrip: " + std::string(descrip));
  if (is_gz(path)) h.details.push_back("compression: gzip");
  return n;
}

DataPtr read_nifti(const fs::path& path, const VolumeReadOptions&) {
  const NiftiHeader n = parse_header(path);
  const std::string file = path.string();
  const uint64_t need = volbytes::checked_bytes(file, n.header.grid.dims, volbytes::dtype_bytes(n.stored));
  const uint64_t size = volbytes::file_size(path);
  const bool gz = is_gz(path);
  if (gz) volbytes::check_compressed(file, size, need + n.vox_offset, "the NIfTI data");
  else volbytes::check_available(file, size > n.vox_offset ? size - n.vox_offset : 0, need, "the voxel data");
  Gz in(path, "rb");
  if (!in.f) throw InputError(file + ": cannot read");
  gzbuffer(in.f, 1 << 20);
  if (gzseek(in.f, static_cast<z_off_t>(n.vox_offset), SEEK_SET) < 0)
    throw InputError(file + ": the data at vox_offset " + std::to_string(n.vox_offset) + " cannot be reached (truncated)");
  DataPtr v = volbytes::decode(n.header.grid, n.stored, n.big_endian, [&](char* dst, uint64_t bytes) {
    const uint64_t got = gz_read(in.f, dst, bytes);
    if (got < bytes) {
      int err = 0;
      const char* msg = gzerror(in.f, &err);
      throw InputError(file + ": the voxel data ends after " + std::to_string(got) + " of " + std::to_string(bytes) +
                       " bytes (" + (err != Z_OK && err != Z_BUF_ERROR && msg ? std::string("corrupt: ") + msg : "truncated") + ")");
    }
  });
  if (!n.scaled) return v;
  auto out = std::make_shared<VolumeF32>(convert_volume<float>(*v, file));
  for (float& x : *out) x = static_cast<float>(x * n.slope + n.inter);
  return out;
}

// Quaternion (b, c, d) and qfac of a rotation matrix (columns = axis directions).
void to_quaternion(const Direction& dir, double& qb, double& qc, double& qd, double& qfac) {
  double r[3][3];
  for (size_t i = 0; i < 3; ++i)
    for (size_t j = 0; j < 3; ++j) r[i][j] = dir[i * 3 + j];
  const double det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
                     r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
  qfac = det < 0 ? -1.0 : 1.0;
  if (qfac < 0)
    for (auto& row : r) row[2] = -row[2];
  double a = r[0][0] + r[1][1] + r[2][2] + 1.0, b = 0, c = 0, d = 0;
  if (a > 0.5) {
    a = 0.5 * std::sqrt(a);
    b = 0.25 * (r[2][1] - r[1][2]) / a;
    c = 0.25 * (r[0][2] - r[2][0]) / a;
    d = 0.25 * (r[1][0] - r[0][1]) / a;
  } else {
    const double xd = 1.0 + r[0][0] - (r[1][1] + r[2][2]);
    const double yd = 1.0 + r[1][1] - (r[0][0] + r[2][2]);
    const double zd = 1.0 + r[2][2] - (r[0][0] + r[1][1]);
    if (xd > 1.0) {
      b = 0.5 * std::sqrt(xd);
      c = 0.25 * (r[0][1] + r[1][0]) / b;
      d = 0.25 * (r[0][2] + r[2][0]) / b;
      a = 0.25 * (r[2][1] - r[1][2]) / b;
    } else if (yd > 1.0) {
      c = 0.5 * std::sqrt(yd);
      b = 0.25 * (r[0][1] + r[1][0]) / c;
      d = 0.25 * (r[1][2] + r[2][1]) / c;
      a = 0.25 * (r[0][2] - r[2][0]) / c;
    } else {
      d = 0.5 * std::sqrt(zd);
      b = 0.25 * (r[0][2] + r[2][0]) / d;
      c = 0.25 * (r[1][2] + r[2][1]) / d;
      a = 0.25 * (r[1][0] - r[0][1]) / d;
    }
    if (a < 0) b = -b, c = -c, d = -d;
  }
  qb = b, qc = c, qd = d;
}

void write_nifti(const fs::path& path, const DataObject& volume, const VolumeWriteOptions& o) {
  const std::string shown = display_path(path).string();
  const Grid& g = volume_grid(volume, shown);
  char units = 0;
  if (g.unit == "m") units = 1;
  else if (g.unit == "mm") units = 2;
  else if (g.unit == kDefaultUnit) units = 3;
  else
    throw InputError(shown + ": NIfTI-1 stores lengths in m, mm or µm only; this volume's unit is '" + g.unit +
                     "' (convert it, or write NRRD or MetaImage)");
  for (size_t i = 0; i < 3; ++i)
    if (g.dims[i] > 32767)
      throw InputError(shown + ": NIfTI-1 stores at most 32767 voxels per axis; axis " + std::string(1, "xyz"[i]) + " has " +
                       std::to_string(g.dims[i]));
  const std::string dtype = volbytes::volume_dtype(volume);
  char h[352] = {};
  auto put = [&](size_t off, auto v) { std::memcpy(h + off, &v, sizeof v); };
  put(0, int32_t{348});
  h[38] = 'r';
  put(40, int16_t{3});
  for (size_t i = 0; i < 3; ++i) put(42 + 2 * i, static_cast<int16_t>(g.dims[i]));
  for (size_t i = 3; i < 7; ++i) put(42 + 2 * i, int16_t{1});
  put(70, static_cast<int16_t>(datatype_code(dtype)));
  put(72, static_cast<int16_t>(8 * volbytes::dtype_bytes(dtype)));
  double qb = 0, qc = 0, qd = 0, qfac = 1;
  to_quaternion(g.direction, qb, qc, qd, qfac);
  put(76, static_cast<float>(qfac));
  for (size_t i = 0; i < 3; ++i) put(80 + 4 * i, static_cast<float>(g.spacing[i]));
  for (size_t i = 3; i < 7; ++i) put(80 + 4 * i, 1.0f);
  put(108, 352.0f);
  put(112, 1.0f);
  put(116, 0.0f);
  h[123] = units;
  std::snprintf(h + 148, 80, "Skelflow");
  put(252, int16_t{1});
  put(254, int16_t{1});
  put(256, static_cast<float>(qb));
  put(260, static_cast<float>(qc));
  put(264, static_cast<float>(qd));
  for (size_t r = 0; r < 3; ++r) {
    put(268 + 4 * r, static_cast<float>(g.origin[r]));
    for (size_t c = 0; c < 3; ++c) put(280 + 16 * r + 4 * c, static_cast<float>(g.direction[r * 3 + c] * g.spacing[c]));
    put(280 + 16 * r + 12, static_cast<float>(g.origin[r]));
  }
  std::memcpy(h + 344, "n+1\0", 4);
  if (std::endian::native == std::endian::big) throw Error("NIfTI writer: big-endian hosts are not supported");
  visit_volume(volume, shown, [&](const auto& v) {
    write_atomically(path, [&](const fs::path& tmp) {
      const std::string mode = is_gz(path) ? "wb" + std::to_string(std::clamp(o.compression, 0, 9)) : "wbT";
      Gz out(tmp, mode.c_str());
      if (!out.f) throw Error("cannot write " + shown + ": " + std::strerror(errno));
      const char* p = reinterpret_cast<const char*>(v.data());
      uint64_t n = static_cast<uint64_t>(v.size()) * sizeof(*v.data());
      bool ok = gzwrite(out.f, h, sizeof h) == static_cast<int>(sizeof h);
      while (ok && n > 0) {
        const auto chunk = static_cast<unsigned>(std::min<uint64_t>(n, 1u << 30));
        ok = gzwrite(out.f, p, chunk) == static_cast<int>(chunk);
        p += chunk;
        n -= chunk;
      }
      const int rc = gzclose(out.f);
      out.f = nullptr;
      if (!ok || rc != Z_OK) throw Error("cannot write " + shown + ": " + std::strerror(errno ? errno : EIO));
    });
  });
}

}  // namespace

VolumeFormat nifti_volume_format() {
  VolumeFormat f;
  f.name = "NIfTI-1";
  f.extensions = {".nii", ".nii.gz"};
  f.sniff = [](std::string_view head) {
    return head.size() >= kHeader && head.substr(344, 4) == std::string_view("n+1\0", 4);
  };
  f.read_header = [](const fs::path& p, const VolumeReadOptions&) { return parse_header(p).header; };
  f.read = read_nifti;
  f.write = write_nifti;
  return f;
}

}  // namespace skel::io
