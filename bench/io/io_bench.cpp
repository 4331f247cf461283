// HDF5 I/O benchmark: io::write_volume / read_volume / read_box on a 512³ uint8 mask and a 512³
// float32 grey image (synthetic.network rods), deflate levels 0 and 1, automatic ~1 MiB chunks.
// `generate` writes both volumes as .npy for the h5py peer (identical arrays); `run` writes, reads
// and block-reads one (dtype, level) combination in its own process and prints key=value lines.
//
// usage: bench_io SIZE DIR generate
//        bench_io SIZE DIR run uint8|float32 LEVEL BLOCK
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <string>

#include "common/bench_util.hpp"
#include "io/hdf5_probe.hpp"
#include "io/hdf5_volume.hpp"
#include "synthetic/network.hpp"

using namespace skel;

namespace {

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

// CPU seconds of this process (all threads) spent in f.
template <class F>
double cpu_of(F&& f) {
  auto now = [] {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
  };
  const double t0 = now();
  f();
  return now() - t0;
}

template <class T>
int run(int64_t n, const std::string& dir, const std::string& dtype, int level, int64_t block) {
  const Dims d{n, n, n};
  const Volume<T> v = read_npy<T>(dir + "/" + dtype + ".npy", d);
  const std::string file = dir + "/ours_" + dtype + "_" + std::to_string(level) + ".h5";
  io::WriteOptions wo;
  wo.compression = level;
  const double tw = bench::best_of(2, [&] { io::write_volume(file, v, "/volume", wo); });
  const auto size = std::filesystem::file_size(file);
  const io::VolumeInfo info = io::read_volume_info(file);
  DataPtr back;
  const double tr = bench::best_of(2, [&] { back = io::read_volume(file); });
  const double cpu = cpu_of([&] { back = io::read_volume(file); });
  const auto* r = dynamic_cast<const Volume<T>*>(back.get());
  const bool same = r && *r == v;
  back.reset();
  // every block x block x block box of the volume, each by its own read_box call
  uint64_t sum = 0;
  auto blocks = [&] {
    for (int64_t z = 0; z < n; z += block)
      for (int64_t y = 0; y < n; y += block)
        for (int64_t x = 0; x < n; x += block) {
          const Dims b{x, y, z}, s{std::min(block, n - x), std::min(block, n - y), std::min(block, n - z)};
          const Volume<T> box = io::read_box<T>(file, "/volume", b, s);
          sum += static_cast<uint64_t>(box[box.size() / 2] != T{});
        }
  };
  const double tb = bench::best_of(2, blocks);
  // The same reads through H5Dread (SKEL_HDF5_OWN_CHUNKS=0: libhdf5's filter pipeline, one thread)
  // in the same process, for the ratio to our chunk decoding (io/hdf5_chunks.hpp).
  setenv("SKEL_HDF5_OWN_CHUNKS", "0", 1);
  bool same_h5 = false;
  const double tr_h5 = bench::best_of(2, [&] { back = io::read_volume(file); });
  const double cpu_h5 = cpu_of([&] { back = io::read_volume(file); });
  {
    const auto* r5 = dynamic_cast<const Volume<T>*>(back.get());
    same_h5 = r5 && *r5 == v;
    back.reset();
  }
  const double tb_h5 = bench::best_of(2, blocks);
  unsetenv("SKEL_HDF5_OWN_CHUNKS");
  // The same reads in this process (SKEL_HDF5_PROBE=0), for the cost of reading in the helper
  // program, the default since issue 22 (io/hdf5_read.hpp: no libhdf5 call on a user's file here).
  const bool helper = io::hdf5_reads_in_helper();
  setenv("SKEL_HDF5_PROBE", "0", 1);
  const double tr_in = bench::best_of(2, [&] { back = io::read_volume(file); });
  const double cpu_in = cpu_of([&] { back = io::read_volume(file); });
  bool same_in = false;
  {
    const auto* ri = dynamic_cast<const Volume<T>*>(back.get());
    same_in = ri && *ri == v;
    back.reset();
  }
  const double tb_in = bench::best_of(2, blocks);
  unsetenv("SKEL_HDF5_PROBE");
  std::printf("reads_in_helper=%s\nread_inprocess=%.4f\nread_inprocess_cpu=%.4f\nblocks_inprocess=%.4f\nidentical_inprocess=%s\n",
              helper ? "yes" : "no", tr_in, cpu_in, tb_in, same_in ? "yes" : "NO");
  std::printf("read_h5dread=%.4f\nblocks_h5dread=%.4f\nidentical_h5dread=%s\nread_cpu=%.4f\nread_h5dread_cpu=%.4f\n", tr_h5,
              tb_h5, same_h5 ? "yes" : "NO", cpu, cpu_h5);
  std::printf("write=%.4f\nread=%.4f\nblocks=%.4f\nfile_bytes=%llu\nchunks=%lldx%lldx%lld\nidentical=%s\nblock_probe=%llu\n",
              tw, tr, tb, static_cast<unsigned long long>(size), static_cast<long long>(info.chunks[0]),
              static_cast<long long>(info.chunks[1]), static_cast<long long>(info.chunks[2]), same ? "yes" : "NO",
              static_cast<unsigned long long>(sum));
  std::printf("peak_rss_mib=%.0f\n", bench::peak_rss_mib());
  return same ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s SIZE DIR generate | SIZE DIR run uint8|float32 LEVEL BLOCK\n", argv[0]);
    return 2;
  }
  const int64_t n = std::atoll(argv[1]);
  const std::string dir = argv[2], mode = argv[3];
  if (mode == "generate") {
    synthetic::NetworkOptions no;
    no.shape = synthetic::Shape::rods;
    no.size = {n, n, n};
    no.seed = 1;
    no.noise = 0.1;
    no.threads = 2;
    const synthetic::NetworkResult r = synthetic::make_network(no);
    bench::write_npy(dir + "/uint8.npy", r.mask);
    bench::write_npy(dir + "/float32.npy", r.image);
    return 0;
  }
  if (mode == "run" && argc >= 7) {
    const std::string dtype = argv[4];
    const int level = std::atoi(argv[5]);
    const int64_t block = std::atoll(argv[6]);
    if (dtype == "uint8") return run<uint8_t>(n, dir, dtype, level, block);
    if (dtype == "float32") return run<float>(n, dir, dtype, level, block);
  }
  std::fprintf(stderr, "bad arguments\n");
  return 2;
}
