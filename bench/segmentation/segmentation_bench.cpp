// Segmentation benchmark: connected components (26), Gaussian (float32, sigma 2), median radius 1
// (noisy uint8), dilation with a radius-3 ball and Otsu threshold on synthetic.network rods / plates.
// `generate` writes the inputs as .npy (mask, noisy uint8, noisy float32) so that the SciPy /
// scikit-image peer processes exactly the same data; every other mode runs one operation in its own
// process (so that peak RSS is that operation's) and prints key=value lines; run.sh builds the table.
//
// usage: bench_segmentation SIZE rods|plates DIR generate|cc|gaussian|median|dilate|otsu [THREADS]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "common/bench_util.hpp"
#include "segmentation/segmentation.hpp"
#include "synthetic/network.hpp"

using namespace skel;

namespace {

// Uniform [0, 1) per voxel from its index (splitmix64); deterministic and thread-free.
double noise01(uint64_t i) {
  uint64_t z = i + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

// Reads a .npy written by bench::write_npy (version 1 header, C order, shape (z, y, x) = d reversed).
template <class T>
Volume<T> read_npy(const std::string& path, Dims d) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw Error("cannot read " + path);
  unsigned char pre[10];
  if (std::fread(pre, 1, 10, f) != 10) throw Error(path + ": short read");
  const size_t header_len = static_cast<size_t>(pre[8] | (pre[9] << 8));
  std::string header(header_len, ' ');
  if (std::fread(header.data(), 1, header_len, f) != header_len) throw Error(path + ": short read");
  const std::string shape = "(" + std::to_string(d[2]) + ", " + std::to_string(d[1]) + ", " + std::to_string(d[0]) + ")";
  if (header.find(bench::npy_descr<T>()) == std::string::npos || header.find(shape) == std::string::npos)
    throw Error(path + ": unexpected dtype or shape: " + header);
  Volume<T> v = Volume<T>::uninitialized(Grid(d));
  const size_t got = std::fread(v.data(), sizeof(T), static_cast<size_t>(v.size()), f);
  std::fclose(f);
  if (got != static_cast<size_t>(v.size())) throw Error(path + ": short read");
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr, "usage: %s SIZE rods|plates DIR generate|cc|gaussian|median|dilate|otsu [THREADS]\n", argv[0]);
    return 2;
  }
  const int64_t n = std::atoll(argv[1]);
  const std::string kind = argv[2], dir = argv[3], mode = argv[4];
  const int threads = argc > 5 ? std::atoi(argv[5]) : 2;
  if (mode == "generate") {
    synthetic::NetworkOptions no;
    no.shape = parse_enum<synthetic::Shape>(kind, "shape");
    no.size = {n, n, n};
    no.seed = 1;
    no.threads = threads;
    const VolumeU8 m = std::move(synthetic::make_network(no).mask);
    int64_t object = 0;
    for (uint8_t v : m) object += v;
    bench::write_npy(dir + "/mask.npy", m);
    // Noisy grey images of the same object: uint8 object 128..223 / background 0..95, and float32
    // object 0.6..1.0 / background 0..0.4, the noise uniform per voxel.
    VolumeU8 g = VolumeU8::uninitialized(m.grid());
    for (int64_t i = 0; i < m.size(); ++i)
      g[i] = static_cast<uint8_t>(128 * m[i] + static_cast<int>(noise01(static_cast<uint64_t>(i)) * 96));
    bench::write_npy(dir + "/noisy_u8.npy", g);
    g = VolumeU8();
    VolumeF32 f = VolumeF32::uninitialized(m.grid());
    for (int64_t i = 0; i < m.size(); ++i)
      f[i] = static_cast<float>(0.6 * m[i] + 0.4 * noise01(static_cast<uint64_t>(i) ^ 0x5bd1e995ull));
    bench::write_npy(dir + "/noisy_f32.npy", f);
    std::printf("object_fraction=%.4f\n", static_cast<double>(object) / static_cast<double>(m.size()));
    return 0;
  }
  const Dims d{n, n, n};
  const int repeats = n <= 256 ? 3 : 2;
  double t = 0;
  double rss_input = 0;
  if (mode == "cc") {
    const VolumeU8 m = read_npy<uint8_t>(dir + "/mask.npy", d);
    rss_input = bench::peak_rss_mib();
    segmentation::ComponentOptions o;
    o.connectivity = Connectivity::c26;
    o.threads = threads;
    int64_t count = 0;
    t = bench::best_of(repeats, [&] { count = segmentation::connected_components(m, o).count; });
    std::printf("count=%lld\n", static_cast<long long>(count));
  } else if (mode == "gaussian") {
    // the mask as float32 (converted outside the timing), sigma 2 voxels, truncate 3.5 (radius 7)
    VolumeF32 f = VolumeF32::uninitialized(Grid(d));
    {
      const VolumeU8 m = read_npy<uint8_t>(dir + "/mask.npy", d);
      for (int64_t i = 0; i < m.size(); ++i) f[i] = static_cast<float>(m[i]);
    }
    rss_input = bench::peak_rss_mib();
    segmentation::GaussianOptions o;
    o.sigma = {2, 2, 2};
    o.truncate = 3.5;
    o.threads = threads;
    VolumeF32 g;
    t = bench::best_of(repeats, [&] { g = segmentation::gaussian(f, o); });
    if (n <= 256) bench::write_npy(dir + "/gauss.npy", g);
  } else if (mode == "median") {
    const VolumeU8 g = read_npy<uint8_t>(dir + "/noisy_u8.npy", d);
    rss_input = bench::peak_rss_mib();
    segmentation::MedianOptions o;
    o.radius = 1;
    o.threads = threads;
    VolumeU8 out;
    t = bench::best_of(repeats, [&] { out = segmentation::median_as(g, o); });
    if (n <= 256) bench::write_npy(dir + "/median.npy", out);
  } else if (mode == "dilate") {
    const VolumeU8 m = read_npy<uint8_t>(dir + "/mask.npy", d);
    rss_input = bench::peak_rss_mib();
    segmentation::MorphologyOptions o;
    o.op = segmentation::MorphologyOp::dilate;
    o.radius = 3;
    o.threads = threads;
    VolumeU8 out;
    t = bench::best_of(repeats, [&] { out = segmentation::morphology(m, o); });
    if (n <= 256) bench::write_npy(dir + "/dilate.npy", out);
  } else if (mode == "otsu") {
    // Otsu's threshold of the float image, then the mask image > threshold (as the peer does)
    const VolumeF32 f = read_npy<float>(dir + "/noisy_f32.npy", d);
    rss_input = bench::peak_rss_mib();
    double th = 0;
    int64_t object = 0;
    t = bench::best_of(repeats, [&] {
      th = segmentation::otsu_threshold(f, threads);
      const VolumeU8 m = segmentation::threshold(f, std::nextafter(th, 1e300), 1e300, threads);
      object = m[m.size() / 2];
    });
    const VolumeU8 m = segmentation::threshold(f, std::nextafter(th, 1e300), 1e300, threads);
    object = 0;
    for (uint8_t v : m) object += v;
    std::printf("threshold=%.6f\nobject=%lld\n", th, static_cast<long long>(object));
  } else {
    std::fprintf(stderr, "unknown mode %s\n", mode.c_str());
    return 2;
  }
  std::printf("time=%.4f\npeak_rss_mib=%.0f\ninput_rss_mib=%.0f\n", t, bench::peak_rss_mib(), rss_input);
  return 0;
}
