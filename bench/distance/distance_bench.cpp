// Distance transform benchmark: Euclidean DT, feature transform and chamfer on rods / plates
// volumes; chamfer compared with a memcpy of its output bytes. Writes the mask (and at <= 256^3 our
// EDT) as .npy for the SciPy peer; run.sh assembles the markdown section.
//
// usage: bench_distance SIZE rods|plates OUT_DIR MODE [THREADS]; prints key=value lines.
// The volume is synthetic.network (make_network, module defaults) when that library is built, else a
// built-in lattice of rods / plates.

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "common/bench_util.hpp"
#include "distance/distance.hpp"
#if defined(SKEL_HAVE_SYNTHETIC)
#include "synthetic/network.hpp"
#endif

using namespace skel;

namespace {

// A lattice network: rods along x, y and z (radius n/40) on a grid of period n/8 with a deterministic
// offset per rod, or plates (thickness n/40) perpendicular to the three axes with period n/6.
#if defined(SKEL_HAVE_SYNTHETIC)
VolumeU8 make_volume(int64_t n, const std::string& kind) {
  synthetic::NetworkOptions o;
  o.shape = parse_enum<synthetic::Shape>(kind, "shape");
  o.size = {n, n, n};
  o.threads = 2;
  return std::move(synthetic::make_network(o).mask);
}
#else
VolumeU8 make_volume(int64_t n, const std::string& kind) {
  VolumeU8 m({n, n, n}, 0);
  const int64_t period = kind == "rods" ? std::max<int64_t>(8, n / 8) : std::max<int64_t>(8, n / 6);
  const double r = std::max(2.0, static_cast<double>(n) / 40.0);
  auto offset = [&](int64_t k) { return static_cast<double>((k * 7919) % 11) - 5.0; };
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y) {
      uint8_t* row = m.data() + m.index(0, y, z);
      for (int64_t x = 0; x < n; ++x) {
        bool in = false;
        if (kind == "rods") {
          auto near_axis = [&](int64_t a, int64_t b) {
            const int64_t ka = a / period, kb = b / period;
            const double ca = static_cast<double>(ka * period + period / 2) + offset(ka + 3 * kb);
            const double cb = static_cast<double>(kb * period + period / 2) + offset(kb + 5 * ka);
            const double da = static_cast<double>(a) - ca, db = static_cast<double>(b) - cb;
            return da * da + db * db <= r * r;
          };
          in = near_axis(y, z) || near_axis(x, z) || near_axis(x, y);
        } else {
          auto near_plane = [&](int64_t a) {
            const int64_t k = a / period;
            const double c = static_cast<double>(k * period + period / 2) + offset(k);
            return std::abs(static_cast<double>(a) - c) <= r / 2;
          };
          in = near_plane(x) || near_plane(y) || near_plane(z);
        }
        row[x] = in ? 1 : 0;
      }
    }
  return m;
}
#endif

