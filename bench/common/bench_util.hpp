#pragma once
// Small helpers shared by benchmark programs: wall-clock timing, peak RSS, and .npy files so that
// Python peers (SciPy, scikit-image) process exactly the same volume in the same run.
#include <sys/resource.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "skel/error.hpp"
#include "skel/volume.hpp"

namespace skel::bench {

inline double now_seconds() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}

// Runs f() `repeats` times and returns the best wall time in seconds.
template <class F>
double best_of(int repeats, F&& f) {
  double best = 1e300;
  for (int i = 0; i < repeats; ++i) {
    const double t0 = now_seconds();
    f();
    best = std::min(best, now_seconds() - t0);
  }
  return best;
}

// Peak resident set size of this process so far, in MiB.
inline double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

template <class T> constexpr const char* npy_descr();
template <> constexpr const char* npy_descr<uint8_t>() { return "|u1"; }
template <> constexpr const char* npy_descr<uint16_t>() { return "<u2"; }
template <> constexpr const char* npy_descr<uint32_t>() { return "<u4"; }
template <> constexpr const char* npy_descr<uint64_t>() { return "<u8"; }
template <> constexpr const char* npy_descr<int32_t>() { return "<i4"; }
template <> constexpr const char* npy_descr<float>() { return "<f4"; }
template <> constexpr const char* npy_descr<double>() { return "<f8"; }

// Writes a volume as a NumPy .npy file with shape (z, y, x), C order (numpy.load reads it).
template <class T>
void write_npy(const std::string& path, const Volume<T>& v) {
  std::string header = std::string("{'descr': '") + npy_descr<T>() + "', 'fortran_order': False, 'shape': (" +
                       std::to_string(v.nz()) + ", " + std::to_string(v.ny()) + ", " +
                       std::to_string(v.nx()) + "), }";
  const size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  if (!f) throw Error("cannot write " + path);
  const char magic[8] = {'\x93', 'N', 'U', 'M', 'P', 'Y', 1, 0};
  f.write(magic, 8);
  const uint16_t len = static_cast<uint16_t>(header.size());
  f.write(reinterpret_cast<const char*>(&len), 2);
  f.write(header.data(), static_cast<std::streamsize>(header.size()));
  f.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.bytes()));
  if (!f) throw Error("short write to " + path);
}

}  // namespace skel::bench
