#include "segmentation/segmentation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>
#include <vector>

#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::segmentation {

namespace {
// The voxel rule of threshold(), shared by the in-memory and the block-wise path.
template <class T>
void threshold_span(const T* in, uint8_t* out, int64_t n, double low, double high) {
  for (int64_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(in[i]);
    out[i] = x >= low && x <= high ? 1 : 0;
  }
}

// Otsu's bin of value x (x not NaN), shared by both paths.
inline size_t otsu_bin(double x, double base, double scale, int bins) {
  return static_cast<size_t>(std::clamp<int64_t>(static_cast<int64_t>((x - base) * scale), 0, bins - 1));
}

// Otsu's threshold from the 256-bin histogram of values in [lo, hi] (see otsu_threshold).
double otsu_from_histogram(const std::vector<int64_t>& h, double base, double scale, bool byte) {
  const int bins = static_cast<int>(h.size());
  const double total = static_cast<double>(std::accumulate(h.begin(), h.end(), int64_t{0}));
  double sum_all = 0;
  for (int b = 0; b < bins; ++b) sum_all += b * static_cast<double>(h[b]);
  double w0 = 0, sum0 = 0, best = -1;
  int best_b = 0, best_last = 0;  // the plateau of maximal variance (empty bins between the modes)
  for (int b = 0; b < bins - 1; ++b) {
    w0 += static_cast<double>(h[b]);
    sum0 += b * static_cast<double>(h[b]);
    const double w1 = total - w0;
    if (w0 == 0 || w1 == 0) continue;
    const double m0 = sum0 / w0, m1 = (sum_all - sum0) / w1;
    const double between = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (between > best * (1 + 1e-12)) {
      best = between;
      best_b = best_last = b;
    } else if (between >= best * (1 - 1e-12)) {
      best_last = b;
    }
  }
  // Voxels of bins <= the chosen bin are background, the rest object (value > threshold, as in
  // scikit-image); when several bins tie (an empty gap between the modes) the middle of the gap is
  // taken. uint8: the bin is the grey value itself; otherwise the largest value below the next bin.
  const int chosen = (best_b + best_last) / 2;
  if (byte) return static_cast<double>(chosen);
  return std::nextafter(base + (chosen + 1) / scale, -std::numeric_limits<double>::infinity());
}
// Below this many values the range, histogram and mask loops run on the calling thread.
constexpr int64_t kParallelValues = int64_t{1} << 16;

// Smallest and largest non-NaN value of p[0..n) on `threads` threads (+inf, -inf when none).
template <class T>
std::pair<double, double> value_range(const T* p, int64_t n, int threads) {
  if (n < kParallelValues) threads = 1;  // small blocks: not worth the tasks
  const int parts = threads == 1 ? 1 : std::max(1, effective_threads(threads)) * 4;
  std::vector<std::pair<double, double>> part(static_cast<size_t>(parts),
                                              {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()});
  parallel_chunks(0, n, parts, threads, [&](int64_t c, int64_t b, int64_t e) {
    double lo = part[static_cast<size_t>(c)].first, hi = part[static_cast<size_t>(c)].second;
    for (int64_t i = b; i < e; ++i) {
      const double x = static_cast<double>(p[i]);
      if (std::isnan(x)) continue;
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
    part[static_cast<size_t>(c)] = {lo, hi};
  });
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& [a, b] : part) {
    lo = std::min(lo, a);
    hi = std::max(hi, b);
  }
  return {lo, hi};
}

// Adds the non-NaN values of p[0..n) to the Otsu histogram h (bins of otsu_bin) on `threads` threads.
template <class T>
void add_to_histogram(const T* p, int64_t n, double base, double scale, std::vector<int64_t>& h, int threads) {
  const int bins = static_cast<int>(h.size());
  if (n < kParallelValues) threads = 1;
  const int parts = threads == 1 ? 1 : std::max(1, effective_threads(threads)) * 4;
  std::vector<std::vector<int64_t>> part(static_cast<size_t>(parts), std::vector<int64_t>(h.size(), 0));
  parallel_chunks(0, n, parts, threads, [&](int64_t c, int64_t b, int64_t e) {
    auto& ph = part[static_cast<size_t>(c)];
    for (int64_t i = b; i < e; ++i) {
      const double x = static_cast<double>(p[i]);
      if (!std::isnan(x)) ++ph[otsu_bin(x, base, scale, bins)];
    }
  });
  for (const auto& ph : part)
    for (size_t b = 0; b < h.size(); ++b) h[b] += ph[b];
}
}  // namespace

double otsu_threshold(const DataObject& image, int threads) {
  return visit_volume(image, "image", [&](const auto& v) -> double {
    using T = typename std::decay_t<decltype(v)>::value_type;
    if (v.size() == 0) throw InputError("input 'image' is empty");
    const auto [lo, hi] = value_range(v.data(), v.size(), threads);
    if (!(hi > lo)) return lo;
    const bool byte = std::is_same_v<T, uint8_t>;
    const int bins = 256;
    const double scale = byte ? 1.0 : (bins - 1) / (hi - lo);
    const double base = byte ? 0.0 : lo;
    std::vector<int64_t> h(bins, 0);
    add_to_histogram(v.data(), v.size(), base, scale, h, threads);
    return otsu_from_histogram(h, base, scale, byte);
  });
}