// Reads back a uint8 .npy written by bench::write_npy (shape (z, y, x), C order).
VolumeU8 read_mask_npy(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot read " + path);
  char magic[8];
  f.read(magic, 8);
  uint16_t len = 0;
  f.read(reinterpret_cast<char*>(&len), 2);
  std::string header(len, ' ');
  f.read(header.data(), len);
  const size_t p = header.find("'shape': (");
  if (p == std::string::npos || header.find("|u1") == std::string::npos) throw Error(path + ": not a uint8 volume");
  int64_t z = 0, y = 0, x = 0;
  if (std::sscanf(header.c_str() + p + 10, "%ld, %ld, %ld", &z, &y, &x) != 3) throw Error(path + ": bad shape");
  VolumeU8 m({x, y, z}, 0);
  f.read(reinterpret_cast<char*>(m.data()), static_cast<std::streamsize>(m.size()));
  if (!f) throw Error(path + ": short read");
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr, "usage: %s SIZE rods|plates OUT_DIR generate|edt|ft|chamfer|chamfer_bp|memcpy|memcpy_fresh [THREADS]\n", argv[0]);
    return 2;
  }
  const int64_t n = std::atoll(argv[1]);
  const std::string kind = argv[2], dir = argv[3], mode = argv[4];
  const int threads = argc > 5 ? std::atoi(argv[5]) : 2;
  if (mode == "generate") {
    const VolumeU8 g = make_volume(n, kind);
    int64_t object = 0;
    for (uint8_t v : g) object += v != 0;
    std::printf("object_fraction=%.4f\n", static_cast<double>(object) / static_cast<double>(g.size()));
    bench::write_npy(dir + "/mask.npy", g);
    return 0;
  }
  const VolumeU8 m = read_mask_npy(dir + "/mask.npy");
  if (m.nx() != n) throw Error("mask.npy does not have the requested size");
  const double rss_input = bench::peak_rss_mib();
  const int repeats = n <= 256 ? 3 : 2;
  double t = 0;
  int runs = repeats;  // calls timed below (for the CPU seconds per call)
  const std::clock_t cpu0 = std::clock();
  if (mode == "edt") {
    // border_is_object: the same convention as scipy.ndimage.distance_transform_edt
    distance::EuclideanOptions o;
    o.border_is_object = true;
    o.threads = threads;
    VolumeF32 d;
    t = bench::best_of(repeats, [&] { d = distance::euclidean(m, o); });
    if (n <= 256) bench::write_npy(dir + "/edt.npy", d);
  } else if (mode == "ft") {
    distance::DistanceOptions o;
    o.threads = threads;
    t = bench::best_of(repeats, [&] { (void)distance::feature_transform(m, o); });
  } else if (mode == "chamfer") {
    distance::ChamferOptions o;
    o.threads = threads;
    t = bench::best_of(repeats, [&] { (void)distance::chamfer(m, o); });
    std::printf("bits=%d\n", distance::chamfer_output_bits(m.grid(), o));
  } else if (mode == "chamfer_bp") {
    distance::ChamferOptions o;
    runs = 1;
    t = bench::best_of(1, [&] { (void)distance::chamfer_nearest(m, o); });
  } else if (mode == "memcpy") {
    // the bytes of the chamfer output (uint16), copied between two warm buffers
    const size_t bytes = static_cast<size_t>(m.size()) * 2;
    std::vector<char> a(bytes, 1), b(bytes, 0);
    runs = repeats + 2;
    t = bench::best_of(repeats + 2, [&] {
      std::memcpy(b.data(), a.data(), bytes);
      a[static_cast<size_t>(static_cast<unsigned char>(b[bytes / 2])) % bytes] ^= 1;  // keep the copy observable
    });
  } else if (mode == "memcpy_fresh") {
    // the same copy into a newly allocated buffer each time (page faults included, with the same
    // transparent-huge-page advice the distance outputs get), as a function returning a new volume pays
    const size_t bytes = static_cast<size_t>(m.size()) * 2;
    std::vector<char> a(bytes, 1);
    runs = repeats + 2;
    t = bench::best_of(repeats + 2, [&] {
      std::unique_ptr<char[]> b(new char[bytes]);
      advise_huge_pages(b.get(), bytes);
      std::memcpy(b.get(), a.data(), bytes);
      a[static_cast<size_t>(static_cast<unsigned char>(b[bytes / 2])) % bytes] ^= 1;
    });
  } else {
    std::fprintf(stderr, "unknown mode %s\n", mode.c_str());
    return 2;
  }
  // process CPU seconds (all threads) per repeat: less sensitive than wall time to a loaded machine
  const double cpu = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC / runs;
  std::printf("time=%.4f\ncpu=%.4f\npeak_rss_mib=%.0f\ninput_rss_mib=%.0f\n", t, cpu, bench::peak_rss_mib(), rss_input);
  return 0;
}