VolumeU8 threshold(const DataObject& image, double low, double high, int threads) {
  if (low > high) throw InputError("threshold: low (" + std::to_string(low) + ") is above high (" + std::to_string(high) + ")");
  return visit_volume(image, "image", [&](const auto& v) {
    VolumeU8 m = VolumeU8::uninitialized(v.grid());
    parallel_for(0, v.size(), threads, [&](int64_t b, int64_t e) {
      threshold_span(v.data() + b, m.data() + b, e - b, low, high);
    }, 1 << 16);
    return m;
  });
}

ThresholdResult threshold(const DataObject& image, const ThresholdOptions& options) {
  ThresholdResult r;
  r.low = options.low;
  r.high = options.high;
  if (options.method == ThresholdMethod::otsu) {
    r.low = std::nextafter(otsu_threshold(image, options.threads), std::numeric_limits<double>::infinity());
    r.high = std::numeric_limits<double>::infinity();
  }
  r.mask = threshold(image, r.low, r.high, options.threads);
  // Counted in parallel (a sequential byte sum took ~1.5 s of the stage at 1280³).
  const int64_t n = r.mask.size(), chunks = std::clamp<int64_t>(n >> 22, 1, 256);
  std::vector<int64_t> count(static_cast<size_t>(chunks), 0);
  const uint8_t* m = r.mask.data();
  parallel_chunks(0, n, chunks, options.threads, [&](int64_t c, int64_t b, int64_t e) {
    int64_t k = 0;
    for (int64_t i = b; i < e; ++i) k += m[i];
    count[static_cast<size_t>(c)] = k;
  });
  for (int64_t k : count) r.object_voxels += k;
  return r;
}

// ---------------------------------------------------------------- block-wise (out-of-core)
BlockThresholdResult threshold_blocks(const DataObject& image, const ChunkedVolume& mask, const ThresholdOptions& options,
                                      const Dims& block, const Interrupter& interrupter) {
  const Grid& grid = any_volume_grid(image, "input 'image'");
  if (mask.dims() != grid.dims) throw Error("threshold_blocks: the mask's grid differs from the image's");
  const BlockLayout layout(grid.dims, block);
  BlockThresholdResult r;
  r.low = options.low;
  r.high = options.high;
  visit_voxel_type(image.type_id(), "input 'image'", [&](auto tag) {
    using T = decltype(tag);
    const bool otsu = options.method == ThresholdMethod::otsu;
    const Interrupter work = otsu ? interrupter.sub(2.0 / 3.0, 1.0) : interrupter;
    if (otsu) {
      if (grid.voxel_count() == 0) throw InputError("input 'image' is empty");
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for_each_owned_block(layout, interrupter.sub(0.0, 1.0 / 3.0), "threshold (range)", [&](const Block& b) {
        const Volume<T> v = read_block<T>(image, b.begin, b.size, "input 'image'");
        const auto [blo, bhi] = value_range(v.data(), v.size(), options.threads);
        lo = std::min(lo, blo);
        hi = std::max(hi, bhi);
      });
      // Several ranks: each saw its own blocks.
      std::tie(lo, hi) = minmax_over_ranks(lo, hi);
      if (!(hi > lo)) {
        r.low = std::nextafter(lo, std::numeric_limits<double>::infinity());
      } else {
        const int bins = 256;
        const bool byte = std::is_same_v<T, uint8_t>;
        const double scale = byte ? 1.0 : (bins - 1) / (hi - lo);
        const double base = byte ? 0.0 : lo;
        std::vector<int64_t> h(bins, 0);
        for_each_owned_block(layout, interrupter.sub(1.0 / 3.0, 2.0 / 3.0), "threshold (histogram)", [&](const Block& b) {
          const Volume<T> v = read_block<T>(image, b.begin, b.size, "input 'image'");
          add_to_histogram(v.data(), v.size(), base, scale, h, options.threads);
        });
        h = sum_over_ranks(h);
        r.low = std::nextafter(otsu_from_histogram(h, base, scale, byte), std::numeric_limits<double>::infinity());
      }
      r.high = std::numeric_limits<double>::infinity();
    }
    if (r.low > r.high)
      throw InputError("threshold: low (" + std::to_string(r.low) + ") is above high (" + std::to_string(r.high) + ")");
    // Otsu's passes read only the image (they run again when resumed); the mask's blocks are
    // resumable (--resume), each committing its object count.
    const auto body = [&](const Block& b) {
      const Volume<T> v = read_block<T>(image, b.begin, b.size, "input 'image'");
      VolumeU8 m = VolumeU8::uninitialized(v.grid());
      const int t = v.size() < kParallelValues ? 1 : options.threads;
      std::vector<int64_t> count(t == 1 ? 1 : static_cast<size_t>(std::max(1, effective_threads(t))) * 4, 0);
      parallel_chunks(0, v.size(), static_cast<int64_t>(count.size()), t, [&](int64_t c, int64_t b0, int64_t e) {
        threshold_span(v.data() + b0, m.data() + b0, e - b0, r.low, r.high);
        int64_t k = 0;
        for (int64_t i = b0; i < e; ++i) k += m[i];
        count[static_cast<size_t>(c)] = k;
      });
      int64_t n = 0;
      for (int64_t k : count) n += k;
      r.object_voxels += n;
      mask.write(m, b.begin);
      return payload_of(n);
    };
    if (distributing())
      for_each_owned_block(layout, work, "threshold", body);
    else
      for_each_block_resumable(layout, work, "threshold", body,
                               [&](const Block&, const std::string& p) { r.object_voxels += payload_as<int64_t>(p); });
    r.object_voxels = sum_over_ranks(r.object_voxels);
  });
  return r;
}

}  // namespace skel::segmentation
